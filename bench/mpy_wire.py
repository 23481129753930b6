"""Wire-layer figures on the running port (bench_wire.py runs this under MicroPython,
with and without MAVSTACK_PORTABLE=1).

    mpy_wire.py V1_STREAM V2_STREAM ENCODE_COUNT

Ingest: the stream fed in 4 KiB chunks, parsed, CRC-checked and delivered to a no-op
callback. Encode: pack_into + finish, MAVLink 2, the same six messages. Each chunk (or
batch of frames) is timed on its own and the best of several runs counts, so that other
processes taking the CPU now and then do not show. Allocation: the bytes requested from
the heap (micropython.mem_total()) over a whole run. Prints one JSON object.
"""
import gc
import json
import micropython
import struct
import sys
import time

from mavstack import kernels
from mavstack.dialects import common
from mavstack.encoder import Encoder
from mavstack.parser import Parser

CHUNK = 4096
BATCH = 100  # frames encoded per timing
REPEATS = 9


def noop(msgid, payload):
    pass


def chunks(data):
    mv = memoryview(data)
    views = [mv[i:i + CHUNK] for i in range(0, len(data), CHUNK)]
    return views, [len(v) for v in views]


def feed_all(p, views, sizes):
    for i in range(len(views)):
        p.feed(views[i], sizes[i])


def feed_timed(p, views, sizes, best):
    for i in range(len(views)):
        t0 = time.ticks_us()
        p.feed(views[i], sizes[i])
        dt = time.ticks_diff(time.ticks_us(), t0)
        if dt < best[i]:
            best[i] = dt


FLOATS = (0.0, 0.125, -1.5, 3.25, 1000.5, -0.75, 2.0)
NAME = b"SYSID_THISMAV"


def encode_all(enc, count, first=0):
    f_hb, f_att, f_gps = common.FMT[0], common.FMT[30], common.FMT[24]
    f_pv, f_cmd, f_mi = common.FMT[22], common.FMT[76], common.FMT[73]
    fl = FLOATS
    for i in range(first, first + count):
        off = enc.begin()
        buf = enc.buf
        k = i % 6
        x = fl[i % 7]
        if k == 0:
            struct.pack_into(f_hb, buf, off, i, 2, 3, 81, 4, 3)
            enc.finish(0, 1, 1)
        elif k == 1:
            struct.pack_into(f_att, buf, off, i, x, x, x, x, x, x)
            enc.finish(30, 1, 1)
        elif k == 2:
            struct.pack_into(f_gps, buf, off, i * 1000, 473977418, 85455939, 488000, 120, 150,
                             500, 9000, 3, 12, 0, 0, 0, 0, 0, 0)
            enc.finish(24, 1, 1)
        elif k == 3:
            struct.pack_into(f_pv, buf, off, x, 300, i % 300, NAME, 9)
            enc.finish(22, 1, 1)
        elif k == 4:
            struct.pack_into(f_cmd, buf, off, x, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 400, 1, 1, 0)
            enc.finish(76, 1, 1)
        else:
            struct.pack_into(f_mi, buf, off, 0.0, x, 0.0, 0.0, 473977418, 85455939, x,
                             i & 0xFFFF, 16, 1, 1, 3, 0, 1, 0)
            enc.finish(73, 1, 1)


def allocated(fn, a, b, c, none):
    """Bytes fn(a, b, c) requested from the heap beyond what fn(a, none...) does, i.e.
    for its frames and not for the bench's own calls. micropython.mem_total() counts
    every request, also those freed before the call returns (a function's frame state
    on the heap: docs/design.md), which gc.mem_alloc() would not show."""
    gc.collect()
    before = micropython.mem_total()
    fn(a, b, c)
    n = micropython.mem_total() - before
    gc.collect()
    before = micropython.mem_total()
    fn(a, none[0], none[1])
    return n - (micropython.mem_total() - before)


def ingest(path):
    with open(path, "rb") as f:
        data = f.read()
    views, sizes = chunks(data)
    p = Parser(common.CRC_LEN, noop)
    feed_all(p, views, sizes)  # once to count; a clean stream leaves the parser idle
    frames = p.frames
    assert frames and not p.crc_errors and not p.bytes_discarded
    best = [1 << 30] * len(views)
    for _ in range(REPEATS):
        gc.collect()
        feed_timed(p, views, sizes, best)
    return frames, sum(best), allocated(feed_all, p, views, sizes, ([], []))


def encode(count):
    enc = Encoder(common.CRC_LEN, 2)
    batches = count // BATCH
    best = [1 << 30] * batches
    for _ in range(REPEATS):
        gc.collect()
        for b in range(batches):
            t0 = time.ticks_us()
            encode_all(enc, BATCH, b * BATCH)
            dt = time.ticks_diff(time.ticks_us(), t0)
            if dt < best[b]:
                best[b] = dt
    return batches * BATCH, sum(best), allocated(encode_all, enc, count, 0, (0, 0))


def main(argv):
    v1_frames, v1_us, v1_alloc = ingest(argv[0])
    v2_frames, v2_us, v2_alloc = ingest(argv[1])
    count, enc_us, enc_alloc = encode(int(argv[2]))
    print(json.dumps({
        "kernels": kernels.IMPL,
        "ingest_v1_fps": v1_frames * 1000000 // v1_us,
        "ingest_v2_fps": v2_frames * 1000000 // v2_us,
        "encode_v2_fps": count * 1000000 // enc_us,
        "ingest_v1_alloc_per_frame": v1_alloc / v1_frames,
        "ingest_v2_alloc_per_frame": v2_alloc / v2_frames,
        "encode_v2_alloc_per_frame": enc_alloc / count,
    }))


main(sys.argv[1:])
