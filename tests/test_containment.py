"""No bug in a handler ends the vehicle: a fault is contained, counted and reported.

On MicroPython (tests/mpy/faults_steady.py, viper and portable kernels; test_mcu.py runs it
on both emulated boards): a handler raising on one message id and a tick raising every 100th
call, under heap_lock, while parameters, missions and streams go on. And the unix vehicle
as `make run` starts it (its simulator in), with a faulty handler added by a board of this
test's: a ground station keeps reading parameters, uploading and downloading missions and
getting its streams, and is told (STATUSTEXT at ERROR, at most one every 5 s; SYS_STATUS
errors_count2); the process prints no traceback.
"""
import os
import time

import pytest

from conftest import ROOT, recv, run_mpy
from mission_gcs import MissionClient, plan, same

MPY = os.path.join(ROOT, "tests", "mpy")

FAULTY_BOARD = '''"""The unix vehicle with a bug: a handler of NAMED_VALUE_INT that raises (a test's board)."""
from unix import *  # noqa: F401,F403
import unix

NAME = "unix_faulty"


class Faulty:
    NAME = "faulty"
    CLOCK = False

    def attach(self, ep):
        ep.on(252, self.handle)

    def handle(self, link, p):
        return {}["no such key"]  # a KeyError, as a real bug would raise


def application(ep):
    app = unix.application(ep)
    ep.add(Faulty())
    return app
'''


@pytest.mark.parametrize("portable", [False, True])
def test_faults_contained_on_micropython_heap_locked(portable):
    env = dict(os.environ, MAVSTACK_PORTABLE="1") if portable else None
    old = dict(os.environ)
    if env:
        os.environ.update(env)
    try:
        r = run_mpy(os.path.join(MPY, "faults_steady.py"), 200, path=[MPY], timeout=300)
    finally:
        os.environ.clear()
        os.environ.update(old)
    assert r.returncode == 0, r.stdout + r.stderr
    line = r.stdout.strip().splitlines()[-1]
    assert line.startswith("ok"), r.stdout
    assert " requested=0" in line + " "
    assert "Traceback" not in r.stdout + r.stderr
    assert "mavstack: Fault: msg 252: ValueError" in r.stdout
    assert "mavstack: Fault: tick faulty: RuntimeError" in r.stdout


def test_the_unix_vehicle_survives_a_faulty_handler(vehicle, tmp_path):
    (tmp_path / "unix_faulty.py").write_text(FAULTY_BOARD)
    path = os.pathsep.join([str(tmp_path), os.path.join(ROOT, "firmware"), os.path.join(ROOT, "boards"), ".frozen"])
    v = vehicle(board="unix_faulty", env={"MICROPYPATH": path})
    m = v.gcs()
    texts = []
    t0 = time.time()
    for i in range(60):  # 6 s of a faulty message at 10 Hz
        m.mav.named_value_int_send(0, b"bug", i)
        m.mav.heartbeat_send(6, 8, 0, 0, 0)
        msg = recv(m, "STATUSTEXT", 0.1, lambda s: s.text.startswith("Fault:"))
        if msg is not None:
            texts.append((time.time(), msg))
    # The original report: one NAMED_VALUE_FLOAT whose name is not UTF-8 ended the vehicle.
    m.mav.named_value_float_send(0, b"\xff\xfe\xc3abc", 1.0)
    assert texts, "no fault reported"
    assert all(t.severity == 3 and t.text.startswith("Fault: msg 252: KeyError") for _, t in texts), texts
    assert len(texts) <= 2 and (len(texts) < 2 or texts[1][0] - texts[0][0] > 4), texts  # 1 per 5 s
    status = recv(m, "SYS_STATUS", 3)
    assert status is not None and status.errors_count2 >= 50
    # Everything else goes on: parameters, missions, streams.
    m.mav.param_request_read_send(1, 1, b"WP_SPEED", -1)
    assert recv(m, "PARAM_VALUE", 5, lambda p: p.param_id == "WP_SPEED") is not None
    c = MissionClient(m)
    assert c.upload(plan(20)) == 0
    assert same(c.download(), plan(20))
    assert recv(m, "ATTITUDE", 3) is not None
    v.check_alive()
    v.stop()
    out = v.output()
    assert "Traceback" not in out and "mavstack: Fault: msg 252: KeyError" in out, out
    assert time.time() - t0 < 60


def test_what_the_board_fuzz_found_is_answered_heap_locked():
    # tests/mpy/fuzz_found.py: ints of 2^30 and more, huge floats, refusals' texts; the
    # emulated boards run it too (test_mcu.py), where such ints are heap objects.
    r = run_mpy(os.path.join(MPY, "fuzz_found.py"), path=[MPY], timeout=120)
    assert r.returncode == 0, r.stdout + r.stderr
    assert r.stdout.strip().splitlines()[-1].startswith("ok"), r.stdout
