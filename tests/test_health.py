"""What ground stations read as the vehicle's health and how its modes answer: the unix
vehicle over UDP, with pymavlink, MAVSDK and MAVProxy as the ground stations.

SYS_STATUS's pre-arm bit follows the arming check (`--set arm_veto=1` makes it fail),
its geofence bits the fence (the simulator checks none: not present, and healthy, which
ground stations read as "no breach"). A mode the vehicle does not have is refused and
leaves the mode as it was; one of the board's CUSTOM_MODES is taken and shows in
HEARTBEAT.
"""
import time

from conftest import recv
from gcs_tools import (MAV_RESULT_ACCEPTED, MAV_RESULT_DENIED, MAV_RESULT_UNSUPPORTED, MavProxy, ack,
                       listen, mavsdk_system, run, start, statustext, two_links, vehicle_heartbeat)

PREARM_CHECK = 0x10000000  # MAV_SYS_STATUS_PREARM_CHECK
GEOFENCE = 0x100000  # MAV_SYS_STATUS_GEOFENCE
SIM_SENSORS = 1 | 2 | 4 | 8 | 32 | 1024 | 2048 | 4096 | 8192 | 16384 | 32768  # firmware/simulator.py
MODE_CUSTOM = 1
MODE_STABILIZE = 16
MODE_AUTO = 4
AUTO = 3  # boards/unix.py CUSTOM_MODES
LOITER = 5
UNKNOWN = 4  # what a multicopter ground station calls GUIDED; the unix vehicle has no such mode


def _sys_status(m, timeout=5.0):
    s = listen(m, "SYS_STATUS", timeout, lambda s: s.get_srcSystem() == 1)
    assert s is not None, "no SYS_STATUS"
    return s


# --- health ---------------------------------------------------------------------------

def test_prearm_and_geofence_bits_when_arming_would_succeed(vehicle):
    m = start(vehicle).gcs()
    s = _sys_status(m)
    assert s.onboard_control_sensors_present & PREARM_CHECK
    assert s.onboard_control_sensors_enabled & PREARM_CHECK
    assert s.onboard_control_sensors_health & PREARM_CHECK
    # No fence checked: not present, not enabled, and no breach.
    assert not s.onboard_control_sensors_present & GEOFENCE
    assert not s.onboard_control_sensors_enabled & GEOFENCE
    assert s.onboard_control_sensors_health & GEOFENCE
    # The application's sensors are untouched around them.
    assert s.onboard_control_sensors_present & ~(PREARM_CHECK | GEOFENCE) == SIM_SENSORS
    assert s.onboard_control_sensors_health & ~(PREARM_CHECK | GEOFENCE) == SIM_SENSORS
    assert run(m, 400, 1) == MAV_RESULT_ACCEPTED  # and arming does succeed
    assert _sys_status(m).onboard_control_sensors_health & PREARM_CHECK  # armed: still healthy


def test_prearm_bit_clear_while_the_arming_check_objects(vehicle):
    m = start(vehicle, "--set", "arm_veto=1").gcs()
    s = _sys_status(m)
    assert s.onboard_control_sensors_present & PREARM_CHECK
    assert s.onboard_control_sensors_enabled & PREARM_CHECK
    assert not s.onboard_control_sensors_health & PREARM_CHECK
    assert run(m, 400, 1) == MAV_RESULT_DENIED  # what the bit said
    # Forced, the vehicle is armed: nothing stands in the way of arming any more.
    assert run(m, 400, 1, 21196) == MAV_RESULT_ACCEPTED
    deadline = time.time() + 4
    while not _sys_status(m).onboard_control_sensors_health & PREARM_CHECK:
        assert time.time() < deadline, "pre-arm bit never set while armed"


def _armable(port, want):
    from mavsdk.plugins.telemetry import Telemetry

    with mavsdk_system(port) as system:
        tel = Telemetry(system)
        deadline = time.time() + 10
        health = tel.health()
        while health.is_armable != want and time.time() < deadline:
            time.sleep(0.3)
            health = tel.health()
    return health.is_armable


def test_mavsdk_sees_the_vehicle_armable(vehicle):
    v = start(vehicle)
    assert _armable(v.port, True) is True


def test_mavsdk_sees_the_vehicle_not_armable_while_vetoed(vehicle):
    v = start(vehicle, "--set", "arm_veto=1")
    assert _armable(v.port, False) is False


