"""Every board profile builds a working vehicle (on the unix port, its links replaced by
UDP), and says how much heap it holds; the unix vehicle stays within its RAM budget."""
import ast
import os
import re
import subprocess
import sys

import pytest

from conftest import MICROPYTHON, ROOT

sys.path.insert(0, os.path.join(ROOT, "boards"))


@pytest.mark.parametrize("board", ["unix", "unix_signed", "pico", "esp32", "pyboard", "qemu_m3", "qemu_m0",
                                   "unix_peripheral", "unix_camera", "qemu_m0_rangefinder"])
def test_profile_builds_a_vehicle_and_reports_its_heap(vehicle, board):
    # The emulated boards lock the heap once up; the unix port's UDP links allocate for
    # each new peer, so here they run unlocked (tests/test_mcu_vehicle.py runs them locked).
    profile = __import__(board)
    args = ["--set", "heap_lock=0"] if board.startswith("qemu") else []
    if getattr(profile, "SYSID", 1) == "follow":
        args += ["--sysid", "3"]  # a peripheral with its system id given: it speaks at once
    v = vehicle(board=board, args=args)
    m = v.gcs()
    hb = m.recv_match(type="HEARTBEAT", blocking=True, timeout=5)
    assert hb is not None and hb.type == profile.MAV_TYPE
    assert hb.get_srcComponent() == getattr(profile, "COMPID", 1)
    assert (hb.autopilot == 8) == ("peripheral" in profile.SERVICES)  # MAV_AUTOPILOT_INVALID
    v.stop()
    ready = re.search(r"mavstack: (\w+) ready, (\d+) KB of heap in use \(budget (\d+) KB\)", v.output())
    assert ready, v.output()
    assert ready.group(1) == board and int(ready.group(3)) == profile.RAM_BUDGET >> 10
    if board == "unix":
        assert int(ready.group(2)) <= int(ready.group(3))


@pytest.mark.parametrize("services, line", [
    (("status", "calibration"), "service calibration needs commands: add it to SERVICES, before calibration"),
    (("status", "calibration", "commands"), "service calibration needs commands: list it before calibration in SERVICES"),
    (("status", "commands", "streams", "inputs"), "service streams comes after inputs: list inputs before it in SERVICES"),
    (("status", "params", "peripheral"), "service peripheral replaces status: list one of them in SERVICES"),
])
def test_services_out_of_order_are_named_in_one_line(tmp_path, services, line):
    """A board whose SERVICES miss or misorder what a service declares (NEEDS, AFTER) does
    not start: one line names the service and what it needs; no traceback."""
    (tmp_path / "bad_board.py").write_text(
        "from unix import *  # noqa\nNAME = 'bad_board'\nSERVICES = %r\n" % (services,))
    env = dict(os.environ, MICROPYPATH="%s:%s:.frozen" % (tmp_path, os.path.join(ROOT, "boards")))
    r = subprocess.run([MICROPYTHON, os.path.join(ROOT, "firmware", "main.py"), "--board", "bad_board",
                        "--link", "udpout:127.0.0.1:9", "--storage", str(tmp_path / "st")],
                       capture_output=True, text=True, timeout=60, env=env)
    assert r.returncode == 1, (r.stdout, r.stderr)
    assert r.stdout.strip().splitlines()[-1] == "mavstack: board bad_board: " + line, r.stdout
    assert "Traceback" not in r.stdout + r.stderr


def test_follow_without_the_peripheral_service_is_refused(tmp_path):
    """SYSID "follow" is the peripheral service's: a board without it would never speak."""
    (tmp_path / "bad_board.py").write_text(
        "from unix import *  # noqa\nNAME = 'bad_board'\nSYSID = 'follow'\nSERVICES = ('status', 'params')\n")
    env = dict(os.environ, MICROPYPATH="%s:%s:.frozen" % (tmp_path, os.path.join(ROOT, "boards")))
    r = subprocess.run([MICROPYTHON, os.path.join(ROOT, "firmware", "main.py"), "--board", "bad_board",
                        "--link", "udpout:127.0.0.1:9", "--storage", str(tmp_path / "st")],
                       capture_output=True, text=True, timeout=60, env=env)
    assert r.returncode == 1, (r.stdout, r.stderr)
    assert r.stdout.strip().splitlines()[-1] == ('mavstack: board bad_board: SYSID "follow" needs the '
                                                 'peripheral service: add it to SERVICES'), r.stdout


def test_every_service_declares_the_services_it_looks_up():
    """A service (and its package's helpers) names every other service it reaches through
    ep.services in NEEDS, AFTER or USES: dependencies are said, not found out."""
    services = os.path.join(ROOT, "firmware", "mavstack", "services")
    for entry in sorted(os.listdir(services)):
        path = os.path.join(services, entry)
        files = ([os.path.join(path, f) for f in os.listdir(path) if f.endswith(".py")] if os.path.isdir(path)
                 else [path] if entry.endswith(".py") and entry != "__init__.py" else [])
        if not files:
            continue
        name = entry[:-3] if entry.endswith(".py") else entry
        main = path if entry.endswith(".py") else os.path.join(path, "__init__.py")
        declared = set()
        with open(main) as f:
            for node in ast.parse(f.read()).body:
                if isinstance(node, ast.Assign) and node.targets[0].id in ("NEEDS", "AFTER", "USES"):
                    declared |= set(ast.literal_eval(node.value))
        used = set()
        for file in files:
            with open(file) as f:
                code = f.read()
            tree = ast.parse(code)
            for node in ast.walk(tree):  # ep.services.get("x"), ep.services["x"], "x" in ep.services
                if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "get" \
                        and isinstance(node.func.value, ast.Attribute) and node.func.value.attr == "services":
                    used.add(node.args[0].value)
                elif isinstance(node, ast.Subscript) and isinstance(node.value, ast.Attribute) \
                        and node.value.attr == "services" and isinstance(node.slice, ast.Constant):
                    used.add(node.slice.value)
                elif isinstance(node, ast.Compare) and isinstance(node.left, ast.Constant) \
                        and isinstance(node.comparators[0], ast.Attribute) and node.comparators[0].attr == "services":
                    used.add(node.left.value)
        used.discard(name)
        assert used <= declared, "%s looks up %s without declaring it" % (name, sorted(used - declared))
