"""Routing between links (mavstack/router.py), in-process on CPython: an endpoint with
three in-memory links, frames made by pymavlink (the wire oracle), what comes out of
each link compared byte for byte."""
import os
import sys

import pytest
from pymavlink.dialects.v20 import common as mav2

from conftest import ROOT

sys.path.insert(0, os.path.join(ROOT, "tests", "mpy"))
from harness import Bench, loop_pair  # noqa: E402
from mavstack.router import Router  # noqa: E402

VEHICLE = 1


class Net:
    """The bench vehicle with three links (0: the bench's own) and a router."""

    def __init__(self, capacity=16, timeout_ms=10000, private=0, services=("status", "commands")):
        self.b = Bench(services=services)
        ep = self.b.ep
        self.ends = [self.b.gcs_end]
        for i in (1, 2):
            v, g = loop_pair(8192, name="loop%d" % i)
            ep.add_link(v)
            self.ends.append(g)
        self.router = ep.add(Router(capacity, timeout_ms, private))
        self.ep = ep
        self.buf = bytearray(8192)

    def send(self, link, data):
        assert self.ends[link].write(bytearray(data), len(data)) == len(data)

    def run(self, n=1, step_ms=1):
        """Poll n times; link 0's output stays to be read by out(0) (or the bench's drain())."""
        from mavstack.compat import ticks_add

        for _ in range(n):
            self.b.now = ticks_add(self.b.now, step_ms)
            self.ep.poll(self.b.now)

    def acks(self):
        """COMMAND_ACKs the vehicle sent on link 0 (what is on link 0 is read and gone)."""
        self.b.drain()
        return self.b.acks

    def out(self, link):
        """Frames that came out of a link, not the vehicle's own: [bytes]."""
        frames = []
        data = self._read(link)
        m = mav2.MAVLink(None)
        m.robust_parsing = True
        for msg in m.parse_buffer(bytes(data)) or []:
            if msg.get_srcSystem() != VEHICLE:
                frames.append(bytes(msg.get_msgbuf()))
        return frames

    def _read(self, link):
        data = bytearray()
        end = self.ends[link]
        while True:
            n = end.readinto(self.buf)
            if not n:
                return data
            data += self.buf[:n]


def packer(sysid, compid, mavlink1=False, signing_key=None):
    m = mav2.MAVLink(None, srcSystem=sysid, srcComponent=compid)
    if signing_key is not None:
        m.signing.secret_key = signing_key
        m.signing.sign_outgoing = True
        m.signing.timestamp = 1
        m.signing.link_id = 3

    def pack(msg):
        return bytes(msg.pack(m, force_mavlink1=mavlink1))

    return pack


def ping(target_system=0, target_component=0, seq=7):
    return mav2.MAVLink_ping_message(123456, seq, target_system, target_component)


def heartbeat(mav_type=6):
    return mav2.MAVLink_heartbeat_message(mav_type, 8, 0, 0, 0, 3)


def settle(net):
    """Let the vehicle's own frames out and clear every link."""
    net.run(3)
    for i in range(3):
        net.out(i)


@pytest.fixture
def net():
    n = Net()
    settle(n)
    return n


def test_broadcast_reaches_every_other_link_unchanged(net):
    f = packer(255, 190)(ping())
    net.send(0, f)
    net.run()
    assert net.out(1) == [f] and net.out(2) == [f]
    assert net.out(0) == []  # never back to its sender
    assert net.ep.links[1].fwd_frames == net.ep.links[2].fwd_frames == 1