def test_mavproxy_announces_no_fence_breach(vehicle, tmp_path):
    v, port, check = two_links(vehicle)
    mp = MavProxy(port, tmp_path, "fence")
    try:
        mp.expect(r"online system 1|Detected vehicle 1:1")
        time.sleep(3)  # a few SYS_STATUS later
        mp.say("fence status")  # prints nothing new to wait for; the output so far is what counts
        time.sleep(1)
        while not mp.lines.empty():
            mp.seen.append(mp.lines.get())
    finally:
        mp.close()
    text = "".join(mp.seen)
    assert "fence breach" not in text.lower(), text
    assert "fence present" not in text.lower(), text  # the simulator checks no fence


# --- modes ----------------------------------------------------------------------------

def _mode(m):
    hb = vehicle_heartbeat(m)
    return hb.base_mode & 0x7F, hb.custom_mode


def test_unknown_custom_mode_refused_by_do_set_mode(vehicle):
    m = start(vehicle).gcs()
    before = _mode(m)
    result = run(m, 176, MODE_CUSTOM, UNKNOWN)
    assert result in (MAV_RESULT_DENIED, MAV_RESULT_UNSUPPORTED)
    assert statustext(m, "no such custom mode") is not None
    for _ in range(2):  # heartbeats after the refusal: nothing changed
        assert _mode(m) == before
    # As COMMAND_INT too.
    m.mav.command_int_send(1, 1, 0, 176, 0, 0, MODE_CUSTOM, 99, 0, 0, 0, 0, 0)
    assert ack(m, 176).result in (MAV_RESULT_DENIED, MAV_RESULT_UNSUPPORTED)
    assert _mode(m) == before


def test_known_custom_mode_accepted_and_shown(vehicle):
    m = start(vehicle).gcs()
    # The ground station gives only CUSTOM_MODE_ENABLED; the mode sets its own flags.
    assert run(m, 176, MODE_CUSTOM, AUTO) == MAV_RESULT_ACCEPTED
    hb = vehicle_heartbeat(m, lambda h: h.custom_mode == AUTO)
    assert hb is not None and hb.base_mode & 0x7F == MODE_CUSTOM | MODE_STABILIZE | MODE_AUTO
    assert run(m, 176, MODE_CUSTOM | MODE_AUTO, LOITER) == MAV_RESULT_ACCEPTED
    hb = vehicle_heartbeat(m, lambda h: h.custom_mode == LOITER)
    assert hb is not None and hb.base_mode & 0x7F == MODE_CUSTOM | MODE_STABILIZE  # LOITER is not AUTO


def test_set_mode_message_unknown_refused_with_statustext(vehicle):
    m = start(vehicle).gcs()
    assert run(m, 176, MODE_CUSTOM, LOITER) == MAV_RESULT_ACCEPTED
    assert vehicle_heartbeat(m, lambda h: h.custom_mode == LOITER) is not None
    m.mav.set_mode_send(1, MODE_CUSTOM, UNKNOWN)  # SET_MODE (#11) has no ACK
    assert statustext(m, "no such custom mode") is not None
    for _ in range(2):
        assert _mode(m) == (MODE_CUSTOM | MODE_STABILIZE, LOITER)
    m.mav.set_mode_send(1, MODE_CUSTOM, AUTO)
    assert vehicle_heartbeat(m, lambda h: h.custom_mode == AUTO) is not None


def test_unsupported_mode_flag_refused(vehicle):
    m = start(vehicle).gcs()
    before = _mode(m)
    assert run(m, 176, 32) == MAV_RESULT_DENIED  # HIL: not something this vehicle does
    assert statustext(m, "not supported") is not None
    assert _mode(m) == before


def test_mavproxy_mode_names(vehicle, tmp_path):
    # MAVProxy names a generic multicopter's custom modes as ArduCopter's: AUTO and
    # LOITER are the unix vehicle's, GUIDED is not (it is refused, and the mode stays).
    v, port, check = two_links(vehicle)
    mp = MavProxy(port, tmp_path, "mode,cmdlong")
    try:
        mp.expect(r"online system 1|Detected vehicle 1:1")
        mp.say("mode LOITER")
        assert vehicle_heartbeat(check, lambda h: h.custom_mode == LOITER, timeout=10) is not None
        mp.say("mode GUIDED")
        assert recv(check, "STATUSTEXT", 5, lambda s: "no such custom mode" in s.text) is not None
        assert vehicle_heartbeat(check).custom_mode == LOITER
        mp.say("mode AUTO")
        hb = vehicle_heartbeat(check, lambda h: h.custom_mode == AUTO, timeout=10)
        assert hb is not None and hb.base_mode & MODE_AUTO
    finally:
        mp.close()
