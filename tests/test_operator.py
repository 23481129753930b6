"""Operator control belongs to the ground station that took it: its system id and
component id, on that link (and for UDP, from that address). Another station with the
same system id (255 is QGroundControl's and MAVProxy's default) is refused everything
that needs control, and its heartbeats do not keep the holder's control alive.
End to end against the unix vehicle over UDP with pymavlink."""
import os

import pytest

from conftest import FIRMWARE, free_udp_port, recv
from gcs_tools import MAV_RESULT_ACCEPTED, MAV_RESULT_DENIED, listen, run, statustext, vehicle_heartbeat
from mission_gcs import MissionClient, plan

ARMED = 128
PASSKEY = "Open-Sesame"
MISSION_ACCEPTED = 0
MISSION_DENIED = 2


def _control(m, request=0, passkey=PASSKEY):
    m.mav.change_operator_control_send(1, request, 0, passkey.encode())
    r = recv(m, "CHANGE_OPERATOR_CONTROL_ACK", 5, lambda r: r.control_request == request)
    return None if r is None else r.ack


def _param(m, name):
    m.mav.param_request_read_send(1, 1, name.encode(), -1)
    return listen(m, "PARAM_VALUE", 5, lambda p: p.param_id == name)


def _drain(m):
    # Answers to another station of the same identity reach this one too (the vehicle
    # writes to every UDP peer): only what comes after its own requests counts.
    while m.recv_match(blocking=False) is not None:
        pass


def _five(m):
    """The five changes -> what came of each: True where the vehicle took it."""
    _drain(m)
    index = _param(m, "SIM_SPEED").param_index
    before = _param(m, "SIM_SPEED").param_value
    m.mav.param_set_send(1, 1, b"SIM_SPEED", before + 1.0, 9)
    p = listen(m, "PARAM_VALUE", 5, lambda p: p.param_id == "SIM_SPEED")
    took = {"param_set": p.param_value == before + 1.0}
    took["do_set_parameter"] = run(m, 180, index, before + 2.0) == MAV_RESULT_ACCEPTED
    took["load_defaults"] = run(m, 245, 2) == MAV_RESULT_ACCEPTED
    took["mission_upload"] = MissionClient(m, retries=2).upload(plan(2)) == MISSION_ACCEPTED
    took["forced_arm"] = run(m, 400, 1, 21196) == MAV_RESULT_ACCEPTED
    return took


def _disarm(m):
    assert run(m, 400, 0, 21196) == MAV_RESULT_ACCEPTED
    assert vehicle_heartbeat(m, lambda h: not h.base_mode & ARMED) is not None


def _vehicle(vehicle, *args):
    ports = free_udp_port(), free_udp_port()
    v = vehicle(links=["udpin:127.0.0.1:%d" % p for p in ports],
                args=["--set", "operator_passkey=" + PASSKEY] + list(args))
    return v, ports


def test_second_gcs_with_the_same_sysid_is_refused_everything(vehicle):
    v, ports = _vehicle(vehicle)
    boss = v.gcs(port=ports[0])  # sysid 255, compid 190
    other_link = v.gcs(port=ports[1])  # sysid 255, compid 190, on the other link
    assert _control(boss) == 0
    # The same address, another component: not the holder.
    boss.mav.srcComponent = 191
    got = _five(boss)
    boss.mav.srcComponent = 190
    assert got == dict.fromkeys(got, False), got
    # The same sysid and compid on another link: not the holder.
    got = _five(other_link)
    assert got == dict.fromkeys(got, False), got
    assert _control(other_link) == 3  # already under control
    assert _control(other_link, 1, "") == 3  # nor may it release it
    boss.mav.srcComponent = 191
    assert _control(boss, 1, "") == 3
    boss.mav.srcComponent = 190
    assert vehicle_heartbeat(other_link, lambda h: not h.base_mode & ARMED) is not None
    # The holder itself: all five.
    got = _five(boss)
    assert got == dict.fromkeys(got, True), got
    _disarm(boss)


def test_only_the_holders_heartbeats_keep_control(vehicle):
    v, ports = _vehicle(vehicle, "--set", "gcs_timeout_ms=1500")
    boss = v.gcs(port=ports[0])
    other_link = v.gcs(port=ports[1])
    assert _control(boss) == 0
    # The holder goes silent while a station of the same sysid on the other link (and the
    # holder's own address as another component) keeps beating: control is released.
    boss.mav.srcComponent = 191
    deadline_text = None
    for _ in range(8):
        boss.mav.heartbeat_send(6, 8, 0, 0, 0)
        deadline_text = statustext(other_link, "released: GCS lost", timeout=0.5)
        if deadline_text is not None:
            break
    boss.mav.srcComponent = 190
    assert deadline_text is not None
    assert _control(other_link) == 0
    assert run(other_link, 400, 1, 21196) == MAV_RESULT_ACCEPTED
    assert run(boss, 400, 0, 21196) == MAV_RESULT_DENIED
    _disarm(other_link)


def _udp_knows_the_sender():
    with open(os.path.join(FIRMWARE, "mavstack", "transport", "udp.py")) as f:
        return "rx_peer" in f.read()


@pytest.mark.skipif(not _udp_knows_the_sender(), reason="the UDP transport does not tell the datagram's address yet")
def test_same_sysid_and_compid_from_another_address_is_refused(vehicle):
    port = free_udp_port()
    v = vehicle(links=["udpin:127.0.0.1:%d" % port], args=["--set", "operator_passkey=" + PASSKEY])
    boss = v.gcs(port=port)
    assert _control(boss) == 0
    twin = v.gcs(port=port)  # sysid 255, compid 190, from another socket
    got = _five(twin)
    assert got == dict.fromkeys(got, False), got
    got = _five(boss)
    assert got == dict.fromkeys(got, True), got
    _disarm(boss)


LOCKED = """
import sys
sys.path.insert(0, "tests/mpy")
import micropython
from harness import Bench, Board

class B(Board):
    OPERATOR_PASSKEY = "pw"

b = Bench(services=("status", "commands"), board=B)
boss, other = b.gcs(255, 190), b.gcs(255, 191)
take = boss.frame(5, 1, 0, 0, b"pw")
beat, beat2 = boss.heartbeat(), other.heartbeat()
arm, arm2, disarm = boss.command(400, 1.0), other.command(400, 1.0), boss.command(400, 0.0)
status = b.ep.services["status"]
got = [0, 0, 0, 0]  # (module globals made under the lock would allocate)
text = bytearray(50)

def watch(msgid, p):
    if msgid == 253 and p[1] == 0x4F and p[10] == 0x63:  # "Operator c..."
        for i in range(50):
            text[i] = p[1 + i]

b.watch = watch
micropython.heap_lock()
try:
    b.send(beat); b.send(beat2); b.run(2)
    b.send(arm2); b.run(1)
    got[0] = b.ack_result
    b.send(take); b.run(2)
    b.send(arm2); b.run(1)
    got[1] = b.ack_result
    b.send(arm); b.run(1)
    got[2] = b.ack_result
    got[3] = status.armed
    b.send(disarm); b.run(1)
finally:
    micropython.heap_unlock()
print(got[0], got[1], got[2], got[3], bytes(text).rstrip(b"\\0").decode())
"""


def test_taking_and_checking_control_with_the_heap_locked():
    """A board runs with its heap locked: taking control, its text and the checks ask
    nothing of the heap."""
    from conftest import run_mpy

    r = run_mpy(LOCKED)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == ["2", "2", "0", "True", "Operator", "control:", "GCS", "255/190", "link", "0"]
