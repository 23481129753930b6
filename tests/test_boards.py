"""Every board profile builds a working vehicle (on the unix port, its links replaced by
UDP), and says how much heap it holds; the unix vehicle stays within its RAM budget."""
import os
import re
import sys

import pytest

from conftest import ROOT

sys.path.insert(0, os.path.join(ROOT, "boards"))


@pytest.mark.parametrize("board", ["unix", "pico", "esp32", "pyboard", "qemu_m3", "qemu_m0"])
def test_profile_builds_a_vehicle_and_reports_its_heap(vehicle, board):
    # The emulated boards lock the heap once up; the unix port's UDP links allocate for
    # each new peer, so here they run unlocked (tests/test_mcu_vehicle.py runs them locked).
    v = vehicle(board=board, args=["--set", "heap_lock=0"] if board.startswith("qemu") else [])
    m = v.gcs()
    profile = __import__(board)
    hb = m.recv_match(type="HEARTBEAT", blocking=True, timeout=5)
    assert hb is not None and hb.type == profile.MAV_TYPE
    v.stop()
    ready = re.search(r"mavstack: (\w+) ready, (\d+) KB of heap in use \(budget (\d+) KB\)", v.output())
    assert ready, v.output()
    assert ready.group(1) == board and int(ready.group(3)) == profile.RAM_BUDGET >> 10
    if board == "unix":
        assert int(ready.group(2)) <= int(ready.group(3))