def test_targeted_goes_only_where_its_target_was_heard(net):
    gcs, companion, camera = packer(255, 190), packer(42, 191), packer(43, 100)
    first = gcs(ping(42, 191))
    net.send(0, first)
    net.run()
    assert net.out(1) == [] and net.out(2) == []  # unknown system: dropped
    net.send(2, companion(heartbeat(18)))
    net.send(1, camera(heartbeat(30)))
    net.run()
    net.out(0), net.out(1), net.out(2)
    f = gcs(ping(42, 191))
    net.send(0, f)
    net.run()
    assert net.out(2) == [f] and net.out(1) == [] and net.out(0) == []
    # Another system's other component: wherever that system was heard.
    f = gcs(ping(42, 5))
    net.send(0, f)
    net.run()
    assert net.out(2) == [f] and net.out(1) == []
    # Answers go back to the station, and only there.
    back = companion(ping(255, 190))
    net.send(2, back)
    net.run()
    assert net.out(0) == [back] and net.out(1) == [] and net.out(2) == []


def test_our_system_other_component(net):
    gcs, camera = packer(255, 190), packer(VEHICLE, 100)
    # Not heard yet: handled here (the vehicle answers the command), not forwarded.
    assert net.ep.for_us(VEHICLE, 100)
    net.send(1, camera(heartbeat(30)))
    net.run()
    assert not net.ep.for_us(VEHICLE, 100) and net.ep.for_us(VEHICLE, 0) and net.ep.for_us(0, 0)
    net.out(0), net.out(2)
    f = gcs(mav2.MAVLink_command_long_message(VEHICLE, 100, 512, 0, 1, 0, 0, 0, 0, 0, 0))
    acks = net.acks()
    net.send(0, f)
    net.run(3)
    assert net.out(1) == [f] and net.out(2) == []
    assert net.acks() == acks  # the camera's, not ours
    # Our system, component 0: every link a component of ours was heard on, and handled here.
    f = gcs(mav2.MAVLink_command_long_message(VEHICLE, 0, 512, 0, 1, 0, 0, 0, 0, 0, 0))
    net.send(0, f)
    net.run(3)
    assert net.out(1) == [f] and net.out(2) == []
    assert net.acks() == acks + 1
    # Ours alone: not forwarded.
    net.send(0, gcs(mav2.MAVLink_command_long_message(VEHICLE, 1, 512, 0, 1, 0, 0, 0, 0, 0, 0)))
    net.run(3)
    assert net.out(1) == [] and net.out(2) == []


def test_mavlink1_stays_mavlink1(net):
    f = packer(255, 190, mavlink1=True)(ping())
    assert f[0] == 0xFE
    net.send(0, f)
    net.run()
    assert net.out(1) == [f] and net.out(2) == [f]


def test_truncated_mavlink2_payload_kept_as_sent(net):
    f = packer(255, 190)(mav2.MAVLink_named_value_int_message(0, b"X", 0))
    assert f[1] < 18  # trailing zeros cut: the parser widens the payload over the CRC
    net.send(0, f)
    net.run()
    assert net.out(1) == [f]


def test_signed_frame_forwarded_intact(net):
    key = bytes(range(32))
    f = packer(255, 190, signing_key=key)(ping())
    assert f[2] & 1 and len(f) == 10 + f[1] + 2 + 13
    net.send(0, f)
    net.run()
    assert net.out(1) == [f] and net.out(2) == [f]


def test_never_forwarded_radio_and_own_frames(net):
    radio = packer(51, 68)
    net.send(0, radio(mav2.MAVLink_radio_status_message(100, 90, 50, 10, 20, 0, 0)))
    # (RADIO, 166, is ArduPilot's dialect's: not in common, so the parser drops it anyway.)
    net.send(0, packer(VEHICLE, 1)(ping()))  # our own, looped back
    net.run()
    assert net.out(1) == [] and net.out(2) == []
    assert (VEHICLE, 1) not in [(s, c) for s, c, _, _ in net.router.routes()]


