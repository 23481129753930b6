"""The vehicle obeys its pilot: real ground stations over UDP drive the unix vehicle.

MAVSDK-Python's offboard plugin (set_position_ned, set_velocity_ned, started and
stopped) and its manual_control plugin; MAVProxy's `rc 3 1600`; pymavlink streaming
MANUAL_CONTROL at 20 Hz, then stopping, which trips the input-loss failsafe (hold, then
return to launch), and the same for offboard setpoints, without which OFFBOARD is refused.
The vehicle's motion is read from its own telemetry.
"""
import math
import threading
import time

from gcs_tools import (MAV_RESULT_ACCEPTED, MAV_RESULT_DENIED, MavProxy, listen, mavsdk_system, px4_station, run, start,
                       two_links)

FAST = ("--set", "sim_speed=8", "--set", "sim_climb=4")
# boards/unix.py FLIGHT_MODES numbers (ArduPilot's, as pymavlink reads them)
ALT_HOLD, POSITION, LOITER, RTL = 2, 16, 5, 6
EARTH_RADIUS = 6378137.0




def _position(m, timeout=5.0):
    """(north m, east m, up m) from GLOBAL_POSITION_INT, relative to the first fix read."""
    g = listen(m, "GLOBAL_POSITION_INT", timeout, lambda g: g.get_srcSystem() == 1)
    assert g is not None, "no GLOBAL_POSITION_INT"
    return g.lat / 1e7, g.lon / 1e7, g.relative_alt / 1000.0


def _metres(a, b):
    """(north, east, up) from position a to b."""
    dn = math.radians(b[0] - a[0]) * EARTH_RADIUS
    de = math.radians(b[1] - a[1]) * EARTH_RADIUS * math.cos(math.radians(a[0]))
    return dn, de, b[2] - a[2]


def _mode_is(m, number, timeout, texts=None):
    """Wait for the vehicle's HEARTBEAT in mode `number`; STATUSTEXTs seen meanwhile go to texts."""
    def seen(msg):
        if msg.get_type() == "STATUSTEXT":
            if texts is not None:
                texts.append(msg.text)
            return False
        return msg.get_srcSystem() == 1 and msg.custom_mode == number

    return listen(m, ["HEARTBEAT", "STATUSTEXT"], timeout, seen) is not None


class ManualStream:
    """MANUAL_CONTROL at 20 Hz from a thread, the sticks settable while it runs."""

    def __init__(self, m, hz=20):
        self.m = m
        self.period = 1.0 / hz
        self.sticks = (0, 0, 500, 0)
        self.lock = threading.Lock()
        self.sent = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _run(self):
        while not self._stop.is_set():
            x, y, z, r = self.sticks
            with self.lock:
                self.m.mav.manual_control_send(self.m.target_system, x, y, z, r, 0)
            self.sent += 1
            time.sleep(self.period)

    def __enter__(self):
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join()


def _climb_until(m, start, metres, timeout):
    deadline = time.time() + timeout
    p = start
    while time.time() < deadline:
        p = _position(m)
        if _metres(start, p)[2] >= metres:
            return p
    raise AssertionError("climbed only %.1f m" % _metres(start, p)[2])


def test_pymavlink_manual_control_then_input_loss_failsafe(vehicle):
    m = start(vehicle, *FAST).gcs()
    assert run(m, 176, 1, POSITION) == MAV_RESULT_ACCEPTED
    assert run(m, 400, 1) == MAV_RESULT_ACCEPTED  # arm
    home = _position(m)
    with ManualStream(m) as stream:
        stream.sticks = (0, 0, 1000, 0)  # throttle up: climb
        above = _climb_until(m, home, 3.0, 30)
        stream.sticks = (1000, 0, 500, 0)  # full forward (north: the nose points north)
        deadline = time.time() + 30
        while time.time() < deadline:
            p = _position(m)
            if _metres(above, p)[0] >= 5.0:
                break
        north = _metres(above, p)[0]
        assert north >= 5.0, "moved %.1f m north" % north
        stream.sticks = (0, 0, 500, 0)
        time.sleep(0.5)
        assert _mode_is(m, POSITION, 3)
    # The stream stops: after INPUT_TIMEOUT_MS the vehicle holds, then returns to launch.
    stopped = time.time()
    texts = []
    assert _mode_is(m, LOITER, 10, texts), "no hold after the manual input stopped"
    assert _mode_is(m, RTL, 20, texts), "no return to launch after the hold"
    assert time.time() - stopped < 25
    assert any("lost" in t.lower() for t in texts), texts  # the failsafe says why


def test_mavproxy_rc_override_climbs(vehicle, tmp_path):
    v, port, m = two_links(vehicle, *FAST)
    assert run(m, 176, 1, ALT_HOLD) == MAV_RESULT_ACCEPTED
    assert run(m, 400, 1) == MAV_RESULT_ACCEPTED
    home = _position(m)
    mp = MavProxy(port, tmp_path, "rc")
    try:
        mp.expect(r"online system 1|Detected vehicle 1:1")
        mp.say("rc 3 1600")  # throttle a fifth up: climb at a fifth of the climb rate
        _climb_until(m, home, 1.5, 40)
        mp.say("rc 3 1500")  # centred: the climb stops
        time.sleep(1.5)
        a = _position(m)
        time.sleep(2.0)
        b = _position(m)
        assert abs(_metres(a, b)[2]) < 0.5
    finally:
        mp.close()


