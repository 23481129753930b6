"""mavctl flash (host_tools/mavctl/flash_*.py) builds the file tree a board gets (the unix vehicle runs from it),
and mavctl (the command `make setup` installs) drives the real unix vehicle over UDP and
over a serial line (two ptys joined by a relay thread, as a USB radio pair joins two
computers)."""
import contextlib
import io
import math
import os
import select
import subprocess
import sys
import threading
import time
import tty

import pytest

from conftest import MICROPYTHON, PYTHON, ROOT, free_udp_port, recv, run_mpy

MAVCTL = os.path.join(ROOT, ".venv", "bin", "mavctl")
STACK = os.path.join(ROOT, "firmware", "mavstack")
sys.path.insert(0, os.path.join(ROOT, "host_tools"))
import mavctl.flash_build as flash_tool  # noqa: E402
from mavctl import cli as mavctl_tool  # noqa: E402

WPL = """QGC WPL 110
0\t1\t0\t16\t0\t0\t0\t0\t47.397742\t8.545594\t488.0\t1
1\t0\t3\t22\t0\t0\t0\t0\t47.3977420\t8.5455940\t10.0\t1
2\t0\t3\t16\t0.5\t2\t0\tnan\t47.3980001\t8.5460003\t15.25\t1
3\t0\t3\t16\t0\t0\t0\t0\t-33.8567844\t151.2152967\t20\t1
4\t0\t2\t177\t1\t-1\t0\t0\t0\t0\t0\t1
5\t0\t3\t21\t0\t0\t0\t0\t47.397742\t8.545594\t0\t1
"""


def run(cmd, timeout=60, **kw):
    return subprocess.run([str(c) for c in cmd], capture_output=True, text=True, timeout=timeout,
                          cwd=kw.pop("cwd", ROOT), **kw)


def flash(*args):
    r = run([PYTHON, "-m", "mavctl.flash_build"] + list(args))
    assert "Traceback" not in r.stderr, r.stderr
    return r


def mavctl_cli(link, *args, timeout=60):
    """mavctl as the user runs it: a process, its exit status, no traceback."""
    r = run([MAVCTL, "--connect", link] + list(args), timeout=timeout)
    assert "Traceback" not in r.stderr, r.stderr
    return r


def mavctl(link, *args):
    """mavctl.main() in this process (saves an interpreter start per call); an
    unexpected exception fails the test."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            status = mavctl_tool.main(["--connect", link] + [str(a) for a in args])
        except SystemExit as e:  # argparse
            status = e.code
    return subprocess.CompletedProcess(args, status, out.getvalue(), err.getvalue())


def ok(r):
    assert r.returncode == 0, (r.returncode, r.stdout, r.stderr)
    return r.stdout


def wpl_items(text):
    lines = text.strip().splitlines()
    assert lines[0] == "QGC WPL 110"
    return [[float(w) for w in line.split()] for line in lines[1:]]


def same_items(a, b):
    assert len(a) == len(b)
    for x, y in zip(a, b):
        for u, v in zip(x, y):
            assert (math.isnan(u) and math.isnan(v)) or u == pytest.approx(v, abs=1e-7), (x, y)


@pytest.fixture
def gcs_link(vehicle):
    """A vehicle sending to a UDP port that each mavctl run listens on (udpin): a
    new run is heard at once, as a ground station restarting on the same port."""

    def start(**kw):
        port = free_udp_port()
        v = vehicle(links=["udpout:127.0.0.1:%d" % port], **kw)
        return v, "udpin:127.0.0.1:%d" % port

    return start


# --- flash --------------------------------------------------------------------------

def stack_modules(with_meta=False):
    """The tree paths of the stack's modules a common-dialect board gets."""
    out = set()
    for dirpath, dirnames, filenames in os.walk(STACK):
        dirnames[:] = [d for d in dirnames if d != "__pycache__"]
        for name in filenames:
            if not name.endswith(".py"):
                continue
            rel = os.path.relpath(os.path.join(dirpath, name), os.path.dirname(STACK))
            if "/dialects/" in rel and name not in ("__init__.py", "common.py", "table.py") and not (
                    with_meta and name in ("common_meta.py", "layout.py")):
                continue
            if name.endswith("_meta.py") and not with_meta:
                continue
            out.add(rel[:-3] + ".mpy")
    return out


