"""Pilot inputs allocate nothing in steady state (MicroPython: no heap requests counted
by mem_total, then the same rounds under heap_lock): every input kind arriving, the
accessors read, inputs lost and regained, setpoint echoes and HIL_CONTROLS streamed;
in today's message set and the seed's, with the viper kernels and the portable ones,
and under operator control with a second station refused."""
import os

import pytest

from conftest import ROOT, run_mpy

MPY = os.path.join(ROOT, "tests", "mpy")
SCRIPT = os.path.join(MPY, "inputs_steady.py")
ROUNDS = 3000


def _figures(r):
    assert r.returncode == 0, r.stdout + r.stderr
    line = r.stdout.strip().splitlines()[-1]
    assert line.startswith("OK"), line
    return dict((k, int(v)) for k, v in (kv.split("=") for kv in line.split()[1:]))


@pytest.mark.parametrize("portable", [False, True])
@pytest.mark.parametrize("dialect", ["common", "seed2012"])
def test_inputs_steady_under_heap_lock(dialect, portable):
    # seed: MANUAL_SETPOINT, HIL_STATE, HIL_RC_INPUTS_RAW, GLOBAL_VISION_POSITION_ESTIMATE
    # seed: VISION_POSITION_ESTIMATE, VISION_SPEED_ESTIMATE, VICON_POSITION_ESTIMATE
    # seed: SET_ROLL_PITCH_YAW_SPEED_THRUST, SET_QUAD_MOTORS_SETPOINT, SETPOINT_6DOF
    # seed: SET_QUAD_SWARM_ROLL_PITCH_YAW_THRUST, SET_QUAD_SWARM_LED_ROLL_PITCH_YAW_THRUST
    # (each delivered into its record, read by every accessor, counted and heap-locked)
    env = os.environ
    if portable:
        env["MAVSTACK_PORTABLE"] = "1"
    try:
        r = run_mpy(SCRIPT, str(ROUNDS), dialect, path=[MPY], timeout=120)
    finally:
        env.pop("MAVSTACK_PORTABLE", None)
    f = _figures(r)
    assert f["requested"] == 0
    assert f["delivered"] >= 1000  # every input but the one for another vehicle
    assert f["lost"] >= 6 * 10  # every kind, at each of the six pauses
    assert f["echoes"] >= 100 and f["hil"] >= 100  # target slots and HIL_CONTROLS streamed
    assert f["refused"] == 1


def test_inputs_under_operator_control():
    f = _figures(run_mpy(SCRIPT, str(ROUNDS), "common", "operator", path=[MPY], timeout=120))
    assert f["requested"] == 0 and f["refused"] == 1


def test_inputs_inside_a_safety_area():
    # Every position setpoint checked against the area (geography.check_target), on the
    # counted and the heap-locked path; the global one is inside it and taken.
    f = _figures(run_mpy(SCRIPT, str(ROUNDS), "common", "area", path=[MPY], timeout=120))
    assert f["requested"] == 0 and f["delivered"] >= 1000
