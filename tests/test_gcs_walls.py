"""Issue 23's walls, flown as MAVSDK and MAVProxy users fly: MAVSDK with its own identity
(245/190) and as `mavsdk_server --sysid 255 --compid 1` sets it up, on one vehicle and one
session per identity that the flights here share; MAVProxy on the vehicle's second link.
What a station means is learned from what it does, never from its system id
(services/status/conventions.py): modes by PX4's numbers for MAVSDK, ArduPilot's for
MAVProxy, on the same vehicle; ACCEPTED means the mode is in force; a float for an
integer parameter changes no encoding (tests/test_params_gcs.py); back to armable after a
landing by PX4's rules, not by ArduPilot's; takeoffs in every form MAVSDK can send. Each
flight ends on the ground (EXTENDED_SYS_STATE ON_GROUND) and disarmed, ready for the next.
Last, the signed board with files: a signed MAVProxy gets parameters and files."""
import json
import math
import time

import pytest

from conftest import free_udp_port
from gcs_tools import MavProxy, mavsdk_system
from mission_gcs import LAT0, LON0
from vehicle import Vehicle

FAST = ("--set", "sim_speed=40", "--set", "sim_climb=20")
HOME_ALT = 488.0
IDENTITIES = {"245/190": None, "255/1": (255, 1)}
ACCEPTED = 0
INT32_MAX = 2 ** 31 - 1
NAN = float("nan")


def until(check, timeout=20.0, every=0.05):
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


def angle(a, b):
    return abs((a - b + 180.0) % 360.0 - 180.0)


class Flyer:
    """The vehicle, a MAVSDK session on its first link and the plugins a user takes."""

    def __init__(self, v, identity, system, mavproxy_port):
        from mavsdk.plugins.action import Action
        from mavsdk.plugins.mavlink_direct import MavlinkDirect
        from mavsdk.plugins.mission import Mission
        from mavsdk.plugins.mission_raw import MissionRaw
        from mavsdk.plugins.offboard import Offboard
        from mavsdk.plugins.telemetry import Telemetry

        self.v = v
        self.identity = identity
        self.action, self.tel, self.direct = Action(system), Telemetry(system), MavlinkDirect(system)
        self.mission, self.raw, self.offboard = Mission(system), MissionRaw(system), Offboard(system)
        self.mavproxy_port = mavproxy_port

    def mode(self, want, timeout=10.0):
        return until(lambda: self.tel.flight_mode() == want, timeout)

    def down(self, timeout=40.0):
        """On the ground (EXTENDED_SYS_STATE) and disarmed."""
        from mavsdk.plugins.telemetry import LandedState

        return until(lambda: self.tel.landed_state() == LandedState.ON_GROUND and not self.tel.armed(), timeout)

    def home_and_down(self):
        """RTL, then on the ground at home and disarmed."""
        self.action.return_to_launch()
        assert self.down(), (self.tel.landed_state(), self.tel.armed())
        p = self.tel.position()
        assert metres(p.latitude_deg, p.longitude_deg, LAT0 / 1e7, LON0 / 1e7) < 2.5, p

    def command(self, message, **fields):
        """COMMAND_LONG / COMMAND_INT through MAVSDK (MavlinkDirect) -> its final result."""
        from mavsdk.plugins.mavlink_direct import MavlinkMessage

        fields = dict(fields, target_system=1, target_component=1)
        ack = self.direct.send_command(MavlinkMessage(message_name=message, target_system_id=1,
                                                      target_component_id=1, fields_json=json.dumps(fields)))
        return json.loads(ack.fields_json)["result"]

    def near(self, rel_alt, heading=None, lat=LAT0 / 1e7, lon=LON0 / 1e7):
        """Holding at rel_alt (m above home), heading (deg) and lat, lon, to within 5 cm and 1 degree."""
        p = self.tel.position()
        return (abs(p.relative_altitude_m - rel_alt) < 0.05 and metres(p.latitude_deg, p.longitude_deg, lat, lon) < 0.5
                and (heading is None or angle(self.tel.heading().heading_deg, heading) < 1.0))


