"""`mavctl flash` against the emulated Cortex-M3 board (MCU stage): MicroPython 1.25 with
a littlefs filesystem over RAM and nothing of mavstack frozen in (mcu/firmware.py
build_with_filesystem), its REPL and MAVLink UARTs on ptys.

flash compiles the stack for armv7m, copies the tree over the REPL with mpremote's
transport, soft-resets the board, which runs main.py from its filesystem, and waits
for the vehicle's HEARTBEAT on the MAVLink UART; mavctl then lists parameters, uploads
a .plan and arms over that UART. A second flash of the same tree copies nothing. A
profile for another board, a port with no MicroPython on it, a board whose firmware
makes another .mpy version and a missing port are refused with one line and mavctl's
exit status.
"""
import contextlib
import io
import os
import re
import subprocess
import sys
import threading

import pytest

from conftest import ROOT
from mavctl_tools import mavctl, mavctl_cli, ok, write_test_plan
from test_mcu import _gate

sys.path.insert(0, os.path.join(ROOT, "mcu"))
import firmware  # noqa: E402
from mavctl.flash_device import Board  # noqa: E402  (host_tools is on sys.path: mavctl_tools)

MAVCTL = os.path.join(ROOT, ".venv", "bin", "mavctl")  # the installed command (make setup)
EXIT_USAGE, EXIT_NO_PORT, EXIT_NOT_MICROPYTHON, EXIT_MPY_VERSION = 2, 3, 6, 7


def flash(*args, timeout=300):
    cmd = [MAVCTL] if os.path.exists(MAVCTL) else [sys.executable, "-m", "mavctl"]
    r = subprocess.run(cmd + ["flash"] + [str(a) for a in args], capture_output=True, text=True,
                       timeout=timeout, cwd=ROOT)
    assert "Traceback" not in r.stderr, r.stderr
    return r


class _Terminal(io.StringIO):
    def isatty(self):
        return True


def flash_on_terminal(*args):
    """`mavctl flash` in this process, its stderr a terminal (where progress is drawn)."""
    out, err = io.StringIO(), _Terminal()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        status = mavctl_cli.main(["flash"] + [str(a) for a in args])
    return subprocess.CompletedProcess(args, status, out.getvalue(), err.getvalue())


def one_line_error(r, status, text):
    assert r.returncode == status, (r.returncode, r.stdout, r.stderr)
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and text in lines[0], r.stderr


