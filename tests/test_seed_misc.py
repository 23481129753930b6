"""The rest of the seed on the unix vehicle over UDP: AUTH_KEY only over a signed link,
debug values and STATE_CORRECTION delivered (the simulated vehicle tells them back),
calibration (accepted disarmed with progress, refused armed or not in control), the
seed's remaining commands, and the setpoint echoes, from pymavlink ground stations of
today's set and of the seed's (built from ../shared/spec/common-2012.xml)."""
import socket
import time

import pytest

from conftest import recv
from gcs_tools import (MAV_RESULT_ACCEPTED, MAV_RESULT_DENIED, MAV_RESULT_UNSUPPORTED, ack, command, run,
                       statustext, vehicle_heartbeat)
from mavctl_tools import signed_board

PASSKEY = "sesame"
IN_PROGRESS = 5
KEY = bytes(range(1, 33))


# --- AUTH_KEY ---------------------------------------------------------------------------
def test_auth_key_only_over_a_signed_link(vehicle, tmp_path):
    # seed: AUTH_KEY
    v = vehicle(board="unix_signed", env={"MICROPYPATH": signed_board(tmp_path)},
                args=["--set", "auth_key=vehicle-secret"])
    m = v.gcs()
    # Unsigned: the vehicle's key is not sent, and a station's is not taken.
    assert run(m, 512, 7) == MAV_RESULT_DENIED
    assert statustext(m, "only over a signed link") is not None
    m.mav.auth_key_send(b"station-key")
    assert statustext(m, "AUTH_KEY refused: link not signed") is not None
    assert recv(m, "AUTH_KEY", 1.0) is None
    # Signed (SETUP_SIGNING, then every frame signed): both ways.
    stamp = int((time.time() - 1420070400) * 1e5)
    m.mav.setup_signing_send(1, 1, KEY, stamp)
    m.setup_signing(KEY, sign_outgoing=True, initial_timestamp=stamp + 100)
    assert run(m, 512, 7) == MAV_RESULT_ACCEPTED
    k = recv(m, "AUTH_KEY", 5)
    assert k is not None and k.key == "vehicle-secret" and k._signed
    m.mav.auth_key_send(b"station-key")
    assert statustext(m, "AUTH_KEY accepted") is not None
    # An unsigned frame on the signed link is dropped before any service sees it.
    m.mav.signing.sign_outgoing = False
    m.mav.auth_key_send(b"station-key")
    assert statustext(m, "AUTH_KEY", 1.5) is None


# --- debug values -----------------------------------------------------------------------
def test_debug_values_are_delivered(vehicle):
    # seed: NAMED_VALUE_FLOAT, NAMED_VALUE_INT, DEBUG, DEBUG_VECT, MEMORY_VECT
    v = vehicle()
    m = v.gcs()
    m.mav.named_value_float_send(0, b"speed", 1.5)
    assert statustext(m, "Debug speed=1.50") is not None
    m.mav.named_value_int_send(0, b"count", -7)
    assert statustext(m, "Debug count=-7") is not None
    m.mav.debug_send(0, 3, 2.5)
    assert statustext(m, "Debug [3]=2.50") is not None
    m.mav.debug_vect_send(b"vec", 0, 1.0, 2.0, 3.0)
    assert statustext(m, "Debug vec=(1.00,2.00,3.00)") is not None
    m.mav.memory_vect_send(256, 1, 0, list(range(32)))
    assert statustext(m, "Debug mem@256") is not None


