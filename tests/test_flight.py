"""The simulated vehicle flies what its pilot asks (firmware/sim/pilot.py), seen by a
pymavlink ground station over UDP: takeoff, hold, land, reposition, speed, RTL, mode
changes with the same effect as the commands, MISSION_START, failsafes, and telemetry
telling the truth throughout (EXTENDED_SYS_STATE landed_state, HEARTBEAT system_status,
GLOBAL_POSITION_INT). Fast simulation: 40 m/s, 20 m/s climb."""
import math
import struct
import time

import gcs_tools
from conftest import recv
from gcs_tools import MAV_RESULT_ACCEPTED as ACCEPTED, MAV_RESULT_DENIED as DENIED, MAV_RESULT_FAILED as FAILED
from mission_gcs import LAT0, LON0, Item, MissionClient

IN_PROGRESS = 5
ON_GROUND, IN_AIR, TAKEOFF, LANDING = 1, 2, 3, 4
STANDBY, ACTIVE = 3, 4
ARMED = 128
# ArduPilot's numbers (the unix board's FLIGHT_MODES), as a pymavlink link reads them.
AUTO, GUIDED, LOITER, RTL, LAND = 3, 4, 5, 6, 9
FAST = ("--set", "sim_speed=40", "--set", "sim_climb=20")


def fly_vehicle(vehicle, *args):
    v = vehicle(args=list(FAST + args))
    return v, v.gcs()


def heartbeat(m, cond=None, timeout=10.0):
    return gcs_tools.vehicle_heartbeat(m, cond, timeout)


def set_mode(m, number):
    """SET_MODE with an ArduPilot-numbered custom mode (no ACK: the heartbeat tells)."""
    m.mav.set_mode_send(m.target_system, 1, number)
    return heartbeat(m, lambda h: h.custom_mode == number)


def wait_ack(m, cmd, timeout=20.0):
    """The final COMMAND_ACK of a command (IN_PROGRESS ones counted) -> (result, in_progress seen)."""
    progress = 0
    deadline = time.time() + timeout
    while time.time() < deadline:
        a = gcs_tools.listen(m, "COMMAND_ACK", deadline - time.time(), lambda a: a.command == cmd)
        if a is None:
            break
        if a.result != IN_PROGRESS:
            return a.result, progress
        progress += 1
    return None, progress


def takeoff(m, alt=10.0):
    assert gcs_tools.run(m, 400, 1) == ACCEPTED  # arm
    gcs_tools.command(m, 22, 0, 0, 0, 0, 0, 0, alt)
    result, progress = wait_ack(m, 22)
    assert (result, progress > 0) == (ACCEPTED, True)


def position(m, cond=None, timeout=20.0):
    return gcs_tools.listen(m, "GLOBAL_POSITION_INT", timeout, cond)


def metres(lat_e7, lon_e7, lat0_e7, lon0_e7):
    dn = (lat_e7 - lat0_e7) / 1e7 * math.pi / 180 * 6378137.0
    de = (lon_e7 - lon0_e7) / 1e7 * math.pi / 180 * 6378137.0 * math.cos(math.radians(lat0_e7 / 1e7))
    return math.hypot(dn, de)


def landed_states(m, until, timeout=30.0):
    """EXTENDED_SYS_STATE landed_state values, repeats folded, until `until` is seen ->
    (states, {command: final result} of the COMMAND_ACKs that came meanwhile)."""
    seen, acks = [], {}
    deadline = time.time() + timeout
    while time.time() < deadline:
        s = gcs_tools.listen(m, ["EXTENDED_SYS_STATE", "COMMAND_ACK"], deadline - time.time())
        if s is None:
            break
        if s.get_type() == "COMMAND_ACK":
            if s.result != IN_PROGRESS:
                acks[s.command] = s.result
            continue
        if not seen or seen[-1] != s.landed_state:
            seen.append(s.landed_state)
        if s.landed_state == until and len(seen) > 1:
            break
    return seen, acks


# The failsafes' hold in these tests: two seconds, so that the 1 Hz HEARTBEAT shows it
# however the vehicle's passes fall on a loaded machine (with one second, a late pass
# once let the hold go by between two HEARTBEATs).
HOLD_S = 2.0


