"""Command protocol: end to end against the unix vehicle (pymavlink), and in-process on
the bench (tests/mpy/harness.py) where exact counts and single polls are visible.
"""
import os
import sys
import time

import pytest

from conftest import ROOT, recv
from gcs_tools import (MAV_RESULT_ACCEPTED, MAV_RESULT_DENIED, MAV_RESULT_FAILED, MAV_RESULT_TEMPORARILY_REJECTED,
                       MAV_RESULT_UNSUPPORTED, ack, ardupilot_station, command, listen, mavsdk_system, request, run,
                       start, statustext, vehicle_heartbeat)

sys.path.insert(0, os.path.join(ROOT, "tests", "mpy"))
from harness import Bench  # noqa: E402

ARMED = 128
HOME = (473977420, 85455940, 488000)  # firmware/sim/motion.py
NAN = float("nan")
INF = float("inf")


# --- end to end ---------------------------------------------------------------

def test_arm_disarm_and_forced_arm_past_a_veto(vehicle):
    v = start(vehicle, "--set", "arm_veto=1")
    m = v.gcs()
    assert run(m, 400, 1) == MAV_RESULT_DENIED
    assert statustext(m, "simulated pre-arm check failed") is not None
    assert vehicle_heartbeat(m).base_mode & ARMED == 0
    assert run(m, 400, 1, 21196) == MAV_RESULT_ACCEPTED  # forced
    assert vehicle_heartbeat(m, lambda h: h.base_mode & ARMED) is not None
    assert run(m, 400, 0) == MAV_RESULT_ACCEPTED
    assert vehicle_heartbeat(m, lambda h: not h.base_mode & ARMED) is not None


def test_arm_veto_can_ask_to_retry_later(vehicle):
    v = start(vehicle, "--set", "arm_veto=2")
    m = v.gcs()
    assert run(m, 400, 1) == MAV_RESULT_TEMPORARILY_REJECTED
    assert statustext(m, "warming up") is not None


def test_modes_by_command_long_command_int_and_set_mode(vehicle):
    v = start(vehicle, "--set", "application=0")  # the modes alone (the simulator vetoes AUTO without a mission)
    m = ardupilot_station(v.gcs())  # custom modes by ArduPilot's numbers (test_modes.py)
    assert run(m, 176, 1 | 4, 3) == MAV_RESULT_ACCEPTED  # custom mode 3, AUTO
    hb = vehicle_heartbeat(m, lambda h: h.custom_mode == 3)
    assert hb.base_mode & 4 and hb.base_mode & 1
    m.mav.command_int_send(1, 1, 0, 176, 0, 0, 8 | 16, 0, 0, 0, 0, 0, 0)  # GUIDED | STABILIZE
    assert ack(m, 176).result == MAV_RESULT_ACCEPTED
    hb = vehicle_heartbeat(m, lambda h: h.base_mode & 8)
    assert hb.base_mode & 0x7F == 1 | 8 | 16 and hb.custom_mode == 4  # the mode with those flags: GUIDED
    m.mav.set_mode_send(1, 64 | 16, 0)  # the seed's SET_MODE: MANUAL_INPUT | STABILIZE
    hb = vehicle_heartbeat(m, lambda h: h.base_mode & 64)
    assert hb.base_mode & 0x7F == 1 | 64 | 16 and hb.custom_mode == 0  # STABILIZE
    m.mav.set_mode_send(1, 4 | 128, 0)  # the armed bit does not arm
    hb = vehicle_heartbeat(m, lambda h: h.base_mode & 4)
    assert not hb.base_mode & ARMED
    assert run(m, 176, 32) == MAV_RESULT_DENIED  # HIL is not something this vehicle does
    assert statustext(m, "not supported") is not None


