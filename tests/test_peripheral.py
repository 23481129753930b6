"""mavstack as a peripheral (boards/unix_peripheral.py, unix_camera.py) on the unix port,
a pymavlink peer playing the autopilot and the ground station: the system id followed
from the autopilot's HEARTBEAT (nothing sent before it; the fallback after
SYSID_WAIT_MS), the HEARTBEAT of a component that is no autopilot, its parameters listed
for component 0 and set and read by component, commands (REQUEST_MESSAGE, the
application's own, none answered for other components), DISTANCE_SENSOR and
NAMED_VALUE_INT out; the camera's discovery and image capture."""
import os
import time

import pytest

from conftest import ROOT, run_mpy
from vehicle import recv

MPY = os.path.join(ROOT, "tests", "mpy")

AUTOPILOT = (7, 1)  # the autopilot the peripheral follows
GCS = (255, 190)
COMPID = 158
MAV_AUTOPILOT_INVALID = 8


def _as(m, who):
    m.mav.srcSystem, m.mav.srcComponent = who


def _autopilot_heartbeat(m, who=AUTOPILOT):
    _as(m, who)
    m.mav.heartbeat_send(2, 3, 0, 0, 3)  # a quadrotor, MAV_AUTOPILOT_ARDUPILOTMEGA
    _as(m, GCS)


def _peer(vehicle, board="unix_peripheral", args=()):
    v = vehicle(board=board, args=list(args))
    m = v.gcs(wait=False)
    return v, m


def _followed(m, sysid=AUTOPILOT[0], compid=COMPID, timeout=10):
    """Heartbeats from the autopilot until the peripheral's own comes -> it."""
    deadline = time.time() + timeout
    while time.time() < deadline:
        _autopilot_heartbeat(m, (sysid, 1))
        hb = recv(m, "HEARTBEAT", 0.5, lambda h: h.get_srcComponent() == compid)
        if hb is not None:
            return hb
    raise AssertionError("no HEARTBEAT from the peripheral")


def _silent(m, seconds):
    """Nothing at all from the vehicle for this long (a GCS heartbeat now and then)."""
    deadline = time.time() + seconds
    while time.time() < deadline:
        m.mav.heartbeat_send(6, 8, 0, 0, 0)
        got = m.recv_match(blocking=True, timeout=0.3)
        if got is not None and got.get_type() != "BAD_DATA":
            return got
    return None


def test_follows_the_autopilot_and_sends_nothing_before(vehicle):
    v, m = _peer(vehicle)
    assert _silent(m, 2.5) is None  # GCS heartbeats are not an autopilot's: still waiting
    hb = _followed(m)
    assert hb.get_srcSystem() == AUTOPILOT[0]
    assert hb.autopilot == MAV_AUTOPILOT_INVALID and hb.type == 0 and hb.base_mode == 0
    ds = recv(m, "DISTANCE_SENSOR", 3)
    assert ds is not None and ds.get_srcSystem() == 7 and ds.get_srcComponent() == COMPID
    assert 100 <= ds.current_distance <= 400 and ds.min_distance == 20 and ds.max_distance == 700
    assert ds.orientation == 25 and ds.signal_quality == 100
    count = recv(m, "NAMED_VALUE_INT", 3)
    assert count is not None and count.name == "RNG_COUNT" and count.value > 0
    # Another autopilot heard later changes nothing: the first one is followed.
    _autopilot_heartbeat(m, (9, 1))
    time.sleep(0.3)
    m.recv_match(blocking=False)
    hb = recv(m, "HEARTBEAT", 3, lambda h: h.get_srcComponent() == COMPID)
    assert hb.get_srcSystem() == 7
    v.check_alive()


def test_falls_back_after_the_wait_then_takes_the_autopilots_id(vehicle):
    v, m = _peer(vehicle, args=["--set", "sysid_wait_ms=1500", "--set", "sysid_fallback=42"])
    t = time.time()
    hb = None
    while hb is None and time.time() - t < 8:
        m.mav.heartbeat_send(6, 8, 0, 0, 0)  # a ground station's: the udpin link's peer
        hb = recv(m, "HEARTBEAT", 0.3, lambda h: h.get_srcComponent() == COMPID)
    assert hb is not None and hb.get_srcSystem() == 42
    assert time.time() - t > 1.0
    _autopilot_heartbeat(m)
    hb = recv(m, "HEARTBEAT", 3, lambda h: h.get_srcComponent() == COMPID and h.get_srcSystem() == 7)
    assert hb is not None