def failsafe(m, what, hold, ret, silent=False, timeout=40.0):
    """From now until the vehicle is disarmed, everything it reports of a failsafe on
    `what`, in the order it came: its STATUSTEXTs and the modes its HEARTBEAT shows (repeats
    folded). Nothing is read past, so a mode shown before its text counts too. Asserts the
    hold (STATUSTEXT "...: holding", mode `hold`), then the return ("...: returning", mode
    `ret`), then the landing (disarmed). silent: send no GCS heartbeats meanwhile."""
    texts, modes = [], []
    deadline = time.time() + timeout
    while time.time() < deadline:
        wait = deadline - time.time()
        msg = recv(m, ["HEARTBEAT", "STATUSTEXT"], wait) if silent else \
            gcs_tools.listen(m, ["HEARTBEAT", "STATUSTEXT"], wait)
        if msg is None:
            break
        if msg.get_type() == "STATUSTEXT":
            if msg.text.startswith("Failsafe: %s lost" % what):
                texts.append(msg.text)
        elif msg.get_srcSystem() == m.target_system and msg.get_srcComponent() == 1:
            if not modes or modes[-1] != msg.custom_mode:
                modes.append(msg.custom_mode)
            if not msg.base_mode & ARMED:
                break
    assert [t.split(":")[2].split(",")[0].strip() for t in texts] == ["holding", "returning"], texts
    assert hold in modes and ret in modes[modes.index(hold):], modes
    assert not msg.base_mode & ARMED, modes  # home, landed


def test_takeoff_hold_and_land(vehicle):
    v, m = fly_vehicle(vehicle)
    assert heartbeat(m).system_status == STANDBY
    # Disarmed: refused, and said why.
    assert gcs_tools.run(m, 22, 0, 0, 0, 0, 0, 0, 10.0) == DENIED
    assert gcs_tools.statustext(m, "Takeoff: disarmed") is not None
    assert gcs_tools.run(m, 400, 1) == ACCEPTED
    assert heartbeat(m, lambda h: h.base_mode & ARMED).system_status == STANDBY  # armed, on the ground
    gcs_tools.command(m, 22, 0, 0, 0, 0, 0, 0, 10.0)
    result, progress = wait_ack(m, 22)
    assert result == ACCEPTED and progress >= 1  # IN_PROGRESS first, ACCEPTED at the altitude
    pos = position(m)
    assert abs(pos.relative_alt - 10000) < 600
    hb = heartbeat(m, lambda h: h.custom_mode == LOITER)  # holds once there
    assert hb is not None and hb.system_status == ACTIVE
    assert recv(m, "EXTENDED_SYS_STATE", 5, lambda s: s.landed_state == IN_AIR) is not None
    vfr = recv(m, "VFR_HUD", 5)
    assert abs(vfr.alt - 498.0) < 0.6 and vfr.groundspeed < 0.1
    # Flying: a second takeoff fails (ArduPilot's answer), disarming is refused.
    assert gcs_tools.run(m, 22, 0, 0, 0, 0, 0, 0, 20.0) == FAILED
    assert gcs_tools.statustext(m, "Takeoff: already flying") is not None
    assert gcs_tools.run(m, 400, 0) == DENIED
    time.sleep(0.5)
    assert abs(position(m).relative_alt - 10000) < 600  # still holding
    # Land: IN_PROGRESS, down, disarmed, ACCEPTED on touchdown.
    gcs_tools.command(m, 21)
    result, progress = wait_ack(m, 21)
    assert result == ACCEPTED and progress >= 1
    hb = heartbeat(m, lambda h: not h.base_mode & ARMED)
    assert hb.custom_mode == LAND and hb.system_status == STANDBY
    assert recv(m, "EXTENDED_SYS_STATE", 5, lambda s: s.landed_state == ON_GROUND) is not None
    assert abs(position(m).relative_alt) < 200
    v.check_alive()


def test_landed_state_goes_through_takeoff_in_air_landing(vehicle):
    v, m = fly_vehicle(vehicle, "--set", "sim_climb=4")
    gcs_tools.command(m, 511, 245, 100000)  # EXTENDED_SYS_STATE at 10 Hz
    assert wait_ack(m, 511)[0] == ACCEPTED
    assert gcs_tools.run(m, 400, 1) == ACCEPTED
    assert recv(m, "EXTENDED_SYS_STATE", 5).landed_state == ON_GROUND
    gcs_tools.command(m, 22, 0, 0, 0, 0, 0, 0, 6.0)
    seen, acks = landed_states(m, IN_AIR)
    assert seen[-2:] == [TAKEOFF, IN_AIR] and acks.get(22, ACCEPTED) == ACCEPTED
    time.sleep(0.5)
    gcs_tools.command(m, 21)
    seen, acks = landed_states(m, ON_GROUND)
    assert seen == [IN_AIR, LANDING, ON_GROUND] and acks.get(21, ACCEPTED) == ACCEPTED


