"""Wire layer: machine instructions per frame ingested, counted by callgrind.

The unix port runs bench/mpy_instr.py (viper kernels) under valgrind --tool=callgrind
twice with the same set-up: once feeding the 20,000 mixed frames of wire_streams.py,
once feeding none; for the MAVLink 2 stream and the MAVLink 1 one. Instructions per
frame = (Ir(N) - Ir(0)) / N, Ir being the total in the "summary:" line of callgrind's
output. Unlike frames/s this does not depend on the machine's load. valgrind is
installed with apt-get where that can be done (root); without it the keys are left
out and the floor is reported missed.

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

import wire_streams  # noqa: E402

DRIVER = os.path.join(BENCH, "mpy_instr.py")


def instructions(valgrind, stream, feed, tmp):
    """Total Ir of one run of the driver under callgrind; also checks the frames parsed."""
    out = os.path.join(tmp, "callgrind.out.%d" % feed)
    env = dict(os.environ)
    env["MICROPYPATH"] = wire_streams.FIRMWARE
    env.pop("MAVSTACK_PORTABLE", None)
    p = subprocess.run([valgrind, "--tool=callgrind", "--callgrind-out-file=" + out,
                        wire_streams.MICROPYTHON, "-X", "heapsize=32M", DRIVER, stream, str(feed)],
                       cwd=wire_streams.ROOT, env=env, capture_output=True, text=True, timeout=600)
    if p.returncode != 0:
        raise RuntimeError("callgrind run failed\n" + p.stdout + p.stderr)
    impl, frames = p.stdout.split()[-2:]
    assert impl == "viper", impl
    assert int(frames) == (wire_streams.FRAMES if feed else 0), frames
    with open(out) as f:
        for line in f:
            if line.startswith("summary:"):
                return int(line.split()[1])
    raise RuntimeError("no summary: line in " + out)


def find_valgrind():
    """valgrind's path, installing Debian's package first where we can (root, apt-get)."""
    if shutil.which("valgrind"):
        return shutil.which("valgrind")
    if os.geteuid() == 0 and shutil.which("apt-get"):
        print("  installing valgrind (apt-get)", flush=True)
        cmd = ["apt-get", "install", "-y", "-q", "--no-install-recommends", "valgrind"]
        if subprocess.run(cmd, capture_output=True).returncode != 0:
            subprocess.run(["apt-get", "update", "-q"], capture_output=True)
            subprocess.run(cmd, capture_output=True)
    return shutil.which("valgrind")


def run():
    valgrind = find_valgrind()
    if not valgrind:
        print("  valgrind not found and not installable here: instructions per frame not counted")
        return {}
    os.environ.setdefault("MAVLINK20", "1")
    r = {}
    with tempfile.TemporaryDirectory() as tmp:
        for version in (2, 1):
            stream = os.path.join(tmp, "v%d.bin" % version)
            with open(stream, "wb") as f:
                f.write(wire_streams.pack_stream(version, wire_streams.FRAMES))
            base = instructions(valgrind, stream, 0, tmp)
            full = instructions(valgrind, stream, 1, tmp)
            r["ingest_v%d_instr_per_frame" % version] = round((full - base) / wire_streams.FRAMES)
    return r


def floors(r):
    if "ingest_v2_instr_per_frame" not in r:
        return [("ingest_v2_instr_per_frame <= 12000 (not counted: no valgrind)", False)]
    return [("ingest_v%d_instr_per_frame <= 12000" % v, r["ingest_v%d_instr_per_frame" % v] <= 12000)
            for v in (2, 1)]


if __name__ == "__main__":
    results = run()
    print(json.dumps(results, indent=1))
    for text, ok in floors(results):
        print("%s: %s" % (text, "ok" if ok else "MISSED"))