def test_request_message_known_unknown_and_ack_first(vehicle):
    v = start(vehicle)
    m = v.gcs()
    command(m, 512, 1)
    first = m.recv_match(type=["COMMAND_ACK", "SYS_STATUS"], blocking=True, timeout=5)
    # SYS_STATUS may also be streamed; the requested one comes right after the ACK.
    while first is not None and first.get_type() == "SYS_STATUS":
        first = m.recv_match(type=["COMMAND_ACK", "SYS_STATUS"], blocking=True, timeout=5)
    assert first.command == 512 and first.result == MAV_RESULT_ACCEPTED
    assert recv(m, "SYS_STATUS", 2) is not None
    assert run(m, 512, 9999) == MAV_RESULT_DENIED  # no such message
    assert run(m, 512, 11) == MAV_RESULT_DENIED  # SET_MODE: a message the vehicle never produces
    assert run(m, 512, NAN) == MAV_RESULT_DENIED
    result, st = request(m, 2)
    assert result == MAV_RESULT_ACCEPTED and st is not None


def test_home_position_get_and_set(vehicle):
    v = start(vehicle)
    m = v.gcs()
    command(m, 410)
    assert ack(m, 410).result == MAV_RESULT_ACCEPTED
    h = recv(m, "HOME_POSITION", 5)
    assert (h.latitude, h.longitude, h.altitude) == HOME
    # Explicit coordinates (COMMAND_LONG floats: float32 precision)
    assert run(m, 179, 0, 0, 0, 0, 47.4, 8.55, 500.0) == MAV_RESULT_ACCEPTED
    h = recv(m, "HOME_POSITION", 5, lambda h: abs(h.latitude - 474000000) < 100)
    assert h is not None and abs(h.longitude - 85500000) < 100 and h.altitude == 500000
    # COMMAND_INT: exact degrees * 1e7; relative altitude frame adds to the old home's altitude
    m.mav.command_int_send(1, 1, 6, 179, 0, 0, 0, 0, 0, 0, 473000001, 85000001, 10.0)
    assert ack(m, 179).result == MAV_RESULT_ACCEPTED
    h = recv(m, "HOME_POSITION", 5, lambda h: h.latitude == 473000001)
    assert h.longitude == 85000001 and h.altitude == 510000
    # param1 = 1: here (the simulator is at its start position)
    assert run(m, 179, 1) == MAV_RESULT_ACCEPTED
    h = recv(m, "HOME_POSITION", 5, lambda h: h.latitude == HOME[0])
    assert (h.longitude, h.altitude) == HOME[1:]
    assert run(m, 179, 0, 0, 0, 0, 1000.0, 8.5, 500.0) == MAV_RESULT_DENIED  # latitude out of range
    m.mav.command_int_send(1, 1, 1, 179, 0, 0, 0, 0, 0, 0, 10, 10, 10.0)  # a local frame: not a home
    assert ack(m, 179).result == MAV_RESULT_DENIED


def test_unknown_command_targets_broadcast_and_resend(vehicle):
    v = start(vehicle)
    m = v.gcs()
    t0 = time.time()
    assert run(m, 31999) == MAV_RESULT_UNSUPPORTED
    assert time.time() - t0 < 1.0
    assert run(m, 42600, 1, 1) == MAV_RESULT_UNSUPPORTED  # DO_WINCH: no handler on this vehicle
    command(m, 520, 1, target=(2, 1))  # another system
    command(m, 520, 1, target=(1, 99))  # another component
    assert recv(m, "COMMAND_ACK", 1.5) is None
    assert run(m, 520, 1, target=(0, 0)) == MAV_RESULT_ACCEPTED  # broadcast
    # A re-sent command (confirmation 1) is acknowledged again, the same way.
    ardupilot_station(m)  # (custom mode 5 by ArduPilot's numbers: LOITER)
    assert run(m, 176, 1, 5) == MAV_RESULT_ACCEPTED
    assert run(m, 176, 1, 5, confirmation=1) == MAV_RESULT_ACCEPTED