def test_reposition_speed_and_return(vehicle):
    v, m = fly_vehicle(vehicle)
    # On the ground: nowhere to go yet.
    assert gcs_tools.run(m, 400, 1) == ACCEPTED
    m.mav.command_int_send(1, 1, 6, 192, 0, 0, -1, 1, 0, float("nan"), LAT0 + 9000, LON0, 15.0)
    assert gcs_tools.ack(m, 192).result == DENIED
    assert gcs_tools.statustext(m, "Reposition: on the ground") is not None
    takeoff(m)
    # 100 m north at 15 m above home (relative frame), at the default speed.
    m.mav.command_int_send(1, 1, 6, 192, 0, 0, -1, 1, 0, float("nan"), LAT0 + 9000, LON0, 15.0)
    assert gcs_tools.ack(m, 192).result == ACCEPTED
    assert heartbeat(m, lambda h: h.custom_mode == GUIDED) is not None
    moving = position(m, lambda p: math.hypot(p.vx, p.vy) > 1500)
    assert moving is not None and moving.vx > 0  # north
    there = position(m, lambda p: metres(p.lat, p.lon, LAT0 + 9000, LON0) < 1.0 and abs(p.relative_alt - 15000) < 500)
    assert there is not None
    # DO_CHANGE_SPEED: 3 m/s; then 20 m east, latitude kept (INT32_MAX), altitude in AMSL.
    assert gcs_tools.run(m, 178, 1, 3.0, -1) == ACCEPTED
    m.mav.command_int_send(1, 1, 5, 192, 0, 0, -1, 1, 0, float("nan"), 2147483647, LON0 + 2650, 488.0 + 15.0)
    assert gcs_tools.ack(m, 192).result == ACCEPTED
    vfr = gcs_tools.listen(m, "VFR_HUD", 10, lambda h: h.groundspeed > 1.0)
    assert vfr is not None and abs(vfr.groundspeed - 3.0) < 0.3
    assert gcs_tools.run(m, 178, 1, -5.0, -1) == DENIED  # a negative speed
    # RTL: up to RTL_ALT (15 m), home, down, disarmed.
    assert gcs_tools.run(m, 178, 1, -2, -1) == ACCEPTED  # back to the parameter's speed
    assert gcs_tools.run(m, 20) == ACCEPTED
    assert heartbeat(m, lambda h: h.custom_mode == RTL) is not None
    hb = heartbeat(m, lambda h: not h.base_mode & ARMED, timeout=40)
    assert hb is not None and hb.system_status == STANDBY
    pos = position(m)
    assert metres(pos.lat, pos.lon, LAT0, LON0) < 2.5 and abs(pos.relative_alt) < 200
    assert gcs_tools.run(m, 20) == DENIED  # disarmed
    v.check_alive()


def test_mode_changes_do_what_the_commands_do(vehicle):
    """A ground station's SET_MODE: LOITER holds, GUIDED holds, LAND lands and disarms,
    RTL returns; NAV_LOITER_UNLIM holds; DO_PAUSE_CONTINUE pauses a reposition and goes on."""
    v, m = fly_vehicle(vehicle)
    takeoff(m)
    m.mav.command_int_send(1, 1, 6, 192, 0, 0, 2.0, 1, 0, float("nan"), LAT0 + 9000, LON0, 10.0)
    assert gcs_tools.ack(m, 192).result == ACCEPTED
    assert position(m, lambda p: metres(p.lat, p.lon, LAT0, LON0) > 3.0) is not None
    # Pause: held where it is; continue: on to the point.
    assert gcs_tools.run(m, 193, 0) == ACCEPTED
    assert heartbeat(m, lambda h: h.custom_mode == LOITER) is not None
    a = position(m)
    time.sleep(0.5)
    b = position(m)
    assert metres(a.lat, a.lon, b.lat, b.lon) < 0.5
    assert gcs_tools.run(m, 193, 1) == ACCEPTED
    assert heartbeat(m, lambda h: h.custom_mode == GUIDED) is not None
    assert position(m, lambda p: metres(p.lat, p.lon, a.lat, a.lon) > 1.0) is not None
    assert gcs_tools.run(m, 193, 1) == DENIED  # nothing paused now
    # Mode LOITER by SET_MODE: holds.
    set_mode(m, LOITER)
    a = position(m)
    time.sleep(0.5)
    assert metres(a.lat, a.lon, position(m).lat, position(m).lon) < 0.5
    assert gcs_tools.run(m, 17) == ACCEPTED  # NAV_LOITER_UNLIM: here
    # Mode RTL by SET_MODE: home (back over it, then down).
    set_mode(m, RTL)
    assert position(m, lambda p: metres(p.lat, p.lon, LAT0, LON0) < 2.5, timeout=20) is not None
    # Mode LAND by SET_MODE before touchdown: down here, disarmed.
    set_mode(m, LAND)
    assert heartbeat(m, lambda h: not h.base_mode & ARMED, timeout=30) is not None
    assert recv(m, "EXTENDED_SYS_STATE", 5, lambda s: s.landed_state == ON_GROUND) is not None
    v.check_alive()


