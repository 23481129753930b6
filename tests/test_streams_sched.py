"""The stream scheduler in-process (CPython) on a simulated clock: exact long-run
rates, ticks_ms wrap-around, streams due together on one grid, the byte budget and its fair
shares, priority traffic, a link that cannot take more, a stall, the seed's
REQUEST_DATA_STREAM on a MAVLink 1 link, and the message-interval commands."""
import os
import struct
import sys

from conftest import ROOT

sys.path.insert(0, os.path.join(ROOT, "tests", "mpy"))
from harness import Bench  # noqa: E402

from mavstack.compat import ticks_add  # noqa: E402
from mavstack.dialects import common, seed2012  # noqa: E402
from mavstack.services.streams import GROUPS, group  # noqa: E402

ATTITUDE, GPI, VFR_HUD, SCALED_IMU, LOCAL, RC, SERVO, GPS_RAW = 30, 33, 74, 26, 32, 65, 36, 24
FRAME_MAX = 280


class Vehicle:
    """A bench endpoint with the streams service, every slot written each tick."""

    def __init__(self, bps=200000, version=2, dialect=common, start=None, defaults=()):
        class Board:
            DEFAULT_STREAMS = defaults

        self.b = Bench(services=("commands", "streams"), dialect=dialect, version=version, board=Board)
        self.ep = self.b.ep
        self.link = self.ep.links[0]
        self.link.bytes_per_s = bps
        if version == 2:
            self.link.tx.version = 2
            self.link.negotiate = False
        self.streams = self.ep.services["streams"]
        self.tm = self.ep.telemetry
        if start is not None:
            self.b.now = start
        self.per_tick = []  # frames sent in each tick, when recording
        self.record = False
        self.bytes = []  # bytes sent in each tick, when recording
        self.b.watch = self._watch
        self._frames = 0
        self.write = True

    def _watch(self, msgid, p):
        self._frames += 1

    def fill(self):
        tm = self.tm
        tm.attitude(0.1, 0.2, 0.3, 0.0, 0.0, 0.0)
        tm.attitude_quaternion(1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
        tm.global_position(473977420, 85455940, 488000, 1000, 1, 2, 3, 9000)
        tm.local_position(1.0, 2.0, 3.0, 0.0, 0.0, 0.0)
        tm.vfr_hud(1.0, 1.0, 90, 40, 500.0, 0.5)
        tm.scaled_imu(1, 2, -1000, 4, 5, 6, 210, 0, 430)
        tm.rc_channels([1500] * 8)
        tm.servo_output([1200] * 4)
        tm.gps_raw(3, 473977420, 85455940, 488000, 80, 120, 150, 9000, 12)
        tm.battery(12300, 400, 80)

    def run(self, ticks, fill=True):
        link = self.link
        for _ in range(ticks):
            if fill and self.write:
                self.fill()
            before = link.tx_bytes
            self._frames = 0
            self.b.run(1)
            if self.record:
                self.per_tick.append(self._frames)
                self.bytes.append(link.tx_bytes - before)

    def counts(self, ids):
        return {m: self.b.seen[m] for m in ids}

    def measure(self, ids, ticks):
        before = self.counts(ids)
        self.run(ticks)
        after = self.counts(ids)
        return {m: after[m] - before[m] for m in ids}


def test_long_run_rates_are_exact():
    v = Vehicle()
    # Intervals that are not whole milliseconds keep their remainder.
    rates = {ATTITUDE: 50, GPI: 7, VFR_HUD: 3, SCALED_IMU: 1, LOCAL: 13}
    for m, hz in rates.items():
        assert v.streams.set_rate(v.link, m, hz)
    v.run(500)
    got = v.measure(list(rates), 30000)
    for m, hz in rates.items():
        assert abs(got[m] - hz * 30) <= 1, (m, got[m], hz)


def test_rates_survive_ticks_wrap_around():
    start = ticks_add(0, -3000)  # CPython's ticks wrap at 2**30
    v = Vehicle(start=start)
    rates = {ATTITUDE: 50, GPI: 10, VFR_HUD: 1}
    for m, hz in rates.items():
        v.streams.set_rate(v.link, m, hz)
    got = v.measure(list(rates), 10000)
    assert v.b.now < start  # wrapped
    for m, hz in rates.items():
        assert abs(got[m] - hz * 10) <= 1, (m, got[m])
    assert v.tm.uptime_ms >= 9999  # the uptime kept counting across the wrap


def test_streams_share_one_grid():
    """Streams whose intervals divide each other fall due together, however far apart
    they were set: the loop wakes once for all of them (docs/services/streams.md)."""
    v = Vehicle()
    ids = [ATTITUDE, GPI, VFR_HUD, SCALED_IMU, LOCAL, RC, SERVO, GPS_RAW, 31, 147]
    for i, m in enumerate(ids):
        v.streams.set_rate(v.link, m, 10 if i % 2 else 5)
        v.run(37)
    v.record = True
    v.run(3000)
    assert 225 <= sum(v.per_tick) <= 235
    busy = [n for n in v.per_tick if n]
    assert len(busy) <= 31 and max(busy) == 10, busy  # a tick each 100 ms, all ten every 200


def test_over_budget_rates_scale_fairly_and_bytes_stay_within():
    bps = 5760  # 57600 baud
    v = Vehicle(bps=bps)
    rates = {ATTITUDE: 100, GPI: 100, VFR_HUD: 50, SCALED_IMU: 50}  # about twice the budget
    demand = 0
    for m, hz in rates.items():
        v.streams.set_rate(v.link, m, hz)
        demand += hz * ((common.CRC_LEN[m] >> 16) + 12)
    assert demand > 1.9 * bps
    v.run(2000)
    v.record = True
    got = v.measure(list(rates), 10000)
    # Every second, the link carried no more than its budget (plus one saved-up burst).
    for s in range(10):
        assert sum(v.bytes[s * 1000:(s + 1) * 1000]) <= bps + 300, s
    assert sum(v.bytes) <= bps * 10
    shares = {m: got[m] / (rates[m] * 10) for m in rates}
    assert min(shares.values()) > 0.3
    assert max(shares.values()) - min(shares.values()) < 0.05  # the same share each
    # MESSAGE_INTERVAL reports what was achieved.
    for m in rates:
        achieved_hz = 1e6 / v.streams.interval(v.link, m)
        assert abs(achieved_hz * 10 - got[m]) <= 0.03 * got[m] + 1, (m, achieved_hz, got[m])


def test_priority_traffic_goes_first_and_counts_against_the_budget():
    bps = 5760
    v = Vehicle(bps=bps)
    for m, hz in {ATTITUDE: 50, GPI: 50, VFR_HUD: 50}.items():
        v.streams.set_rate(v.link, m, hz)
    link = v.link
    payload = bytearray(b"\x01" * 25)
    sent = []

    def priority(n):
        # Half the link in PARAM_VALUEs (37 bytes each), sent outside the scheduler.
        for i in range(n):
            if i % 13 == 0:
                sent.append(link.send_payload(22, payload, 25))
            v.run(1)

    v.run(2000)
    alone = v.measure([ATTITUDE], 5000)[ATTITUDE]
    v.record = True
    priority(2000)  # the fit adapts within a second or two
    before = v.b.seen[ATTITUDE]
    v.bytes = []
    priority(5000)
    shared = v.b.seen[ATTITUDE] - before
    assert sum(v.bytes) <= bps * 5 + 300  # tx_bytes include the PARAM_VALUEs
    assert 0 < shared < 0.6 * alone
    assert all(sent) and v.b.seen[22] == len(sent)  # priority traffic was never held back


def test_a_full_link_is_left_until_the_next_tick():
    v = Vehicle()
    for m in (ATTITUDE, GPI, VFR_HUD):
        v.streams.set_rate(v.link, m, 50)
    v.run(1000)
    transport = v.b.vehicle_end
    writes = []

    def full(buf, n):
        writes.append(n)
        return 0

    transport.write = full
    v.run(500)
    assert v.link.tx_dropped == len(writes)
    assert len(writes) <= 500  # at most one attempt per tick: nothing spins on a full link
    del transport.write
    v.record = True
    got = v.measure([ATTITUDE, GPI, VFR_HUD], 1000)
    # Resumes at the rate, with one message of catch-up at most each, not the backlog.
    for m, n in got.items():
        assert 50 <= n <= 51, (m, n)
    assert max(v.per_tick) <= 3


def test_after_a_stall_the_missed_messages_are_not_burst():
    v = Vehicle()
    v.streams.set_rate(v.link, ATTITUDE, 50)
    v.run(1000)
    before = v.b.seen[ATTITUDE]
    v.b.now = ticks_add(v.b.now, 700)  # the loop was away for 700 ms (35 intervals)
    v.record = True
    v.run(100)
    assert v.b.seen[ATTITUDE] - before <= 7  # 5 in 100 ms, and a catch-up of one or two
    assert max(v.per_tick) == 1


def test_unwritten_slot_is_not_streamed():
    v = Vehicle()
    v.write = False
    assert v.streams.set_rate(v.link, 105, 20)  # HIGHRES_IMU: nobody writes it yet
    v.run(1000)
    assert v.b.seen[105] == 0
    v.tm.highres_imu(0.0, 0.0, -9.8, 0.0, 0.0, 0.0, 0.2, 0.0, 0.4, 1013.0, 0.0, 100.0, 20.0, 0)
    v.run(1000)
    assert abs(v.b.seen[105] - 20) <= 1


def test_defaults_stream_unasked_and_zero_restores_them():
    v = Vehicle(defaults=((ATTITUDE, 10), (GPI, 2.5)))
    got = v.measure([ATTITUDE, GPI, VFR_HUD], 4000)
    assert abs(got[ATTITUDE] - 40) <= 1 and abs(got[GPI] - 10) <= 1 and got[VFR_HUD] == 0
    v.streams.set_interval(v.link, ATTITUDE, -1)
    assert v.streams.interval(v.link, ATTITUDE) == -1
    assert v.measure([ATTITUDE], 1000)[ATTITUDE] == 0
    v.streams.set_interval(v.link, ATTITUDE, 0)
    assert v.streams.interval(v.link, ATTITUDE) == 100000
    assert abs(v.measure([ATTITUDE], 2000)[ATTITUDE] - 20) <= 1


def test_message_interval_commands_in_process():
    v = Vehicle(defaults=((ATTITUDE, 10),))
    g = v.b.gcs()
    got = []
    v.b.watch = lambda msgid, p: got.append((msgid, struct.unpack_from("<iH", p, 0))) if msgid == 244 else None
    v.b.send(g.command(510, float(ATTITUDE)))
    v.run(1)
    assert v.b.ack_command == 510 and v.b.ack_result == 0
    assert got == [(244, (100000, ATTITUDE))]
    v.b.send(g.command(511, float(ATTITUDE), 40000.0))
    v.b.send(g.command(512, 244.0, float(ATTITUDE)))  # REQUEST_MESSAGE for MESSAGE_INTERVAL
    v.run(1)
    assert got[-1] == (244, (40000, ATTITUDE))
    v.b.send(g.command(511, 22.0, 100000.0))  # PARAM_VALUE is not a stream here
    v.run(1)
    assert v.b.ack_command == 511 and v.b.ack_result == 2
    v.b.send(g.command(510, 22.0))
    v.run(1)
    assert got[-1] == (244, (0, 22))  # not available


def test_seed_request_data_stream_on_a_mavlink1_link():
    v = Vehicle(version=1, dialect=seed2012)
    g = v.b.gcs(version=1)
    replies = []
    v.b.watch = lambda msgid, p: replies.append((p[2], p[3], p[0] | p[1] << 8)) if msgid == 67 else None
    # REQUEST_DATA_STREAM: rate, target system, target component, stream id, start
    v.b.send(g.frame(66, 10, 1, 1, 10, 1))  # EXTRA1 (ATTITUDE...) at 10 Hz
    v.run(2000)
    assert replies == [(10, 1, 10)]
    assert abs(v.b.seen[ATTITUDE] - 20) <= 1 and v.b.seen[31] > 0
    v.b.send(g.frame(66, 0, 1, 1, 10, 0))
    v.run(10)
    before = v.b.seen[ATTITUDE]
    v.run(1000)
    assert replies[-1] == (10, 0, 0)
    assert v.b.seen[ATTITUDE] == before
    v.b.send(g.frame(66, 4, 2, 1, 10, 1))  # another vehicle's request: ignored
    v.run(500)
    assert len(replies) == 2 and v.b.seen[ATTITUDE] == before


def test_group_table():
    ids = group(0)
    assert len(ids) == len(set(ids))  # each message in one group
    assert sorted(sid for sid, _ in GROUPS) == [1, 2, 3, 4, 6, 10, 11, 12]
    assert group(5) is None
