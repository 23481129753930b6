"""A flood must not silence the real ground station. The unix vehicle (its simulator
running), budgeted as a 57600 baud radio (5,760 B/s), hears a ground station sending
HEARTBEATs at 1 Hz; then, on the same link, a flood of requests (PARAM_REQUEST_READ,
COMMAND_LONG REQUEST_MESSAGE, PING, MISSION_REQUEST_LIST) from 249 system ids, for 20 s,
far more than the link can answer. During it the station's three parameter reads are
answered and its three COMMAND_LONGs ACKed, each within 2 s and without a retry; the
vehicle keeps its 1 Hz HEARTBEAT and sends no more than its budget. Real UDP sockets,
pymavlink on both sides. Then, in-process: the held-back ACKs' queue (order, replies,
retries, drops), the sender table through 249 identities, and the held-back path under
heap_lock (tests/mpy/flood_steady.py)."""
import os
import sys
import time

import pytest

os.environ.setdefault("MAVLINK20", "1")
from pymavlink.dialects.v20 import common as mav  # noqa: E402

from conftest import ROOT, run_mpy  # noqa: E402
from gcs_tools import UdpSender  # noqa: E402

BYTES_PER_S = 5760
FLOOD_S = 20.0
STATION = (255, 190)
# 1..255 but the vehicle's 1, the station's 255 and 251..254 (other ground stations' ids)
FLOOD_SYSIDS = tuple(range(2, 251))
READS = (b"WP_SPEED", b"SIM_GPS_GLITCH_M", b"RTL_LOIT_TIME_S")
MSG_SYSTEM_TIME = 2