def test_private_link():
    net = Net(private=1 << 2)
    settle(net)
    gcs, hidden = packer(255, 190), packer(42, 191)
    net.send(2, hidden(heartbeat(18)))
    net.send(0, gcs(ping()))
    net.run()
    assert net.out(0) == [] and net.out(2) == []  # nothing from it, nothing to it
    assert len(net.out(1)) == 1
    net.send(0, gcs(ping(42, 191)))
    net.run()
    assert net.out(2) == []
    assert (42, 191) in [(s, c) for s, c, _, _ in net.router.routes()]  # learnt all the same


def test_oldest_route_evicted_when_full():
    net = Net(capacity=4)
    settle(net)
    for sysid in (10, 11, 12, 13):
        net.send(1, packer(sysid, 1)(heartbeat(2)))
        net.run(1, 10)
    net.send(1, packer(10, 1)(heartbeat(2)))  # 10 heard again: 11 is now the oldest
    net.run(1, 10)
    net.send(2, packer(255, 190)(heartbeat()))  # the bench's station is on link 0: this is another
    net.run()
    routes = sorted((s, c) for s, c, _, _ in net.router.routes())
    assert routes == [(10, 1), (12, 1), (13, 1), (255, 190)], routes
    assert net.router.evicted >= 1
    net.out(0), net.out(1), net.out(2)
    net.send(0, packer(200, 1)(ping(11, 1)))
    net.run()
    assert net.out(1) == []  # 11 forgotten: dropped


def test_reboot_forgets_the_system():
    net = Net()
    settle(net)
    ap, cam = packer(42, 1), packer(42, 100)
    net.send(1, ap(mav2.MAVLink_system_time_message(0, 500000)))
    net.send(1, cam(heartbeat(30)))
    net.run()
    assert {(42, 1), (42, 100)} <= {(s, c) for s, c, _, _ in net.router.routes()}
    net.send(1, ap(mav2.MAVLink_system_time_message(0, 600000)))
    net.run()
    assert (42, 100) in [(s, c) for s, c, _, _ in net.router.routes()]
    net.send(1, ap(mav2.MAVLink_system_time_message(0, 1200)))  # booted again
    net.run()
    routes = [(s, c) for s, c, _, _ in net.router.routes()]
    assert (42, 1) in routes and (42, 100) not in routes
    assert net.router.forgotten == 1
    # time_boot_ms past 2^30 read without a large int (checked on MicroPython by route_steady)
    net.send(1, ap(mav2.MAVLink_system_time_message(0, 0xFFFFFFF0)))
    net.run()
    assert net.router.forgotten == 1


def test_silent_routes_forgotten():
    net = Net(timeout_ms=3000)
    settle(net)
    net.send(1, packer(42, 191)(heartbeat(18)))
    net.run()
    assert (42, 191) in [(s, c) for s, c, _, _ in net.router.routes()]
    net.run(40, 100)  # 4 s of silence
    assert (42, 191) not in [(s, c) for s, c, _, _ in net.router.routes()]


def test_forwarding_is_paid_from_the_budget():
    net = Net()
    settle(net)
    link = net.ep.links[1]
    link.bytes_per_s = 1000  # 200 ms: a 700-byte bucket at most
    link.credit = 0
    gcs = packer(255, 190)
    for _ in range(40):
        net.send(0, gcs(ping()))
    net.run()
    assert len(net.out(1)) < 40 and link.tx_held > 0
    assert len(net.out(2)) == 40


def test_main_adds_routing_by_link_count(tmp_path):
    import main

    class Board:
        NAME = "t"
        DIALECT = "common"
        SERVICES = ("status",)
        STORAGE = str(tmp_path)

    one = {"links": ["udpout:127.0.0.1:9"], "options": {}}
    ep, _ = main.build(Board, one)
    assert ep.router is None
    ep.close()
    three = {"links": ["udpout:127.0.0.1:9", "udpout:127.0.0.1:10", "udpout:127.0.0.1:11"],
             "options": {"private_links": "2", "routes": "5"}}
    ep, _ = main.build(Board, three)
    assert ep.router is not None and ep.router.private == 4 and ep.router.capacity == 5
    ep.close()
    off = dict(three, options={"routing": "0"})
    ep, _ = main.build(Board, off)
    assert ep.router is None
    ep.close()


