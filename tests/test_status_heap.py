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
    assert int(figures["acks"]) == 88  # 120 frames of the burst, 11 of every 15 are commands
    assert int(figures["unsupported"]) >= 16  # an unknown command and a standard mode it has not
    assert int(figures["version"]) >= 8 and int(figures["ping"]) >= 8  # once a round of the burst
    assert int(figures["errors_comm"]) >= 8  # the corrupted frames, counted
    assert int(figures["text"]) >= 8


@pytest.mark.parametrize("portable", [False, True])
def test_budget_refusals_allocate_nothing(tmp_path, portable):
    # The link budgeted as a 57600 baud radio and a station flooding PINGs: frames the
    # budget refuses (their sequence numbers given back) are on the counted path too.
    if portable:
        os.environ["MAVSTACK_PORTABLE"] = "1"
    try:
        r = run_mpy(SCRIPT, "status,params,commands", str(tmp_path), 6000, "radio", path=[MPY], timeout=120)
    finally:
        os.environ.pop("MAVSTACK_PORTABLE", None)
    assert r.returncode == 0, r.stdout + r.stderr
    line = r.stdout.strip().splitlines()[-1]
    figures = dict(kv.split("=") for kv in line.split()[1:])
    assert line.startswith("OK") and int(figures["requested"]) == 0, line
    assert int(figures["held"]) > 1000  # the flood's answers beyond the budget
    assert int(figures["heartbeats"]) == 6  # HEARTBEAT keeps its 1 Hz all the same
    assert int(figures["acks"]) >= 80  # the other station's commands are still answered


def test_udpin_peers_allocate_nothing(tmp_path):
    # A real udpin socket with two ground stations on sockets of their own: reads from
    # each peer, the valid-frame notice, and every frame written to both.
    from conftest import free_udp_port

    r = run_mpy(SCRIPT, "status,commands", str(tmp_path), 6000, "udpin", free_udp_port(), path=[MPY], timeout=120)
    assert r.returncode == 0, r.stdout + r.stderr
    line = r.stdout.strip().splitlines()[-1]
    figures = dict(kv.split("=") for kv in line.split()[1:])
    assert line.startswith("OK") and int(figures["requested"]) == 0, line
    assert int(figures["udp_a"]) > 10000 and int(figures["udp_b"]) > 10000  # both hear the vehicle
