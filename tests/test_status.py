"""Status service end to end: the unix vehicle over UDP, pymavlink as the ground station.

Identity and life cycle (HEARTBEAT), SYS_STATUS figures, SYSTEM_TIME, PING,
STATUSTEXT, AUTOPILOT_VERSION, ground-station loss, MAVLink 1 and 2 ground stations,
operator control. Steady state under heap_lock is in test_status_heap.py.
"""
import os
import sys
import time

from pymavlink import mavutil

from conftest import ROOT, free_udp_port, recv
from gcs_tools import (MAV_RESULT_ACCEPTED, MAV_RESULT_DENIED, command, request, run, start,
                       statustext, vehicle_heartbeat)

sys.path.insert(0, os.path.join(ROOT, "tests", "mpy"))
from harness import Bench, loop_pair  # noqa: E402

MAV_STATE_BOOT = 1
MAV_STATE_STANDBY = 3
MAV_STATE_ACTIVE = 4
ARMED = 128
CAP_COMMAND_INT = 8
CAP_PARAM_ENCODE_BYTEWISE = 16
CAP_MAVLINK2 = 8192


def test_heartbeat_identity_and_rate(vehicle):
    v = start(vehicle)
    m = v.gcs()
    hb = vehicle_heartbeat(m)
    assert hb.type == 2  # boards/unix.py MAV_TYPE_QUADROTOR
    assert hb.autopilot == 0  # MAV_AUTOPILOT_GENERIC
    assert hb.mavlink_version == 3
    assert hb.get_srcComponent() == 1
    assert hb.system_status == MAV_STATE_STANDBY
    assert not hb.base_mode & ARMED
    # 1 Hz: over 3.5 s, 3 or 4 heartbeats
    t0 = time.time()
    count = 0
    while time.time() - t0 < 3.5:
        if recv(m, "HEARTBEAT", 0.3, lambda h: h.get_srcComponent() == 1) is not None:
            count += 1
        m.mav.heartbeat_send(6, 8, 0, 0, 0)
    assert 3 <= count <= 4, count


def test_life_cycle_boot_standby_active(vehicle, tmp_path):
    # udpout: the vehicle talks first, so its very first heartbeat (BOOT) is heard.
    port = free_udp_port()
    m = mavutil.mavlink_connection("udpin:127.0.0.1:%d" % port, source_system=255, source_component=190,
                                   dialect="common")
    try:
        start(vehicle, links=["udpout:127.0.0.1:%d" % port])
        first = recv(m, "HEARTBEAT", 20)
        assert first is not None
        assert first.system_status == MAV_STATE_BOOT
        assert first.get_msgbuf()[0] == 0xFE  # MAVLink 1 until the ground station speaks MAVLink 2
        m.target_system, m.target_component = first.get_srcSystem(), 1
        assert vehicle_heartbeat(m, lambda h: h.system_status == MAV_STATE_STANDBY) is not None
        assert run(m, 400, 1) == MAV_RESULT_ACCEPTED
        hb = vehicle_heartbeat(m, lambda h: h.base_mode & ARMED)
        assert hb.system_status == MAV_STATE_STANDBY  # armed, but on the ground (the simulator says)
        assert hb.get_msgbuf()[0] == 0xFD
        assert run(m, 22, 0, 0, 0, 0, 0, 0, 3) in (0, 5)  # NAV_TAKEOFF to 3 m: ACCEPTED or IN_PROGRESS
        assert vehicle_heartbeat(m, lambda h: h.system_status == MAV_STATE_ACTIVE, timeout=10) is not None
        assert run(m, 400, 0, 21196) == MAV_RESULT_ACCEPTED  # forced: disarmed in the air (it falls)
        hb = vehicle_heartbeat(m, lambda h: not h.base_mode & ARMED)
        assert hb.system_status == MAV_STATE_STANDBY
    finally:
        m.close()


def _sys_status(m, cond, timeout=8.0):
    deadline = time.time() + timeout
    last = None
    while time.time() < deadline:
        result, s = request(m, 1, timeout=2)
        assert result == MAV_RESULT_ACCEPTED
        if s is not None:
            last = s
            if cond(s):
                return s
        time.sleep(0.3)
    raise AssertionError("no matching SYS_STATUS; last %s" % last)