@pytest.fixture(scope="module", params=sorted(IDENTITIES))
def flyer(request, tmp_path_factory):
    ports = free_udp_port(), free_udp_port()
    v = Vehicle(tmp_path_factory.mktemp("walls"), links=["udpin:127.0.0.1:%d" % p for p in ports],
                args=list(FAST)).start()
    try:
        with mavsdk_system(ports[0], IDENTITIES[request.param]) as system:
            f = Flyer(v, request.param, system, ports[1])
            assert f.down(20)
            yield f
        v.check_alive()
    finally:
        v.stop()


def test_takeoff_goto_hold_rtl_then_arm_and_fly_again(flyer):
    """Modes by PX4's numbers whatever the identity: hold() holds (no GUIDED hover in
    the wrong mode), return_to_launch() returns. A 2 m takeoff holds at 2 m, in Hold.
    Landed by RTL and disarmed, PX4's rule puts it back in Hold: MAVSDK arms and takes
    off again with no mode command in between, and lands."""
    from mavsdk.plugins.telemetry import FlightMode

    f, a, tel = flyer, flyer.action, flyer.tel
    a.set_takeoff_altitude(2.0)
    a.arm()
    a.takeoff()
    assert f.mode(FlightMode.HOLD), tel.flight_mode()  # PX4 takes off, then holds
    assert until(lambda: f.near(2.0)), tel.position()
    lat, lon = LAT0 / 1e7 + 0.0009, LON0 / 1e7  # 100 m north, 15 m up
    a.goto_location(lat, lon, HOME_ALT + 15.0, NAN)
    assert until(lambda: metres(tel.position().latitude_deg, tel.position().longitude_deg, LAT0 / 1e7, LON0 / 1e7) > 20)
    a.hold()  # stops where it is
    assert f.mode(FlightMode.HOLD)
    time.sleep(0.3)
    p, q = tel.position(), (time.sleep(1.0), tel.position())[1]
    assert metres(p.latitude_deg, p.longitude_deg, q.latitude_deg, q.longitude_deg) < 0.5
    a.return_to_launch()
    assert f.mode(FlightMode.RETURN_TO_LAUNCH)
    assert f.down() and f.mode(FlightMode.HOLD)  # disarmed: back to the last armable mode
    a.arm()
    a.takeoff()
    assert until(lambda: f.near(2.0), 20), tel.position()
    a.land()  # (down from 2 m in a tenth of a second: LAND is over before a heartbeat tells it)
    assert f.down() and f.mode(FlightMode.HOLD)


def test_start_mission_flies_to_the_end(flyer):
    """start_mission (PX4's AUTO.MISSION) flies MAVSDK's plan from its first item (PX4's
    convention: no home row) to the end, then holds; RTL home."""
    from mavsdk.plugins.mission import MissionItem, MissionPlan
    from mavsdk.plugins.telemetry import FlightMode

    CA, VA = MissionItem.CameraAction, MissionItem.VehicleAction
    lat, lon = LAT0 / 1e7, LON0 / 1e7

    def item(dlat, dlon, alt, loiter=NAN, action=VA.NONE):
        return MissionItem(lat + dlat, lon + dlon, alt, NAN, False, NAN, NAN, CA.NONE, loiter, NAN, NAN,
                           NAN, NAN, action)

    items = [item(0, 0, 10, action=VA.TAKEOFF), item(0.0003, 0, 12, loiter=0.5), item(0.0003, 0.0003, 12)]
    f, progress = flyer, []
    f.mission.upload_mission(MissionPlan(items))
    handle = f.mission.subscribe_mission_progress(lambda p, ud: progress.append((p.current, p.total)))
    try:
        f.action.arm()
        f.mission.start_mission()
        assert f.mode(FlightMode.MISSION)
        assert until(lambda: progress and progress[-1] == (len(items), len(items)), 30), progress
        assert until(f.mission.is_mission_finished, 10)
    finally:
        f.mission.unsubscribe_mission_progress(handle)
    assert f.mode(FlightMode.HOLD)  # done in the air: holding at the last item
    assert until(lambda: f.near(12.0, None, lat + 0.0003, lon + 0.0003)), f.tel.position()
    f.home_and_down()


