"""Routing and peripheral mode end to end: the unix vehicle with three links, UDP to a
ground station (pymavlink, and MAVSDK on the same port), a pty to the emulated Cortex-M0
running mavstack as a distance-sensor peripheral (boards/qemu_m0_rangefinder.py, system
id followed from the vehicle's HEARTBEAT, component 158), a pty to a pymavlink companion
(system 2, component 191). The peripheral's pty passes through a tap (pty_relay.PtyRelay
with far_dev) that records what the vehicle sends it. Through the vehicle: the station
sees the peripheral, lists, reads and sets its parameters and commands it; its data
reach the station; the station and the companion reach each other; PINGs in the style of
mavlink-router's routing test reach exactly the right links; MAVSDK sees one vehicle and
flies it. One vehicle and one board for the whole file (docs/routing.md, end to end)."""
import contextlib
import os
import threading
import time

import pytest

from conftest import free_udp_port, recv
from pty_relay import TO_GCS, PtyRelay
from test_gcs_walls import until
from test_mcu import _gate
from vehicle import Vehicle

BOARD = "qemu_m0_rangefinder"
VEHICLE = (1, 1)
PERIPHERAL = (1, 158)
COMPANION = (2, 191)
STATION = (255, 190)
FAST = ("--set", "sim_speed=40", "--set", "sim_climb=20")
MAV_CMD_USER_1 = 31010  # the rangefinder's pause (0) and resume (1)


def src(msg):
    return msg.get_srcSystem(), msg.get_srcComponent()


class Rig:
    """The vehicle, the board, the tap on the peripheral's line, the station and the
    companion; a thread sends the station's and the companion's HEARTBEATs at 1 Hz so the
    vehicle keeps their routes (every send goes through one lock)."""

    def __init__(self, stack, storage):
        from pymavlink import mavutil
        from mcu_rig import EmulatedBoard

        self.board = stack.enter_context(EmulatedBoard(BOARD))
        self.peripheral_pty, self.ready = self.board.start_peripheral()
        self.tap = PtyRelay(rate=0.0, far_dev=self.peripheral_pty, record=True)
        stack.callback(self.tap.close)
        self.cable = PtyRelay(rate=0.0)
        stack.callback(self.cable.close)
        self.port = free_udp_port()
        self.v = Vehicle(storage, links=["udpin:127.0.0.1:%d" % self.port,
                                         "serial:%s:115200" % self.tap.vehicle_dev,
                                         "serial:%s:115200" % self.cable.vehicle_dev], args=list(FAST)).start()
        stack.callback(self.v.stop)
        self.lock = threading.RLock()
        self.gcs = self._locked(mavutil.mavlink_connection("udpout:127.0.0.1:%d" % self.port, source_system=255,
                                                           source_component=190, dialect="common"))
        stack.callback(self.gcs.close)
        self.comp = self._locked(mavutil.mavlink_connection(self.cable.gcs_dev, baud=115200, source_system=2,
                                                            source_component=191, dialect="common"))
        stack.callback(self.comp.close)
        self._parser = mavutil.mavlink.MAVLink(None)
        self._parser.robust_parsing = True
        self._stop = threading.Event()
        self._beats = threading.Thread(target=self._beat, daemon=True)
        self._beats.start()
        stack.callback(self._beats.join)
        stack.callback(self._stop.set)

    def _locked(self, m):
        send = m.mav.send

        def locked(msg, force_mavlink1=False):
            with self.lock:
                send(msg, force_mavlink1=force_mavlink1)

        m.mav.send = locked
        return m

    def _beat(self):
        while True:
            self.gcs.mav.heartbeat_send(6, 8, 0, 0, 0)  # MAV_TYPE_GCS
            self.comp.mav.heartbeat_send(18, 8, 0, 0, 4)  # MAV_TYPE_ONBOARD_CONTROLLER
            if self._stop.wait(1.0):
                return

    def to_peripheral(self, start=0):
        """The messages the vehicle sent down the peripheral's line, from frame `start` on."""
        out = []
        for f in list(self.tap.frames[TO_GCS][start:]):
            msg = self._parser.parse_char(f)
            if msg is not None and msg.get_type() != "BAD_DATA":
                out.append(msg)
        return out

    def mark(self):
        return len(self.tap.frames[TO_GCS])

    def drain(self, seconds=0.3):
        end = time.time() + seconds
        while time.time() < end:
            for m in (self.gcs, self.comp):
                while m.recv_match(blocking=False) is not None:
                    pass
            time.sleep(0.01)