def test_sys_status_figures_follow_link_errors(vehicle):
    v = start(vehicle)
    m = v.gcs()
    s = _sys_status(m, lambda s: 0 < s.load < 1000)
    assert s.onboard_control_sensors_present != 0
    assert 0 <= s.battery_remaining <= 100 and 6000 <= s.voltage_battery <= 60000
    errors0 = s.errors_comm
    # Frames with a broken CRC: counted as communication errors.
    good = m.mav.heartbeat_encode(6, 8, 0, 0, 0).pack(m.mav)
    for i in range(6):
        bad = bytearray(good)
        bad[-1] ^= 0x5A
        m.write(bytes(bad))
    _sys_status(m, lambda s: s.errors_comm >= errors0 + 6)
    # Sequence gaps: frames lost on the way in, shown as drop_rate_comm (c%).
    for i in range(10):
        m.mav.seq = (m.mav.seq + 20) % 256
        m.mav.heartbeat_send(6, 8, 0, 0, 0)
    s = _sys_status(m, lambda s: s.drop_rate_comm > 0)
    assert s.drop_rate_comm <= 10000


def test_system_time(vehicle):
    v = start(vehicle)
    m = v.gcs()
    result, t1 = request(m, 2)
    assert result == MAV_RESULT_ACCEPTED and t1 is not None
    assert abs(t1.time_unix_usec / 1e6 - time.time()) < 5  # the simulator's clock is the host's
    time.sleep(0.3)
    _, t2 = request(m, 2)
    assert t2.time_boot_ms > t1.time_boot_ms


def test_ping_request_is_answered_response_is_not(vehicle):
    v = start(vehicle)
    m = v.gcs()
    m.mav.ping_send(123456789012, 77, 0, 0)
    p = recv(m, "PING", 5, lambda p: p.seq == 77)
    assert p is not None
    assert p.time_usec == 123456789012
    assert (p.target_system, p.target_component) == (255, 190)
    assert p.get_srcSystem() == 1
    m.mav.ping_send(5, 78, 1, 1)  # a response addressed to the vehicle: nothing comes back
    assert recv(m, "PING", 1.0, lambda p: p.seq == 78) is None


def _ordered(m, types, timeout=5.0):
    got = []
    deadline = time.time() + timeout
    while time.time() < deadline and len(got) < len(types):
        msg = m.recv_match(type=types, blocking=True, timeout=0.5)
        if msg is not None and msg.get_type() not in [g.get_type() for g in got]:
            got.append(msg)
    return got


def test_autopilot_version_by_512_and_520(vehicle):
    v = start(vehicle)
    m = v.gcs()
    for cmd, params in ((512, (148,)), (520, (1,))):
        command(m, cmd, *params)
        got = _ordered(m, ["COMMAND_ACK", "AUTOPILOT_VERSION"])
        assert [g.get_type() for g in got] == ["COMMAND_ACK", "AUTOPILOT_VERSION"], got  # ACK first
        assert got[0].command == cmd and got[0].result == MAV_RESULT_ACCEPTED
        av = got[1]
        assert av.capabilities & CAP_MAVLINK2
        assert av.capabilities & CAP_COMMAND_INT
        assert av.capabilities & CAP_PARAM_ENCODE_BYTEWISE  # the unix board has parameters
        assert av.flight_sw_version == 0 << 24 | 1 << 16 | 0 << 8 | 0  # mavstack 0.1.0, DEV
        assert av.os_sw_version >> 24 == 1  # MicroPython 1.x
        assert av.uid != 0


def test_statustext_from_arm_veto(vehicle):
    v = start(vehicle, "--set", "arm_veto=1")
    m = v.gcs()
    command(m, 400, 1)
    s = statustext(m, "pre-arm")
    assert s is not None and s.text.startswith("Arm: ")
    assert s.severity == 2  # MAV_SEVERITY_CRITICAL


def test_gcs_lost_and_regained(vehicle):
    v = start(vehicle, "--set", "gcs_timeout_ms=1000")
    m = v.gcs()  # its first heartbeat was "heard" (that STATUSTEXT went by while connecting)
    # Silence (no heartbeats): after 1 s the application is told, and says so.
    lost = recv(m, "STATUSTEXT", 5, lambda s: "GCS lost" in s.text)
    assert lost is not None and lost.severity == 4
    assert statustext(m, "GCS heard") is not None


def _frames_versions(m, seconds):
    magics = set()
    t0 = time.time()
    while time.time() - t0 < seconds:
        msg = m.recv_match(blocking=True, timeout=0.3)
        if msg is not None and msg.get_type() != "BAD_DATA":
            magics.add(msg.get_msgbuf()[0])
    return magics


def test_mavlink1_ground_station_gets_mavlink1_only(vehicle):
    v = start(vehicle)
    m = v.gcs(version=1)
    assert m.recv_match(type="HEARTBEAT", blocking=True, timeout=3).get_msgbuf()[0] == 0xFE
    command(m, 512, 148)
    a = recv(m, "COMMAND_ACK", 5, lambda a: a.command == 512)
    av = recv(m, "AUTOPILOT_VERSION", 5)
    assert a.result == MAV_RESULT_ACCEPTED and av is not None
    assert a.get_msgbuf()[0] == 0xFE and av.get_msgbuf()[0] == 0xFE
    m.mav.heartbeat_send(6, 8, 0, 0, 0)
    assert _frames_versions(m, 2.0) == {0xFE}


