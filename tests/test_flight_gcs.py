"""Real ground stations fly the simulated vehicle over UDP: MAVSDK-Python's Action,
Telemetry and Mission plugins, and MAVProxy as a user types it, each by its autopilot's
conventions (MAVProxy ArduPilot's: ArduCopter's mode numbers, GUIDED after a takeoff, not
armable in RTL after landing, a plan's item 0 home; tests/test_gcs_walls.py has MAVSDK's,
PX4's). A pymavlink ground station on a second link checks what the vehicle does (mode,
position, arming)."""
import math
import time

import gcs_tools
from conftest import recv
from gcs_tools import MavProxy, mavsdk_system
from mission_gcs import LAT0, LON0

FAST = ("--set", "sim_speed=40", "--set", "sim_climb=20")
ARMED = 128
HOME_ALT = 488.0


def until(check, timeout=30.0, every=0.1):
    """Poll check() until it returns something true -> that, or None at the timeout."""
    deadline = time.time() + timeout
    while time.time() < deadline:
        got = check()
        if got:
            return got
        time.sleep(every)
    return None


def metres(lat, lon, lat0, lon0):
    dn = math.radians(lat - lat0) * 6378137.0
    de = math.radians(lon - lon0) * 6378137.0 * math.cos(math.radians(lat0))
    return math.hypot(dn, de)


def test_mavsdk_takeoff_goto_hold_return(vehicle):
    """action.set_takeoff_altitude (MAVSDK keeps it and sends it in NAV_TAKEOFF's param7), arm, takeoff,
    telemetry.in_air, goto_location (DO_REPOSITION, altitude AMSL), hold (DO_SET_MODE PX4
    AUTO.LOITER), return_to_launch (DO_SET_MODE PX4 AUTO.RTL) down to ON_GROUND, disarmed."""
    from mavsdk.plugins.action import Action
    from mavsdk.plugins.telemetry import LandedState, Telemetry

    v, port, m = gcs_tools.two_links(vehicle, *FAST)
    with mavsdk_system(port) as system:
        action, tel = Action(system), Telemetry(system)
        action.set_takeoff_altitude(8.0)
        until(lambda: tel.landed_state() == LandedState.ON_GROUND, 10)
        action.arm()
        action.takeoff()
        assert until(tel.in_air, 20), "never in the air"
        assert until(lambda: abs(tel.position().relative_altitude_m - 8.0) < 0.5, 20), tel.position()
        lat, lon = LAT0 / 1e7 + 0.0009, LON0 / 1e7  # 100 m north, 15 m up
        action.goto_location(lat, lon, HOME_ALT + 15.0, float("nan"))
        assert until(lambda: metres(tel.position().latitude_deg, tel.position().longitude_deg, LAT0 / 1e7, LON0 / 1e7) > 20, 20)
        action.hold()  # stops where it is
        time.sleep(0.5)
        a = tel.position()
        time.sleep(1.0)
        b = tel.position()
        assert metres(a.latitude_deg, a.longitude_deg, b.latitude_deg, b.longitude_deg) < 1.0
        action.goto_location(lat, lon, HOME_ALT + 15.0, float("nan"))
        assert until(lambda: metres(tel.position().latitude_deg, tel.position().longitude_deg, lat, lon) < 1.0
                     and abs(tel.position().relative_altitude_m - 15.0) < 0.5, 20), tel.position()
        action.return_to_launch()
        assert until(lambda: tel.landed_state() == LandedState.ON_GROUND and not tel.armed(), 40), tel.landed_state()
        p = tel.position()
        assert metres(p.latitude_deg, p.longitude_deg, LAT0 / 1e7, LON0 / 1e7) < 2.5
        assert not tel.in_air()
    v.check_alive()


def test_mavsdk_refusals(vehicle):
    """Takeoff disarmed: MAVSDK's COMMAND_DENIED; start_mission without a mission: refused."""
    import pytest
    from mavsdk.plugins.action import Action, ActionError
    from mavsdk.plugins.mission import Mission, MissionError

    v, port, m = gcs_tools.two_links(vehicle, *FAST)
    with mavsdk_system(port) as system:
        with pytest.raises(ActionError) as e:
            Action(system).takeoff()
        assert "DENIED" in str(e.value).upper()
        with pytest.raises(MissionError):
            Mission(system).start_mission()
    assert recv(m, "STATUSTEXT", 5, lambda s: "Mode: no mission" in s.text) is not None