@pytest.fixture(scope="module")
def rig(tmp_path_factory):
    _gate()
    os.environ["MAVLINK20"] = "1"
    t0 = time.time()
    with contextlib.ExitStack() as stack:
        r = Rig(stack, tmp_path_factory.mktemp("e2e") / "storage")
        # Everyone heard by the station: the vehicle, the peripheral behind it (once it has
        # heard the vehicle's HEARTBEAT), the companion.
        seen = set()
        deadline = time.time() + 30
        while len(seen) < 3 and time.time() < deadline:
            hb = recv(r.gcs, "HEARTBEAT", 0.5)
            if hb is not None and src(hb) in (VEHICLE, PERIPHERAL, COMPANION):
                seen.add(src(hb))
            r.v.check_alive()
        assert len(seen) == 3, (seen, r.ready, r.v.output())
        print("\n%s; all three heard by the station %.1f s after start" % (r.ready, time.time() - t0))
        yield r
        r.v.check_alive()


def test_station_sees_the_peripheral_and_its_measurements(rig):
    """Its HEARTBEAT (the vehicle's system id, component 158, MAV_AUTOPILOT_INVALID) and
    every DISTANCE_SENSOR reach the station, and the companion (broadcast)."""
    hb = recv(rig.gcs, "HEARTBEAT", 10, lambda h: src(h) == PERIPHERAL)
    assert hb is not None and hb.autopilot == 8 and hb.type == 0
    # None lost on the way: between two of its RNG_COUNTs (NAMED_VALUE_INT, once a second,
    # each right after a reading) as many readings come as the count went up by, whatever
    # the pace of the emulated board on a busy host.
    rig.drain()
    counts, readings = [], 0
    end = time.time() + 20
    while time.time() < end and len(counts) < 4:
        m = recv(rig.gcs, ["DISTANCE_SENSOR", "NAMED_VALUE_INT"], 0.5, lambda m: src(m) == PERIPHERAL)
        if m is None:
            continue
        if m.get_type() == "NAMED_VALUE_INT":
            assert m.name == "RNG_COUNT"
            counts.append((m.value, readings))
        else:
            assert 100 <= m.current_distance <= 400
            readings += 1
    assert len(counts) == 4, counts
    assert counts[-1][0] - counts[0][0] == counts[-1][1] - counts[0][1] > 0, counts
    assert recv(rig.comp, "DISTANCE_SENSOR", 10, lambda d: src(d) == PERIPHERAL) is not None


def test_station_heartbeat_reaches_the_peripheral_and_the_companion(rig):
    """Broadcast: the station's HEARTBEAT goes down both ptys; nothing the peripheral
    sent comes back down its own line."""
    start = rig.mark()
    assert recv(rig.comp, "HEARTBEAT", 10, lambda h: src(h) == STATION) is not None
    assert until(lambda: any(m.get_type() == "HEARTBEAT" and src(m) == STATION for m in rig.to_peripheral(start)), 10)
    assert not [m for m in rig.to_peripheral(start) if src(m) == PERIPHERAL]


def test_peripheral_parameters_by_component(rig):
    """PARAM_REQUEST_LIST to component 158 lists its five from 158 and the vehicle stays
    out; to component 0 both answer, each from its own id; PARAM_SET and
    PARAM_REQUEST_READ by component; the setting shows in DISTANCE_SENSOR."""
    g = rig.gcs
    names = ["RNGFND_MAX_CM", "RNGFND_MIN_CM", "RNGFND_ORIENT", "RNGFND_RATE_HZ", "RNGFND_TYPE"]

    def listing(target_comp, want_vehicle):
        rig.drain()
        g.mav.param_request_list_send(1, target_comp)
        got, vehicle = {}, 0
        end = time.time() + 15
        while time.time() < end and (len(got) < 5 or (want_vehicle and not vehicle)):
            p = recv(g, "PARAM_VALUE", 1)
            if p is None:
                continue
            if src(p) == PERIPHERAL:
                assert p.param_count == 5
                got[p.param_id] = p.param_value
            elif src(p) == VEHICLE:
                vehicle += 1
        return got, vehicle

    got, vehicle = listing(158, False)
    assert sorted(got) == names and vehicle == 0, (got, vehicle)
    time.sleep(1.0)
    assert recv(g, "PARAM_VALUE", 0.5, lambda p: src(p) == VEHICLE) is None
    got, vehicle = listing(0, True)
    assert sorted(got) == names and vehicle > 0, (got, vehicle)
    time.sleep(3)  # (the vehicle's own list runs out)
    g.mav.param_set_send(1, 158, b"RNGFND_MAX_CM", 550.0, 9)
    p = recv(g, "PARAM_VALUE", 10, lambda p: p.param_id == "RNGFND_MAX_CM")
    assert p is not None and src(p) == PERIPHERAL and p.param_value == 550.0
    g.mav.param_request_read_send(1, 158, b"RNGFND_MAX_CM", -1)
    p = recv(g, "PARAM_VALUE", 10, lambda p: p.param_id == "RNGFND_MAX_CM")
    assert p is not None and src(p) == PERIPHERAL and p.param_value == 550.0
    assert recv(g, "DISTANCE_SENSOR", 10, lambda d: d.max_distance == 550) is not None
    g.mav.param_set_send(1, 158, b"RNGFND_MAX_CM", 700.0, 9)
    assert recv(g, "PARAM_VALUE", 10, lambda p: p.param_id == "RNGFND_MAX_CM" and p.param_value == 700.0)