def test_mavsdk_offboard_position_and_velocity(vehicle):
    from mavsdk.plugins.action import Action
    from mavsdk.plugins.offboard import Offboard, PositionNedYaw, VelocityNedYaw
    from mavsdk.plugins.telemetry import FlightMode, Telemetry

    v, port, m = two_links(vehicle, *FAST)
    with mavsdk_system(port) as system:
        action, offboard, tel = Action(system), Offboard(system), Telemetry(system)
        action.arm()
        offboard.set_position_ned(PositionNedYaw(4.0, 3.0, -6.0, 0.0))
        offboard.start()
        assert _wait(lambda: tel.flight_mode() == FlightMode.OFFBOARD, 10)
        # The target is answered, as the vehicle took it.
        t = listen(m, "POSITION_TARGET_LOCAL_NED", 5, lambda t: t.z == -6.0)
        assert t is not None and (t.x, t.y) == (4.0, 3.0)
        assert _wait(lambda: _near(tel.position_velocity_ned().position, 4.0, 3.0, -6.0), 30), \
            tel.position_velocity_ned().position
        offboard.set_velocity_ned(VelocityNedYaw(0.0, 3.0, 0.0, 0.0))  # east
        east = tel.position_velocity_ned().position.east_m
        assert _wait(lambda: tel.position_velocity_ned().position.east_m > east + 5.0, 30)
        offboard.stop()  # MAVSDK puts a PX4 vehicle in Hold
        assert _wait(lambda: tel.flight_mode() == FlightMode.HOLD, 10), tel.flight_mode()
        assert not offboard.is_active()


def test_mavsdk_manual_control_moves_the_vehicle(vehicle):
    from mavsdk.plugins.action import Action
    from mavsdk.plugins.manual_control import ManualControl
    from mavsdk.plugins.telemetry import FlightMode, Telemetry

    v, port, m = two_links(vehicle, *FAST)
    with mavsdk_system(port) as system:
        action, manual, tel = Action(system), ManualControl(system), Telemetry(system)
        manual.set_manual_control_input(0.0, 0.0, 0.5, 0.0)  # MAVSDK wants input first
        manual.start_position_control()
        assert _wait(lambda: tel.flight_mode() == FlightMode.POSCTL, 10)
        action.arm()
        start_pos = tel.position_velocity_ned().position
        deadline = time.time() + 40
        moved = False
        while time.time() < deadline and not moved:  # climb, forward (x), right (y)
            manual.set_manual_control_input(1.0, 0.5, 1.0, 0.0)
            p = tel.position_velocity_ned().position
            moved = p.down_m < start_pos.down_m - 2.0 and p.north_m > start_pos.north_m + 3.0 \
                and p.east_m > start_pos.east_m + 1.0
            time.sleep(0.05)
        assert moved, (start_pos, tel.position_velocity_ned().position)


def _near(p, n, e, d, tol=1.0):
    return abs(p.north_m - n) < tol and abs(p.east_m - e) < tol and abs(p.down_m - d) < tol


def _wait(cond, timeout):
    deadline = time.time() + timeout
    while time.time() < deadline:
        if cond():
            return True
        time.sleep(0.1)
    return False



def test_pymavlink_offboard_refused_without_setpoints_then_loss_failsafe(vehicle):
    # PX4's rule: OFFBOARD only with setpoints streaming; when they stop, hold, then RTL.
    m = px4_station(start(vehicle, *FAST).gcs())  # PX4's numbers: it shows PX4's convention (MAVSDK's way)
    assert run(m, 400, 1) == MAV_RESULT_ACCEPTED
    assert run(m, 176, 1, 6, 0) == MAV_RESULT_DENIED  # no setpoint yet
    stop = threading.Event()

    def stream():
        while not stop.is_set():
            m.mav.set_position_target_local_ned_send(0, 1, 1, 1, 0b100111111000, 0.0, 0.0, -4.0,
                                                     0, 0, 0, 0, 0, 0, 0.0, 0.0)
            time.sleep(0.05)

    t = threading.Thread(target=stream, daemon=True)
    t.start()
    try:
        time.sleep(0.3)
        assert run(m, 176, 1, 6, 0) == MAV_RESULT_ACCEPTED
        home = _position(m)
        _climb_until(m, home, 3.0, 30)
    finally:
        stop.set()
        t.join()
    texts = []
    assert _mode_is(m, 3 << 24 | 4 << 16, 10, texts), "no hold after the setpoints stopped"  # PX4 AUTO.LOITER
    assert _mode_is(m, 5 << 24 | 4 << 16, 20, texts), "no return to launch after the hold"  # AUTO.RTL
    assert any("Offboard setpoints lost" in t for t in texts), texts
