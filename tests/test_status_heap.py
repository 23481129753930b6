"""Status and command handling allocate nothing in steady state (MicroPython: no heap
requests counted by mem_total, then the same rounds under heap_lock),
with the viper kernels and the portable ones, alone and with the parameter service."""
import os

import pytest

from conftest import ROOT, run_mpy

MPY = os.path.join(ROOT, "tests", "mpy")
SCRIPT = os.path.join(MPY, "status_steady.py")


@pytest.mark.parametrize("services", ["status,commands", "status,params,commands"])
@pytest.mark.parametrize("portable", [False, True])
def test_steady_state_under_heap_lock(tmp_path, services, portable):
    if portable:
        os.environ["MAVSTACK_PORTABLE"] = "1"
    try:
        r = run_mpy(SCRIPT, services, str(tmp_path), 6000, path=[MPY], timeout=120)
    finally:
        os.environ.pop("MAVSTACK_PORTABLE", None)
    assert r.returncode == 0, r.stdout + r.stderr
    line = r.stdout.strip().splitlines()[-1]
    assert line.startswith("OK"), line
    figures = dict(kv.split("=") for kv in line.split()[1:])
    assert int(figures["requested"]) == 0  # the same rounds unlocked, counted by mem_total
    assert int(figures["heartbeats"]) == 6  # one a simulated second
    assert int(figures["acks"]) == 96  # 120 frames of the burst, 8 of every 10 are commands
    assert int(figures["unsupported"]) >= 12
    assert int(figures["version"]) >= 12 and int(figures["ping"]) >= 12
    assert int(figures["errors_comm"]) >= 12  # the corrupted frames, counted
    assert int(figures["text"]) >= 8