def test_mavproxy_sees_the_peripheral_and_sets_its_parameter(rig, tmp_path):
    """MAVProxy, a second station on the UDP link: it detects component 158 of system 1,
    fetches that component's parameters and sets one; the peripheral says so to
    everyone (its PARAM_VALUE from 158)."""
    from gcs_tools import MavProxy

    mp = MavProxy(rig.port, tmp_path, "param")
    try:
        mp.expect(r"Detected vehicle 1:158")
        mp.say("set target_system 1")
        mp.say("set target_component 158")
        mp.say("param fetch")
        assert int(mp.expect(r"Received (\d+) parameters", 30).group(1)) == 5
        rig.drain()
        mp.say("param set RNGFND_MIN_CM 25")
        p = recv(rig.gcs, "PARAM_VALUE", 20, lambda p: p.param_id == "RNGFND_MIN_CM" and p.param_value == 25.0)
        assert p is not None and src(p) == PERIPHERAL, "".join(mp.seen)
        mp.say("param set RNGFND_MIN_CM 20")
        assert recv(rig.gcs, "PARAM_VALUE", 20, lambda p: p.param_id == "RNGFND_MIN_CM" and p.param_value == 20.0)
    finally:
        mp.close()


def test_peripheral_commands_and_acks(rig):
    """REQUEST_MESSAGE(DISTANCE_SENSOR) and the application's MAV_CMD_USER_1 addressed to
    158 are ACKed by 158 (pause stops the data, resume restarts it); the vehicle, whose
    component 158 has been heard on a link, leaves them alone."""
    g = rig.gcs

    def run(cmd, p1):
        """-> the ACKs: the first (within 10 s), then any more within a second; what
        else comes meanwhile is read and dropped."""
        rig.drain()
        g.mav.command_long_send(1, 158, cmd, 0, p1, 0, 0, 0, 0, 0, 0)
        a = recv(g, "COMMAND_ACK", 10, lambda a: a.command == cmd)
        acks = [] if a is None else [(src(a), a.result)]
        end = time.time() + 1
        while a is not None and time.time() < end:
            a2 = recv(g, "COMMAND_ACK", 0.1, lambda a: a.command == cmd)
            if a2 is not None:
                acks.append((src(a2), a2.result))
        return acks

    assert run(512, 132) == [(PERIPHERAL, 0)]
    # Paused: after its ACK nothing more (the board's frames keep their order through
    # the vehicle, so a reading taken before the pause comes before the ACK).
    assert run(MAV_CMD_USER_1, 0) == [(PERIPHERAL, 0)]
    assert recv(g, "DISTANCE_SENSOR", 1.5) is None
    assert run(MAV_CMD_USER_1, 1) == [(PERIPHERAL, 0)]
    assert recv(g, "DISTANCE_SENSOR", 10, lambda d: src(d) == PERIPHERAL) is not None


def test_companion_and_station_reach_each_other(rig):
    """The companion's HEARTBEAT reaches the station; a command from the station to
    system 2 reaches the companion alone (not the peripheral's line) and its ACK comes
    back to the station."""
    g, c = rig.gcs, rig.comp
    hb = recv(g, "HEARTBEAT", 10, lambda h: src(h) == COMPANION)
    assert hb is not None and hb.type == 18
    rig.drain()
    start = rig.mark()
    g.mav.command_long_send(2, 191, MAV_CMD_USER_1, 0, 1, 0, 0, 0, 0, 0, 0)
    cmd = recv(c, "COMMAND_LONG", 10, lambda m: m.command == MAV_CMD_USER_1)
    assert cmd is not None and src(cmd) == STATION and cmd.target_system == 2
    c.mav.command_ack_send(MAV_CMD_USER_1, 0, 0, 0, 255, 190)
    a = recv(g, "COMMAND_ACK", 10, lambda a: a.command == MAV_CMD_USER_1)
    assert a is not None and src(a) == COMPANION and a.result == 0
    time.sleep(0.5)  # (the tap's thread is behind the companion's reads, if at all)
    assert not [m for m in rig.to_peripheral(start) if m.get_type() in ("COMMAND_LONG", "COMMAND_ACK")]