# --- calibration ------------------------------------------------------------------------
def test_calibration_disarmed_armed_and_not_in_control(vehicle):
    # seed: PREFLIGHT_CALIBRATION, PREFLIGHT_SET_SENSOR_OFFSETS
    v = vehicle(args=["--set", "sim_cal_ms=200"])
    m = v.gcs()
    command(m, 241, 1, 0, 0, 0, 1)  # gyro and accelerometer
    first = ack(m, 241)
    assert first.result == IN_PROGRESS
    texts, final = [], None
    deadline = time.time() + 10
    while final is None and time.time() < deadline:
        msg = recv(m, ["STATUSTEXT", "COMMAND_ACK"], 1.0)
        if msg is None:
            continue
        if msg.get_type() == "STATUSTEXT":
            texts.append(msg.text)
        elif msg.command == 241 and msg.result != IN_PROGRESS:
            final = msg.result
    assert final == MAV_RESULT_ACCEPTED
    for t in ("Calibrating gyro: 50%", "Calibrating gyro: 100%", "Calibrating accelerometer: 50%"):
        assert t in texts, texts
    # The queued STATUSTEXTs may follow the ACK, which goes at once.
    assert "Calibration done" in texts or statustext(m, "Calibration done") is not None
    assert run(m, 241) == MAV_RESULT_DENIED  # nothing asked for
    assert run(m, 242, 1, 0.1, 0.2, 0.3) == MAV_RESULT_ACCEPTED
    assert statustext(m, "Offsets set: sensor 1") is not None
    assert run(m, 242, 9) == MAV_RESULT_DENIED
    assert run(m, 400, 1, 21196) == MAV_RESULT_ACCEPTED  # armed (forced)
    assert run(m, 241, 1) == MAV_RESULT_DENIED
    assert statustext(m, "Calibration refused: armed") is not None
    assert run(m, 242, 1) == MAV_RESULT_DENIED
    assert run(m, 400, 0, 21196) == MAV_RESULT_ACCEPTED


def test_calibration_needs_control(vehicle):
    v = vehicle(args=["--set", "operator_passkey=" + PASSKEY])
    m = v.gcs()
    assert run(m, 241, 1) == MAV_RESULT_DENIED
    assert statustext(m, "Calibration: GCS not in control") is not None
    assert run(m, 241, 1, target=(9, 1), timeout=1.5) is None  # not ours: no answer


# --- the remaining commands ---------------------------------------------------------------
def test_remaining_commands(vehicle):
    # seed: OVERRIDE_GOTO, NAV_ROI, NAV_PATHPLANNING, DO_CONTROL_VIDEO
    # seed: CONDITION_DELAY, CONDITION_CHANGE_ALT, CONDITION_DISTANCE, CONDITION_YAW
    # seed: NAV_LAST, CONDITION_LAST, DO_LAST
    v = vehicle()
    m = v.gcs()
    assert run(m, 252, 0, 2) == MAV_RESULT_ACCEPTED  # hold here: LOITER
    assert vehicle_heartbeat(m, lambda h: h.custom_mode == 5) is not None
    assert run(m, 252, 1) == MAV_RESULT_ACCEPTED  # continue: AUTO
    assert vehicle_heartbeat(m, lambda h: h.custom_mode == 3) is not None
    assert run(m, 252, 7) == MAV_RESULT_DENIED
    # A position outside the allowed area: DENIED; inside: the application's.
    m.mav.safety_set_allowed_area_send(1, 1, 0, 47.0, 8.0, 0.0, 47.5, 8.6, 100.0)
    assert recv(m, "SAFETY_ALLOWED_AREA", 5) is not None
    assert run(m, 252, 0, 3, 0, 0, 48.0, 8.5, 20.0) == MAV_RESULT_DENIED
    assert statustext(m, "Target outside the allowed area") is not None
    m.mav.command_int_send(1, 1, 6, 252, 0, 0, 0, 3, 0, 0, 480000000, 85000000, 20.0)  # as COMMAND_INT
    assert recv(m, "COMMAND_ACK", 5, lambda a: a.command == 252).result == MAV_RESULT_DENIED
    assert run(m, 252, 0, 3, 0, 0, 47.2, 8.5, 20.0) == MAV_RESULT_DENIED  # inside: the simulator's, but on the ground
    assert statustext(m, "Goto: disarmed") is not None  # (flown: tests/test_flight.py)
    assert run(m, 80, 3, 0, 0, 0, 47.4, 8.55, 20.0) == MAV_RESULT_ACCEPTED
    assert run(m, 80, 9) == MAV_RESULT_DENIED
    assert run(m, 81, 1, 1) == MAV_RESULT_UNSUPPORTED
    assert statustext(m, "no planner") is not None
    assert run(m, 200, -1, 1, 0, 1) == MAV_RESULT_ACCEPTED  # the simulator's camera
    assert statustext(m, "Video on") is not None
    for cid in (112, 113, 114, 115):
        assert run(m, cid, 1) == MAV_RESULT_UNSUPPORTED
    assert statustext(m, "a mission item, not a command") is not None
    for cid in (95, 159, 240):
        assert run(m, cid) == MAV_RESULT_UNSUPPORTED
    assert statustext(m, "a marker") is not None


