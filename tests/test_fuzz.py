"""The fuzzer (tests/fuzz) for FUZZ_SECONDS (default 60): the unix port's vehicles (both
dialects, the make-run board with signing and its simulator) fuzzed over UDP, with real
exchanges in between and the invariants checked every couple of seconds; the in-process
engine on CPython for a short while too. `make fuzz SECONDS=N` runs it longer. Also: the
seed frames are valid, the checks catch what they are there to catch, and the faults
the fuzz found stay fixed."""
import json
import os
import random
import struct
import subprocess
import sys
import time

import pytest

from conftest import PYTHON, ROOT

sys.path.insert(0, os.path.join(ROOT, "tests"))
from fuzz import frames, invariants, wire  # noqa: E402
from fuzz.rig import FuzzVehicle  # noqa: E402

FUZZ_SECONDS = float(os.environ.get("FUZZ_SECONDS", "60"))


def test_corpus_is_every_message_valid():
    from pymavlink.dialects.v20 import common as mav

    corpus = frames.corpus(random.Random(3))
    dec = mav.MAVLink(None)
    dec.robust_parsing = True
    got = dec.parse_buffer(b"".join(corpus))
    assert len(got) == len(corpus)
    assert not [m for m in got if m.get_type() == "BAD_DATA"]
    assert {m.get_msgId() for m in got} == set(frames.IDS)


def test_exchanges_and_checks_on_a_fresh_vehicle(tmp_path):
    v = FuzzVehicle(tmp_path / "st")
    v.param_exchange()
    v.command_exchange()
    v.mission_exchange(4)
    v.quiesce(3000)
    invariants.check(v, invariants.snapshot(v.storage))


def test_checks_see_a_stored_value_that_is_not_in_force(tmp_path):
    v = FuzzVehicle(tmp_path / "st")
    v.param_exchange()
    v.quiesce(3000)  # saved
    stored = invariants.snapshot(v.storage)
    invariants.check(v, stored)
    v.params.put(v.params.index("SIM_SPEED"), 29.5)  # in force, not saved, not marked dirty
    with pytest.raises(invariants.Broken, match="SIM_SPEED"):
        invariants.check(v, stored)


def test_checks_see_a_plan_that_is_not_the_stored_one(tmp_path):
    v = FuzzVehicle(tmp_path / "st")
    v.mission_exchange(2)
    with open(os.path.join(v.storage, "mission.0"), "r+b") as f:
        f.write(b"\xff" * 16)
    with open(os.path.join(v.storage, "mission.1"), "r+b") as f:
        f.write(b"\xff" * 16)
    with pytest.raises(invariants.Broken, match="mission plan stored"):
        invariants.check(v, invariants.snapshot(v.storage))


def _run(tmp_path, seconds, *args):
    report = tmp_path / "report.json"
    proc = subprocess.run([PYTHON, os.path.join(ROOT, "tests", "fuzz", "engine.py"), "--seconds", str(seconds),
                           "--report", str(report)] + list(args),
                          cwd=str(tmp_path), capture_output=True, text=True, timeout=seconds + 300)
    tail = (proc.stdout[-6000:] + "\n" + proc.stderr[-6000:])
    assert proc.returncode == 0, tail
    r = json.loads(report.read_text())
    print(r)
    return r