MARKER = 0xFFFF  # the seq of the broadcast PING that closes each case


def collect(rig, start, sender, timeout=15.0):
    """{link: [(src, PING seq, target)]}: the PINGs each link got that the vehicle did not
    make, the peripheral's line as the tap saw it from frame `start` on, until a broadcast
    PING (seq MARKER) from the same sender has reached the other two links. The vehicle
    keeps a link's frames in order, so what the case's PING led to is in by then, however
    busy the machine; then a quarter second more, for anything sent back to the sender."""
    got = {"gcs": [], "companion": [], "peripheral": []}
    others = [name for name in got if name != sender]
    sender_m = rig.gcs if sender == "gcs" else rig.comp
    sender_m.mav.ping_send(1, MARKER, 0, 0)
    marked = set()
    end, after = time.time() + timeout, None
    while time.time() < end and (after is None or time.time() < after):
        for name, m in (("gcs", rig.gcs), ("companion", rig.comp)):
            msg = m.recv_match(type="PING", blocking=False)
            while msg is not None:
                if src(msg) != VEHICLE:
                    got[name].append((src(msg), msg.seq, (msg.target_system, msg.target_component)))
                msg = m.recv_match(type="PING", blocking=False)
        got["peripheral"] = [(src(msg), msg.seq, (msg.target_system, msg.target_component))
                             for msg in rig.to_peripheral(start) if msg.get_type() == "PING" and src(msg) != VEHICLE]
        marked = {name for name in others if any(p[1] == MARKER for p in got[name])}
        if after is None and len(marked) == 2:
            after = time.time() + 0.25
        time.sleep(0.01)
    assert len(marked) == 2, ("the marker PING did not get through", got)
    marker = (STATION if sender == "gcs" else COMPANION, MARKER, (0, 0))
    return {name: [p for p in pings if p != marker] for name, pings in got.items()}


def test_pings_across_the_three_links(rig):
    """mavlink-router's routing test on a station (UDP), a peripheral and a companion
    (ptys): broadcasts reach every other link, a targeted PING only the link its target
    was heard on, the first to an unknown system none, and nothing comes back to its
    sender. (The vehicle's own PING answers aside.)"""
    g, c = rig.gcs, rig.comp
    rig.drain()
    cases = [
        (g, (77, 1), []),  # an unknown system: dropped
        (g, (0, 0), ["companion", "peripheral"]),  # broadcast
        (g, (2, 191), ["companion"]),
        (g, (2, 0), ["companion"]),  # a system, any component
        (g, (1, 158), ["peripheral"]),  # a component behind the vehicle
        (g, (1, 0), ["peripheral"]),  # our system, every component
        (g, (1, 1), []),  # the vehicle's alone
        (c, (0, 0), ["gcs", "peripheral"]),
        (c, (255, 190), ["gcs"]),
        (c, (1, 158), ["peripheral"]),
        (c, (78, 1), []),
    ]
    for seq, (m, target, where) in enumerate(cases, 200):
        start = rig.mark()
        m.mav.ping_send(1, seq, *target)
        got = collect(rig, start, "gcs" if m is g else "companion")
        sender = STATION if m is g else COMPANION
        want = {name: ([(sender, seq, target)] if name in where else []) for name in got}
        assert got == want, (target, got)
    # System 77, unknown at first, speaks up on the companion's line: now the vehicle
    # knows where it is, and a PING to it goes there alone.
    with rig.lock:
        c.mav.srcSystem, c.mav.srcComponent = 77, 1
        c.mav.heartbeat_send(2, 3, 0, 0, 4)  # (a vehicle behind the companion, say)
        c.mav.srcSystem, c.mav.srcComponent = COMPANION
    assert recv(g, "HEARTBEAT", 10, lambda h: src(h) == (77, 1)) is not None
    start = rig.mark()
    g.mav.ping_send(1, 299, 77, 1)
    got = collect(rig, start, "gcs")
    assert got == {"gcs": [], "companion": [(STATION, 299, (77, 1))], "peripheral": []}, got
    # The vehicle answers a request (a broadcast PING) to its sender alone.
    rig.drain()
    g.mav.ping_send(1, 300, 0, 0)
    ans = recv(g, "PING", 10, lambda p: src(p) == VEHICLE and p.seq == 300)
    assert ans is not None and (ans.target_system, ans.target_component) == STATION
    assert recv(c, "PING", 1, lambda p: src(p) == VEHICLE) is None
    # The peripheral's broadcasts (DISTANCE_SENSOR) reach both others, never its own line.
    start = rig.mark()
    assert recv(g, "DISTANCE_SENSOR", 10, lambda d: src(d) == PERIPHERAL)
    assert recv(c, "DISTANCE_SENSOR", 10, lambda d: src(d) == PERIPHERAL)
    assert not [m for m in rig.to_peripheral(start) if src(m) == PERIPHERAL]