MISSION = [Item(3, 22, 0, 1, 0, 0, 0, float("nan"), 0, 0, 10.0),
           Item(3, 16, 0, 1, 0.5, 1.0, 0, float("nan"), LAT0 + 4500, LON0, 10.0),
           Item(3, 16, 0, 1, 0, 1.0, 0, float("nan"), LAT0 + 4500, LON0 + 4500, 12.0),
           Item(3, 21, 0, 1, 0, 0, 0, float("nan"), LAT0 + 4500, LON0 + 4500, 0.0)]


def test_mission_start(vehicle):
    v, m = fly_vehicle(vehicle)
    assert gcs_tools.run(m, 300, 0, 0) == DENIED
    assert gcs_tools.statustext(m, "Mission: no mission") is not None
    m.mav.set_mode_send(1, 1, AUTO)  # the mode, likewise
    assert gcs_tools.statustext(m, "Mode: no mission") is not None
    assert MissionClient(m).upload(MISSION) == 0
    assert gcs_tools.run(m, 300, 0, 0) == DENIED  # disarmed
    assert gcs_tools.statustext(m, "Mission: disarmed") is not None
    assert gcs_tools.run(m, 400, 1) == ACCEPTED
    assert gcs_tools.run(m, 300, 0, 0) == ACCEPTED
    reached, modes = [], set()
    deadline = time.time() + 40
    while time.time() < deadline and len(reached) < len(MISSION):
        r = gcs_tools.listen(m, ["MISSION_ITEM_REACHED", "HEARTBEAT"], deadline - time.time())
        if r is not None and r.get_type() == "HEARTBEAT":
            modes.add(r.custom_mode)
        elif r is not None and r.seq not in reached:
            reached.append(r.seq)
    assert reached == [0, 1, 2, 3] and AUTO in modes
    hb = heartbeat(m, lambda h: not h.base_mode & ARMED)  # landed by the mission: disarmed
    assert hb is not None and hb.system_status == STANDBY
    cur = gcs_tools.listen(m, "MISSION_CURRENT", 5)
    assert cur.mission_state == 5  # complete
    pos = position(m)
    assert metres(pos.lat, pos.lon, LAT0 + 4500, LON0 + 4500) < 2.5 and abs(pos.relative_alt) < 200
    v.check_alive()


def test_mode_auto_flies_the_mission_and_holds_at_its_end(vehicle):
    v, m = fly_vehicle(vehicle)
    assert MissionClient(m).upload(MISSION[:3]) == 0
    assert gcs_tools.run(m, 400, 1) == ACCEPTED
    set_mode(m, AUTO)
    assert gcs_tools.statustext(m, "Mission: complete, holding", timeout=30) is not None
    hb = heartbeat(m, lambda h: h.custom_mode == LOITER)
    assert hb.base_mode & ARMED and hb.system_status == ACTIVE
    assert abs(position(m).relative_alt - 12000) < 600


