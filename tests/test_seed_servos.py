"""Relays and servos on the unix vehicle over UDP, pymavlink as the ground station:
DO_SET_SERVO / DO_REPEAT_SERVO show in SERVO_OUTPUT_RAW (outputs 5-16; the simulator's
motors stay on 1-4), DO_SET_RELAY / DO_REPEAT_RELAY in NAMED_VALUE_INT "RELAYS"; the
repeats run over time while the vehicle goes on answering; refusals for outputs out of
the table, a sender not in control, and no answer to a command for another system."""
import time

from conftest import recv
from gcs_tools import (MAV_RESULT_ACCEPTED, MAV_RESULT_DENIED, MavProxy, ardupilot_station, command, run, statustext,
                       two_links)

PASSKEY = "sesame"


def servo_outputs(m, timeout=5.0, cond=None):
    return recv(m, "SERVO_OUTPUT_RAW", timeout, cond)


def relays(m):
    command(m, 512, 252)  # REQUEST_MESSAGE NAMED_VALUE_INT: each name in turn
    deadline = time.time() + 5
    while time.time() < deadline:
        nv = recv(m, "NAMED_VALUE_INT", 1.0)
        if nv is not None and nv.name == "RELAYS":
            return nv.value
        command(m, 512, 252)
    return None


def test_servo_table_in_servo_output_raw_and_repeat(vehicle):
    # seed: DO_SET_SERVO, DO_REPEAT_SERVO, SERVO_OUTPUT_RAW
    v = vehicle(args=["--set", "sim_speed=20"])
    m = v.gcs()
    assert run(m, 511, 36, 50000) == MAV_RESULT_ACCEPTED  # SERVO_OUTPUT_RAW at 20 Hz
    s = servo_outputs(m)
    assert (s.servo5_raw, s.servo6_raw, s.servo16_raw) == (1500, 1500, 1500)  # nominal
    assert s.servo1_raw == 1000  # the simulator's motor, disarmed
    assert run(m, 183, 6, 1800) == MAV_RESULT_ACCEPTED
    assert servo_outputs(m, cond=lambda s: s.servo6_raw == 1800) is not None
    # A motor output, or a width out of range: DENIED, and said why.
    assert run(m, 183, 2, 1800) == MAV_RESULT_DENIED
    assert run(m, 183, 6, 3000) == MAV_RESULT_DENIED
    assert statustext(m, "no such output") is not None
    # Three cycles of 0.4 s between 1200 us and nominal, then nominal; meanwhile the
    # vehicle answers other commands.
    assert run(m, 184, 7, 1200, 3, 0.4) == MAV_RESULT_ACCEPTED
    seen = []
    deadline = time.time() + 6
    while time.time() < deadline:
        s = servo_outputs(m, 1.0)
        if s is not None and (not seen or seen[-1] != s.servo7_raw):
            seen.append(s.servo7_raw)
        if len(seen) >= 6:
            break
    assert seen[:6] == [1200, 1500, 1200, 1500, 1200, 1500], seen
    assert run(m, 512, 1) == MAV_RESULT_ACCEPTED
    time.sleep(0.6)
    assert servo_outputs(m, cond=lambda s: s.servo7_raw == 1500 and s.servo6_raw == 1800) is not None
    # A bad cycle time is refused.
    assert run(m, 184, 7, 1200, 3, 0) == MAV_RESULT_DENIED


def test_relays(vehicle):
    # seed: DO_SET_RELAY, DO_REPEAT_RELAY
    v = vehicle()
    m = v.gcs()
    assert run(m, 181, 1, 1) == MAV_RESULT_ACCEPTED
    assert relays(m) == 2
    assert run(m, 181, 9, 1) == MAV_RESULT_DENIED  # the board has relays 0-3
    assert run(m, 181, 1, 5) == MAV_RESULT_DENIED  # 1 on / 0 off only
    # Two cycles of 0.2 s on relay 0: on, off, on, off; relay 1 untouched.
    assert run(m, 182, 0, 2, 0.2) == MAV_RESULT_ACCEPTED
    assert relays(m) in (2, 3)
    time.sleep(1.0)
    assert relays(m) == 2
    assert run(m, 181, 1, 0) == MAV_RESULT_ACCEPTED
    assert relays(m) == 0


