"""Ingest on a small heap, nearly empty or nearly full (bench_wire_heap.py runs this on
the unix port with -X heapsize=256K).

    mpy_heap.py V2_STREAM empty|full [FREE_BYTES]

The parser, a 4 KiB buffer and the open stream are made first; with "full", the heap
is then filled with small live objects (bytearrays and two-item lists, held in a
two-level table so the collector's mark stack stays shallow) until gc.mem_free() is at
most FREE_BYTES (2048). Each pass reads the stream in 4 KiB chunks with readinto and
feeds them; only the feeds are timed, and the fastest of REPEATS passes counts (a
pass's time includes every collection that happens in it). Prints one JSON object.
"""
import gc
import json
import sys
import time

from mavstack import kernels
from mavstack.dialects import common
from mavstack.parser import Parser

CHUNK = 4096
REPEATS = 9
PAGES = 256
PAGE = 32


def noop(msgid, payload):
    pass


def fill(limit):
    """Keep small objects alive until at most `limit` bytes are free; -> (holder, count)."""
    pages = [None] * PAGES
    count = 0
    gc.collect()
    while True:
        while gc.mem_free() > limit:
            page = pages[count // PAGE]
            if page is None:
                page = pages[count // PAGE] = [None] * PAGE
            page[count % PAGE] = bytearray(8) if count & 1 else [count, None]
            count += 1
        gc.collect()  # anything freed since (temporaries) is filled again
        if gc.mem_free() <= limit:
            return pages, count


def one_pass(f, p, buf):
    f.seek(0)
    us = 0
    while True:
        n = f.readinto(buf)
        if not n:
            return us
        t0 = time.ticks_us()
        p.feed(buf, n)
        us += time.ticks_diff(time.ticks_us(), t0)


def main(argv):
    mode = argv[1]
    limit = int(argv[2]) if len(argv) > 2 else 2048
    f = open(argv[0], "rb")
    buf = bytearray(CHUNK)
    p = Parser(common.CRC_LEN, noop)
    one_pass(f, p, buf)  # to count; a clean stream leaves the parser idle
    frames = p.frames
    assert frames and not p.crc_errors and not p.bytes_discarded
    keep, objects = fill(limit) if mode == "full" else (None, 0)
    free = gc.mem_free()
    best = 1 << 30
    for _ in range(REPEATS):
        gc.collect()
        before = p.frames
        us = one_pass(f, p, buf)
        assert p.frames - before == frames
        if us < best:
            best = us
    f.close()
    print(json.dumps({
        "kernels": kernels.IMPL,
        "mode": mode,
        "frames": frames,
        "fps": frames * 1000000 // best,
        "free_bytes": free,
        "fill_objects": objects,
        "held": keep is not None,
    }))


main(sys.argv[1:])