@pytest.fixture(scope="module")
def board():
    """The board, freshly powered: (REPL pty, MAVLink pty)."""
    _gate()
    elf = firmware.build_with_filesystem("qemu_m3")
    proc = subprocess.Popen(firmware.qemu_command("qemu_m3", elf, ["pty", "pty"]),
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    ptys = []
    try:
        while len(ptys) < 2:
            line = proc.stdout.readline()
            assert line, "qemu exited: %s" % proc.poll()
            m = re.search(r"(/dev/pts/\d+)", line)
            if m:
                ptys.append(m.group(1))
        yield ptys
    finally:
        proc.kill()
        proc.wait()
        proc.stdout.close()


def repl(port, code):
    b = Board(port).open()
    try:
        return b.exec(code)
    finally:
        b.close()


def test_flash_end_to_end(board, tmp_path):
    repl_pty, mav_pty = board
    # The firmware has nothing of mavstack, and an empty filesystem as its current directory.
    assert repl(repl_pty, "import os\ntry:\n import mavstack\nexcept ImportError:\n print('no stack')\n"
                          "print(os.getcwd(), os.listdir())") .split() == ["no", "stack", "/flash", "[]"]

    # A profile for another board (the Cortex-M0 micro:bit) is refused before any copy.
    r = flash("--board", "qemu_m0", "--port", repl_pty, "--mavlink", mav_pty)
    one_line_error(r, EXIT_USAGE, "board profile qemu_m0 is for a nRF51")
    assert repl(repl_pty, "import os\nprint(os.listdir())").strip() == "[]"

    # The first flash copies the whole tree, resets the board and sees the vehicle; on a
    # terminal it draws a progress bar over the bytes copied.
    r = flash_on_terminal("--board", "qemu_m3", "--port", repl_pty, "--mavlink", mav_pty, "--timeout", 120)
    assert r.returncode == 0, (r.stdout, r.stderr)
    tree_bytes = re.search(r"flash: \d+ files, (\d+) bytes", r.stdout).group(1)
    assert re.search(r"flash: +\d+%%\|[^|]*\| \d+/%s " % tree_bytes, r.stderr), r.stderr[-500:]
    assert "building for armv7m" in r.stdout
    total = int(re.search(r"flash: (\d+) files, \d+ bytes", r.stdout).group(1))
    assert "flash: %d files copied, 0 unchanged" % total in r.stdout, r.stdout
    assert "the vehicle is up: HEARTBEAT from system 1 on %s" % mav_pty in r.stdout
    assert "the board says: qemu_m3 ready" in r.stdout

    # mavctl over the MAVLink UART: parameters, a QGroundControl .plan, arming.
    link = "serial:%s:115200" % mav_pty
    params = ok(mavctl(link, "params", "list"))
    assert "BRD_SERIAL_NUM" in params and "MAV_SYS_ID" in params
    plan = write_test_plan(tmp_path / "route.plan")
    assert "uploaded 5 mission, 8 fence, 2 rally items" in ok(mavctl(link, "mission", "upload", plan))
    ok(mavctl(link, "arm"))
    ok(mavctl(link, "disarm"))

    # The vehicle's MAVLink port is no MicroPython REPL: refused, nothing sent there but
    # the REPL's control characters (the vehicle's parser skips them).
    r = flash("--board", "qemu_m3", "--port", mav_pty)
    one_line_error(r, EXIT_NOT_MICROPYTHON, "no MicroPython REPL answers there")

    # Flashing the same tree again stops the running vehicle (Ctrl-C), copies nothing,
    # and the vehicle comes back from the same files: they survived the soft reset.
    r = flash("--board", "qemu_m3", "--port", repl_pty, "--mavlink", mav_pty, "--timeout", 120)
    assert r.returncode == 0, (r.stdout, r.stderr)
    assert "flash: 0 files copied, %d unchanged, 0 stale removed" % total in r.stdout, r.stdout
    assert r.stderr == ""  # no progress bar in a pipe
    assert "the vehicle is up" in r.stdout
    assert "BRD_SERIAL_NUM" in ok(mavctl(link, "params", "list"))


class OldMicroPython(threading.Thread):
    """A board on a pty whose MicroPython 1.18 (.mpy v5) answers the raw REPL the way the
    firmware does: banner on Ctrl-A, no raw-paste, "OK" + output + EOFs for a command."""

    def __init__(self):
        threading.Thread.__init__(self, daemon=True)
        self.master, slave = os.openpty()
        self.port = os.ttyname(slave)
        self.slave = slave
        self.stop = False

    def run(self):
        import select

        buf = b""
        while not self.stop:
            if not select.select([self.master], [], [], 0.1)[0]:
                continue
            try:
                buf += os.read(self.master, 4096)
            except OSError:
                return
            while True:
                if b"\x05A\x01" in buf:
                    buf = buf.replace(b"\x05A\x01", b"", 1)
                    os.write(self.master, b"R\x00")
                    continue
                i = min([j for j in (buf.find(b"\x01"), buf.find(b"\x04")) if j >= 0], default=-1)
                if i < 0:
                    break
                code, kind, buf = buf[:i], buf[i], buf[i + 1:]
                if kind == 1:
                    os.write(self.master, b"raw REPL; CTRL-B to exit\r\n>")
                elif code.strip(b"\r\x03"):
                    out = b"MPYINFO %d 1.18.0\r\nMACHINE old board with Cortex-M3\r\n" % (5 | 5 << 10) \
                        if b"MPYINFO" in code else b""
                    os.write(self.master, b"OK" + out + b"\x04\x04>")


def test_flash_refuses_another_mpy_version():
    old = OldMicroPython()
    old.start()
    try:
        r = flash("--board", "qemu_m3", "--port", old.port, timeout=60)
    finally:
        old.stop = True
        old.join()
        os.close(old.master)
        os.close(old.slave)
    one_line_error(r, EXIT_MPY_VERSION, "the board runs MicroPython 1.18.0 (.mpy v5)")


def test_flash_without_a_port():
    r = flash("--board", "qemu_m3", "--port", "/dev/ttyNOSUCH0", timeout=60)
    one_line_error(r, EXIT_NO_PORT, "/dev/ttyNOSUCH0: no such port")
