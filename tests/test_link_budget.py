"""Everything a link sends shares its byte budget: under a flood of requests from
several system ids (parameter lists, mission lists, data stream requests, PINGs) the
unix vehicle, budgeted as a 57600 baud radio, sends no more than the radio carries,
HEARTBEAT keeps its 1 Hz, and another ground station's parameter reads and commands
are still answered. Real UDP sockets, pymavlink on both sides of the flood."""
import os
import time

os.environ.setdefault("MAVLINK20", "1")
from pymavlink.dialects.v20 import common as mav  # noqa: E402

from gcs_tools import UdpSender  # noqa: E402

BYTES_PER_S = 5760
FLOOD_SYSIDS = (100, 101, 102, 103, 104)


class Flood(UdpSender):
    """From one address, round robin over several system ids: PARAM_REQUEST_LIST,
    MISSION_REQUEST_LIST, REQUEST_DATA_STREAM (all streams at 50 Hz) and PING, about
    `per_s` frames a second, until stopped."""

    def __init__(self, port, per_s=2000):
        UdpSender.__init__(self, port)
        self.per_s = per_s
        self._sock.setblocking(False)
        self._mavs = [mav.MAVLink(None, s, 190) for s in FLOOD_SYSIDS]

    def _frame(self, k):
        m = self._mavs[k % len(self._mavs)]
        kind = (k // len(self._mavs)) % 4
        if kind == 0:
            msg = mav.MAVLink_param_request_list_message(1, 1)
        elif kind == 1:
            msg = mav.MAVLink_mission_request_list_message(1, 1, 0)
        elif kind == 2:
            msg = mav.MAVLink_request_data_stream_message(1, 1, 0, 50, 1)
        else:
            msg = mav.MAVLink_ping_message(k, k & 0xFFFF, 0, 0)
        return msg.pack(m)

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
            # (drain what the vehicle writes to the flood's address, so its socket stays open)
            try:
                while self._sock.recv(4096):
                    pass
            except OSError:
                pass


class Watch:
    """The second ground station's view: every frame the vehicle sends to it, counted in
    bytes, HEARTBEATs timed, answers kept."""

    def __init__(self, m):
        self.m = m
        self.bytes = 0
        self.heartbeats = []
        self.beat_at = 0

    def pump(self, seconds, want=None):
        """Read for `seconds` (or until a message matching want arrives) -> it or None,
        with a HEARTBEAT a second, as a ground station sends them."""
        deadline = time.time() + seconds
        while time.time() < deadline:
            if time.time() >= self.beat_at:
                self.m.mav.heartbeat_send(6, 8, 0, 0, 0)
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


def test_flood_stays_within_the_budget_and_others_are_still_answered(vehicle):
    v = vehicle(args=["--set", "udp_bytes_per_s=%d" % BYTES_PER_S])
    m = v.gcs(source_system=250)  # the ground station that is not flooding
    w = Watch(m)
    with Flood(v.port) as flood:
        w.pump(1.5)  # the flood in full swing
        start_bytes, start = w.bytes, time.time()
        hb_from = len(w.heartbeats)
        reads = commands = 0
        for i in range(4):
            name = (b"WP_SPEED", b"SIM_GPS_GLITCH_M", b"MOT_SPOOL_TIME_S", b"RTL_LOIT_TIME_S")[i]
            m.mav.param_request_read_send(1, 1, name, -1)
            got = w.pump(2.0, lambda msg, name=name: msg.get_type() == "PARAM_VALUE"
                         and msg.param_id == name.decode() and msg.param_index >= 0)
            reads += got is not None
            # REQUEST_MESSAGE SYSTEM_TIME, sent again after a second without its ACK with
            # confirmation 1, as the command protocol has a ground station do: a one-off
            # answer the budget cannot pay for at that moment is dropped, not queued.
            ack = None
            for confirmation in (0, 1):
                m.mav.command_long_send(1, 1, 512, confirmation, 2, 0, 0, 0, 0, 0, 0)
                ack = w.pump(1.0, lambda msg: msg.get_type() == "COMMAND_ACK" and msg.command == 512)
                if ack is not None:
                    break
            commands += ack is not None and ack.result == 0
        w.pump(max(0.0, 8.0 - (time.time() - start)))
        elapsed = time.time() - start
        rate = (w.bytes - start_bytes) / elapsed
        beats = w.heartbeats[hb_from:]
        v.check_alive()
    assert flood.sent > 10000, flood.sent
    # Within the budget, and a burst's worth of slack (the bucket holds 200 ms of it).
    assert rate <= BYTES_PER_S * 1.08, (rate, BYTES_PER_S)
    assert rate >= BYTES_PER_S * 0.5, rate  # and the link is used, not starved
    assert reads == 4 and commands == 4, (reads, commands)
    # HEARTBEAT at 1 Hz: no gap much over a second, about one a second.
    gaps = [b - a for a, b in zip(beats, beats[1:])]
    assert len(beats) >= int(elapsed) - 1, (len(beats), elapsed)
    assert max(gaps) < 1.6, gaps


# --- the bucket and its ranks, in-process on CPython (the same code runs on the boards) --

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


def _endpoint(bytes_per_s=BYTES_PER_S):
    from mavstack.dialects import common
    from mavstack.endpoint import Endpoint

    ep = Endpoint(common, 1, 1)
    ep.poll(1000)
    link = ep.add_link(Mem(bytes_per_s))
    return ep, link


def _heartbeat(link):
    off = link.begin()
    link.txbuf[off:off + 9] = bytes((0, 0, 0, 0, 2, 0, 0, 3, 3))
    return link.send(0)


def test_ranks_spend_the_bucket_down_to_their_floors_in_order():
    from mavstack.link import RANK_VITAL, RANK_REPLY, RANK_BULK, RANK_FILL, RANK_OTHER, RANK_AUTO

    ep, link = _endpoint()
    assert link.credit == 1152000  # a full bucket: 200 ms of the link, in 1/1000 bytes
    frame = None
    left = {}
    for rank in (RANK_OTHER, RANK_FILL, RANK_BULK, RANK_REPLY, RANK_VITAL):
        link.rank = rank
        while True:  # at one instant: nothing refills
            before = link.tx_bytes
            if not _heartbeat(link):
                break
            frame = link.tx_bytes - before
        left[rank] = link.credit // 1000
        assert not link.can_send(frame, rank)
    link.rank = RANK_AUTO
    # Each rank spends what the ones below it left, down to its own floor (less than a
    # frame above it), HEARTBEAT a little into debt.
    floors = {RANK_OTHER: 384, RANK_FILL: 320, RANK_BULK: 256, RANK_REPLY: 0, RANK_VITAL: -128}
    for rank, floor in floors.items():
        assert floor <= left[rank] < floor + frame, (rank, left)
    assert link.tx_held == 5  # one refusal per rank, counted
    assert len(link.transport.out) == 1152 - left[RANK_VITAL]
    # Time refills it at the link's rate (when next asked): 100 ms is 576 bytes.
    ep.poll(1100)
    assert link.can_send(frame, RANK_BULK) and not link.can_send(500, RANK_OTHER)
    assert link.credit // 1000 == left[RANK_VITAL] + 576


def test_ready_in_says_when_a_held_frame_would_go():
    from mavstack.link import RANK_FILL, RANK_AUTO

    ep, link = _endpoint()
    link.rank = RANK_FILL
    while _heartbeat(link):
        pass
    link.rank = RANK_AUTO
    ms = link.ready_in(100, RANK_FILL)
    assert 1 < ms <= 100 * 1000 // BYTES_PER_S + 1  # (the bucket is at its floor, or a frame above)
    ep.poll(1000 + ms - 1)
    assert not link.can_send(100, RANK_FILL)
    ep.poll(1000 + ms)
    assert link.can_send(100, RANK_FILL) and link.ready_in(100, RANK_FILL) == 1
    assert _endpoint(10 ** 7)[1].ready_in(100, RANK_FILL) == 1  # not budgeted


def test_a_refused_frame_gives_its_sequence_number_back():
    from mavstack.link import RANK_OTHER, RANK_AUTO

    ep, link = _endpoint()
    link.rank = RANK_OTHER
    while _heartbeat(link):
        pass
    seq = link.tx.seq
    assert not _heartbeat(link) and link.tx.seq == seq  # nothing sent, no gap for the peer
    link.rank = RANK_AUTO
    assert _heartbeat(link)  # (at REPLY it goes, with the next number)
    assert link.tx.seq == (seq + 1) & 0xFF


def test_over_ten_seconds_a_busy_link_sends_its_budget_and_no_more():
    from mavstack.link import RANK_FILL, RANK_AUTO

    ep, link = _endpoint()
    now = 1000
    for _ in range(10000):  # 10 s of 1 ms polls, something always waiting at every rank
        now += 1
        ep.poll(now)
        link.rank = RANK_FILL
        while _heartbeat(link):
            pass
        link.rank = RANK_AUTO
        _heartbeat(link)
    assert len(link.transport.out) <= BYTES_PER_S * 10 + 1152 + 128
    assert len(link.transport.out) >= BYTES_PER_S * 10 * 0.99


def test_a_flooding_sender_falls_to_the_last_rank_and_another_is_still_answered():
    from pymavlink.dialects.v20 import common as mav_common

    ep, link = _endpoint()
    answered = {}

    def answer(link, p):  # an answer to every PING, ranked by its sender (RANK_AUTO)
        off = link.begin()
        link.txbuf[off:off + 14] = bytes(14)
        key = link.rx.sysid
        before = link.tx_bytes
        link.send(4)
        answered[key] = answered.get(key, 0) + link.tx_bytes - before  # bytes

    ep.on(4, answer)
    flood = mav_common.MAVLink(None, 100, 190)
    other = mav_common.MAVLink(None, 200, 190)
    now = 1000
    asked = 0
    for k in range(5000):  # 5 s: 20 requests a ms from one sender, one a second from another
        now += 1
        for _ in range(20):
            link.transport.inbox += mav_common.MAVLink_ping_message(k, 0, 0, 0).pack(flood)
        if k % 1000 == 500:
            link.transport.inbox += mav_common.MAVLink_ping_message(k, 0, 0, 0).pack(other)
            asked += 1
        ep.poll(now)
        # Bulk traffic keeps the bucket at its floor, as streams and lists do.
        link.rank = 3
        while _heartbeat(link):
            pass
        link.rank = -1
    assert answered.get(200) == asked * 13  # every one answered (13-byte frames)
    # The flood: its allowance (a second's worth to start, then 1/16 of the link), not
    # the link's 28,800 bytes; what the bucket's floors leave it as RANK_OTHER is nothing
    # here, as the bulk traffic keeps the bucket below them.
    assert 0 < answered[100] <= (5 + 1) * BYTES_PER_S // 16 + 13
