"""Wire layer: machine instructions per frame ingested, counted by callgrind.

The unix port runs bench/mpy_instr.py (viper kernels) under valgrind --tool=callgrind
twice with the same set-up: once feeding the 20,000 mixed v2 frames bench_wire.py uses,
once feeding none. Instructions per frame = (Ir(N) - Ir(0)) / N, Ir being the total in
the "summary:" line of callgrind's output. Unlike frames/s this does not depend on the
machine's load. Without valgrind the key is left out (with a note).

    .venv/bin/python bench/bench_wire_instr.py
"""
import json
import os
import shutil
import subprocess
import sys
import tempfile

BENCH = os.path.dirname(os.path.abspath(__file__))
if BENCH not in sys.path:
    sys.path.insert(0, BENCH)

import bench_wire  # noqa: E402

DRIVER = os.path.join(BENCH, "mpy_instr.py")


def instructions(valgrind, stream, feed, tmp):
    """Total Ir of one run of the driver under callgrind; also checks the frames parsed."""
    out = os.path.join(tmp, "callgrind.out.%d" % feed)
    env = dict(os.environ)
    env["MICROPYPATH"] = bench_wire.FIRMWARE
    env.pop("MAVSTACK_PORTABLE", None)
    p = subprocess.run([valgrind, "--tool=callgrind", "--callgrind-out-file=" + out,
                        bench_wire.MICROPYTHON, "-X", "heapsize=32M", DRIVER, stream, str(feed)],
                       cwd=bench_wire.ROOT, env=env, capture_output=True, text=True, timeout=600)
    if p.returncode != 0:
        raise RuntimeError("callgrind run failed\n" + p.stdout + p.stderr)
    impl, frames = p.stdout.split()[-2:]
    assert impl == "viper", impl
    assert int(frames) == (bench_wire.FRAMES if feed else 0), frames
    with open(out) as f:
        for line in f:
            if line.startswith("summary:"):
                return int(line.split()[1])
    raise RuntimeError("no summary: line in " + out)


def run():
    valgrind = shutil.which("valgrind")
    if not valgrind:
        print("  valgrind not found: ingest_v2_instr_per_frame skipped")
        return {}
    os.environ.setdefault("MAVLINK20", "1")
    v2 = bench_wire.pack_stream(2, bench_wire.FRAMES)
    with tempfile.TemporaryDirectory() as tmp:
        stream = os.path.join(tmp, "v2.bin")
        with open(stream, "wb") as f:
            f.write(v2)
        base = instructions(valgrind, stream, 0, tmp)
        full = instructions(valgrind, stream, 1, tmp)
    return {"ingest_v2_instr_per_frame": round((full - base) / bench_wire.FRAMES)}


def floors(r):
    if "ingest_v2_instr_per_frame" not in r:
        return []
    return [("ingest_v2_instr_per_frame <= 12000", r["ingest_v2_instr_per_frame"] <= 12000)]


if __name__ == "__main__":
    results = run()
    print(json.dumps(results, indent=1))
    for text, ok in floors(results):
        print("%s: %s" % (text, "ok" if ok else "MISSED"))
