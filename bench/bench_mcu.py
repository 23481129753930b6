"""The emulated boards' heap and flash figures (mcu/firmware.py, tests/test_mcu_vehicle.py).

  heap_used_kb_m3/_m0   heap the whole vehicle holds (100 params, a 500-item mission
                        store, 10 streams, signing) once up and after the ground-station
                        test: the heap is locked in between, so the two are one figure
  min_heap_kb_m3/_m0    the smallest MICROPY_HEAP_SIZE (4 KB steps) at which that whole
                        test still passes, found by bisection over firmware builds
  flash_kb_frozen_m3/_m0, flash_kb_plain_m3/_m0   firmware image with the stack frozen in,
                        and the same firmware with nothing frozen
  heap_used_kb_m0_peripheral, min_heap_kb_m0_peripheral, flash_kb_frozen_m0_peripheral
                        the same for the Cortex-M0 as a distance-sensor peripheral
                        (qemu_m0_rangefinder; held: its `ready` line, once up)
"""
import re
import os
import subprocess
import sys

BENCH = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(BENCH)
sys.path.insert(0, os.path.join(ROOT, "mcu"))
sys.path.insert(0, os.path.join(ROOT, "tests"))

import firmware  # noqa: E402

PY = os.path.join(ROOT, ".venv", "bin", "python")
FLOOR_KB = 60
TARGET_KB = 48
BISECT_FROM_KB = 60  # the bisection's upper bound: it passed there when last measured


def _passes(board, heap_kb):
    """The whole-vehicle test (the peripheral's, for qemu_m0_rangefinder) at this heap size -> passed."""
    if board == "qemu_m0_rangefinder":
        env = dict(os.environ, MCU_PERIPHERAL_HEAP_KB=str(heap_kb))
        test = [os.path.join(ROOT, "tests", "test_mcu_peripheral.py")]
    else:
        env = dict(os.environ, MCU_VEHICLE_HEAP_KB=str(heap_kb))
        test = [os.path.join(ROOT, "tests", "test_mcu_vehicle.py"), "-k", "whole and %s" % board]
    r = subprocess.run([PY, "-m", "pytest", "-q", "-x", "-p", "no:cacheprovider"] + test,
                       cwd=ROOT, env=env, capture_output=True, text=True)
    return r.returncode == 0


def _peripheral_heap_kb():
    """The peripheral's held heap, as its `ready` line says once it is up (KB)."""
    from mcu_rig import EmulatedBoard

    with EmulatedBoard("qemu_m0_rangefinder") as b:
        _pty, line = b.start_peripheral()
    return int(re.search(r"ready, (\d+) KB", line).group(1))


def _heap_used_kb(board):
    """Boot the vehicle, run a short session, shut it down, read its heap figures."""
    from mcu_rig import EmulatedBoard
    from gcs_tools import command

    with EmulatedBoard(board) as b:
        gcs = b.start_vehicle()
        gcs.mav.param_request_list_send(1, 1)
        for _ in range(100):
            gcs.recv_match(type="PARAM_VALUE", blocking=True, timeout=2)
        command(gcs, 246, 2.0)  # shut down: main.py returns to the REPL
        gcs.recv_match(type="COMMAND_ACK", blocking=True, timeout=3)
        if b.uarts == 1:
            gcs.close()
            b.reopen_repl()
        out = b.exec("import board\nprint(board.HEAP[0], board.HEAP[1])")
    used, free = (int(x) for x in out.split())
    return used / 1024, (used + free) / 1024


def _min_heap_kb(board):
    lo, hi = 16, BISECT_FROM_KB  # bisection in 4 KB steps; hi must pass
    if not _passes(board, hi):
        return float(hi + 4)  # not even the floor: report it as missed
    while hi - lo > 4:
        mid = (lo + hi) // 2 // 4 * 4
        if _passes(board, mid):
            hi = mid
        else:
            lo = mid
    return float(hi)


def run():
    if firmware.tools_missing():
        raise RuntimeError("MCU tools missing (make mcu-deps): %s" % firmware.tools_missing())
    out = {}
    for board, tag in (("qemu_m3", "m3"), ("qemu_m0", "m0")):
        out["flash_kb_frozen_" + tag] = round(firmware.flash_kb(firmware.build(board)), 1)
        out["flash_kb_plain_" + tag] = round(firmware.flash_kb(firmware.build(board, frozen=False)), 1)
        used, _total = _heap_used_kb(board)
        out["heap_used_kb_" + tag] = round(used, 1)
        out["min_heap_kb_" + tag] = _min_heap_kb(board)
    out["flash_kb_frozen_m0_peripheral"] = round(firmware.flash_kb(firmware.build("qemu_m0_rangefinder")), 1)
    out["heap_used_kb_m0_peripheral"] = float(_peripheral_heap_kb())
    out["min_heap_kb_m0_peripheral"] = _min_heap_kb("qemu_m0_rangefinder")
    return out


def floors(r):
    return [("whole vehicle in a %d KB heap on the %s" % (FLOOR_KB, cpu), r["min_heap_kb_" + tag] <= FLOOR_KB)
            for tag, cpu in (("m3", "Cortex-M3"), ("m0", "Cortex-M0"))]