def test_commands_for_every_component_of_the_system(rig):
    """COMMAND_LONG to (1, 0) reaches the vehicle and the peripheral, and each answers
    for itself: arming is the vehicle's alone (the peripheral, which has none, stays
    quiet: ACK_UNSUPPORTED_BROADCAST False); REQUEST_MESSAGE(DISTANCE_SENSOR) is
    ACCEPTED by 158 (the vehicle, which has no such message, answers for itself too)."""
    g = rig.gcs

    def acks(cmd, p1):
        rig.drain()
        g.mav.command_long_send(1, 0, cmd, 0, p1, 0, 0, 0, 0, 0, 0)
        got = []
        end = time.time() + 10
        while time.time() < end and len(got) < 2:
            a = recv(g, "COMMAND_ACK", 0.2, lambda a: a.command == cmd)
            if a is not None:
                got.append((src(a), a.result))
            elif got and time.time() > end - 8:
                break  # (two seconds at least with the first in hand)
        return dict(got)

    assert acks(400, 1) == {VEHICLE: 0}  # armed
    assert acks(400, 0) == {VEHICLE: 0}  # and disarmed
    got = acks(512, 132)
    assert got.get(PERIPHERAL) == 0 and set(got) <= {VEHICLE, PERIPHERAL}, got


def test_mavsdk_sees_one_vehicle_and_flies_it(rig):
    """MAVSDK on the station's UDP port: one system (1), whose autopilot is the vehicle
    (GENERIC) although component 158 of that system says MAV_AUTOPILOT_INVALID; it arms,
    takes off to 2 m, holds there 2.5 s and lands, the peripheral's HEARTBEATs and
    DISTANCE_SENSOR reaching MAVSDK meanwhile (its MavlinkDirect subscription)."""
    from mavsdk.autopilot import Autopilot
    from mavsdk.plugins.action import Action
    from mavsdk.plugins.mavlink_direct import MavlinkDirect
    from mavsdk.plugins.telemetry import LandedState, Telemetry

    from gcs_tools import mavsdk_system

    seen = []
    t0 = time.time()
    with mavsdk_system(rig.port) as system:
        direct = MavlinkDirect(system)
        handles = [direct.subscribe_message(name, lambda m, ud: seen.append((m.message_name, m.system_id,
                                                                               m.component_id)))
                   for name in ("HEARTBEAT", "DISTANCE_SENSOR")]
        try:
            action, tel = Action(system), Telemetry(system)
            assert system.get_system_id() == 1 and system.has_autopilot()
            assert system.autopilot_type() == Autopilot.GENERIC, system.autopilot_type()
            assert until(lambda: tel.landed_state() == LandedState.ON_GROUND and not tel.armed(), 20)
            action.set_takeoff_altitude(2.0)
            before, t1 = len(seen), time.time()
            action.arm()
            action.takeoff()
            assert until(lambda: abs(tel.position().relative_altitude_m - 2.0) < 0.1, 30), tel.position()
            time.sleep(2.5)  # holding at 2 m while the peripheral's frames keep coming
            assert abs(tel.position().relative_altitude_m - 2.0) < 0.1 and tel.armed()
            action.land()
            assert until(lambda: tel.landed_state() == LandedState.ON_GROUND and not tel.armed(), 40)
            flown, flight = seen[before:], time.time() - t1
            assert ("HEARTBEAT", 1, 158) in flown and ("DISTANCE_SENSOR", 1, 158) in flown, flown
            # One vehicle all the while: the peripheral's heartbeats made no second one (the
            # companion, system 2, is a system without an autopilot).
            systems = {s.get_system_id(): s.has_autopilot() for s in system.sdk.get_systems()}
            assert systems == {1: True, 2: False}, systems
            assert sorted(system.component_ids()) == [1, 158]
        finally:
            for h in handles:
                direct.unsubscribe_message(h)
    print("\nMAVSDK: armed, took off to 2 m and landed in %.1f s (%.1f s with its connection); %d of the "
          "peripheral's frames seen meanwhile" % (flight, time.time() - t0, len(flown)))

