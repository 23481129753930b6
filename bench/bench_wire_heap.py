"""Wire layer on a full heap: ingest frames/s on a 256 KB heap, nearly empty and filled
with live objects to within 2 KB of full.

The unix port (viper kernels, -X heapsize=256K) runs bench/mpy_heap.py over the 20,000
mixed v2 frames of wire_streams.py, read in 4 KiB chunks. Anything the ingest allocates
per frame would, on the full heap, run a collection (marking all the live objects)
every couple of KB; full_heap_slowdown = empty fps / full fps shows it. The two modes
run alternately, ROUNDS processes each, and each mode's best counts.

    .venv/bin/python bench/bench_wire_heap.py
"""
import json
import os
import subprocess
import sys
import tempfile

BENCH = os.path.dirname(os.path.abspath(__file__))
if BENCH not in sys.path:
    sys.path.insert(0, BENCH)

import wire_streams  # noqa: E402

DRIVER = os.path.join(BENCH, "mpy_heap.py")
HEAPSIZE = "256K"
FREE_BYTES = 2048
ROUNDS = 4


def ingest(stream, mode):
    env = dict(os.environ)
    env["MICROPYPATH"] = wire_streams.FIRMWARE
    env.pop("MAVSTACK_PORTABLE", None)
    p = subprocess.run([wire_streams.MICROPYTHON, "-X", "heapsize=" + HEAPSIZE, DRIVER,
                        stream, mode, str(FREE_BYTES)],
                       cwd=wire_streams.ROOT, env=env, capture_output=True, text=True, timeout=300)
    if p.returncode != 0:
        raise RuntimeError("mpy_heap.py %s failed\n%s%s" % (mode, p.stdout, p.stderr))
    got = json.loads(p.stdout.strip().split("\n")[-1])
    assert got["kernels"] == "viper", got
    assert got["frames"] == wire_streams.FRAMES, got
    if mode == "full":
        assert 0 < got["free_bytes"] <= FREE_BYTES, got
    return got["fps"]


def run():
    os.environ.setdefault("MAVLINK20", "1")
    v2 = wire_streams.pack_stream(2, wire_streams.FRAMES)
    best = {"empty": 0, "full": 0}
    with tempfile.TemporaryDirectory() as tmp:
        stream = os.path.join(tmp, "v2.bin")
        with open(stream, "wb") as f:
            f.write(v2)
        for _ in range(ROUNDS):
            for mode in ("empty", "full"):
                best[mode] = max(best[mode], ingest(stream, mode))
    return {
        "ingest_v2_fps_empty_heap": best["empty"],
        "ingest_v2_fps_full_heap": best["full"],
        "full_heap_slowdown": round(best["empty"] / best["full"], 3),
    }


def floors(r):
    return [("full_heap_slowdown <= 1.2", r["full_heap_slowdown"] <= 1.2)]


if __name__ == "__main__":
    results = run()
    print(json.dumps(results, indent=1))
    for text, ok in floors(results):
        print("%s: %s" % (text, "ok" if ok else "MISSED"))