def test_offboard_position_then_velocity(flyer):
    """Offboard (PX4's main mode 6, never ArduCopter's RTL) to a local NED position, then
    at a velocity; stop() holds; RTL home."""
    from mavsdk.plugins.offboard import PositionNedYaw, VelocityNedYaw
    from mavsdk.plugins.telemetry import FlightMode

    f, tel = flyer, flyer.tel
    f.action.set_takeoff_altitude(5.0)
    f.action.arm()
    f.action.takeoff()
    assert f.mode(FlightMode.HOLD) and until(lambda: f.near(5.0))
    f.offboard.set_position_ned(PositionNedYaw(20.0, 10.0, -12.0, 90.0))
    f.offboard.start()
    assert f.mode(FlightMode.OFFBOARD)

    def at(n, e, d):
        p = tel.position_velocity_ned().position
        return abs(p.north_m - n) < 0.5 and abs(p.east_m - e) < 0.5 and abs(p.down_m - d) < 0.5

    assert until(lambda: at(20.0, 10.0, -12.0)), tel.position_velocity_ned().position
    f.offboard.set_velocity_ned(VelocityNedYaw(0.0, 5.0, 0.0, 90.0))
    assert until(lambda: tel.position_velocity_ned().position.east_m > 15.0, 10)
    assert tel.flight_mode() == FlightMode.OFFBOARD
    f.offboard.stop()
    assert f.mode(FlightMode.HOLD)
    f.home_and_down()


def test_hold_then_arm_at_once(flyer):
    """ACCEPTED means done: an arm sent right after hold()'s ACK is judged in Hold, not in
    the LAND it was in. 10 of 10."""
    from mavsdk.plugins.telemetry import FlightMode

    f = flyer
    for i in range(10):
        assert f.command("COMMAND_LONG", command=176, param1=1, param2=4, param3=6) == ACCEPTED  # AUTO.LAND
        assert i or f.mode(FlightMode.LAND)  # (ACCEPTED: in force; the heartbeat says so too)
        f.action.hold()
        f.action.arm()  # (raises ActionError if refused)
        f.action.disarm()
    assert f.down()


@pytest.mark.parametrize("form", ["COMMAND_INT", "mission"])
def test_takeoff_altitudes_frames_headings_and_positions(flyer, form):
    """NAV_TAKEOFF as MAVSDK sends it in a COMMAND_INT (MavlinkDirect) and as a plan's first
    item (MissionRaw): 1 to 100 m, relative (frame 6) or above sea level (frame 5), NaN (the
    default takeoff altitude, MIS_TAKEOFF_ALT 10 m, in a mission), param4's heading taken
    modulo 360 (past 360 and negative), a position in x/y flown to once up; it holds there in
    Hold (a mission: once done). Each flight then RTL, down, disarmed. (What MAVSDK's
    identity changes is the other tests': these fly as 255/1 only.)"""
    from mavsdk.plugins.mission_raw import MissionItem
    from mavsdk.plugins.telemetry import FlightMode

    if flyer.identity != "255/1":
        pytest.skip("flown as 255/1")

    north, east = LAT0 + 2700, LON0 + 4000  # about 30 m north and 30 m east
    flights = [  # frame, z, param4, x, y -> m above home, heading, where
        (6, 1.0, 0.0, INT32_MAX, INT32_MAX, 1.0, 0.0, (LAT0, LON0)),
        (5, HOME_ALT + 100.0, 370.0, INT32_MAX, INT32_MAX, 100.0, 10.0, (LAT0, LON0)),
        (6, 30.0, -90.0, north, east, 30.0, 270.0, (north, east)),
    ]
    if form == "mission":
        flights[0] = (6, NAN, 45.0, INT32_MAX, INT32_MAX, 10.0, 45.0, (LAT0, LON0))
        flights[1] = (5, HOME_ALT + 50.0, 450.0, north, LON0, 50.0, 90.0, (north, LON0))
    f = flyer
    for frame, z, yaw, x, y, alt, heading, (lat, lon) in flights:
        f.action.arm()
        if form == "COMMAND_INT":
            assert f.command("COMMAND_INT", command=22, frame=frame, param4=yaw, x=x, y=y, z=z) == ACCEPTED
        else:
            f.raw.upload_mission([MissionItem(0, frame, 22, 1, 1, 0, 0, 0, yaw, x, y, z, 0)])
            f.raw.start_mission()
            assert until(f.raw.is_mission_finished, 30), f.raw.mission_progress()
        assert f.mode(FlightMode.HOLD), (z, f.tel.flight_mode())
        assert until(lambda: f.near(alt, heading, lat / 1e7, lon / 1e7), 5), (z, f.tel.position(), f.tel.heading())
        f.home_and_down()


