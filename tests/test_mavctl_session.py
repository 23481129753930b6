"""The README's first session with the installed `mavctl`, over a real serial line: `mavctl
sim` starts the simulated vehicle on a pty pair, then parameters (list, save, load), a
QGroundControl .plan up and back, arm and disarm, all with --connect serial:DEVICE."""
import json
import os
import signal
import subprocess
import time

from conftest import ROOT
from plan_samples import qgc_plan, same_numbers

MAVCTL = os.path.join(ROOT, ".venv", "bin", "mavctl")


def run(*args, timeout=60):
    r = subprocess.run([MAVCTL] + [str(a) for a in args], capture_output=True, text=True,
                       timeout=timeout, cwd=ROOT)
    assert "Traceback" not in r.stderr, r.stderr
    assert r.returncode == 0, (args, r.returncode, r.stdout, r.stderr)
    return r.stdout


def start_sim(tmp_path):
    """`mavctl sim` -> (process, the device it printed)."""
    proc = subprocess.Popen([MAVCTL, "sim", "--storage", tmp_path / "storage"], cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline:
        line = proc.stdout.readline()
        if not line:
            break
        if " vehicle on " in line:
            return proc, line.split(" vehicle on ")[1].strip()
    proc.kill()
    raise AssertionError("mavctl sim printed no device: %s" % proc.stderr.read())


def test_first_session_over_the_sim_pty(tmp_path):
    proc, device = start_sim(tmp_path)
    try:
        link = ("--connect", "serial:%s" % device)
        listing = run(*link, "params", "list").splitlines()
        assert any(line.split()[0] == "WP_SPEED" for line in listing)
        run(*link, "params", "save", tmp_path / "before.params")
        run(*link, "params", "set", "WP_SPEED", "7.5")
        out = run(*link, "params", "load", tmp_path / "before.params")
        assert out.splitlines()[-1].endswith(": 1 changed, %d unchanged, 0 refused" % (len(listing) - 1))

        plan = qgc_plan()
        (tmp_path / "route.plan").write_text(json.dumps(plan))
        assert "uploaded 5 mission, 9 fence, 2 rally items" in run(*link, "mission", "upload",
                                                                   tmp_path / "route.plan")
        run(*link, "mission", "download", tmp_path / "back.plan")
        back = json.loads((tmp_path / "back.plan").read_text())
        same_numbers(plan["mission"]["items"], back["mission"]["items"])
        same_numbers(plan["geoFence"], back["geoFence"])
        same_numbers(plan["rallyPoints"], back["rallyPoints"])

        assert "MAV_RESULT_ACCEPTED" in run(*link, "arm")
        assert "MAV_RESULT_ACCEPTED" in run(*link, "disarm")
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            status = proc.wait(20)
        except subprocess.TimeoutExpired:
            proc.kill()
            raise
    assert status == 0, proc.stderr.read()