def test_absurd_parameters_are_refused_without_harm(vehicle):
    v = start(vehicle)
    m = v.gcs()
    booted = request(m, 2)[1].time_boot_ms
    for p1 in (INF, -INF, NAN, 1e30, -1.0, 2.0):
        assert run(m, 400, p1) == MAV_RESULT_DENIED, p1
    for p in ((NAN,), (INF,), (1e9,), (-5.0,), (4.0, INF), (4.0, -3.0)):
        assert run(m, 176, *p) == MAV_RESULT_DENIED, p
    assert run(m, 246, 1e30) == MAV_RESULT_DENIED
    assert run(m, 246, 2) == MAV_RESULT_DENIED  # shutdown: the unix board has none
    assert run(m, 246, 3) == MAV_RESULT_DENIED  # bootloader
    assert run(m, 246, NAN) == MAV_RESULT_ACCEPTED  # nothing asked, nothing done
    assert run(m, 246, 0) == MAV_RESULT_ACCEPTED
    assert run(m, 179, 0, 0, 0, 0, NAN, INF, 1e38) == MAV_RESULT_DENIED
    assert run(m, 512, INF) == MAV_RESULT_DENIED
    assert run(m, 512, -1e20) == MAV_RESULT_DENIED
    m.mav.command_int_send(1, 1, 5, 179, 0, 0, NAN, NAN, NAN, NAN, 2**31 - 1, -2**31, INF)
    assert ack(m, 179).result == MAV_RESULT_DENIED
    # Still the same vehicle, not rebooted, answering.
    result, st = request(m, 2)
    assert result == MAV_RESULT_ACCEPTED and st.time_boot_ms > booted
    assert vehicle_heartbeat(m) is not None
    assert v.proc.poll() is None


def _param(m, name, timeout=5.0):
    m.mav.param_request_read_send(1, 1, name.encode(), -1)
    return listen(m, "PARAM_VALUE", timeout, lambda p: p.param_id == name)


def test_reboot_acks_first_then_comes_back_with_params(vehicle):
    v = start(vehicle)
    m = v.gcs()
    p = _param(m, "WP_SPEED")
    if p is None:
        pytest.skip("no parameter service on this build")
    m.mav.param_set_send(1, 1, b"WP_SPEED", 7.5, 9)
    assert listen(m, "PARAM_VALUE", 5, lambda p: p.param_id == "WP_SPEED" and p.param_value == 7.5)
    assert run(m, 245, 1) == MAV_RESULT_ACCEPTED  # write parameters now
    assert run(m, 400, 1) == MAV_RESULT_ACCEPTED
    assert run(m, 246, 1) == MAV_RESULT_DENIED  # armed: disarm first
    assert run(m, 400, 0) == MAV_RESULT_ACCEPTED
    _, before = request(m, 2)
    before_at = time.time()
    command(m, 246, 1)
    # The ACK and the "Rebooting" STATUSTEXT both come out before the restart (a text
    # queued earlier, e.g. from disarming, may come first: texts are paced).
    seen = {}
    deadline = time.time() + 5
    while len(seen) < 2 and time.time() < deadline:
        msg = m.recv_match(type=["COMMAND_ACK", "STATUSTEXT"], blocking=True, timeout=1)
        if msg is not None and msg.get_type() == "COMMAND_ACK" and msg.command == 246:
            seen["ack"] = msg.result
        elif msg is not None and msg.get_type() == "STATUSTEXT" and "Rebooting" in msg.text:
            seen["text"] = True
    assert seen == {"ack": MAV_RESULT_ACCEPTED, "text": True}, seen
    # The same process restarts in place; the new endpoint learns us from our heartbeats.
    time.sleep(0.3)
    assert vehicle_heartbeat(m, timeout=15) is not None
    deadline = time.time() + 10
    while True:
        result, after = request(m, 2, timeout=1)
        # Restarted: its uptime is behind where the old clock would be by now, by the
        # old reading plus the 100 ms reboot delay (the new one may already be past the
        # old reading, if that was taken early in the old one's life).
        if after is not None:
            continuing = before.time_boot_ms + (time.time() - before_at) * 1000
            if after.time_boot_ms < continuing - 80:
                break
        assert time.time() < deadline, ("vehicle did not restart", before.time_boot_ms,
                                        after and after.time_boot_ms, time.time() - before_at)
    assert v.proc.poll() is None
    p = _param(m, "WP_SPEED")
    assert p is not None and p.param_value == 7.5


def _set(m, name, value):
    m.mav.param_set_send(1, 1, name.encode(), value, 9)  # MAV_PARAM_TYPE_REAL32
    p = listen(m, "PARAM_VALUE", 5, lambda p: p.param_id == name and p.param_value == value)
    assert p is not None, (name, value)
    return p