def test_guided_mission_item_goes_there(vehicle):
    """ArduPilot's guided waypoint (MAVProxy's `guided`): MISSION_ITEM_INT with current 2;
    current 3 changes the altitude. Refused (MISSION_ACK DENIED) on the ground."""
    v, m = fly_vehicle(vehicle)
    m.mav.mission_item_int_send(1, 1, 0, 6, 16, 2, 0, 0, 0, 0, 0, LAT0 + 4500, LON0, 12.0)
    assert recv(m, "MISSION_ACK", 5).type == 14  # MAV_MISSION_DENIED
    takeoff(m)
    m.mav.mission_item_int_send(1, 1, 0, 6, 16, 2, 0, 0, 0, 0, 0, LAT0 + 4500, LON0, 12.0)
    assert recv(m, "MISSION_ACK", 5).type == 0
    assert heartbeat(m, lambda h: h.custom_mode == GUIDED) is not None
    assert position(m, lambda p: metres(p.lat, p.lon, LAT0 + 4500, LON0) < 1.0 and abs(p.relative_alt - 12000) < 500) is not None
    m.mav.mission_item_int_send(1, 1, 0, 6, 16, 3, 0, 0, 0, 0, 0, 0, 0, 20.0)
    assert recv(m, "MISSION_ACK", 5).type == 0
    assert position(m, lambda p: metres(p.lat, p.lon, LAT0 + 4500, LON0) < 1.0 and abs(p.relative_alt - 20000) < 500) is not None
    assert MissionClient(m).count().count == 0  # not a plan's item


def test_gcs_loss_holds_then_returns(vehicle):
    v, m = fly_vehicle(vehicle, "--set", "gcs_timeout_ms=1000")
    assert gcs_tools.run(m, 180, 1, 0) is not None  # (a command: the vehicle hears us)
    m.mav.param_set_send(1, 1, b"FS_HOLD_S", HOLD_S, 9)
    assert recv(m, "PARAM_VALUE", 5, lambda p: p.param_id == "FS_HOLD_S").param_value == HOLD_S
    takeoff(m)
    failsafe(m, "GCS", LOITER, RTL, silent=True)  # silence: no heartbeats from here on


def test_gcs_back_before_the_hold_ends_stays_holding(vehicle):
    v, m = fly_vehicle(vehicle, "--set", "gcs_timeout_ms=1000")
    m.mav.param_set_send(1, 1, b"FS_HOLD_S", 3.0, 9)
    assert gcs_tools.listen(m, "PARAM_VALUE", 5, lambda p: p.param_id == "FS_HOLD_S").param_value == 3.0
    takeoff(m)
    assert recv(m, "STATUSTEXT", 10, lambda s: "Failsafe: GCS lost: holding" in s.text) is not None
    assert gcs_tools.statustext(m, "Failsafe: GCS back: holding here") is not None
    deadline = time.time() + 4
    while time.time() < deadline:
        assert gcs_tools.listen(m, "HEARTBEAT", 2, lambda h: h.get_srcSystem() == 1).custom_mode == LOITER


def px4(main, sub=0):
    return main << 16 | sub << 24


def test_offboard_setpoints_flown_and_their_loss_holds_then_returns(vehicle):
    """OFFBOARD (set the PX4 way, which turns the link to PX4's numbering) flies the
    streamed SET_POSITION_TARGET_LOCAL_NED; when it stops: LOITER (PX4 AUTO.LOITER) at
    once, RTL (AUTO.RTL) FS_HOLD_S later."""
    v, m = fly_vehicle(vehicle)
    m.mav.param_set_send(1, 1, b"FS_HOLD_S", HOLD_S, 9)
    assert gcs_tools.listen(m, "PARAM_VALUE", 5, lambda p: p.param_id == "FS_HOLD_S").param_value == HOLD_S
    takeoff(m)
    position_only = 8 | 16 | 32 | 64 | 128 | 256 | 1024 | 2048

    def setpoint():
        m.mav.set_position_target_local_ned_send(0, 1, 1, 1, position_only, 20.0, 0.0, -10.0, 0, 0, 0, 0, 0, 0, 0, 0)

    m.mav.set_mode_send(1, 1, px4(6))  # OFFBOARD without a setpoint: refused
    assert gcs_tools.statustext(m, "Mode: no offboard setpoint") is not None
    for _ in range(3):
        setpoint()
        time.sleep(0.1)
    m.mav.set_mode_send(1, 1, px4(6))
    deadline = time.time() + 20
    there = None
    while time.time() < deadline and there is None:
        setpoint()
        there = recv(m, "LOCAL_POSITION_NED", 0.2, lambda p: abs(p.x - 20.0) < 0.5 and abs(p.z + 10.0) < 0.5)
    assert there is not None
    assert gcs_tools.vehicle_heartbeat(m).custom_mode == px4(6)
    failsafe(m, "Offboard setpoints", px4(4, 3), px4(4, 5))  # the stream stops


