"""mavctl's errors are one line and a documented exit status, never a traceback: no port,
port busy, permission denied, no heartbeat; auto-connect (the one USB serial device, or the
one vehicle heard on UDP) and its refusal when there is none or several; progress bars on
a terminal only; the installed command and its plug-in list."""
import contextlib
import errno
import fcntl
import io
import os
import subprocess
import sys
import tty

import pytest
import serial

from conftest import ROOT, free_udp_port
from pty_relay import PtyRelay

sys.path.insert(0, os.path.join(ROOT, "host_tools"))
from mavctl import cli as mavctl_cli  # noqa: E402
from mavctl import link as mavctl_link  # noqa: E402
from mavctl import progress as mavctl_progress  # noqa: E402
from mavctl.errors import EXIT_NO_HEARTBEAT, EXIT_NO_PORT, EXIT_PERMISSION, EXIT_USAGE  # noqa: E402

MAVCTL = os.path.join(ROOT, ".venv", "bin", "mavctl")


def mavctl(*args, timeout=60):
    r = subprocess.run([MAVCTL] + [str(a) for a in args], capture_output=True, text=True,
                       timeout=timeout, cwd=ROOT)
    assert "Traceback" not in r.stderr, r.stderr
    return r


def in_process(*args):
    """mavctl_cli.main() here, so that a test can stand in for the operating system."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            status = mavctl_cli.main([str(a) for a in args])
        except SystemExit as e:
            status = e.code
    return subprocess.CompletedProcess(args, status, out.getvalue(), err.getvalue())


def one_line(r, status, *words):
    assert r.returncode == status, (r.returncode, r.stdout, r.stderr)
    line = r.stderr.strip()
    assert line.startswith("mavctl: ") and "\n" not in line and "Traceback" not in line, line
    for w in words:
        assert w in line, (w, line)


@pytest.fixture
def pty_end():
    master, slave = os.openpty()
    tty.setraw(slave)
    yield os.ttyname(slave)
    os.close(master)
    os.close(slave)


def test_installed_command():
    """`make setup` put the command in .venv/bin; it runs from any directory."""
    r = subprocess.run([MAVCTL, "--help"], capture_output=True, text=True, cwd="/", timeout=60)
    assert r.returncode == 0, r.stderr
    for name in ("params", "mission", "arm", "watch", "flash", "ports"):
        assert name in r.stdout
    text = " ".join(r.stdout.split())
    assert "Exit status: 0 done" in text
    assert "3 no port or port busy, 4 permission denied, 5 no heartbeat" in text
    r = subprocess.run([MAVCTL, "mission", "--help"], capture_output=True, text=True, timeout=60)
    assert "upload" in r.stdout and "download" in r.stdout


def test_no_port_busy_and_no_heartbeat(tmp_path, pty_end):
    one_line(mavctl("--connect", "serial:%s:57600" % (tmp_path / "ttyACM9"), "params", "list"),
             EXIT_NO_PORT, "no such port", "plugged in")
    one_line(mavctl("--connect", tmp_path / "ttyUSB4", "arm"), EXIT_NO_PORT, "no such port")
    # Busy: another program holds the device (pyserial's exclusive lock, as mavctl takes it).
    holder = os.open(pty_end, os.O_RDWR | os.O_NOCTTY)
    try:
        fcntl.flock(holder, fcntl.LOCK_EX | fcntl.LOCK_NB)
        one_line(mavctl("--connect", "serial:%s" % pty_end, "arm"), EXIT_NO_PORT, "port busy")
    finally:
        os.close(holder)
    # A device that answers nothing (here a pty nobody drives): no heartbeat, say what to check.
    one_line(mavctl("--connect", "serial:%s:115200" % pty_end, "--timeout", "1", "params", "list"),
             EXIT_NO_HEARTBEAT, "no HEARTBEAT", "baud")
    port = free_udp_port()
    one_line(mavctl("--connect", "udpin:127.0.0.1:%d" % port, "--timeout", "1", "arm"),
             EXIT_NO_HEARTBEAT, "no HEARTBEAT")
    one_line(mavctl("--connect", "bogus:1", "arm"), EXIT_USAGE, "--connect")


def test_permission_denied(tmp_path, monkeypatch):
    """As pyserial reports a device the user may not open (root may open anything, so the
    refusal is stood in for in-process)."""
    def refuse(device, **kw):
        raise serial.SerialException(errno.EACCES, "could not open port %s: [Errno 13] "
                                     "Permission denied: %r" % (device, device))

    monkeypatch.setattr(mavctl_link.mavutil, "mavlink_connection", refuse)
    one_line(in_process("--connect", "serial:/dev/ttyACM0:115200", "arm"), EXIT_PERMISSION,
             "/dev/ttyACM0", "permission denied", "dialout")
    if os.geteuid() != 0:  # and for real where the test does not run as root
        dev = tmp_path / "locked"
        dev.write_bytes(b"")
        dev.chmod(0)
        one_line(mavctl("--connect", "serial:%s" % dev, "arm"), EXIT_PERMISSION, "permission denied")


def test_autoconnect(vehicle, monkeypatch, tmp_path):
    """No --connect: a vehicle heard on the UDP port is used when it is the only candidate;
    with a USB serial device as well, the error lists both; with neither, says so."""
    port = free_udp_port()
    vehicle(links=["udpout:127.0.0.1:%d" % port])
    monkeypatch.setattr(mavctl_link, "usb_serial_ports", lambda: [])
    r = in_process("--udp-port", port, "params", "get", "SIM_SPEED")
    assert r.returncode == 0 and r.stdout.split() == ["SIM_SPEED", "5.0"], r
    usb = str(tmp_path / "ttyACM0")
    monkeypatch.setattr(mavctl_link, "usb_serial_ports", lambda: [usb])
    one_line(in_process("--udp-port", port, "arm"), EXIT_NO_PORT, "several",
             "serial:%s:57600" % usb, "udpin:0.0.0.0:%d (system 1)" % port, "--connect")
    # The single USB device is the one opened (at --baud): here it has gone away since.
    one_line(in_process("--udp-port", free_udp_port(), "--baud", "115200", "arm"), EXIT_NO_PORT,
             "serial:%s:115200: no such port" % usb)
    monkeypatch.setattr(mavctl_link, "usb_serial_ports", lambda: [])
    one_line(in_process("--udp-port", free_udp_port(), "arm"), EXIT_NO_PORT, "no vehicle found",
             "--connect")


def test_autoconnect_two_vehicles_on_udp(vehicle, monkeypatch, tmp_path):
    """Two vehicles sending to the ground station's port: listed; --target-system picks one."""
    port = free_udp_port()
    vehicle(links=["udpout:127.0.0.1:%d" % port])
    vehicle(links=["udpout:127.0.0.1:%d" % port], args=["--sysid", "2"], storage=tmp_path / "second")
    monkeypatch.setattr(mavctl_link, "usb_serial_ports", lambda: [])
    one_line(in_process("--udp-port", port, "arm"), EXIT_NO_PORT, "several",
             "udpin:0.0.0.0:%d (system 1), udpin:0.0.0.0:%d (system 2)" % (port, port),
             "--target-system")
    r = in_process("--udp-port", port, "--target-system", 2, "params", "get", "MAV_SYS_ID")
    assert r.returncode == 0 and r.stdout.split() == ["MAV_SYS_ID", "2"], r