def _param_list(m, target=(7, 0), timeout=10):
    m.mav.param_request_list_send(*target)
    got = {}
    deadline = time.time() + timeout
    while time.time() < deadline:
        p = recv(m, "PARAM_VALUE", 1.0)
        if p is None:
            continue
        assert p.get_srcSystem() == 7 and p.get_srcComponent() == COMPID
        got[p.param_id] = p
        if len(got) == p.param_count:
            break
    return got


def test_parameters_by_component(vehicle):
    v, m = _peer(vehicle)
    _followed(m)
    params = _param_list(m)  # to component 0: every component answers with its own id
    assert sorted(params) == ["RNGFND_MAX_CM", "RNGFND_MIN_CM", "RNGFND_ORIENT", "RNGFND_RATE_HZ", "RNGFND_TYPE"]
    assert params["RNGFND_RATE_HZ"].param_value == 10.0 and params["RNGFND_RATE_HZ"].param_type == 9  # REAL32
    assert len(_param_list(m, (7, COMPID))) == 5
    # To another component (the autopilot's): not ours.
    m.mav.param_request_list_send(7, 1)
    assert recv(m, "PARAM_VALUE", 1.5) is None
    m.mav.param_set_send(7, 1, b"RNGFND_MAX_CM", 500.0, 9)
    assert recv(m, "PARAM_VALUE", 1.5) is None
    # Set and read by component; the application takes the new range.
    m.mav.param_set_send(7, COMPID, b"RNGFND_MAX_CM", 500.0, 9)  # MAV_PARAM_TYPE_REAL32
    p = recv(m, "PARAM_VALUE", 3, lambda p: p.param_id == "RNGFND_MAX_CM")
    assert p is not None and p.param_value == 500.0 and p.get_srcComponent() == COMPID
    m.mav.param_request_read_send(7, COMPID, b"RNGFND_MAX_CM", -1)
    p = recv(m, "PARAM_VALUE", 3, lambda p: p.param_id == "RNGFND_MAX_CM")
    assert p is not None and p.param_value == 500.0
    m.mav.param_request_read_send(7, COMPID, b"", 1)  # by index
    p = recv(m, "PARAM_VALUE", 3)
    assert p is not None and p.param_index == 1 and p.param_id == "RNGFND_MIN_CM"
    ds = recv(m, "DISTANCE_SENSOR", 3, lambda d: d.max_distance == 500)
    assert ds is not None


def _command(m, cmd, p1=0.0, p2=0.0, target=(7, COMPID), timeout=3):
    m.mav.command_long_send(target[0], target[1], cmd, 0, p1, p2, 0, 0, 0, 0, 0)
    return recv(m, "COMMAND_ACK", timeout, lambda a: a.command == cmd)


def test_commands(vehicle):
    v, m = _peer(vehicle)
    _followed(m)
    ack = _command(m, 512, 132.0)  # REQUEST_MESSAGE DISTANCE_SENSOR
    assert ack is not None and ack.result == 0 and ack.get_srcComponent() == COMPID
    assert ack.target_system == GCS[0] and ack.target_component == GCS[1]
    assert recv(m, "DISTANCE_SENSOR", 2) is not None
    ack = _command(m, 512, 0.0)  # HEARTBEAT
    assert ack.result == 0
    ack = _command(m, 512, 33.0)  # GLOBAL_POSITION_INT: not a rangefinder's
    assert ack.result == 2  # DENIED
    assert _command(m, 400, 1.0).result == 3  # arming: a peripheral has none (UNSUPPORTED)
    assert _command(m, 176, 1.0).result == 3  # nor modes
    assert _command(m, 400, 1.0, target=(7, 0), timeout=1.5) is None  # for all: not ours to refuse
    assert _command(m, 512, 132.0, target=(7, 0)).result == 0  # ... but what it has, it answers
    assert _command(m, 512, 132.0, target=(7, 1), timeout=1.5) is None  # the autopilot's
    # The application's own command: pause, then resume the readings.
    assert _command(m, 31010, 0.0).result == 0
    time.sleep(0.3)
    while m.recv_match(blocking=False) is not None:
        pass
    assert recv(m, "DISTANCE_SENSOR", 1.0) is None
    assert _command(m, 31010, 1.0).result == 0
    assert recv(m, "DISTANCE_SENSOR", 2) is not None
    assert _command(m, 31010, 5.0).result == 2
    # No missions, no streams: nothing answers them.
    m.mav.mission_request_list_send(7, COMPID)
    assert recv(m, ["MISSION_COUNT", "MISSION_ACK"], 1.5) is None


CAMERA = 100