def test_mavproxy_sets_modes_by_arducopter_names_on_the_same_vehicle(flyer, tmp_path):
    """MAVProxy on the other link names and reads modes by ArduCopter's numbers while
    MAVSDK reads PX4's: its RTL is MAVSDK's Return (not Offboard), its LAND Land. Landed
    by MAVProxy's RTL the vehicle stays in RTL (ArduPilot's rule: not armable there) until a
    mode is picked: MAVSDK's hold() then arm(). (Alongside MAVSDK as 245/190 only: its
    identity does not reach MAVProxy's link.)"""
    from mavsdk.plugins.action import ActionError
    from mavsdk.plugins.telemetry import FlightMode

    f = flyer
    if f.identity != "245/190":
        pytest.skip("alongside MAVSDK as 245/190")
    mp = MavProxy(f.mavproxy_port, tmp_path, "mode,cmdlong,arm")
    try:
        mp.expect(r"online system 1|Detected vehicle 1:1")
        for name, want in (("GUIDED", FlightMode.HOLD), ("RTL", FlightMode.RETURN_TO_LAUNCH),
                           ("LAND", FlightMode.LAND), ("POSHOLD", FlightMode.POSCTL), ("LOITER", FlightMode.HOLD)):
            mp.say("mode " + name)
            assert f.mode(want), (name, f.tel.flight_mode(), "".join(mp.seen))
            mp.expect(r"Mode %s" % name)
        f.action.return_to_launch()  # ... and MAVSDK's reach MAVProxy by ArduCopter's name
        mp.expect(r"Mode RTL")
        mp.say("mode GUIDED")
        mp.say("arm throttle")
        assert until(f.tel.armed, 10)
        mp.say("mode RTL")  # home already: down, disarmed, and RTL stays
        assert f.down(20) and f.tel.flight_mode() == FlightMode.RETURN_TO_LAUNCH
        with pytest.raises(ActionError):
            f.action.arm()
        f.action.hold()
        mp.expect(r"Mode LOITER")
        f.action.arm()
        f.action.disarm()
    finally:
        mp.close()
    assert f.down()


def test_a_signed_ground_station_gets_parameters_and_files(tmp_path):
    """boards/unix_signed.py: the unix vehicle with signing and files. MAVProxy gives it
    a key; from then on, signed, it fetches the parameters and lists and reads a file
    over MAVLink FTP."""
    st = tmp_path / "storage"
    st.mkdir()
    (st / "notes.txt").write_bytes(b"signed notes\n" * 40)
    v = Vehicle(st, board="unix_signed").start()
    mp = MavProxy(v.port, tmp_path, "signing,param,ftp")
    try:
        mp.expect(r"online system 1|Detected vehicle 1:1")
        mp.say("signing setup sesame")
        mp.expect(r"Signing on")
        mp.say("param fetch")
        assert int(mp.expect(r"Received (\d+) parameters", 60).group(1)) >= 100
        mp.say("ftp list /")
        mp.expect(r"notes.txt\s+520", 30)
        mp.say("ftp get notes.txt got.txt")
        mp.expect(r"Wrote 520 bytes", 30)
        assert until(lambda: (tmp_path / "got.txt").exists() and (tmp_path / "got.txt").read_bytes() == (st / "notes.txt").read_bytes(), 5)
    finally:
        mp.close()
        v.stop()
    assert (st / "signing_key").exists()