def mpy_header(path):
    with open(path, "rb") as f:
        head = f.read(4)
    assert head[:2] == b"M\x06", path
    return head[2] >> 2  # native architecture, 0 for bytecode only


@pytest.mark.parametrize("board, arch", [("pico", 4), ("esp32", 10), ("pyboard", 7)])
def test_flash_build_tree(tmp_path, board, arch):
    out = tmp_path / "tree"
    ok(flash("--board", board, "--build-only", out))
    files = set()
    for dirpath, _, filenames in os.walk(out):
        files.update(os.path.relpath(os.path.join(dirpath, f), out) for f in filenames)
    # radio.mpy: the settings these profiles share (boards/radio.py), which they import.
    # Only the services they list (status, params, commands, missions, streams) come, with
    # what those and main.py import: not SHA-256 (signing's), RAM storage and the clock of
    # the emulated boards (qemu's), nor compat's stand-ins for CPython.
    unlisted = ("services/auth", "services/calibration", "services/debug", "services/ftp/",
                "services/geography", "services/inputs/", "services/seed_", "services/servos",
                "services/signing", "services/peripheral/", "services/camera", "kernels/sha256", "storage_ram",
                "qemu", "compat_cpython")
    used = {f for f in stack_modules() if not any(f.startswith("mavstack/" + u) for u in unlisted)}
    assert files == {"main.py", "board.py", "radio.mpy"} | used
    with open(os.path.join(ROOT, "boards", board + ".py")) as f:
        assert (out / "board.py").read_text() == f.read()
    assert (out / "main.py").read_text() == open(os.path.join(ROOT, "firmware", "main.py")).read()
    for f in files:
        if f.endswith(".mpy"):
            want = arch if f in ("mavstack/kernels/bytes_viper.mpy", "mavstack/kernels/sha256_viper.mpy") else 0
            assert mpy_header(out / f) == want, f


def test_flash_options_and_refusals(tmp_path):
    out = tmp_path / "meta"
    ok(flash("--board", "pico", "--with-meta", "--build-only", out))
    assert (out / "mavstack/dialects/common_meta.mpy").exists()
    assert (out / "mavstack/dialects/layout.mpy").exists()
    # A second build replaces the first.
    ok(flash("--board", "pico", "--build-only", out))
    assert not (out / "mavstack/dialects/common_meta.mpy").exists()
    # A cut-down dialect keeps what the stack names (and what was asked for).
    cut = flash("--board", "pico", "--messages", "TIMESYNC", "--build-only", tmp_path / "cut")
    ok(cut)
    assert " PARAM_VALUE " in cut.stdout and " TIMESYNC " in cut.stdout and " ATTITUDE " in cut.stdout
    assert os.path.getsize(tmp_path / "cut/mavstack/dialects/common.mpy") < \
        os.path.getsize(out / "mavstack/dialects/common.mpy")

    other = tmp_path / "other"
    other.mkdir()
    (other / "notes.txt").write_text("mine")
    r = flash("--board", "pico", "--build-only", other)
    assert r.returncode == 2 and "not touching" in r.stderr
    assert (other / "notes.txt").read_text() == "mine"
    for i, args in enumerate((["--board", "nosuch"], ["--board", "pico", "--messages", "NO_SUCH_MSG"],
                              ["--board", "pico", "--arch", "z80"])):
        r = flash(*args, "--build-only", tmp_path / ("x%d" % i))
        assert r.returncode == 2 and r.stderr.startswith("flash: "), (args, r.stderr)
        assert not (tmp_path / ("x%d" % i)).exists()


def test_flash_device_cleanup_script(tmp_path):
    """The script flash runs on the board: makes the directories, removes stale stack
    files (an old foo.py would shadow the new foo.mpy), leaves the rest alone."""
    (tmp_path / "mavstack").mkdir()
    for name in ("mavstack/parser.py", "mavstack/parser.mpy", "mavstack/gone.mpy", "main.py"):
        (tmp_path / name).write_text("x")
    files = ["main.py", "board.py", "mavstack/parser.mpy", "mavstack/services/params.mpy"]
    r = run_mpy(flash_tool._prepare_script(files), cwd=str(tmp_path))
    assert r.returncode == 0, r.stderr
    left = sorted(os.path.relpath(os.path.join(d, f), tmp_path)
                  for d, _, fs in os.walk(tmp_path) for f in fs)
    assert left == ["main.py", "mavstack/parser.mpy"]
    assert (tmp_path / "mavstack/services").is_dir()