def test_command_sent_again_after_its_ack_runs_again(vehicle):
    """A command repeated after its ACK (confirmation 0) is a new command: it runs again,
    whatever ran in between. Saved parameters on disk are the last ones acknowledged."""
    v = start(vehicle, "--set", "param_autosave_ms=0")  # saved only by PREFLIGHT_STORAGE
    m = v.gcs()
    _set(m, "SIM_SPEED", 6.0)
    assert run(m, 245, 1) == MAV_RESULT_ACCEPTED
    _set(m, "SIM_SPEED", 7.0)
    assert run(m, 245, 1) == MAV_RESULT_ACCEPTED  # the same bytes as the save before
    # DO_SET_PARAMETER by index, a PARAM_SET in between, the same DO_SET_PARAMETER again.
    index = _param(m, "SIM_WIND_SPD").param_index
    assert run(m, 180, index, 4.0) == MAV_RESULT_ACCEPTED
    _set(m, "SIM_WIND_SPD", 9.0)
    assert run(m, 180, index, 4.0) == MAV_RESULT_ACCEPTED
    assert _param(m, "SIM_WIND_SPD").param_value == 4.0
    # DO_SET_MODE (ALT_HOLD), SET_MODE (#11) to another mode (LOITER), the same DO_SET_MODE again.
    assert run(m, 176, 1, 2) == MAV_RESULT_ACCEPTED
    assert vehicle_heartbeat(m, lambda h: h.custom_mode == 2) is not None
    m.mav.set_mode_send(1, 1 | 16, 5)
    assert vehicle_heartbeat(m, lambda h: h.custom_mode == 5) is not None
    assert run(m, 176, 1, 2) == MAV_RESULT_ACCEPTED
    assert vehicle_heartbeat(m, lambda h: h.custom_mode == 2, timeout=3) is not None
    # COMMAND_INT has no confirmation: sent again after its ACK, it runs again too.
    m.mav.command_int_send(1, 1, 0, 176, 0, 0, 1, 2, 0, 0, 0, 0, 0)
    assert ack(m, 176).result == MAV_RESULT_ACCEPTED
    m.mav.set_mode_send(1, 1 | 16, 5)
    assert vehicle_heartbeat(m, lambda h: h.custom_mode == 5) is not None
    m.mav.command_int_send(1, 1, 0, 176, 0, 0, 1, 2, 0, 0, 0, 0, 0)
    assert ack(m, 176).result == MAV_RESULT_ACCEPTED
    assert vehicle_heartbeat(m, lambda h: h.custom_mode == 2, timeout=3) is not None
    # Power lost (kill -9): what is on disk is the 7 the second save acknowledged.
    v.kill()
    v2 = start(vehicle, "--set", "param_autosave_ms=0")
    m2 = v2.gcs()
    assert _param(m2, "SIM_SPEED").param_value == 7.0


def _until(fn, timeout=10.0):
    deadline = time.time() + timeout
    while True:
        try:
            value = fn()
            if value:
                return value
        except Exception:
            if time.time() > deadline:
                raise
        if time.time() > deadline:
            return value
        time.sleep(0.2)


def test_mavsdk_reads_version_arms_disarms_and_reboots(vehicle):
    from mavsdk.plugins.action import Action
    from mavsdk.plugins.info import Info
    from mavsdk.plugins.telemetry import Telemetry

    v = start(vehicle)
    with mavsdk_system(v.port) as system:
        version = _until(Info(system).get_version)  # AUTOPILOT_VERSION, asked for with REQUEST_MESSAGE
        assert (version.flight_sw_major, version.flight_sw_minor, version.flight_sw_patch) == (0, 1, 0)
        assert version.os_sw_major == 1
        action, telemetry = Action(system), Telemetry(system)
        action.arm()
        assert _until(telemetry.armed)
        action.disarm()
        assert _until(lambda: not telemetry.armed())
        action.reboot()  # raises unless ACCEPTED
        time.sleep(1.0)
        action.arm()  # the vehicle came back and answers
        assert _until(telemetry.armed)
    assert v.proc.poll() is None


# --- in-process, on the bench ------------------------------------------------------

def bench(**kw):
    b = Bench(**kw)
    g = b.gcs()
    b.send(g.heartbeat())
    b.run(2)
    return b, g


