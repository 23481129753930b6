"""Wire layer: frames per second in and out, and bytes requested from the heap per frame.

The traffic is a mix of HEARTBEAT, ATTITUDE, GPS_RAW_INT, PARAM_VALUE,
MISSION_ITEM_INT and COMMAND_LONG packed by pymavlink (MAVLink 1, and MAVLink 2 with
its payload tails trimmed). Ingest means fed in 4 KiB chunks, parsed, CRC-checked and
delivered to a no-op callback. The unix port runs bench/mpy_wire.py with viper and
with the portable kernels; pymavlink's MAVLink.parse_buffer and our parser on CPython
run over the same bytes for comparison, and MAVLink's C library (bench_wire_c.py) in
the same run: the floor is a tenth of its frames/s, MAVLink 1 and 2.

    .venv/bin/python bench/bench_wire.py
"""
import json
import os
import sys
import tempfile
import time

BENCH = os.path.dirname(os.path.abspath(__file__))
if BENCH not in sys.path:
    sys.path.insert(0, BENCH)  # bench_wire_c, wire_streams

import bench_wire_c  # noqa: E402
from wire_streams import FIRMWARE, FRAMES, mpy_wire, write_streams  # noqa: E402

CHUNK = 4096
REPEATS = 5


def best_fps(feed, data, frames):
    """frames / the sum over 4 KiB chunks of each chunk's best time in REPEATS runs.

    feed(new=True) starts a fresh parser; feed(chunk) parses one chunk, returning the
    frames it finished. Timing chunk by chunk keeps other processes' turns out of it.
    """
    n = (len(data) + CHUNK - 1) // CHUNK
    best = [float("inf")] * n
    for _ in range(REPEATS):
        feed(None)
        got = 0
        for k in range(n):
            chunk = data[k * CHUNK:(k + 1) * CHUNK]
            t0 = time.perf_counter()
            got += feed(chunk)
            dt = time.perf_counter() - t0
            best[k] = min(best[k], dt)
        assert got == frames, (got, frames)
    return frames / sum(best)


def pymavlink_ingest():
    from pymavlink.dialects.v20 import common as m

    state = {}

    def feed(chunk):
        if chunk is None:
            state["mav"] = m.MAVLink(None, 0, 0)
            return 0
        got = state["mav"].parse_buffer(chunk)
        return len(got) if got else 0

    return feed


def cpython_ingest():
    if FIRMWARE not in sys.path:
        sys.path.insert(0, FIRMWARE)
    from mavstack.dialects import common
    from mavstack.parser import Parser

    def noop(msgid, payload):
        pass

    state = {}
    buf = bytearray(CHUNK)

    def feed(chunk):
        if chunk is None:
            state["p"] = Parser(common.CRC_LEN, noop)
            return 0
        p = state["p"]
        before = p.frames
        n = len(chunk)
        buf[:n] = chunk
        p.feed(buf, n)
        return p.frames - before

    return feed


def run():
    with tempfile.TemporaryDirectory() as tmp:
        v1, v2, v1_path, v2_path = write_streams(tmp)
        viper = mpy_wire(v1_path, v2_path, False)
        c = bench_wire_c.compare(v1_path, v2_path, viper)  # C in this same run
        portable = mpy_wire(v1_path, v2_path, True)
    alloc = max(v for k, v in list(viper.items()) + list(portable.items()) if k.endswith("alloc_per_frame"))
    return dict(c, **{
        "ingest_v1_fps": viper["ingest_v1_fps"],
        "ingest_v2_fps": viper["ingest_v2_fps"],
        "encode_v2_fps": viper["encode_v2_fps"],
        "alloc_bytes_per_frame": alloc,
        "pymavlink_ingest_v2_fps": round(best_fps(pymavlink_ingest(), v2, FRAMES)),
        "ingest_v1_fps_portable": portable["ingest_v1_fps"],
        "ingest_v2_fps_portable": portable["ingest_v2_fps"],
        "encode_v2_fps_portable": portable["encode_v2_fps"],
        "cpython_ingest_v2_fps": round(best_fps(cpython_ingest(), v2, FRAMES)),
        "wire_v2_bytes_per_frame": round(len(v2) / FRAMES, 1),
    })


# Encode's floor: 1.2x the 338k frames/s encode_v2_fps once was. The portable kernels'
# floors: what they did before whole frames went to one kernel call.
ENCODE_FLOOR = 1.2 * 338000
PORTABLE_FLOORS = {1: 105000, 2: 90000}


def floors(r):
    return [
        ("alloc_bytes_per_frame == 0 (heap requests, mem_total)", r["alloc_bytes_per_frame"] == 0),
        ("ingest_v2_fps >= 60% of pymavlink_ingest_v2_fps",
         r["ingest_v2_fps"] >= 0.6 * r["pymavlink_ingest_v2_fps"]),
        ("encode_v2_fps >= %d" % ENCODE_FLOOR, r["encode_v2_fps"] >= ENCODE_FLOOR),
    ] + [("ingest_v%d_fps_portable >= %d" % (v, f), r["ingest_v%d_fps_portable" % v] >= f)
         for v, f in sorted(PORTABLE_FLOORS.items())] + bench_wire_c.floors(r)


if __name__ == "__main__":
    results = run()
    print(json.dumps(results, indent=1))
    for text, ok in floors(results):
        print("%s: %s" % (text, "ok" if ok else "MISSED"))
