"""mavstack's ingest on the emulated Cortex-M3, timed by the board's own clock
(bench_mcu_ingest.py runs this on the frozen firmware, QEMU under -icount shift=0).

    mpy_ingest_m3.py ADDRESS LENGTH

The stream lies in RAM outside the heap, where QEMU's loader put it. It is fed in 4 KiB
views, as on the unix port (mpy_wire.py), once untimed, then PASSES times with CMSDK APB
timer 0 read around the feeding only, the heap locked meanwhile (the ingest allocates
nothing, so no collection can fall in it). Prints the kernels in use, the frames of a
pass, the fewest timer ticks a pass took, and the ticks of the timing around no chunks.
"""
import gc
import machine
import micropython
import sys
import uctypes

from mavstack import kernels
from mavstack.dialects import common
from mavstack.parser import Parser

CHUNK = 4096
PASSES = 3
TIMER_VALUE = 0x40000004  # counts down (mavstack.qemu runs it: the boards' clock)
TIMER_RELOAD = 0x40000008


def noop(msgid, payload):
    pass


def feed_all(p, views, sizes):
    for i in range(len(views)):
        p.feed(views[i], sizes[i])


def timed(p, views, sizes):
    """Timer ticks of one feed_all."""
    mem32 = machine.mem32
    gc.collect()
    micropython.heap_lock()
    t0 = mem32[TIMER_VALUE]
    feed_all(p, views, sizes)
    t1 = mem32[TIMER_VALUE]
    micropython.heap_unlock()
    ticks = t0 - t1
    if ticks < 0:  # wrapped once (a wrap is 40 s of the 25 MHz clock)
        ticks += mem32[TIMER_RELOAD] + 1
    return ticks


def main(argv):
    address, n = int(argv[0]), int(argv[1])
    mv = memoryview(uctypes.bytearray_at(address, n))
    views = [mv[i:i + CHUNK] for i in range(0, n, CHUNK)]
    sizes = [len(v) for v in views]
    p = Parser(common.CRC_LEN, noop)
    feed_all(p, views, sizes)  # once to count; a clean stream leaves the parser idle
    frames = p.frames
    best = 1 << 29
    for _ in range(PASSES):
        ticks = timed(p, views, sizes)
        if ticks < best:
            best = ticks
    assert p.frames == frames * (PASSES + 1) and not p.crc_errors and not p.bytes_discarded
    print(kernels.IMPL, frames, best, timed(p, [], []))


main(sys.argv[1:])