@pytest.mark.parametrize("portable", [False, True], ids=["viper", "portable"])
def test_route_steady_heap_locked_on_micropython(portable):
    """tests/mpy/route_steady.py on the unix port: forwarding allocates nothing (test_mcu.py
    runs it on the emulated boards)."""
    from conftest import run_mpy

    mpy = os.path.join(ROOT, "tests", "mpy")
    env = dict(os.environ)
    if portable:
        os.environ["MAVSTACK_PORTABLE"] = "1"
    try:
        r = run_mpy(os.path.join(mpy, "route_steady.py"), 3000, path=[mpy], timeout=300)
    finally:
        os.environ.clear()
        os.environ.update(env)
    lines = r.stdout.strip().splitlines()
    assert r.returncode == 0 and lines and lines[-1].startswith("OK"), r.stdout + r.stderr
    assert lines[-1].endswith(" requested=0"), lines[-1]


def test_links_setting_opens_several(tmp_path):
    import main

    class Board:
        NAME = "t"
        DIALECT = "common"
        SERVICES = ("status",)
        STORAGE = str(tmp_path)

    ep, _ = main.build(Board, {"links": [], "options": {"links": "udpout:127.0.0.1:9,udpout:127.0.0.1:10"}})
    assert len(ep.links) == 2 and ep.router is not None
    ep.close()


def test_a_signing_vehicle_forwards_what_passes_its_check_intact():
    """With signing on, every frame must pass the vehicle's check before it is handled or
    forwarded: one signed with its key is forwarded as it came (signature and all), one
    signed with another key, or unsigned, goes nowhere (docs/routing.md)."""
    from harness import Board
    from mavstack.dialects import common
    from mavstack.endpoint import Endpoint
    from mavstack.services import compose
    from mavstack.storage_ram import RamStorage

    ep = Endpoint(common, VEHICLE, 1)
    ep.board = Board
    ep.options = {}
    ep.storage = RamStorage(bytearray(8192))
    ends = []
    for i in range(3):
        v, g = loop_pair(8192, name="loop%d" % i)
        ep.add_link(v)
        ends.append(g)
    assert compose(ep, ("signing", "status")) is None
    ep.add(Router())
    key = bytes(range(32))
    ep.services["signing"].set_key(key)
    net = Net.__new__(Net)
    net.ends, net.ep, net.buf = ends, ep, bytearray(8192)
    net.b = type("B", (), {"now": ep.now})()
    net.run(3)
    [net.out(i) for i in range(3)]
    good = packer(42, 191, signing_key=key)(ping())
    other = packer(43, 191, signing_key=bytes(32 * [7]))(ping())
    unsigned = packer(44, 191)(ping())
    for f in (good, other, unsigned):
        net.send(0, f)
        net.run()
    assert net.out(1) == [good] and net.out(2) == [good]
    routes = [(s, c) for s, c, _, _ in ep.router.routes()]
    assert (42, 191) in routes and (43, 191) not in routes and (44, 191) not in routes


def test_two_paths_to_one_peer_do_not_loop(net):
    """A companion heard on links 1 and 2 (two paths to it): its broadcast from one is not
    sent back to it by the other; the station on link 0 gets it."""
    comp = packer(42, 191)
    net.send(1, comp(heartbeat(18)))
    net.run()
    net.send(2, comp(heartbeat(18)))
    net.run()
    net.out(0), net.out(1), net.out(2)
    f = comp(ping())
    net.send(1, f)
    net.run()
    assert net.out(0) == [f] and net.out(2) == []


def test_forwarding_rank_floor():
    from mavstack import link

    assert link._FLOOR_FILL == link._FLOOR[link.RANK_FILL] * 1000