class Flood(UdpSender):
    """From one address, round robin over FLOOD_SYSIDS, about `per_s` requests a second:
    PARAM_REQUEST_READ (by index, never one of `spare`), COMMAND_LONG REQUEST_MESSAGE
    SYSTEM_TIME, PING and MISSION_REQUEST_LIST. The frames are made beforehand, so the
    sender's own speed is not what limits it."""

    def __init__(self, port, spare, count, per_s=2000):
        UdpSender.__init__(self, port)
        self.per_s = per_s
        self._sock.setblocking(False)
        indices = [i for i in range(count) if i not in spare]
        self._frames = []
        for k, sysid in enumerate(FLOOD_SYSIDS):
            m = mav.MAVLink(None, sysid, 190)
            msgs = (mav.MAVLink_param_request_read_message(1, 1, b"", indices[k % len(indices)]),
                    mav.MAVLink_command_long_message(1, 1, 512, 0, MSG_SYSTEM_TIME, 0, 0, 0, 0, 0, 0),
                    mav.MAVLink_ping_message(k, 0, 0, 0),
                    mav.MAVLink_mission_request_list_message(1, 1, 0))
            self._frames.append([msg.pack(m) for msg in msgs])
        self.received = 0

    def _frame(self, k):
        n = len(self._frames)
        return self._frames[k % n][(k // n) % 4]

    def _run(self):
        batch = 20
        while not self._stop.is_set():
            for _ in range(batch):
                try:
                    self._sock.sendto(self._frame(self.sent), ("127.0.0.1", self.port))
                except OSError:
                    pass
                self.sent += 1
            self._stop.wait(batch / self.per_s)
            try:  # what the vehicle writes to the flood's address, counted
                while True:
                    self.received += len(self._sock.recv(4096))
            except OSError:
                pass


class Station:
    """The ground station that is not flooding: a HEARTBEAT a second, every byte the
    vehicle sends it counted, the vehicle's HEARTBEATs timed."""

    def __init__(self, m):
        self.m = m
        self.bytes = 0
        self.heartbeats = []
        self.beat_at = 0

    def pump(self, seconds, want=None):
        """Read for `seconds` (or until a message matching want arrives) -> it or None."""
        deadline = time.time() + seconds
        while time.time() < deadline:
            if time.time() >= self.beat_at:
                self.m.mav.heartbeat_send(6, 8, 0, 0, 0)  # MAV_TYPE_GCS
                self.beat_at = time.time() + 1
            msg = self.m.recv_match(blocking=True, timeout=0.05)
            if msg is None:
                continue
            if msg.get_type() == "BAD_DATA":
                self.bytes += len(msg.data)
                continue
            self.bytes += len(msg.get_msgbuf())
            if msg.get_srcSystem() != 1:
                continue
            if msg.get_type() == "HEARTBEAT":
                self.heartbeats.append(time.time())
            if want is not None and want(msg):
                return msg
        return None

    def read(self, name, seconds):
        """PARAM_REQUEST_READ by name -> its PARAM_VALUE within `seconds`, else None."""
        self.m.mav.param_request_read_send(1, 1, name, -1)
        return self.pump(seconds, lambda msg: msg.get_type() == "PARAM_VALUE"
                         and msg.param_id == name.decode())

    def command(self, seconds):
        """REQUEST_MESSAGE SYSTEM_TIME, sent once -> (its COMMAND_ACK, seconds taken)."""
        start = time.time()
        self.m.mav.command_long_send(1, 1, 512, 0, MSG_SYSTEM_TIME, 0, 0, 0, 0, 0, 0)
        ack = self.pump(seconds, lambda msg: msg.get_type() == "COMMAND_ACK" and msg.command == 512
                        and (msg.target_system, msg.target_component) == STATION)
        return ack, time.time() - start


def test_a_flood_from_249_system_ids_does_not_silence_a_ground_station_heard_before(vehicle):
    v = vehicle(args=["--set", "udp_bytes_per_s=%d" % BYTES_PER_S])
    m = v.gcs(source_system=STATION[0], source_component=STATION[1])
    s = Station(m)
    # Before the flood: the station's HEARTBEATs heard, and where its parameters are.
    spare = set()
    count = 0
    for name in READS:
        got = s.read(name, 3.0)
        assert got is not None, name
        spare.add(got.param_index)
        count = got.param_count
    s.pump(2.0)  # (more of its HEARTBEATs)
    with Flood(v.port, spare, count) as flood:
        s.pump(2.0)  # the flood in full swing
        start_bytes, start = s.bytes, time.time()
        hb_from = len(s.heartbeats)
        reads, acks, took = 0, 0, []
        for name in READS:
            reads += s.read(name, 2.0) is not None
            ack, seconds = s.command(2.0)
            acks += ack is not None and ack.result == 0
            took.append(round(seconds, 2))
            s.pump(max(0.0, (FLOOD_S - 2.0) / len(READS) - 4.0))
        s.pump(max(0.0, FLOOD_S - 2.0 - (time.time() - start)))
        elapsed = time.time() - start
        rate = (s.bytes - start_bytes) / elapsed
        beats = s.heartbeats[hb_from:]
        v.check_alive()
    print("flood sent %d, rate %.0f B/s, reads %d/3, ACKs %d/3 in %s s, heartbeats %d in %.1f s"
          % (flood.sent, rate, reads, acks, took, len(beats), elapsed))
    assert flood.sent >= 1000 * FLOOD_S, flood.sent
    assert reads == 3 and acks == 3, (reads, acks, took)
    # Within the budget, and a burst's worth of slack (the bucket holds 200 ms of it) ...
    assert rate <= BYTES_PER_S * 1.08, (rate, BYTES_PER_S)
    assert rate >= BYTES_PER_S * 0.5, rate  # ... and the flood does fill it
    # HEARTBEAT at 1 Hz throughout: no gap much over a second, about one a second.
    gaps = [b - a for a, b in zip(beats, beats[1:])]
    assert len(beats) >= int(elapsed) - 1, (len(beats), elapsed)
    assert max(gaps) < 1.6, gaps


# --- held-back COMMAND_ACKs, in-process on the bench (tests/mpy/harness.py) ----------

sys.path.insert(0, os.path.join(ROOT, "tests", "mpy"))
from harness import Bench  # noqa: E402

MSG_SYS_STATUS = 1
CMD_TAGGED = 31020  # a handler that answers with param2 as result_param2 and SYS_STATUS


def bench(services=("status", "commands")):
    """The bench budgeted as a 57600 baud radio, a ground station (255/190) heard by its
    HEARTBEAT, and a handler counting its runs -> (bench, station, runs)."""
    b = Bench(services=services)
    b.ep.links[0].bytes_per_s = BYTES_PER_S
    g = b.gcs(*STATION)
    b.send(g.heartbeat())
    b.run(2)
    runs = []

    def tagged(cmd):
        runs.append(cmd.int(2))
        cmd.result_param2 = cmd.int(2)
        cmd.reply = MSG_SYS_STATUS
        return 0

    b.ep.services["commands"].handle(CMD_TAGGED, tagged)
    return b, g, runs


def record(b):
    """What the bench hears from now on: ("ACK", sysid, result_param2) and "SYS_STATUS"."""
    out = []

    def watch(msgid, p):
        if msgid == 77:
            out.append(("ACK", p[8], int.from_bytes(bytes(p[4:8]), "little", signed=True)))
        elif msgid == MSG_SYS_STATUS:
            out.append("SYS_STATUS")

    b.watch = watch
    return out


def drain_budget(b):
    """The link's credit spent, below every rank's floor: what it sends next waits for
    the bucket to fill again (5.76 bytes a simulated ms)."""
    b.ep.links[0].credit = -200000


def test_held_back_acks_go_later_in_order_each_followed_by_its_message():
    b, g, runs = bench()
    commands = b.ep.services["commands"]
    heard = record(b)
    drain_budget(b)
    for tag in (1, 2, 3):
        b.send(g.command(CMD_TAGGED, 0.0, float(tag)))
    b.run(1)
    assert runs == [1, 2, 3] and commands.acks_held == 3
    assert not [h for h in heard if h[0] == "ACK"]  # none went: held back, not dropped
    # The ground station tries again (confirmation 1): its ACK is on its way, no second run.
    b.send(g.command(CMD_TAGGED, 0.0, 2.0, confirmation=1))
    b.run(1)
    assert runs == [1, 2, 3]
    b.run(500)
    acks = [h for h in heard if h[0] == "ACK"]
    assert acks == [("ACK", STATION[0], 1), ("ACK", STATION[0], 2), ("ACK", STATION[0], 3)]
    for k in range(3):  # each ACK, then the message it asked for
        i = heard.index(acks[k])
        assert heard[i + 1] == "SYS_STATUS", heard
    assert commands.acks_dropped == 0 and runs == [1, 2, 3]


def test_a_full_queue_drops_a_newcomers_ack_before_a_ground_station_heard_before():
    b, g, runs = bench()
    commands = b.ep.services["commands"]
    heard = record(b)
    drain_budget(b)
    for tag in (1, 2, 3):
        b.send(g.command(CMD_TAGGED, 0.0, float(tag)))
    b.run(1)
    for sysid in range(100, 110):  # ten newcomers, one command each: two too many
        b.send(b.gcs(sysid, 190).command(CMD_TAGGED, 0.0, float(sysid)))
    b.run(1)
    b.send(g.command(CMD_TAGGED, 0.0, 4.0))  # the station again: a newcomer's goes for it
    b.run(1)
    assert len(runs) == 14 and commands.acks_held == 14 and commands.acks_dropped == 6
    b.run(1000)
    acks = [h[1:] for h in heard if h[0] == "ACK"]
    # The station's four ACKs all went (before the newcomers': they wait for what the
    # streams leave); of the newcomers', the four latest (the oldest dropped).
    assert [a for a in acks if a[0] == STATION[0]] == [(STATION[0], t) for t in (1, 2, 3, 4)]
    assert [a[1] for a in acks if a[0] != STATION[0]] == [106, 107, 108, 109]
    assert acks[:4] == [(STATION[0], t) for t in (1, 2, 3, 4)]


class Mem:
    """An in-memory transport that takes everything (the budget is what holds back)."""

    name = "mem"

    def __init__(self, bytes_per_s):
        self.bytes_per_s = bytes_per_s
        self.inbox = bytearray()
        self.out = bytearray()

    def readinto(self, buf):
        n = min(len(buf), len(self.inbox))
        buf[:n] = self.inbox[:n]
        del self.inbox[:n]
        return n

    def write(self, buf, n):
        self.out += bytes(buf[:n])
        return n

    def close(self):
        pass


def test_a_station_heard_before_keeps_its_share_through_a_flood_of_249_identities():
    # The bare endpoint (no services): every PING answered at the rank of its sender
    # (RANK_AUTO), bulk traffic keeping the bucket at RANK_BULK's floor as streams do.
    from mavstack.dialects import common
    from mavstack.endpoint import Endpoint
    from mavstack.link import RANK_BULK, RANK_AUTO

    ep = Endpoint(common, 1, 1)
    ep.poll(1000)
    link = ep.add_link(Mem(BYTES_PER_S))
    answered = {}
    lowest = [10 ** 9]  # the least credit a newcomer's answer left

    def answer(link, p):
        off = link.begin()
        link.txbuf[off:off + 14] = bytes(14)
        before = link.tx_bytes
        link.send(4)
        sysid = link.rx.sysid
        if link.tx_bytes != before:
            answered[sysid] = answered.get(sysid, 0) + 1
            if sysid != STATION[0]:
                lowest[0] = min(lowest[0], link.credit)

    ep.on(4, answer)
    station = mav.MAVLink(None, *STATION)
    flood = [mav.MAVLink(None, s, 190) for s in FLOOD_SYSIDS]
    now = 1000
    asked = 0
    for k in range(10000):  # 10 s; the flood from the third second on
        now += 1
        if k % 1000 == 0:
            link.transport.inbox += mav.MAVLink_heartbeat_message(6, 8, 0, 0, 0, 3).pack(station)
        if k >= 2000:
            for j in range(20):  # 20 requests a ms, each from the next identity
                m = flood[(k * 20 + j) % len(flood)]
                link.transport.inbox += mav.MAVLink_ping_message(k, 0, 0, 0).pack(m)
        if k % 100 == 50:
            link.transport.inbox += mav.MAVLink_ping_message(k, 0, 0, 0).pack(station)
            asked += 1
        ep.poll(now)
        link.rank = RANK_BULK
        while link.send_payload(0, bytes(9), 9):
            pass
        link.rank = RANK_AUTO
    assert answered[STATION[0]] == asked  # every one, all through the flood
    flood_answers = sum(n for s, n in answered.items() if s != STATION[0])
    assert flood_answers > 0
    # Newcomers never took the last 128 bytes of the bucket: they are the station's.
    assert lowest[0] >= 128000, lowest


@pytest.mark.parametrize("portable", [False, True])
def test_held_back_acks_allocate_nothing(portable):
    # tests/mpy/flood_steady.py: the held-back ACKs (a flood's and a station's over its
    # share), their queue full, retries and the messages that follow, under heap_lock.
    if portable:
        os.environ["MAVSTACK_PORTABLE"] = "1"
    try:
        r = run_mpy(os.path.join(ROOT, "tests", "mpy", "flood_steady.py"), 6000,
                    path=[os.path.join(ROOT, "tests", "mpy")], timeout=120)
    finally:
        os.environ.pop("MAVSTACK_PORTABLE", None)
    assert r.returncode == 0, r.stdout + r.stderr
    line = r.stdout.strip().splitlines()[-1]
    figures = dict(kv.split("=") for kv in line.split()[1:])
    assert line.startswith("OK") and int(figures["requested"]) == 0, line
    f = {k: int(v) for k, v in figures.items()}
    assert f["late"] > 0 and f["held"] > f["late"] and f["dropped"] > 0 and f["flood_acks"] > 0, line
    assert f["acked"] >= 0.9 * f["asked"] and f["in_order"] == f["acked"], line
    assert f["heartbeats"] == 7, line  # 6 s, then 1 s for the held-back ACKs to go
