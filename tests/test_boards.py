"""Every board profile builds a working vehicle (on the unix port, its links replaced by
UDP), and says how much heap it holds; the unix vehicle stays within its RAM budget."""
import os
import re
import sys

import pytest

from conftest import ROOT

sys.path.insert(0, os.path.join(ROOT, "boards"))


@pytest.mark.parametrize("board", ["unix", "pico", "esp32", "pyboard"])
def test_profile_builds_a_vehicle_and_reports_its_heap(vehicle, board):
    v = vehicle(board=board)
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
