"""Where the held heap goes on the emulated boards, by part: the board's own firmware
(stack frozen) builds the vehicle step by step as main.build does, collecting and
reading gc.mem_alloc() after each; a part is what its step left held.

    heap_kb_<part>_m3/_m0   board (the profile's import: module dicts; its PARAMS block stays in flash),
                            dialect, endpoint, storage, links, guard (the crash-loop
                            guard, on a board with a watchdog), each service of SERVICES
                            (its modules' globals and its objects), application;
    heap_kb_<part>_m0_peripheral   the same for qemu_m0_rangefinder
    .venv/bin/python bench/bench_mcu_heap.py
"""
import os
import re
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tests"))
sys.path.insert(0, os.path.join(ROOT, "mcu"))
import firmware  # noqa: E402

# As main.build composes the vehicle (no watchdog started: the guard's objects only).
PARTS = """import gc
_A = [0]
def _p(name):
    gc.collect()
    u = gc.mem_alloc()
    print("part", name, u - _A[0])
    _A[0] = u
_p("start")
import main
_p("main")
import board
_p("board")
dialect = __import__("mavstack.dialects." + board.DIALECT, None, None, ("CRC_LEN",))
_p("dialect")
from mavstack.endpoint import Endpoint
ep = Endpoint(dialect, 0 if board.SYSID == "follow" else board.SYSID, board.COMPID)
ep.board = board
ep.options = {}
_p("endpoint")
ep.storage = board.storage()
_p("storage")
services = board.SERVICES
if hasattr(board, "watchdog"):
    from mavstack.watchdog import Guard
    ep.add(Guard(board.SERVICES))
    _p("guard")
for t in board.transports():
    ep.add_link(t)
_p("links")
for name in services:
    mod = __import__("mavstack.services." + name, None, None, ("create",))
    mod.create(ep)
    _p(name)
if hasattr(board, "application"):
    board.application(ep)
    _p("application")
print("total", _A[0])
"""


def parts(board):
    """-> {part: bytes held} for one board."""
    from mcu_rig import EmulatedBoard

    with EmulatedBoard(board) as b:
        out = b.exec(PARTS, timeout=120)
    # (On the Cortex-M0 the vehicle's link shares the REPL's UART: a line may come after
    # other bytes.)
    got = {name: int(n) for name, n in re.findall(r"part (\w+) (-?\d+)", out) if name != "start"}
    got["total"] = int(re.search(r"total (\d+)", out).group(1))
    return got


def run():
    if firmware.tools_missing():
        raise RuntimeError("MCU tools missing (make mcu-deps): %s" % firmware.tools_missing())
    out = {}
    for board, tag in (("qemu_m3", "m3"), ("qemu_m0", "m0"), ("qemu_m0_rangefinder", "m0_peripheral")):
        for part, held in parts(board).items():
            out["heap_kb_%s_%s" % (part, tag)] = round(held / 1024, 2)
    return out


if __name__ == "__main__":
    for k, v in sorted(run().items()):
        print("%-32s %8.2f" % (k, v))
