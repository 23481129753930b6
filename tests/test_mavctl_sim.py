"""`mavctl sim`: the unix vehicle on a new pty pair, driven over that serial line by
pymavlink and by mavctl's subcommands (params, mission with a .plan, mission show, arm,
mode, watch with a tlog, log plot, signing), and stopped cleanly by SIGINT and SIGTERM."""
import os
import signal

from pymavlink import mavutil

from conftest import free_udp_port, recv
from mavctl_tools import (Sim, check_png, mavctl, mavproxy_key, ok, processes_naming, refused,
                          signed_board, wait_until, write_test_plan)


def test_sim_session_over_its_pty(tmp_path):
    storage = tmp_path / "sim-storage"
    udp = free_udp_port()
    sim = Sim("--storage", storage, "--set", "sim_speed=40", "--set", "sim_climb=20",
              "--link", "udpout:127.0.0.1:%d" % udp)
    try:
        assert processes_naming(str(storage))  # the vehicle runs
        # The extra link: a ground station on UDP sees the same vehicle.
        beats = ok(mavctl("udpin:127.0.0.1:%d" % udp, "watch", "HEARTBEAT", "--seconds", "1.5"))
        assert beats.startswith("HEARTBEAT {type : 2,")
        # pymavlink straight on the device, as any serial ground station.
        m = mavutil.mavlink_connection(sim.device, baud=57600, source_system=250)
        hb = recv(m, "HEARTBEAT", 20, lambda h: h.get_srcSystem() == 1)
        assert hb is not None and hb.type == 2
        m.close()
        link = sim.link()
        assert ok(mavctl(link, "params", "set", "SIM_SPEED", "7.5")).split() == ["SIM_SPEED", "7.5"]
        plan = write_test_plan(tmp_path / "route.plan")
        assert "uploaded 5 mission, 8 fence, 2 rally items" in ok(mavctl(link, "mission", "upload", plan))
        table = ok(mavctl(link, "mission", "show", "--vehicle", "--png", tmp_path / "v.png",
                          "--size", "640x480")).splitlines()
        assert sum(line.startswith("fence ") for line in table) == 8
        assert sum(line.startswith("rally ") for line in table) == 2
        check_png(tmp_path / "v.png", 640, 480)
        assert "MAV_RESULT_ACCEPTED" in ok(mavctl(link, "arm"))
        assert "MAV_RESULT_ACCEPTED" in ok(mavctl(link, "mode", "5"))  # AUTO by its flag: fly the mission
        tlog = tmp_path / "flight.tlog"
        out = ok(mavctl(link, "watch", "--view", "--seconds", "4", "--tlog", tlog))
        view = out.split("mavctl watch: ")[-1]
        assert "AUTO  ARMED" in view and "m from home" in view
        assert "drawn to" in ok(mavctl(None, "log", "plot", tlog, "--png", tmp_path / "f.png",
                                       "--size", "800x600"))
        check_png(tmp_path / "f.png", 800, 600)
    finally:
        status, out = sim.stop(signal.SIGINT)
    assert status == 0, out
    assert "mavctl sim: stopping" in out and "Traceback" not in out
    assert wait_until(lambda: not processes_naming(str(storage)))  # the vehicle went with it
    assert (storage / "params").exists() or any(storage.iterdir())  # what it keeps, kept


def test_sim_signing_over_its_pty_and_sigterm(tmp_path):
    env = dict(os.environ, MICROPYPATH=signed_board(tmp_path))
    sim = Sim("--board", "unix_signed", env=env)
    try:
        link = sim.link()
        ok(mavctl(link, "signing", "setup", "over the pty"))
        refused(mavctl(link, "signing", "clear"), 2, "--current")
        m = mavutil.mavlink_connection(sim.device, baud=57600, source_system=250)
        m.setup_signing(mavproxy_key("over the pty"), sign_outgoing=True)
        hb = recv(m, "HEARTBEAT", 10, lambda h: h.get_srcSystem() == 1)
        assert hb is not None and hb._signed
        m.close()
        ok(mavctl(link, "signing", "clear", "--current", "over the pty"))
        assert "SIM_SPEED" in ok(mavctl(link, "params", "get", "SIM_SPEED"))
    finally:
        status, out = sim.stop(signal.SIGTERM)
    assert status == 0 and "stopping" in out, out


def test_sim_refusals(tmp_path):
    refused(mavctl(None, "sim", "--board", "no_such_board"), 2, "no board profile")
    refused(mavctl(None, "sim", "--set", "sim_speed"), 2, "KEY=VALUE")