def test_unknown_command_is_answered_in_the_same_poll():
    b, g = bench()
    acks = b.acks
    b.send(g.command(31999))
    b.run(1)
    assert b.acks == acks + 1 and (b.ack_command, b.ack_result) == (31999, MAV_RESULT_UNSUPPORTED)


def test_seed_commands_by_name_reach_application_handlers():
    from mavstack.dialects import seed2012_meta
    from mavstack.services.commands import command_id

    b, g = bench()
    commands = b.ep.services["commands"]
    names = [n for n in dir(seed2012_meta) if n.startswith("MAV_CMD_") and not n.startswith("MAV_CMD_ACK")]
    assert len(names) >= 30
    builtin = set(b.ep.commands)
    seen = []

    def handler(cmd):
        seen.append((cmd.command, cmd.float(7)))
        return MAV_RESULT_ACCEPTED

    for name in names:
        cid = getattr(seed2012_meta, name)
        assert command_id(name) == cid and command_id(name[8:]) == cid
        b.send(g.command(cid, 0, 0, 0, 0, 0, 0, 12.5))
        b.run(1)
        expected = MAV_RESULT_UNSUPPORTED if cid not in builtin else b.ack_result
        assert b.ack_command == cid and b.ack_result == expected, name
        if cid not in builtin:
            commands.handle(name[8:], handler)
            b.send(g.command(cid, 0, 0, 0, 0, 0, 0, 12.5, confirmation=1))
            b.run(1)
            assert b.ack_result == MAV_RESULT_ACCEPTED and seen[-1] == (cid, 12.5)
    with pytest.raises(ValueError):
        commands.handle("NO_SUCH_COMMAND", handler)


def test_retry_is_answered_a_command_sent_again_runs_again():
    """confirmation > 0 matching the command just acknowledged (same sender, command and
    parameters, within the window) gets the same answer without a second run; the same
    command with confirmation 0 is new and runs; a refused one is evaluated again."""
    b, g = bench()
    runs = []
    answer = [MAV_RESULT_ACCEPTED]
    b.ep.services["commands"].handle(31010, lambda cmd: runs.append(cmd.confirmation) or answer[0])
    f = g.command(31010, 1.0)
    resend = g.command(31010, 1.0, confirmation=1)
    resend2 = g.command(31010, 1.0, confirmation=2)
    for frame in (f, resend, resend2):
        b.send(frame)
        b.run(1)
        assert b.ack_result == MAV_RESULT_ACCEPTED
    assert runs == [0] and b.acks >= 3
    b.send(f)  # sent again after its ACK: a new command
    b.run(1)
    assert runs == [0, 0] and b.ack_result == MAV_RESULT_ACCEPTED
    # Another sender's identical retry is not ours to answer from memory.
    other = b.gcs(254, 190)
    b.send(other.command(31010, 1.0, confirmation=1))
    b.run(1)
    assert runs == [0, 0, 1]
    # Other parameters: not a retry of it.
    b.send(g.command(31010, 2.0, confirmation=1))
    b.run(1)
    assert runs == [0, 0, 1, 1]
    answer[0] = MAV_RESULT_DENIED
    b.send(g.command(31010, 3.0))
    b.run(1)
    b.send(g.command(31010, 3.0, confirmation=1))
    b.run(1)
    assert runs == [0, 0, 1, 1, 0, 1] and b.ack_result == MAV_RESULT_DENIED
    # A retry later than the window is run again.
    answer[0] = MAV_RESULT_ACCEPTED
    b.send(f)
    b.run(3100)  # the bench's clock
    b.send(resend)
    b.run(1)
    assert runs == [0, 0, 1, 1, 0, 1, 0, 1]
    # COMMAND_INT has no confirmation field: sent again, it runs again.
    fi = g.command_int(31010, 0, 1.0)
    for _ in range(2):
        b.send(fi)
        b.run(1)
    assert runs[-2:] == [0, 0]