def test_mavsdk_start_mission_flies_it_to_the_end(vehicle):
    """mission.start_mission (mode PX4 AUTO.MISSION) on an uploaded mission with a
    loiter_time_s: flown to the end, mission_progress reaches the total."""
    from mavsdk.plugins.action import Action
    from mavsdk.plugins.mission import Mission, MissionItem, MissionPlan

    nan = float("nan")
    CA, VA = MissionItem.CameraAction, MissionItem.VehicleAction
    lat, lon = LAT0 / 1e7, LON0 / 1e7

    def item(dlat, dlon, alt, loiter=nan, action=VA.NONE):
        return MissionItem(lat + dlat, lon + dlon, alt, nan, False, nan, nan, CA.NONE, loiter, nan, nan,
                           nan, nan, action)

    items = [item(0, 0, 10, action=VA.TAKEOFF), item(0.0003, 0, 12, loiter=1.0),
             item(0.0003, 0.0003, 12), item(0, 0.0003, 10, loiter=0.5)]
    v, port, m = gcs_tools.two_links(vehicle, *FAST)
    progress = []
    with mavsdk_system(port) as system:
        mission = Mission(system)
        mission.upload_mission(MissionPlan(items))
        mission.subscribe_mission_progress(lambda p, ud: progress.append((p.current, p.total)))
        Action(system).arm()
        mission.start_mission()
        assert until(lambda: progress and progress[-1][0] == progress[-1][1] > 0, 40), progress
        assert until(mission.is_mission_finished, 10)
    assert progress[-1][1] == len(items) + 0 or progress[-1][1] > 0
    texts = []
    gcs_tools.listen(m, "STATUSTEXT", 3, lambda t: texts.append(t.text) and False)
    hb = gcs_tools.vehicle_heartbeat(m)
    assert hb.base_mode & ARMED, texts  # done in the air: holding
    pos = gcs_tools.listen(m, "GLOBAL_POSITION_INT", 5)
    assert metres(pos.lat / 1e7, pos.lon / 1e7, lat, lon + 0.0003) < 2.5
    v.check_alive()


def test_mavproxy_guided_takeoff_goto_rtl(vehicle, tmp_path):
    """MAVProxy: `mode GUIDED`, `arm throttle`, `takeoff 10` (then GUIDED, as ArduCopter),
    `guided LAT LON ALT` (a MISSION_ITEM_INT with current 2, ArduPilot's guided waypoint),
    `position X Y Z`, `rtl` (mode RTL); `setyaw` is ArduPilot's alone. Landed by RTL the
    vehicle stays in RTL, where it will not arm (ArduPilot's rule), until another mode."""
    v, port, check = gcs_tools.two_links(vehicle, *FAST)
    mp = MavProxy(port, tmp_path, "mode,cmdlong,arm")
    try:
        mp.expect(r"online system 1|Detected vehicle 1:1")
        mp.say("mode GUIDED")
        assert gcs_tools.vehicle_heartbeat(check, lambda h: h.custom_mode == 4) is not None
        mp.say("arm throttle")
        assert gcs_tools.vehicle_heartbeat(check, lambda h: h.base_mode & ARMED) is not None
        mp.say("takeoff 10")
        assert gcs_tools.listen(check, "GLOBAL_POSITION_INT", 20, lambda p: abs(p.relative_alt - 10000) < 50) is not None
        time.sleep(1.0)
        assert gcs_tools.vehicle_heartbeat(check).custom_mode == 4  # done: GUIDED still
        lat, lon = LAT0 / 1e7 + 0.0005, LON0 / 1e7 + 0.0005
        mp.say("guided %.7f %.7f 20" % (lat, lon))
        mp.expect(r"Guided")
        there = gcs_tools.listen(check, "GLOBAL_POSITION_INT", 30,
                                 lambda p: metres(p.lat / 1e7, p.lon / 1e7, lat, lon) < 1.0 and abs(p.relative_alt - 20000) < 500)
        assert there is not None
        # `position` (SET_POSITION_TARGET_LOCAL_NED, body frame: 10 m ahead), flown in GUIDED
        # as ArduPilot does; the nose points north-east after the goto.
        mp.say("position 10 0 0")
        ahead = gcs_tools.listen(check, "GLOBAL_POSITION_INT", 20,
                                 lambda p: abs(metres(p.lat / 1e7, p.lon / 1e7, lat, lon) - 10.0) < 0.5
                                 and p.vx == 0 and p.vy == 0)
        assert ahead is not None and ahead.lat > lat * 1e7 and ahead.lon > lon * 1e7
        # `setyaw` sends CONDITION_YAW as a command: ArduPilot's own use; MAVLink defines it
        # as a mission item (flown in missions here), so the command is UNSUPPORTED.
        mp.say("setyaw 90 10 1")
        mp.expect(r"CONDITION_YAW.*UNSUPPORTED|UNSUPPORTED.*CONDITION_YAW|result 3")
        mp.say("rtl")
        assert gcs_tools.vehicle_heartbeat(check, lambda h: h.custom_mode == 6) is not None
        assert gcs_tools.vehicle_heartbeat(check, lambda h: not h.base_mode & ARMED, timeout=40) is not None
        pos = gcs_tools.listen(check, "GLOBAL_POSITION_INT", 5)
        assert metres(pos.lat / 1e7, pos.lon / 1e7, LAT0 / 1e7, LON0 / 1e7) < 2.5 and abs(pos.relative_alt) < 200
        assert gcs_tools.vehicle_heartbeat(check).custom_mode == 6  # still RTL
        mp.say("arm throttle")
        assert gcs_tools.statustext(check, "Arm: mode RTL: not armable") is not None
        mp.say("mode LOITER")
        mp.say("arm throttle")
        assert gcs_tools.vehicle_heartbeat(check, lambda h: h.base_mode & ARMED) is not None
    finally:
        mp.close()
    v.check_alive()