def test_mavlink2_ground_station_switches_the_link_to_mavlink2(vehicle):
    v = start(vehicle)
    m = v.gcs(version=2)
    m.mav.heartbeat_send(6, 8, 0, 0, 0)
    time.sleep(0.2)
    m.recv_match(blocking=False)
    assert _frames_versions(m, 2.0) == {0xFD}
    assert run(m, 512, 148) == MAV_RESULT_ACCEPTED


def test_operator_control(vehicle):
    # Two ground stations on two links (a udpin link answers one peer).
    ports = free_udp_port(), free_udp_port()
    v = start(vehicle, "--set", "operator_passkey=Open-Sesame", "--set", "gcs_timeout_ms=1500",
              links=["udpin:127.0.0.1:%d" % p for p in ports])
    a = v.gcs(source_system=255, port=ports[0])
    b = v.gcs(source_system=254, port=ports[1])
    # Nobody in control: arming is refused.
    assert run(a, 400, 1) == MAV_RESULT_DENIED

    def control(m, request, passkey, version=0):
        m.mav.change_operator_control_send(1, request, version, passkey.encode())
        r = recv(m, "CHANGE_OPERATOR_CONTROL_ACK", 5, lambda r: r.gcs_system_id == m.source_system)
        assert r is not None and r.control_request == request
        return r.ack

    assert control(a, 0, "wrong") == 1  # NACK: wrong passkey
    assert control(a, 0, "Open-Sesame", version=1) == 2  # NACK: unsupported encryption
    assert control(a, 0, "Open-Sesame") == 0
    assert statustext(b, "Operator control: GCS 255") is not None
    assert run(a, 400, 1) == MAV_RESULT_ACCEPTED
    assert run(b, 400, 0) == MAV_RESULT_DENIED  # not in control
    assert vehicle_heartbeat(b, lambda h: h.base_mode & ARMED) is not None
    assert control(b, 0, "Open-Sesame") == 3  # NACK: already under control
    assert control(b, 1, "") == 3  # cannot release someone else's control
    assert control(a, 1, "") == 0  # released
    assert control(b, 0, "Open-Sesame") == 0
    assert run(b, 400, 0) == MAV_RESULT_ACCEPTED
    assert run(a, 400, 1) == MAV_RESULT_DENIED
    # The holder goes silent: control is released, another GCS with the passkey takes over.
    assert statustext(a, "released: GCS lost", timeout=5) is not None
    assert control(a, 0, "Open-Sesame") == 0
    assert run(a, 400, 1) == MAV_RESULT_ACCEPTED


def test_change_operator_control_without_passkey_is_granted(vehicle):
    v = start(vehicle)
    m = v.gcs()
    m.mav.change_operator_control_send(1, 0, 0, b"anything")
    r = recv(m, "CHANGE_OPERATOR_CONTROL_ACK", 5)
    assert r is not None and r.ack == 0
    assert run(m, 400, 1) == MAV_RESULT_ACCEPTED


# --- in-process, on the bench (tests/mpy/harness.py) ---------------------------------


def _texts(b):
    got = []

    def watch(msgid, p):
        if msgid == 253:
            got.append((p[0], bytes(p[1:51]).rstrip(b"\0")))
        elif msgid == 1:
            got.append(("sys_status", p[22] | p[23] << 8))  # errors_count1: texts dropped

    b.watch = watch
    return got


def test_statustext_queue_is_bounded_drops_oldest_and_truncates():
    b = Bench()
    status = b.ep.services["status"]
    got = _texts(b)
    for i in range(12):
        b.ep.statustext(6, "text %d" % i)
    status.statustext(2, "x" * 80)
    assert status.texts.count == 8 and status.texts.dropped == 5
    b.run(20)
    texts = [t for t in got if t[0] != "sys_status"]
    assert [t[1] for t in texts[:7]] == [b"text %d" % i for i in range(5, 12)]
    assert texts[7] == (2, b"x" * 50)
    assert len(texts) == 8
    b.run(1000)
    assert ("sys_status", 5) in got


def test_statustext_paced_on_a_slow_link():
    b = Bench()
    b.ep.add_link(loop_pair(bytes_per_s=5760)[0])  # a 57600 baud radio
    b.run(1)
    status = b.ep.services["status"]
    got = _texts(b)
    for i in range(4):
        status.statustext(6, "slow %d" % i)
    b.run(100)
    assert 2 <= len([t for t in got if t[0] != "sys_status"]) <= 3  # about one per 46 ms
    b.run(200)
    assert len([t for t in got if t[0] != "sys_status"]) == 4