def test_reboot_acknowledged_twice_is_scheduled_once():
    from mavstack.endpoint import Reboot

    b, g = bench()
    b.send(g.command(246, 1.0))
    b.run(1)
    assert (b.ack_command, b.ack_result) == (246, MAV_RESULT_ACCEPTED)
    texts = b.seen[253]
    b.run(60)
    # The same reboot again while the first is on its way (a new command, confirmation
    # 0, or COMMAND_INT): ACCEPTED, and the reboot keeps its time.
    b.send(g.command(246, 1.0))
    b.run(1)
    b.send(g.command_int(246, 0, 1.0))
    b.run(1)
    assert b.ack_result == MAV_RESULT_ACCEPTED and b.results[MAV_RESULT_ACCEPTED] >= 3
    with pytest.raises(Reboot):
        b.run(45)
    assert b.seen[253] - texts <= 1  # one "Rebooting"


def test_long_running_command_in_progress_then_final():
    b, g = bench()
    pending = []

    def slow(cmd):
        pending.append(cmd.defer())
        return 5  # MAV_RESULT_IN_PROGRESS

    b.ep.services["commands"].handle(31011, slow)
    progress = []
    b.watch = lambda msgid, p: progress.append((p[2], p[3])) if msgid == 77 else None
    f = g.command(31011)
    b.send(f)
    b.run(1)
    pending[0].progress(40)
    b.run(1)
    b.send(g.command(31011, confirmation=1))  # a retry while running: still in progress
    b.run(1)
    pending[0].done(MAV_RESULT_ACCEPTED)
    b.run(1)
    b.send(g.command(31011, confirmation=2))
    b.run(1)
    assert len(pending) == 1
    assert progress == [(5, 0), (5, 40), (5, 0), (0, 100), (0, 0)]
    # While it runs, the same command again (confirmation 0, or as COMMAND_INT: no
    # confirmation) is the same command in progress, not a second run.
    progress.clear()
    b.send(g.command(31011, 7.0))
    b.run(1)
    b.send(g.command(31011, 7.0))
    b.run(1)
    b.send(g.command_int(31011, 0, 7.0))
    b.run(1)
    b.send(g.command_int(31011, 0, 7.0))
    b.run(1)
    assert len(pending) == 3 and progress == [(5, 0), (5, 0), (5, 0), (5, 0)]
    pending[1].done(MAV_RESULT_ACCEPTED)
    pending[2].done(MAV_RESULT_ACCEPTED)
    b.run(1)
    b.send(g.command(31011, 7.0))  # after its ACK: new again
    b.run(1)
    assert len(pending) == 4