def test_refused_when_not_in_control_or_not_addressed(vehicle):
    v = vehicle(args=["--set", "operator_passkey=" + PASSKEY])
    m = v.gcs()
    assert run(m, 183, 6, 1800) == MAV_RESULT_DENIED
    assert statustext(m, "not in control") is not None
    assert run(m, 181, 1, 1) == MAV_RESULT_DENIED
    assert run(m, 181, 1, 1, target=(7, 1), timeout=1.5) is None  # another system's: no answer
    m.mav.change_operator_control_send(1, 0, 0, PASSKEY.encode())
    assert recv(m, "CHANGE_OPERATOR_CONTROL_ACK", 5).ack == 0
    assert run(m, 183, 6, 1800) == MAV_RESULT_ACCEPTED


def test_mavproxy_relay_and_servo_commands(vehicle, tmp_path):
    # MAVProxy's relay module as a user types it; pymavlink on the other link watches.
    v, port, m = two_links(vehicle)
    assert run(m, 511, 36, 100000) == MAV_RESULT_ACCEPTED  # SERVO_OUTPUT_RAW at 10 Hz
    mp = MavProxy(port, tmp_path, "relay")
    try:
        mp.expect(r"online system 1|Detected vehicle 1:1")
        mp.say("servo set 9 1700")
        mp.expect(r"Got COMMAND_ACK: DO_SET_SERVO: ACCEPTED")
        assert servo_outputs(m, cond=lambda s: s.servo9_raw == 1700) is not None
        mp.say("servo set 3 1700")  # a motor
        mp.expect(r"Got COMMAND_ACK: DO_SET_SERVO: DENIED")
        mp.say("relay set 2 1")
        mp.expect(r"Got COMMAND_ACK: DO_SET_RELAY: ACCEPTED")
        assert relays(m) == 4
        mp.say("servo repeat 10 1100 2 0.5")
        mp.expect(r"Got COMMAND_ACK: DO_REPEAT_SERVO: ACCEPTED")
        assert servo_outputs(m, cond=lambda s: s.servo10_raw == 1100) is not None
        assert servo_outputs(m, cond=lambda s: s.servo10_raw == 1500) is not None
    finally:
        mp.close()


def test_mission_items_drive_the_table(vehicle):
    # A mission's DO_SET_SERVO and DO_SET_RELAY take effect as the runner reaches them.
    from mission_gcs import LAT0, LON0, Item, MissionClient

    v = vehicle(args=["--set", "sim_speed=20", "--set", "sim_climb=10"])
    m = v.gcs()
    assert run(m, 511, 36, 100000) == MAV_RESULT_ACCEPTED
    plan = [Item(3, 22, 0, 1, 0.0, 0.0, 0.0, 0.0, LAT0, LON0, 5.0),
            Item(2, 183, 0, 1, 8.0, 1900.0, 0.0, 0.0, 0, 0, 0.0),  # DO_SET_SERVO 8 1900
            Item(2, 181, 0, 1, 3.0, 1.0, 0.0, 0.0, 0, 0, 0.0),  # DO_SET_RELAY 3 on
            Item(3, 16, 0, 1, 0.0, 2.0, 0.0, 0.0, LAT0 + 500, LON0, 5.0)]
    assert MissionClient(m).upload(plan) == 0
    assert run(m, 400, 1) == MAV_RESULT_ACCEPTED
    assert run(ardupilot_station(m), 176, 1 | 4 | 16, 3) == MAV_RESULT_ACCEPTED  # AUTO (ArduPilot's 3)
    assert servo_outputs(m, 30, lambda s: s.servo8_raw == 1900) is not None
    assert relays(m) == 8
