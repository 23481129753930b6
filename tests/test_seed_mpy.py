"""The seed's remaining messages and commands delivered under heap_lock() (tests/mpy/
seed_steady.py): nothing requested from the heap, counted with mem_total() and locked,
in today's message set and in the seed's."""
import os

import pytest

from conftest import ROOT, run_mpy

MPY = os.path.join(ROOT, "tests", "mpy")


@pytest.mark.parametrize("dialect", ["common", "seed2012"])
def test_delivery_under_heap_lock(dialect):
    # seed: NAMED_VALUE_FLOAT, NAMED_VALUE_INT, DEBUG, DEBUG_VECT, MEMORY_VECT, STATE_CORRECTION
    # seed: SET_GPS_GLOBAL_ORIGIN, SAFETY_SET_ALLOWED_AREA, AUTH_KEY, LOCAL_POSITION_NED_SYSTEM_GLOBAL_OFFSET
    # seed: LOCAL_POSITION_SETPOINT, GLOBAL_POSITION_SETPOINT_INT, ROLL_PITCH_YAW_THRUST_SETPOINT
    # seed: ROLL_PITCH_YAW_SPEED_THRUST_SETPOINT, ROLL_PITCH_YAW_RATES_THRUST_SETPOINT
    r = run_mpy(os.path.join(MPY, "seed_steady.py"), dialect, 3, path=[MPY], timeout=120)
    assert r.returncode == 0, r.stdout + r.stderr
    line = r.stdout.strip().splitlines()[-1]
    assert line.startswith("OK"), line
    f = dict(kv.split("=") for kv in line.split()[1:])
    assert int(f["requested"]) == 0
    assert int(f["acks"]) == 6 * 17  # every command answered, 17 a round
    assert f["origin"] == "1" and f["area"] == "1"
    assert int(f["gps_origin_sent"]) >= 6 and int(f["area_sent"]) >= 6  # on change and on request
    assert int(f["debug"]) == 6 * 5 + 3 * 5  # all five debug messages handed over, every round
    assert int(f["state_corrections"]) == (9 if dialect == "seed2012" else 0)
    assert f["servo6"] == "1800"
    assert f["auth_sent"] == "0"  # never over an unsigned link
    assert (f["item_in"], f["item_out"]) == ("0", "10")  # MAV_MISSION_INVALID_PARAM5_X