def test_failing_handler_gives_failed_and_the_vehicle_goes_on(capsys):
    b, g = bench()
    b.ep.services["commands"].handle(31012, lambda cmd: 1 // 0)
    b.send(g.command(31012))
    b.run(1)
    assert b.ack_result == MAV_RESULT_FAILED
    b.run(5)  # the report goes out with the next STATUSTEXT the status service sends
    # A contained fault: counted, told in one line and a STATUSTEXT, no traceback.
    out = capsys.readouterr()
    assert "mavstack: Fault: cmd 31012: ZeroDivisionError (1)" in out.out and "Traceback" not in out.err
    assert b.ep.faults.counts[1] == 1  # faults.COMMAND
    assert b.seen[253] >= 1  # STATUSTEXT
    b.send(g.command(400, 1.0))
    b.run(1)
    assert b.ack_result == MAV_RESULT_ACCEPTED and b.ep.services["status"].armed


def test_command_targets():
    b, g = bench()
    for ts, tc, answered in ((1, 1, True), (0, 0, True), (1, 0, True), (0, 1, True), (2, 1, False),
                             (1, 2, False), (2, 0, False)):
        acks = b.acks
        b.send(g.command(31999, target_system=ts, target_component=tc))
        b.run(1)
        assert (b.acks == acks + 1) == answered, (ts, tc)
        if answered:
            assert b.ack_result == MAV_RESULT_UNSUPPORTED


def test_ack_echoes_sender_and_command_int_fields():
    b, g = bench()
    got = {}

    def watch(msgid, p):
        if msgid == 77:
            got["ack"] = bytes(p[:10])

    b.watch = watch
    seen = {}

    def handler(cmd):
        seen.update(frame=cmd.frame, x=cmd.int(5), y=cmd.int(6), lat=cmd.float(5), z=cmd.float(7),
                    p1=cmd.int(1), nan2=cmd.nan(2), fin3=cmd.finite(3))
        return MAV_RESULT_ACCEPTED

    b.ep.services["commands"].handle(31013, handler)
    other = b.gcs(200, 42)
    b.send(other.command_int(31013, 6, 2.6, NAN, INF, 0, 473977420, -85455940, 12.25))
    b.run(1)
    assert seen["frame"] == 6 and seen["x"] == 473977420 and seen["y"] == -85455940
    assert seen["lat"] == pytest.approx(47.397742) and seen["z"] == 12.25
    assert seen["p1"] == 3 and seen["nan2"] and not seen["fin3"]
    ack_payload = got["ack"]
    assert ack_payload[0] | ack_payload[1] << 8 == 31013
    assert ack_payload[8] == 200 and ack_payload[9] == 42  # target = sender


def test_reboot_is_raised_after_the_ack_reached_the_wire():
    from mavstack.endpoint import Reboot

    b, g = bench()
    b.send(g.command(246, 1.0))
    b.run(1)
    assert (b.ack_command, b.ack_result) == (246, MAV_RESULT_ACCEPTED)
    with pytest.raises(Reboot):
        b.run(500)
    assert b.seen[253] >= 1  # "Rebooting" went out before


def test_reboot_waits_for_its_held_back_ack():
    """A ground station not kept (no HEARTBEAT) floods requests on a link its streams fill:
    the reboot's ACK is held back behind the others, and the reboot waits for it (at most
    3 s past its time) rather than leaving ACCEPTED unsaid."""
    from mavstack.endpoint import Reboot

    b = Bench(services=("status", "commands", "streams"))
    link = b.ep.links[0]
    link.medium_bps = link.bytes_per_s = 2000
    g = b.gcs()
    b.send(g.frame(66, 50, 1, 1, 0, 1))  # REQUEST_DATA_STREAM: all at 50 Hz
    b.run(2000)
    for _ in range(40):
        b.send(g.command(512, 0.0))  # REQUEST_MESSAGE HEARTBEAT: answers held back
    b.send(g.command(246, 1.0))
    commands = b.ep.services["commands"]
    b.run(1)
    assert commands.holding() > 0 and b.ack_command != 246
    with pytest.raises(Reboot):
        b.run(3200)
    assert (b.ack_command, b.ack_result) == (246, MAV_RESULT_ACCEPTED)
    assert commands.holding() == 0


def test_mavlink1_link_answers_in_mavlink1():
    b, g = bench(version=1)
    b.send(g.command(520, 1.0))
    b.run(1)
    assert b.rx.version == 1 and b.ack_result == MAV_RESULT_ACCEPTED and b.seen[148] == 1
    assert b.ep.links[0].version == 1


def test_seed_dialect_endpoint():
    # The 2012 message set: short COMMAND_ACK and SYS_STATUS, no AUTOPILOT_VERSION or HOME_POSITION.
    from mavstack.dialects import seed2012

    b, g = bench(dialect=seed2012)
    b.send(g.command(400, 1.0))
    b.run(1)
    assert (b.ack_command, b.ack_result) == (400, MAV_RESULT_ACCEPTED)
    b.send(g.command(520, 1.0))
    b.run(1)
    assert b.ack_result == MAV_RESULT_DENIED
    b.ep.statustext(6, "seed text")
    b.run(1100)
    assert b.seen[0] >= 2 and b.seen[1] >= 1 and b.seen[253] == 1


def test_set_home_current_position_needs_a_position():
    b, g = bench()
    status = b.ep.services["status"]
    b.send(g.command(410))
    b.run(1)
    assert b.ack_result == MAV_RESULT_TEMPORARILY_REJECTED  # no home yet
    b.send(g.command(179, 1.0))
    b.run(1)
    assert b.ack_result == MAV_RESULT_TEMPORARILY_REJECTED  # and no position to take it from
    status.position = lambda: (10, 20, 30)
    b.send(g.command(179, 1.0, confirmation=1))
    b.run(2)
    assert b.ack_result == MAV_RESULT_ACCEPTED and status.home == (10, 20, 30) and b.seen[242] == 1