def test_autoconnect_serial(vehicle, monkeypatch):
    """The one USB serial device found is the link (a pty pair standing in for the cable)."""
    cable = PtyRelay(rate=0.0)  # a cable that loses nothing
    try:
        gcs_end = cable.gcs_dev
        vehicle(links=["serial:%s:57600" % cable.vehicle_dev])
        monkeypatch.setattr(mavctl_link, "usb_serial_ports", lambda: [gcs_end])
        r = in_process("--udp-port", free_udp_port(), "params", "get", "SIM_SPEED")
        assert r.returncode == 0 and r.stdout.split() == ["SIM_SPEED", "5.0"], r
    finally:
        cable.close()


class Terminal(io.StringIO):
    def isatty(self):
        return True


def test_progress_on_terminal_only():
    tty_out = Terminal()
    with mavctl_progress.progress("parameters", stream=tty_out, delay=0) as bar:
        for i in range(1, 101):
            bar(i, 100)
    assert "parameters:" in tty_out.getvalue() and "/100" in tty_out.getvalue()
    pipe = io.StringIO()
    with mavctl_progress.progress("parameters", stream=pipe, delay=0) as bar:
        bar(50, 100)
    assert pipe.getvalue() == ""


def test_plugins_missing_or_broken(tmp_path, monkeypatch):
    """A plug-in module that is not there is skipped; one that fails to import costs only
    its own subcommands, with a warning."""
    (tmp_path / "broken_plugin.py").write_text("import no_such_dependency_here\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(mavctl_cli, "PLUGINS", ("no_such_plugin", "broken_plugin", "mavctl.params"))
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        ap = mavctl_cli.parser()
    assert err.getvalue().strip() == ("mavctl: broken_plugin unavailable: No module named "
                                      "'no_such_dependency_here'")
    assert ap.parse_args(["--connect", "udpin:1.2.3.4:5", "params", "get", "X"]).name == "X"


def test_flash_is_a_subcommand(tmp_path):
    """`mavctl flash` takes flash_build.py's options, its help and its refusals."""
    r = mavctl("flash", "--board", "unix", "--arch", "x64", "--build-only", tmp_path / "tree")
    assert r.returncode == 0 and "files" in r.stdout, (r.stdout, r.stderr)
    assert os.path.isfile(tmp_path / "tree" / "main.py")
    assert os.path.isfile(tmp_path / "tree" / "mavstack" / "endpoint.mpy")
    r = mavctl("flash", "-h")
    assert r.returncode == 0 and "--board" in r.stdout
    r = mavctl("flash", "--board", "no_such_board", "--build-only", tmp_path / "t2")
    assert r.returncode == EXIT_USAGE and "no_such_board" in r.stderr