def test_absurd_numbers_keep_the_vehicle_flying(vehicle):
    """What a command may say stays harmless: a reposition at 1e30 m/s to 1e30 m, a climb
    rate of 1e5 m/s: capped (100 m/s, 10 km above the ground), telemetry goes on."""
    v, m = fly_vehicle(vehicle)
    takeoff(m)
    assert gcs_tools.run(m, 178, 2, 1e5, -1) == ACCEPTED  # climb speed
    m.mav.command_int_send(1, 1, 6, 192, 0, 0, 1e30, 1, 0, float("nan"), LAT0 + 90000, LON0, 1e30)
    assert gcs_tools.ack(m, 192).result == ACCEPTED
    high = position(m, lambda p: p.relative_alt > 9000000)
    assert high is not None and high.relative_alt <= 10000000 and -32768 <= high.vz <= 32767  # (saturated)
    assert gcs_tools.run(m, 176, 1, LAND) == ACCEPTED  # DO_SET_MODE LAND, down from 10 km at 1.5 m/s...
    assert gcs_tools.run(m, 178, 3, 1e5, -1) == ACCEPTED  # ... or at 100 km/s
    assert heartbeat(m, lambda h: not h.base_mode & ARMED, timeout=20) is not None
    v.check_alive()


def test_manual_control_flies_alt_hold_and_its_loss_returns(vehicle):
    """ALT_HOLD: MANUAL_CONTROL's throttle climbs from the ground, the pitch stick flies
    forward, centred sticks hold; when it stops: LOITER, then RTL FS_HOLD_S later."""
    v, m = fly_vehicle(vehicle)
    m.mav.param_set_send(1, 1, b"FS_HOLD_S", HOLD_S, 9)
    assert gcs_tools.listen(m, "PARAM_VALUE", 5, lambda p: p.param_id == "FS_HOLD_S").param_value == HOLD_S
    assert gcs_tools.run(m, 400, 1) == ACCEPTED
    set_mode(m, 2)  # ALT_HOLD

    def sticks(x, z, seconds, cond=None):
        deadline = time.time() + seconds
        while time.time() < deadline:
            m.mav.heartbeat_send(6, 8, 0, 0, 0)
            m.mav.manual_control_send(1, x, 0, z, 0, 0)
            p = recv(m, "GLOBAL_POSITION_INT", 0.1)
            if p is not None and cond is not None and cond(p):
                return p
        return None

    assert sticks(0, 1000, 15, lambda p: p.relative_alt > 8000) is not None  # full throttle: up
    assert sticks(1000, 500, 15, lambda p: metres(p.lat, p.lon, LAT0, LON0) > 10 and p.vx > 500) is not None
    a = sticks(0, 500, 1.0) or position(m)
    b = sticks(0, 500, 1.0, lambda p: True)
    time.sleep(0.3)
    assert abs(b.relative_alt - a.relative_alt) < 600
    failsafe(m, "Manual control", LOITER, RTL)  # the sticks stop
    pos = position(m)
    assert metres(pos.lat, pos.lon, LAT0, LON0) < 2.5


def test_takeoff_mode_in_the_air_and_arming_in_land(vehicle):
    """Mode TAKEOFF (standard mode 8) in the air above the takeoff altitude stays there and
    holds; landed in LAND, arming again is refused (it would land at once) until another mode."""
    v, m = fly_vehicle(vehicle)
    takeoff(m, 20.0)
    assert gcs_tools.run(m, 262, 8) == ACCEPTED  # DO_SET_STANDARD_MODE TAKEOFF
    assert heartbeat(m, lambda h: h.custom_mode == LOITER) is not None  # done at once: holds
    assert abs(position(m).relative_alt - 20000) < 600
    gcs_tools.command(m, 21)
    assert wait_ack(m, 21)[0] == ACCEPTED
    assert gcs_tools.run(m, 400, 1) == DENIED
    assert gcs_tools.statustext(m, "Arm: mode LAND: not armable") is not None
    set_mode(m, LOITER)
    assert gcs_tools.run(m, 400, 1) == ACCEPTED
    assert heartbeat(m, lambda h: h.base_mode & ARMED).system_status == STANDBY  # on the ground