# QGC WPL 110 as MAVProxy saves one: index current frame command p1 p2 p3 p4 x y z autocontinue;
# row 0 is home (ArduPilot's convention), at ground level.
WPL = """QGC WPL 110
0\t1\t0\t16\t0\t0\t0\t0\t47.3977420\t8.5455940\t488.000000\t1
1\t0\t3\t22\t0\t0\t0\t0\t0.0000000\t0.0000000\t12.000000\t1
2\t0\t3\t16\t0\t0\t0\t0\t47.3980420\t8.5455940\t12.000000\t1
3\t0\t3\t16\t0\t0\t0\t0\t47.3980420\t8.5459940\t12.000000\t1
"""


def test_mavproxy_mission_start_0_flies_past_the_home_row(vehicle, tmp_path):
    """MAVProxy's plans keep home in item 0, as ArduPilot does: `long MISSION_START 0`
    flies from item 1 (the takeoff), never to the home row at ground level; `mode AUTO`
    after the end flies it again from item 1."""
    v, port, check = gcs_tools.two_links(vehicle, *FAST)
    (tmp_path / "mission.txt").write_text(WPL)
    mp = MavProxy(port, tmp_path, "wp,cmdlong,arm,mode")
    try:
        mp.expect(r"online system 1|Detected vehicle 1:1")
        mp.say("wp load mission.txt")
        mp.expect(r"Sent all 4 waypoints?")
        mp.say("arm throttle")
        assert gcs_tools.vehicle_heartbeat(check, lambda h: h.base_mode & ARMED) is not None
        for start in ("long MISSION_START 0", "mode AUTO"):
            mp.say(start)
            reached, lowest = [], None
            deadline = time.time() + 30
            while time.time() < deadline and 3 not in reached:
                r = gcs_tools.listen(check, ["MISSION_ITEM_REACHED", "GLOBAL_POSITION_INT"], 5)
                if r is not None and r.get_type() == "MISSION_ITEM_REACHED":
                    reached.append(r.seq)
                elif r is not None and reached and (lowest is None or r.relative_alt < lowest):
                    lowest = r.relative_alt  # once up: never back down to the home row
            assert reached == [1, 2, 3] and lowest > 11000, (start, reached, lowest)
        mp.say("rtl")
        assert gcs_tools.vehicle_heartbeat(check, lambda h: not h.base_mode & ARMED, timeout=40) is not None
    finally:
        mp.close()
    v.check_alive()
