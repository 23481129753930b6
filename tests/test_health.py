"""What ground stations read as the vehicle's health: the unix vehicle over UDP, with
pymavlink, MAVSDK and MAVProxy as the ground stations (its modes: tests/test_modes.py).

SYS_STATUS's pre-arm bit follows the arming check (`--set arm_veto=1` makes it fail),
its geofence bits the fence (the simulator checks none: not present, and healthy, which
ground stations read as "no breach").
"""
import time

from gcs_tools import MAV_RESULT_ACCEPTED, MAV_RESULT_DENIED, MavProxy, listen, mavsdk_system, run, start, two_links

PREARM_CHECK = 0x10000000  # MAV_SYS_STATUS_PREARM_CHECK
GEOFENCE = 0x100000  # MAV_SYS_STATUS_GEOFENCE
SIM_SENSORS = 1 | 2 | 4 | 8 | 32 | 1024 | 2048 | 4096 | 8192 | 16384 | 32768  # firmware/sim/__init__.py



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