def test_targets_outside_the_safety_area_are_refused(vehicle):
    """SAFETY_SET_ALLOWED_AREA (services/geography.py): a reposition, loiter or guided
    waypoint outside it is refused (DENIED / MISSION_ACK DENIED, and said); inside, flown."""
    v, m = fly_vehicle(vehicle)
    box = ((LAT0 - 5000) / 1e7, (LON0 - 5000) / 1e7, 0.0), ((LAT0 + 20000) / 1e7, (LON0 + 20000) / 1e7, 100.0)
    m.mav.safety_set_allowed_area_send(1, 1, 0, *box[0], *box[1])
    assert gcs_tools.listen(m, "SAFETY_ALLOWED_AREA", 5) is not None
    takeoff(m)
    m.mav.command_int_send(1, 1, 6, 192, 0, 0, -1, 1, 0, float("nan"), LAT0 - 9000, LON0, 15.0)
    assert gcs_tools.ack(m, 192).result == DENIED
    assert gcs_tools.statustext(m, "outside the allowed area") is not None
    assert gcs_tools.run(m, 17, 0, 0, 0, 0, (LAT0 - 9000) / 1e7, LON0 / 1e7, 15.0) == DENIED
    m.mav.mission_item_int_send(1, 1, 0, 6, 16, 2, 0, 0, 0, 0, 0, LAT0 - 9000, LON0, 12.0)
    assert recv(m, "MISSION_ACK", 5).type == 14
    m.mav.command_int_send(1, 1, 6, 192, 0, 0, -1, 1, 0, float("nan"), LAT0 + 9000, LON0, 15.0)
    assert gcs_tools.ack(m, 192).result == ACCEPTED
    assert position(m, lambda p: metres(p.lat, p.lon, LAT0 + 9000, LON0) < 1.0) is not None


def test_the_vehicle_stops_at_the_safety_area_border(vehicle):
    """Flown by velocity setpoints (GUIDED takes them, as ArduPilot does) straight north
    toward a border 200 m away: the vehicle stops there and says so."""
    v, m = fly_vehicle(vehicle)
    north = LAT0 + 18000  # about 200 m
    box = ((LAT0 - 20000) / 1e7, (LON0 - 20000) / 1e7, 0.0), (north / 1e7, (LON0 + 20000) / 1e7, 1000.0)
    m.mav.safety_set_allowed_area_send(1, 1, 0, *box[0], *box[1])
    assert gcs_tools.listen(m, "SAFETY_ALLOWED_AREA", 5) is not None
    takeoff(m)
    assert set_mode(m, GUIDED) is not None
    deadline = time.time() + 30
    stopped = None
    while time.time() < deadline and stopped is None:
        m.mav.heartbeat_send(6, 8, 0, 0, 0)  # (a ground station that stays present)
        m.mav.set_position_target_local_ned_send(0, 1, 1, 1, 0b010111000111, 0, 0, 0, 30.0, 0, 0, 0, 0, 0, 0, 0)
        stopped = recv(m, "STATUSTEXT", 0.1, lambda t: "border" in t.text)
    assert stopped is not None
    for _ in range(10):  # still pushed north: it stays at the border
        m.mav.set_position_target_local_ned_send(0, 1, 1, 1, 0b010111000111, 0, 0, 0, 30.0, 0, 0, 0, 0, 0, 0, 0)
        time.sleep(0.1)
    p = position(m)
    # At the border, not past it: the border as the area carries it (a float32 of degrees,
    # here 1.8 cm north of LAT0 + 18000).
    border = round(struct.unpack("<f", struct.pack("<f", north / 1e7))[0] * 1e7)
    assert north - 200 <= p.lat <= border, (p.lat - north, border - north)


def test_the_seeds_override_goto_holds_there_and_continues(vehicle):
    # seed: OVERRIDE_GOTO
    """MAV_CMD_OVERRIDE_GOTO (the seed's): hold at a specified position flies there in
    GUIDED and holds; DO_CONTINUE goes back to the mission's mode."""
    v, m = fly_vehicle(vehicle)
    takeoff(m)
    there = (LAT0 + 9000) / 1e7, (LON0 + 4000) / 1e7
    assert gcs_tools.run(m, 252, 0, 3, 3, float("nan"), there[0], there[1], 15.0) == ACCEPTED  # relative alt
    assert heartbeat(m, lambda h: h.custom_mode == GUIDED) is not None
    p = position(m, lambda p: metres(p.lat, p.lon, LAT0 + 9000, LON0 + 4000) < 1.0)
    assert p is not None
    p = position(m, lambda p: abs(p.relative_alt - 15000) < 500)
    assert p is not None
    assert gcs_tools.run(m, 252, 2) == DENIED  # neither hold nor continue