def test_gcs_presence_callbacks():
    b = Bench(options={"gcs_timeout_ms": "300"})
    status = b.ep.services["status"]
    link = b.ep.links[0]
    events = []
    status.on_gcs_lost = lambda l: events.append(("lost", l.index))
    status.on_gcs_regained = lambda l: events.append(("regained", l.index))
    g = b.gcs()
    assert not status.gcs_present(link)
    b.send(g.frame(0, 0, 2, 3, 0, 0, 3))  # another vehicle's heartbeat is not a GCS
    b.run(10)
    assert events == [] and not status.gcs_present(link)
    for _ in range(5):
        b.send(g.heartbeat())
        b.run(100)
    assert events == [("regained", 0)] and status.gcs_present(link)
    b.run(400)
    assert events == [("regained", 0), ("lost", 0)] and not status.gcs_present(link)
    b.send(g.heartbeat())
    b.run(1)
    assert events[-1] == ("regained", 0) and status.gcs_present(link)


def test_ground_station_clock_is_adopted_until_the_application_sets_one():
    b = Bench()
    status = b.ep.services["status"]
    g = b.gcs()
    assert status.unix_usec() == 0
    b.send(g.frame(2, 1700000000000000, 0))
    b.run(250)
    assert 1700000000250000 <= status.unix_usec() <= 1700000000252000
    status.set_clock(1800000000000000)
    b.send(g.frame(2, 1700000000000000, 0))
    b.run(1)
    assert status.unix_usec() >= 1800000000000000


def test_state_override_and_mode_hook():
    b = Bench()
    status = b.ep.services["status"]
    b.run(1)
    assert status.system_status == 3
    status.set_state(5)  # MAV_STATE_CRITICAL
    assert status.arm(True) == 0 and status.system_status == 5
    status.set_state(0)
    assert status.system_status == 4  # ACTIVE: armed
    status.mode_check = lambda base, custom: "no AUTO here" if base & 4 else None
    assert status.set_mode(4) == 2 and status.reason == "no AUTO here" and not status.auto
    assert status.set_mode(16, 7) == 2 and status.custom_mode == 0  # not in the table
    status.custom_modes = ((7, "SEVEN", 16),)
    assert status.set_mode(4 | 1, 7) == 0 and status.base_mode == 128 | 16 | 1 and status.custom_mode == 7


def _sensor_words(b):
    got = []

    def watch(msgid, p):
        if msgid == 1:
            got.append(tuple(int.from_bytes(bytes(p[i:i + 4]), "little") for i in (0, 4, 8)))

    b.watch = watch
    return got


def test_sys_status_prearm_and_geofence_bits_beside_the_applications(tmp_path):
    PREARM, FENCE = 0x10000000, 0x100000
    b = Bench(services=("status", "missions", "commands"), storage=str(tmp_path))
    status = b.ep.services["status"]
    app = 0x80000000 | 0x20000000 | 1  # the application's bits, bit 31 among them, stay its own
    status.set_sensors(app | PREARM | FENCE, app, app)  # ours are not the application's to set
    got = _sensor_words(b)
    b.run(1100)
    assert got[-1] == (app | PREARM, app | PREARM, app | PREARM | FENCE)
    objection = ["not ready"]
    status.arm_check = lambda arm: objection[0]
    b.run(1100)
    assert got[-1][2] == app | FENCE  # arming would be refused
    assert status.arm(True) == 2
    objection[0] = (1, "warming up")  # TEMPORARILY_REJECTED is no green light either
    b.run(1100)
    assert not got[-1][2] & PREARM
    objection[0] = (0, "fine")  # ACCEPTED with a word
    b.run(1100)
    assert got[-1][2] & PREARM
    status.arm_check = lambda arm: 1 // 0  # a broken check
    b.run(1100)
    assert not got[-1][2] & PREARM
    assert status.arm(True, force=True) == 0
    b.run(1100)
    assert got[-1][2] & PREARM  # armed: nothing stands in the way
    # A fence the application checks, and a fence plan: present, enabled, healthy until breached.
    status.fence_enabled = True
    b.run(1100)
    assert not got[-1][0] & FENCE  # no fence plan stored
    b.ep.services["missions"].stores[1].count = 4  # as a stored fence plan of 4 items says
    b.run(1100)
    assert got[-1][0] & FENCE and got[-1][1] & FENCE and got[-1][2] & FENCE
    status.fence_breached = True
    b.run(1100)
    assert got[-1][0] & FENCE and not got[-1][2] & FENCE