def test_fuzz(tmp_path):
    # The MicroPython vehicles; the saved corpus is read, not grown (make fuzz grows it).
    r = _run(tmp_path, FUZZ_SECONDS, "--no-grow")
    assert r["engine"] == "micropython"
    assert r["frames"] >= 1000 * FUZZ_SECONDS, r  # (5,000/s and more alone: make bench)
    assert min(r["frames_by_dialect"].get(d, 0) for d in ("common", "seed2012")) > 0, r
    assert r["exchanges"] >= max(1, FUZZ_SECONDS // 10), r
    assert r["foreign_batches"] >= 1, r
    assert r["signed_frames"] >= 1, r
    assert r["faults"] == {}, r  # each one the fuzz found was a bug, fixed (tests below)


def test_fuzz_in_process(tmp_path):
    r = _run(tmp_path, 10, "--engine", "mutate")
    assert r["frames"] >= 500 and r["exchanges"] >= 1, r


def test_checks_see_a_parameter_in_force_that_is_not_stored(tmp_path):
    import unix

    v = FuzzVehicle(tmp_path / "st", whole=True)
    v.param_exchange()
    v.quiesce(3000)  # saved
    p = v.params
    params = {i: (p.name(i).encode(), bytes(p._values[4 * i:4 * i + 4]), p.type(i)) for i in range(p.count)}
    plans = [(s.count, s.plan_id) for s in v.missions.stores]
    held = invariants.stored(v.storage, unix)
    invariants.in_force(unix, held, params, plans)
    i = p.index("SIM_SPEED")
    params[i] = (params[i][0], struct.pack("<f", 29.5), params[i][2])
    with pytest.raises(invariants.Broken, match="SIM_SPEED"):
        invariants.in_force(unix, held, params, plans)
    plans[0] = (plans[0][0] + 1, plans[0][1])
    with pytest.raises(invariants.Broken, match="mission plan in force"):
        invariants.in_force(unix, dict(held, params=None), params, plans)


def test_checks_see_a_fault_never_reported():
    from fuzz import live

    class Vehicle:
        starts = 1
        faults = []

    class T:
        vehicle = Vehicle()
        fault_state = [1, 0, 0.0, []]

    t = T()
    fz = live.Live.__new__(live.Live)
    counts = {"errors_count2": 0, "errors_count3": 0, "errors_count4": 0}
    fz.fault_check(t, counts)
    fz.fault_check(t, dict(counts, errors_count2=3))  # counted: a report is owed
    t.vehicle.faults.append((time.time(), "Fault: msg 5: KeyError (3)"))
    fz.fault_check(t, dict(counts, errors_count2=3))  # told
    assert t.fault_state[3] == []
    fz.fault_check(t, dict(counts, errors_count2=4, errors_count3=1))
    t.fault_state[3][0] = (t.fault_state[3][0][0], time.time() - 1)  # and never told since
    with pytest.raises(invariants.Broken, match="never reported"):
        fz.fault_check(t, dict(counts, errors_count2=4, errors_count3=1))


def test_sharp_turn_in_auto_keeps_the_vehicle_running(tmp_path):
    # Found by the fuzzer: the simulator turns to a new waypoint's bearing at once, and the
    # yaw rate it published (~157 rad/s) overflowed SCALED_IMU's int16 (struct.error out
    # of app.tick stops the vehicle).
    v = FuzzVehicle(tmp_path / "st")
    north, south = 473977420 + 20000, 473977420 - 20000  # 220 m either side of home
    v.upload([(0, 3, 16, 0, 1, 0.0, 2.0, 0.0, 0.0, north, 85455940, 20.0),
              (1, 3, 16, 0, 1, 0.0, 2.0, 0.0, 0.0, south, 85455940, 20.0)])
    v.params.set("SIM_SPEED", 30.0)
    status = v.ep.services["status"]
    from mavstack.services.status import MODE_AUTO

    status.armed = True
    status.mode |= MODE_AUTO
    for _ in range(3000):  # 60 s: out to the first waypoint, then the turn back
        v.bench.run(1, 20)


def test_debug_values_keep_a_bounded_number_of_names(tmp_path):
    # Found by the fuzzer (the MicroPython engine, seed2012): the simulator kept every debug
    # value by its name, and names are whatever arrives; a few thousand DEBUG_VECTs of
    # random names took the unix vehicle's heap (MemoryError in the handler, contained).
    from sim import seed as sim_seed

    v = FuzzVehicle(tmp_path / "st", dialect="seed2012", whole=True)
    lay = frames.layouts("seed2012")[250]  # DEBUG_VECT
    rng = random.Random(5)
    for i in range(300):
        p = bytearray(rng.randbytes(lay.len2))
        frames.put(p, lay, "name", b"v%d" % i)
        v.feed(frames.encode(250, p, 255, 190, i, 2, table=frames.layouts("seed2012")))
        v.poll(1, 1)
    values = v.ep.services["debug"].values
    assert len(values) == sim_seed.DEBUG_NAMES and "v299" in values


def test_targets_at_infinity_are_outside_the_allowed_area(tmp_path):
    # Found by the fuzzer (the MicroPython engine): NAV_LAND, NAV_LOITER_UNLIM and
    # DO_REPOSITION with an infinite param5 or param6 (NaN means "here"; infinity is no
    # place) raised OverflowError in the allowed-area check (int of an infinity).
    inf = float("inf")
    v = FuzzVehicle(tmp_path / "st", whole=True)
    geo = v.ep.services["geography"]
    v.send("safety_set_allowed_area", 1, 1, 6, 47.0, 8.0, -100.0, 48.0, 9.0, 3000.0)  # global, relative alt
    v.poll(3)
    assert geo.area_set and not geo.area_local
    assert geo.allows_degrees(47.5, 8.5, 10.0)
    for lat, lon, alt in ((inf, 8.5, None), (47.5, -inf, None), (47.5, 8.5, inf), (1e30, 8.5, None),
                          (47.5, 8.5, 1e30), (float("nan"), 8.5, None)):
        assert not geo.allows_degrees(lat, lon, alt), (lat, lon, alt)
    v.send("safety_set_allowed_area", 1, 1, 1, -50.0, -50.0, -100.0, 50.0, 50.0, 10.0)  # local NED
    v.poll(3)
    assert geo.area_local and geo.allows_local(1.0, 2.0, -3.0)
    assert not geo.allows_local(inf, 2.0) and not geo.allows_local(1.0, 2.0, -inf) and not geo.allows_local(1e30, 0.0)


def test_offboard_setpoints_at_infinity_are_no_demand(tmp_path):
    # Found by the fuzzer (the MicroPython engine): a SET_POSITION_TARGET_LOCAL_NED with an
    # infinite north offset, flown to in GUIDED, made the simulator's latitude NaN, and
    # every tick after raised ValueError publishing it (a contained application fault,
    # over and over). Setpoints off the globe, infinite or NaN are no demand: it holds.
    inf, nan = float("inf"), float("nan")
    v = FuzzVehicle(tmp_path / "st", whole=True)
    pilot = v.bench.app.pilot.inputs
    position_only = 0xDF8  # type_mask: velocity, acceleration, yaw and yaw rate ignored

    def demand(x, y, z, frame=1):
        v.send("set_position_target_local_ned", 0, 1, 1, frame, position_only, x, y, z, 0, 0, 0, 0, 0, 0, 0, 0)
        v.poll(2)
        return pilot.demand("OFFBOARD", 0.02)

    assert demand(10.0, 5.0, -20.0)[0] == "pos"
    for x, y, z in ((inf, 0.0, -10.0), (0.0, -inf, -10.0), (0.0, 0.0, inf), (1e30, 0.0, -10.0),
                    (nan, 0.0, -10.0), (0.0, 1e38, -10.0)):
        assert demand(x, y, z) is None, (x, y, z)
    v.send("set_position_target_global_int", 0, 1, 1, 6, position_only, 2000000000, 85455940, 20.0,
           0, 0, 0, 0, 0, 0, 0, 0)  # 200 degrees of latitude
    v.poll(2)
    assert pilot.demand("OFFBOARD", 0.02) is None

    # Found by a 10-minute make fuzz: a velocity setpoint with an infinite yaw (not its
    # rate) made math.sin raise ValueError on every tick. It turns nowhere.
    velocity_and_yaw = 0x9C7  # type_mask: position, acceleration and yaw rate ignored
    for yaw in (inf, -inf):
        v.send("set_position_target_local_ned", 0, 1, 1, 1, velocity_and_yaw, 0, 0, 0, 1.0, 0.5, 0, 0, 0, 0, yaw, 0)
        v.poll(2)
        got = pilot.demand("OFFBOARD", 0.02)
        assert got is not None and got[0] == "vel" and got[4] == 0.0, got


def test_the_simulator_above_44_km_keeps_publishing(tmp_path):
    # Found by a 10-minute make fuzz: a home set 60 km up (DO_SET_HOME takes altitudes to
    # 2,000 km) is the ground the simulated vehicle stands on; the barometer's formula
    # then raised a negative number to a fractional power, a complex pressure, and every
    # tick raised TypeError publishing it (106 reports). There is no air up there.
    v = FuzzVehicle(tmp_path / "st", whole=True)
    v.poll(100, 10)
    v.send("heartbeat", 6, 8, 0, 0, 0)
    v.send("command_long", 1, 1, 179, 0, 0, 0, 0, 0, 47.3, 8.5, 60000.0)
    v.poll(10, 10)
    sim = v.bench.app
    sim.alt = sim.pilot.mission.ground()  # where a landing or a disarm puts it
    assert sim.alt == 60000.0
    v.poll(200, 10)
    assert sum(v.ep.faults.counts) == 0, v.ep.faults.counts


BOARD_HEAP_LOCKED = """
import micropython
from harness import Bench
import qemu_m3
b = Bench(services=qemu_m3.SERVICES, board=qemu_m3, storage="ram", ram_storage_kb=64)
frames = [bytes.fromhex(h) for h in %r]
b.run(20, 10)
micropython.heap_lock()
for i in range(len(frames)):
    b.send_raw(frames[i], len(frames[i]))
    b.run(2, 5)
micropython.heap_unlock()
print("faults", b.ep.faults.counts)
"""


def test_board_paths_found_allocating_under_heap_lock():
    # Found by fuzzing the emulated Cortex-M3 board (test_mcu_fuzz.py), heap locked: a
    # MISSION_SET_CURRENT the vehicle cannot follow said so in a STATUSTEXT given as str,
    # which the text queue encodes (allocates): MemoryError, every time. Checked here on
    # the unix port with the board's own profile and services, heap locked.
    from conftest import run_mpy

    gcs = wire.Speaker((255, 190), frames.LAYOUTS, wire.Signing())
    sent = [gcs.frame("MISSION_SET_CURRENT", seq=4, target_system=1, target_component=1).hex()]
    r = run_mpy(BOARD_HEAP_LOCKED % (sent,), path=[os.path.join(ROOT, "tests", "mpy"), os.path.join(ROOT, "boards")])
    assert r.returncode == 0 and "faults [0, 0, 0, 0, 0, 0]" in r.stdout, r.stdout + r.stderr