def test_loiter_time_and_turns_in_a_mission(vehicle):
    # seed: NAV_LOITER_TIME, NAV_LOITER_TURNS
    """A mission's timed loiter (param1 s) and loiter of turns (param1 turns, param3
    radius) hold the vehicle there that long before the next item."""
    v, m = fly_vehicle(vehicle)
    items = [Item(3, 22, 0, 1, 0, 0, 0, float("nan"), 0, 0, 10.0),
             Item(3, 19, 0, 1, 2.0, 0, 0, float("nan"), LAT0 + 4500, LON0, 10.0),  # 2 s there
             Item(3, 18, 0, 1, 1.0, 0, 10.0, float("nan"), LAT0 + 4500, LON0 + 4500, 10.0),  # one turn, 10 m
             Item(3, 16, 0, 1, 0, 0, 0, float("nan"), LAT0, LON0, 10.0)]
    assert MissionClient(m).upload(items) == 0
    assert gcs_tools.run(m, 400, 1) == ACCEPTED
    assert gcs_tools.run(m, 300, 0, 0) == ACCEPTED
    at = {}
    deadline = time.time() + 40
    while time.time() < deadline and 3 not in at:
        r = gcs_tools.listen(m, "MISSION_ITEM_REACHED", deadline - time.time())
        if r is not None and r.seq not in at:
            at[r.seq] = time.time()
    assert sorted(at) == [0, 1, 2, 3]
    # Item 2 ends no sooner than the flight to it (450 m) and its turn (2 pi 10 m) after item 1.
    assert at[2] - at[1] >= 1.5
    v.check_alive()


def test_idle_on_the_ground_disarms_after_disarm_delay(vehicle):
    """ArduPilot's DISARM_DELAY: armed on the ground with nothing to do, the vehicle
    disarms after that many seconds; 0 never. A takeoff in time keeps it armed."""
    v, m = fly_vehicle(vehicle)
    m.mav.param_set_send(1, 1, b"DISARM_DELAY", 2, 9)  # REAL32 for an INT32: taken as a cast
    assert gcs_tools.listen(m, "PARAM_VALUE", 5, lambda p: p.param_id == "DISARM_DELAY") is not None
    armed_at = time.time()
    assert gcs_tools.run(m, 400, 1) == ACCEPTED
    assert gcs_tools.statustext(m, "Disarmed: 2 s on the ground, idle", timeout=10) is not None
    assert 1.5 < time.time() - armed_at < 8
    hb = heartbeat(m, lambda h: not h.base_mode & ARMED)
    assert hb.system_status == STANDBY
    takeoff(m, 5.0)  # armed and straight up: no idle disarm on the way
    time.sleep(3)
    assert heartbeat(m).base_mode & ARMED
    m.mav.param_set_send(1, 1, b"DISARM_DELAY", 0, 9)
    assert gcs_tools.listen(m, "PARAM_VALUE", 5, lambda p: p.param_id == "DISARM_DELAY" and p.param_value == 0)
    set_mode(m, LAND)
    assert heartbeat(m, lambda h: not h.base_mode & ARMED, timeout=20) is not None  # landed: disarmed
    set_mode(m, GUIDED)  # (not armed in LAND)
    assert gcs_tools.run(m, 400, 1) == ACCEPTED
    time.sleep(3)
    assert heartbeat(m).base_mode & ARMED  # 0: stays armed
    v.check_alive()


def test_a_land_item_mid_mission_lands_and_disarms(vehicle):
    v, m = fly_vehicle(vehicle)
    plan = MISSION + [Item(3, 22, 0, 1, 0, 0, 0, float("nan"), 0, 0, 10.0)]  # a takeoff after the LAND
    assert MissionClient(m).upload(plan) == 0
    assert gcs_tools.run(m, 400, 1) == ACCEPTED
    assert gcs_tools.run(m, 300, 0, 0) == ACCEPTED
    assert gcs_tools.statustext(m, "Landed: disarmed", timeout=40) is not None
    hb = heartbeat(m, lambda h: not h.base_mode & ARMED)
    assert hb is not None and hb.system_status == STANDBY
    time.sleep(1)
    pos = position(m)
    assert abs(pos.relative_alt) < 200  # it stays down: no takeoff disarmed
    cur = gcs_tools.listen(m, "MISSION_CURRENT", 5)
    assert cur.seq == 4  # the mission stopped after the LAND
    v.check_alive()