def test_camera_discovery_and_capture(vehicle):
    v, m = _peer(vehicle, board="unix_camera")
    hb = _followed(m, compid=CAMERA)
    assert hb.type == 30 and hb.autopilot == MAV_AUTOPILOT_INVALID
    # Discovery as QGroundControl and ArduPilot do it: REQUEST_MESSAGE for the
    # information, then the settings.
    ack = _command(m, 512, 259.0, target=(7, CAMERA))
    assert ack is not None and ack.result == 0
    info = recv(m, "CAMERA_INFORMATION", 2)
    assert info is not None and info.get_srcComponent() == CAMERA
    assert bytes(info.vendor_name).rstrip(b"\0") == b"mavstack"
    assert bytes(info.model_name).rstrip(b"\0") == b"unix camera"
    assert (info.resolution_h, info.resolution_v) == (1920, 1080) and info.flags & 2
    assert _command(m, 512, 260.0, target=(7, CAMERA)).result == 0
    settings = recv(m, "CAMERA_SETTINGS", 2)
    assert settings is not None and settings.mode_id == 0
    assert _command(m, 512, 261.0, target=(7, CAMERA)).result == 0  # QGroundControl asks next
    storage = recv(m, "STORAGE_INFORMATION", 2)
    assert storage is not None and storage.status == 3  # STORAGE_STATUS_NOT_SUPPORTED
    # The older commands.
    assert _command(m, 521, 1.0, target=(7, CAMERA)).result == 0
    assert recv(m, "CAMERA_INFORMATION", 2) is not None
    assert _command(m, 522, 1.0, target=(7, CAMERA)).result == 0
    assert recv(m, "CAMERA_SETTINGS", 2) is not None
    # One image: the ACK, then CAMERA_IMAGE_CAPTURED.
    m.mav.command_long_send(7, CAMERA, 2000, 0, 0, 0, 1, 1, 0, 0, 0)
    first = m.recv_match(type=["COMMAND_ACK", "CAMERA_IMAGE_CAPTURED"], blocking=True, timeout=3)
    assert first is not None and first.get_type() == "COMMAND_ACK" and first.result == 0
    shot = recv(m, "CAMERA_IMAGE_CAPTURED", 2)
    assert shot is not None and shot.image_index == 0 and shot.capture_result == 1
    # Three at 0.2 s; asked again meanwhile: refused until they are taken.
    m.mav.command_long_send(7, CAMERA, 2000, 0, 0, 0.2, 3, 0, 0, 0, 0)
    assert recv(m, "COMMAND_ACK", 2, lambda a: a.command == 2000).result == 0
    indexes = []
    deadline = time.time() + 3
    while time.time() < deadline and len(indexes) < 3:
        shot = recv(m, "CAMERA_IMAGE_CAPTURED", 1)
        if shot is not None:
            indexes.append(shot.image_index)
    assert indexes == [1, 2, 3]
    assert _command(m, 527, 1.0, target=(7, CAMERA)).result == 0
    status = recv(m, "CAMERA_CAPTURE_STATUS", 2)
    assert status is not None and status.image_count == 4 and status.image_status == 0
    # Until stopped.
    m.mav.command_long_send(7, CAMERA, 2000, 0, 0, 0.1, 0, 0, 0, 0, 0)
    assert recv(m, "COMMAND_ACK", 2, lambda a: a.command == 2000).result == 0
    assert recv(m, "CAMERA_IMAGE_CAPTURED", 2) is not None
    assert _command(m, 2000, 0.0, 0.1, target=(7, CAMERA)).result == 1  # capturing: TEMPORARILY_REJECTED
    assert _command(m, 2001, target=(7, CAMERA)).result == 0
    time.sleep(0.3)
    while m.recv_match(blocking=False) is not None:
        pass
    assert recv(m, "CAMERA_IMAGE_CAPTURED", 0.8) is None
    v.check_alive()


@pytest.mark.parametrize("portable", ["0", "1"])
def test_steady_state_allocates_nothing(portable, monkeypatch):
    # tests/mpy/peripheral_steady.py; the emulated boards run it too (test_mcu.py STEADY).
    monkeypatch.setenv("MAVSTACK_PORTABLE", portable)
    r = run_mpy(os.path.join(MPY, "peripheral_steady.py"), 3000, path=[MPY], timeout=300)
    lines = r.stdout.strip().splitlines()
    assert r.returncode == 0 and lines and lines[-1].startswith("OK "), r.stdout + r.stderr
    assert " requested=0" in lines[-1] and "silent=0 sysid=7" in lines[-1], lines[-1]