def test_remaining_commands_need_control(vehicle):
    v = vehicle(args=["--set", "operator_passkey=" + PASSKEY])
    m = v.gcs()
    for args in ((252, 0, 2), (80, 3), (200, -1, 1)):
        assert run(m, *args) == MAV_RESULT_DENIED
    assert statustext(m, "not in control") is not None
    assert run(m, 252, 0, 2, target=(9, 1), timeout=1.5) is None


# --- the seed's message set ---------------------------------------------------------------
class SeedStation:
    """A seed-era ground station on a UDP socket (MAVLink 1, the seed's messages)."""

    def __init__(self, mod, port):
        self.mod = mod
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.settimeout(0.1)
        self.addr = ("127.0.0.1", port)
        self.mav = mod.MAVLink(None, srcSystem=255, srcComponent=190)
        self.mav.robust_parsing = True

    def send(self, msg):
        self.sock.sendto(msg.pack(self.mav), self.addr)

    def beat(self):
        self.send(self.mod.MAVLink_heartbeat_message(6, 8, 0, 0, 0, 3))

    def recv(self, type, timeout=5.0, cond=None):
        deadline = time.time() + timeout
        last_beat = 0
        while time.time() < deadline:
            if time.time() - last_beat > 0.5:
                self.beat()
                last_beat = time.time()
            try:
                data = self.sock.recv(4096)
            except socket.timeout:
                continue
            for m in self.mav.parse_buffer(data) or []:
                if m.get_type() == type and (cond is None or cond(m)):
                    return m
        return None

    def command(self, cmd, *p):
        p = list(p) + [0.0] * (7 - len(p))
        self.send(self.mod.MAVLink_command_long_message(1, 1, cmd, 0, *p))


@pytest.fixture
def seed_station(vehicle, seedmav):
    v = vehicle(args=["--set", "dialect=seed2012"])
    g = SeedStation(seedmav, v.port)
    assert g.recv("HEARTBEAT", 20) is not None, v.output()
    yield g
    g.sock.close()


def test_state_correction_delivered(seed_station):
    # seed: STATE_CORRECTION
    g = seed_station
    g.send(g.mod.MAVLink_state_correction_message(0.1, 0.2, 0.3, 0, 0, 0, 0, 0, 0))
    assert g.recv("STATUSTEXT", 5, lambda s: "State correction x=0.10 y=0.20 z=0.30" in s.text) is not None


def test_setpoint_echoes_stream(seed_station):
    # seed: ROLL_PITCH_YAW_THRUST_SETPOINT, ROLL_PITCH_YAW_SPEED_THRUST_SETPOINT
    # seed: ROLL_PITCH_YAW_RATES_THRUST_SETPOINT, LOCAL_POSITION_SETPOINT, GLOBAL_POSITION_SETPOINT_INT
    g = seed_station
    for msgid in (58, 59, 80):
        g.command(511, msgid, 200000)  # SET_MESSAGE_INTERVAL, 5 Hz
    for name in ("ROLL_PITCH_YAW_THRUST_SETPOINT", "ROLL_PITCH_YAW_SPEED_THRUST_SETPOINT",
                 "ROLL_PITCH_YAW_RATES_THRUST_SETPOINT"):
        msg = g.recv(name, 5)
        assert msg is not None, name
        assert 0.0 <= msg.thrust <= 1.0
    # A local setpoint from the station is echoed in the slot the stream carries.
    g.send(g.mod.MAVLink_set_local_position_setpoint_message(1, 1, 1, 4.0, 5.0, -6.0, 0.5))
    g.command(511, 51, 200000)
    sp = g.recv("LOCAL_POSITION_SETPOINT", 5, lambda s: s.x == 4.0)
    assert sp is not None and (sp.y, sp.z, sp.coordinate_frame) == (5.0, -6.0, 1)


def test_geography_in_the_seed_set(seed_station):
    # The seed's forms (no time_usec): origin and area answered as in today's set.
    g = seed_station
    g.send(g.mod.MAVLink_set_gps_global_origin_message(1, 473977420, 85455940, 488000))
    o = g.recv("GPS_GLOBAL_ORIGIN", 5)
    assert (o.latitude, o.longitude, o.altitude) == (473977420, 85455940, 488000)
    g.send(g.mod.MAVLink_safety_set_allowed_area_message(1, 1, 0, 47.3, 8.5, 0.0, 47.5, 8.6, 120.0))
    a = g.recv("SAFETY_ALLOWED_AREA", 5)
    assert a.frame == 0 and abs(a.p2z - 120.0) < 1e-3