@pytest.mark.parametrize("cut", [False, True])
def test_flash_unix_tree_runs(tmp_path, cut):
    """The .mpy tree for the host CPU is a working vehicle: viper kernels load,
    and it answers pymavlink and mavctl."""
    out = tmp_path / "tree"
    ok(flash("--board", "unix", "--arch", "x64", "--build-only", out, *(["--messages", ""] if cut else [])))
    assert not list(out.glob("mavstack/**/*.py"))
    env = dict(os.environ, MICROPYPATH=".frozen")  # nothing from firmware/: only the tree
    r = run([MICROPYTHON, "-c", "import sys; sys.path.insert(0, %r)\n"
             "import mavstack.kernels as k, mavstack.services.params, board\n"
             "print(k.IMPL, k.__file__)" % str(out)], env=env, cwd=tmp_path)
    assert r.stdout.split() == ["viper", str(out / "mavstack/kernels/__init__.mpy")], r.stdout + r.stderr

    port = free_udp_port()
    proc = subprocess.Popen([MICROPYTHON, out / "main.py", "--storage", tmp_path / "storage",
                             "--link", "udpin:127.0.0.1:%d" % port], cwd=tmp_path, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    m = None
    try:
        from pymavlink import mavutil

        m = mavutil.mavlink_connection("udpout:127.0.0.1:%d" % port, source_system=255,
                                       source_component=190, dialect="common")
        deadline = time.time() + 20
        hb = None
        while hb is None and time.time() < deadline and proc.poll() is None:
            m.mav.heartbeat_send(6, 8, 0, 0, 0)
            hb = recv(m, "HEARTBEAT", timeout=0.5)
        assert hb is not None, proc.poll() is not None and proc.stdout.read()
        assert hb.type == 2  # MAV_TYPE_QUADROTOR, boards/unix.py
        m.mav.param_request_read_send(1, 1, b"SIM_SPEED", -1)
        assert recv(m, "PARAM_VALUE", timeout=5, cond=lambda p: p.param_id == "SIM_SPEED") is not None
    finally:
        if m is not None:
            m.close()
        proc.terminate()
        proc.wait(10)


# --- mavctl.py ----------------------------------------------------------------------

def test_params(gcs_link, tmp_path):
    storage = tmp_path / "params"
    v, link = gcs_link(storage=storage)
    listing = ok(mavctl(link, "params", "list")).splitlines()
    values = dict(line.split() for line in listing)
    assert len(values) == len(listing) > 20
    assert "." in values["SIM_SPEED"] and values["SIM_SEED"].isdigit()  # REAL32, UINT32
    sim = ok(mavctl(link, "params", "list", "SIM_*")).splitlines()
    assert sim == [line for line in listing if line.startswith("SIM_")]
    assert ok(mavctl(link, "params", "get", "SIM_SPEED")).split() == ["SIM_SPEED", values["SIM_SPEED"]]

    assert ok(mavctl(link, "params", "set", "SIM_SPEED", "7.25")).split() == ["SIM_SPEED", "7.25"]
    # An int32 whose bytes read as a float are a signalling NaN: bytewise, it must survive.
    assert ok(mavctl(link, "params", "set", "SIM_SEED", "-5000000")).split() == ["SIM_SEED", "-5000000"]
    assert ok(mavctl(link, "params", "get", "SIM_SEED")).split() == ["SIM_SEED", "-5000000"]
    assert ok(mavctl(link, "params", "set", "SIM_GPS_SATS", "0x10")).split() == ["SIM_GPS_SATS", "16"]

    r = mavctl(link, "params", "set", "SIM_SPEED", "99")  # beyond the parameter's maximum
    assert r.returncode == 1 and "SIM_SPEED: MAV_PARAM_ERROR_VALUE_OUT_OF_RANGE" in r.stderr  # the vehicle's PARAM_ERROR
    assert ok(mavctl(link, "params", "get", "SIM_SPEED")).split() == ["SIM_SPEED", "7.25"]
    r = mavctl(link, "params", "set", "MAV_SYS_ID", "7")  # read-only
    assert r.returncode == 1
    r = mavctl(link, "params", "set", "SIM_GPS_SATS", str(1 << 40))  # beyond any integer type
    assert r.returncode == 2 and "is outside" in r.stderr
    r = mavctl(link, "params", "set", "SIM_GPS_SATS", "1.5")
    assert r.returncode == 2
    r = mavctl(link, "params", "set", "SIM_SPEED", "1e39")
    assert r.returncode == 2 and "float32" in r.stderr
    r = mavctl(link, "params", "get", "NO_SUCH_PARAM")
    assert r.returncode == 1 and "NO_SUCH_PARAM" in r.stderr

    assert "MAV_RESULT_ACCEPTED" in ok(mavctl(link, "params", "save"))
    v.stop()
    v, link = gcs_link(storage=storage)
    assert ok(mavctl(link, "params", "get", "SIM_SPEED")).split() == ["SIM_SPEED", "7.25"]
    assert ok(mavctl(link, "params", "get", "SIM_SEED")).split() == ["SIM_SEED", "-5000000"]


def test_mission_round_trip(gcs_link, tmp_path):
    v, link = gcs_link()
    plan = tmp_path / "plan.waypoints"
    plan.write_text(WPL)
    assert "uploaded 6 mission items" in ok(mavctl(link, "mission", "upload", plan))
    back = tmp_path / "back.waypoints"
    ok(mavctl(link, "mission", "download", back))
    same_items(wpl_items(back.read_text()), wpl_items(WPL))
    same_items(wpl_items(ok(mavctl(link, "mission", "download"))), wpl_items(WPL))

    assert "current item 3" in ok(mavctl(link, "mission", "current", "3"))
    assert mavctl(link, "mission", "current", "40").returncode == 1

    # Waypoints are no fence: the vehicle refuses them and keeps its (empty) fence.
    r = mavctl(link, "mission", "upload", plan, "--type", "fence")
    assert r.returncode == 1 and "MAV_MISSION_UNSUPPORTED" in r.stderr
    assert wpl_items(ok(mavctl(link, "mission", "download", "--type", "fence"))) == []

    ok(mavctl(link, "mission", "clear"))
    assert wpl_items(ok(mavctl(link, "mission", "download"))) == []

    bad = tmp_path / "bad.waypoints"
    bad.write_text("QGC WPL 110\n0\t1\t0\t16\t0\t0\n")
    r = mavctl(link, "mission", "upload", bad)
    assert r.returncode == 2 and "bad.waypoints:2" in r.stderr


def test_commands(gcs_link):
    v, link = gcs_link()
    assert ok(mavctl(link, "arm")).strip() == "MAV_CMD_COMPONENT_ARM_DISARM: MAV_RESULT_ACCEPTED"
    assert "MAV_RESULT_ACCEPTED" in ok(mavctl(link, "disarm"))
    assert "MAV_RESULT_ACCEPTED" in ok(mavctl(link, "command", "COMPONENT_ARM_DISARM", "1"))
    assert "MAV_RESULT_ACCEPTED" in ok(mavctl(link, "command", "400", "0"))
    r = mavctl(link, "command", "31010", "1", "2", "nan")  # MAV_CMD_USER_1: nothing handles it
    assert r.returncode == 1 and "MAV_RESULT_UNSUPPORTED" in r.stdout
    r = mavctl(link, "command", "NO_SUCH_COMMAND")
    assert r.returncode == 2 and "unknown MAV_CMD" in r.stderr
    assert "MAV_RESULT_ACCEPTED" in ok(mavctl(link, "mode", "MAV_MODE_FLAG_CUSTOM_MODE_ENABLED", "16"))  # POSITION
    # mavctl shows no convention: 5 is ArduPilot's LOITER or PX4's ACRO (none here), so
    # refused rather than guessed (docs/services/status.md); with PX4's sub mode it is not.
    r = mavctl(link, "mode", "MAV_MODE_FLAG_CUSTOM_MODE_ENABLED", "5")
    assert r.returncode == 1 and "MAV_RESULT_DENIED" in r.stdout
    assert "MAV_RESULT_ACCEPTED" in ok(mavctl(link, "mode", "MAV_MODE_FLAG_CUSTOM_MODE_ENABLED", "4", "3"))  # LOITER

    assert "MAV_RESULT_ACCEPTED" in ok(mavctl(link, "stream", "ATTITUDE", "20"))
    table = ok(mavctl(link, "watch", "ATTITUDE", "--rates", "--seconds", "2"))
    count = int(table.splitlines()[1].split()[1])
    assert count >= 20  # 40 due in 2 s at 20 Hz; the board's default is 4 Hz
    assert "MAV_RESULT_ACCEPTED" in ok(mavctl(link, "stream", "ATTITUDE", "off"))

    assert "MAV_RESULT_ACCEPTED" in ok(mavctl(link, "reboot"))
    assert ok(mavctl(link, "params", "get", "SIM_SPEED")).split()[0] == "SIM_SPEED"
    v.check_alive()


def test_watch_over_udpout(vehicle):
    """The other way round: the vehicle listens (udpin), mavctl sends to it."""
    v = vehicle()
    out = ok(mavctl_cli("udpout:127.0.0.1:%d" % v.port, "watch", "HEARTBEAT", "SYS_STATUS", "--seconds", "2"))
    lines = out.splitlines()
    assert sum(line.startswith("HEARTBEAT {type : 2,") for line in lines) >= 2
    assert any(line.startswith("SYS_STATUS {") for line in lines)
    assert all(line.split()[0] in ("HEARTBEAT", "SYS_STATUS") for line in lines)


def test_usage_and_connection_errors(tmp_path):
    port = free_udp_port()
    r = mavctl_cli("udpin:127.0.0.1:%d" % port, "--timeout", "1", "params", "list")
    assert r.returncode == 5 and "no HEARTBEAT" in r.stderr
    r = mavctl_cli("serial:%s:57600" % (tmp_path / "no-such-tty"), "arm")
    assert r.returncode == 3 and "no such port" in r.stderr
    r = mavctl_cli("bogus:1", "arm")
    assert r.returncode == 2 and "--connect" in r.stderr
    r = mavctl_cli("udpin:127.0.0.1:%d" % port, "params", "frobnicate")
    assert r.returncode == 2 and "invalid choice" in r.stderr
    # Found wrong before any connection is tried (no vehicle here).
    for args in (["mission", "upload", tmp_path / "missing"], ["command", "NO_SUCH_COMMAND"],
                 ["stream", "NO_SUCH_MESSAGE", "1"], ["watch", "NOPE"], ["mode", "NOT_A_MODE"]):
        r = mavctl_cli("udpin:127.0.0.1:%d" % port, *args, timeout=10)
        assert r.returncode == 2 and r.stderr.startswith("mavctl: "), (args, r.stderr)


class PtyCable:
    """Two ptys joined master to master: each end is a /dev/pts path a program opens
    as a serial port; a thread carries bytes both ways, as a radio pair would."""

    def __init__(self):
        self.fds = []
        self.ends = []
        for _ in range(2):
            master, slave = os.openpty()
            tty.setraw(slave)  # raw from the start: no echo before the programs set it
            self.fds += [master, slave]
            self.ends.append(os.ttyname(slave))
        self.masters = self.fds[0], self.fds[2]
        self._stop = False
        self._thread = threading.Thread(target=self._relay, daemon=True)
        self._thread.start()

    def _relay(self):
        a, b = self.masters
        while not self._stop:
            ready, _, _ = select.select([a, b], [], [], 0.05)
            for fd in ready:
                try:
                    data = os.read(fd, 4096)
                    os.write(b if fd == a else a, data)
                except OSError:
                    pass

    def close(self):
        self._stop = True
        self._thread.join()
        for fd in self.fds:
            os.close(fd)


def test_serial_over_pty(vehicle, tmp_path):
    cable = PtyCable()
    v = None
    try:
        vehicle_end, gcs_end = cable.ends
        v = vehicle(links=["serial:%s:57600" % vehicle_end])
        link = "serial:%s:57600" % gcs_end
        assert ok(mavctl_cli(link, "params", "get", "SIM_SPEED")).split()[0] == "SIM_SPEED"
        # 0x7F800001: a signalling NaN if it were read as a float.
        assert ok(mavctl(link, "params", "set", "SIM_SEED", "2139095041")).split()[1] == "2139095041"
        plan = tmp_path / "plan.waypoints"
        plan.write_text(WPL)
        ok(mavctl(link, "mission", "upload", plan))
        same_items(wpl_items(ok(mavctl(link, "mission", "download"))), wpl_items(WPL))
        assert "MAV_RESULT_ACCEPTED" in ok(mavctl(link, "arm"))
        v.check_alive()
    finally:
        if v is not None:
            v.stop()
        cable.close()
