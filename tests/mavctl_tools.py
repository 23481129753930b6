"""Helpers for the tests of mavctl's live view, logs, plots, pty vehicle and signing:
mavctl in this process or as a process, `mavctl sim` as a process, PNG checks, the unix
vehicle with the signing service."""
import contextlib
import io
import os
import signal
import subprocess
import sys
import time

from conftest import FIRMWARE, PYTHON, ROOT

HOST_TOOLS = os.path.join(ROOT, "host_tools")
if HOST_TOOLS not in sys.path:
    sys.path.insert(0, HOST_TOOLS)
from mavctl import cli as mavctl_cli  # noqa: E402

SIGNED_BOARD = '''"""The unix vehicle with message signing (a test's board)."""
from unix import *  # noqa: F401,F403
import unix

NAME = "unix_signed"
SERVICES = ("signing",) + unix.SERVICES
SIGNING_SETUP_LINKS = %r
'''


def mavctl(link, *args):
    """mavctl's main() in this process (no interpreter start per call) -> CompletedProcess."""
    out, err = io.StringIO(), io.StringIO()
    argv = (["--connect", link] if link else []) + [str(a) for a in args]
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            status = mavctl_cli.main(argv)
        except SystemExit as e:  # argparse
            status = e.code
    return subprocess.CompletedProcess(argv, status, out.getvalue(), err.getvalue())


def mavctl_cli_run(link, *args, timeout=60, env=None):
    """mavctl as the user runs it: a process; no traceback allowed."""
    argv = [PYTHON, "-m", "mavctl"] + (["--connect", link] if link else []) + [str(a) for a in args]
    r = subprocess.run(argv, capture_output=True, text=True, timeout=timeout, cwd=ROOT, env=env)
    assert "Traceback" not in r.stderr, r.stderr
    return r


def ok(r):
    assert r.returncode == 0, (r.returncode, r.stdout, r.stderr)
    return r.stdout


def refused(r, status, text):
    assert r.returncode == status, (r.returncode, r.stdout, r.stderr)
    assert r.stderr.startswith("mavctl: ") and text in r.stderr, r.stderr
    assert "Traceback" not in r.stderr


def check_png(path, width, height):
    """A PNG of exactly width x height pixels with a picture on it (not one flat colour)."""
    from matplotlib import image
    img = image.imread(str(path))
    assert img.shape[:2] == (height, width), img.shape
    flat = img[..., :3].reshape(-1, 3)
    assert flat.std() > 0.01
    assert (flat.min(axis=1) < 0.9).mean() > 0.01  # some ink, not only white
    return img


def mavproxy_key(passphrase):
    """The key MAVProxy's `signing setup PASSPHRASE` gives a vehicle (its own code)."""
    from MAVProxy.modules.mavproxy_signing import SigningModule
    return SigningModule.passphrase_to_key(None, passphrase)


HOME = (47.397742, 8.545594, 488.0)


def write_test_plan(path):
    """A .plan: 5 mission items, an inclusion square, an exclusion triangle and circle,
    two rally points."""
    from mavctl.mission_file import Item
    from mavctl.plan_file import Plan, write_plan

    def item(seq, command, p1, lat, lon, alt=0.0, frame=3):
        return Item(seq, 0, frame, command, p1, 0.0, 0.0, 0.0, lat, lon, alt, 1)

    mission = [item(0, 22, 0, 47.397742, 8.545594, 10), item(1, 16, 0, 47.3980001, 8.5460003, 15),
               item(2, 16, 0, 47.3985, 8.5450, 20), item(3, 177, 1, 0, 0, 0, frame=2),
               item(4, 21, 0, 47.397742, 8.545594, 0)]
    square = [(47.3970, 8.5440), (47.3992, 8.5440), (47.3992, 8.5470), (47.3970, 8.5470)]
    triangle = [(47.3973, 8.5462), (47.3975, 8.5466), (47.3972, 8.5466)]
    fence = [item(i, 5001, 4, lat, lon) for i, (lat, lon) in enumerate(square)]
    fence += [item(4 + i, 5002, 3, lat, lon) for i, (lat, lon) in enumerate(triangle)]
    fence.append(item(7, 5004, 15, 47.3982, 8.5452))
    rally = [item(0, 5100, 0, 47.3975, 8.5445, 20), item(1, 5100, 0, 47.3988, 8.5465, 20)]
    write_plan(Plan(mission, fence, rally, home=HOME), str(path))
    return path


def signed_board(tmp_path, setup_links=None):
    """A boards folder holding unix_signed.py -> MICROPYPATH for the vehicle (or mavctl sim)."""
    boards = tmp_path / "boards"
    boards.mkdir(exist_ok=True)
    (boards / "unix_signed.py").write_text(SIGNED_BOARD % (setup_links,))
    return os.pathsep.join([str(boards), FIRMWARE, os.path.join(ROOT, "boards"), ".frozen"])


class Sim:
    """`mavctl sim` as a process; .device is the pty it printed for the ground station."""

    def __init__(self, *args, env=None):
        self.proc = subprocess.Popen([PYTHON, "-m", "mavctl", "sim"] + [str(a) for a in args], cwd=ROOT,
                                     stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                     env=env)
        self.banner = self.proc.stdout.readline()
        assert self.banner.startswith("mavctl sim: the "), self.banner + self.rest()
        self.device = self.banner.split()[-1]
        assert self.device.startswith("/dev/pts/"), self.banner

    def rest(self, timeout=20):
        try:
            out, _ = self.proc.communicate(timeout=timeout)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            out, _ = self.proc.communicate()
        return out or ""

    def stop(self, sig=signal.SIGINT, timeout=20):
        """Send sig -> (exit status, what it printed after the banner)."""
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
        out = self.rest(timeout)
        return self.proc.returncode, out

    def link(self):
        return "serial:%s:57600" % self.device


def processes_naming(text):
    """Pids of running processes whose command line holds text."""
    found = []
    for pid in os.listdir("/proc"):
        if not pid.isdigit():
            continue
        try:
            with open("/proc/%s/cmdline" % pid, "rb") as f:
                if text.encode() in f.read():
                    found.append(int(pid))
        except OSError:
            pass
    return found


def wait_until(cond, timeout=10.0):
    deadline = time.time() + timeout
    while time.time() < deadline:
        if cond():
            return True
        time.sleep(0.1)
    return cond()
