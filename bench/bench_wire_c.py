"""Wire layer against MAVLink's C library: how far our ingest is from C.

pymavlink's mavgen generates the C headers for the common dialect (MAVLink 2) into a
temporary directory; bench/c_ingest.c, built with gcc -O2, reads the same 20,000 mixed
v2 frames bench_wire.py uses and calls mavlink_parse_char on every byte, pass after
pass for at least 0.2 s; the median of 3 runs counts. Our figure is the viper ingest
on the unix port, measured in the same run by bench/mpy_wire.py (as bench_wire.py does).

    .venv/bin/python bench/bench_wire_c.py
"""
import contextlib
import io
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile

BENCH = os.path.dirname(os.path.abspath(__file__))
if BENCH not in sys.path:
    sys.path.insert(0, BENCH)

import bench_wire  # noqa: E402

C_SOURCE = os.path.join(BENCH, "c_ingest.c")
RUNS = 3
MIN_SECONDS = 0.2


def common_xml():
    import pymavlink

    base = os.path.dirname(pymavlink.__file__)
    for path in (os.path.join(base, "message_definitions", "v1.0", "common.xml"),
                 os.path.join(base, "..", "message_definitions", "v1.0", "common.xml"),
                 os.path.join(base, "dialects", "v20", "common.xml")):
        if os.path.isfile(path):
            return os.path.normpath(path)
    raise FileNotFoundError("common.xml not found in pymavlink")


def build(tmp):
    """Generate the C headers and compile c_ingest.c; -> path of the executable."""
    from pymavlink.generator import mavgen

    include = os.path.join(tmp, "include")
    opts = mavgen.Opts(include, wire_protocol="2.0", language="C", validate=False)
    with contextlib.redirect_stdout(io.StringIO()):
        ok = mavgen.mavgen(opts, [common_xml()])
    if not ok or not os.path.isfile(os.path.join(include, "common", "mavlink.h")):
        raise RuntimeError("mavgen did not generate common/mavlink.h")
    gcc = shutil.which("gcc")
    if not gcc:
        raise RuntimeError("gcc not found")
    exe = os.path.join(tmp, "c_ingest")
    p = subprocess.run([gcc, "-O2", "-w", "-I", include, "-o", exe, C_SOURCE],
                       capture_output=True, text=True)
    if p.returncode != 0:
        raise RuntimeError("gcc failed\n" + p.stdout + p.stderr)
    return exe


def c_fps(exe, path, frames):
    rates = []
    for _ in range(RUNS):
        p = subprocess.run([exe, path, str(frames), str(MIN_SECONDS)],
                           capture_output=True, text=True, timeout=120)
        if p.returncode != 0:
            raise RuntimeError("c_ingest failed\n" + p.stdout + p.stderr)
        got, seconds, _passes = p.stdout.split()
        rates.append(int(got) / float(seconds))
    return statistics.median(rates)


def run():
    frames = bench_wire.FRAMES
    with tempfile.TemporaryDirectory() as tmp:
        _v1, _v2, v1_path, v2_path = bench_wire.write_streams(tmp)
        exe = build(tmp)
        c = c_fps(exe, v2_path, frames)
        ours = bench_wire.micropython(v1_path, v2_path, False)["ingest_v2_fps"]
    return {
        "c_ingest_v2_fps": round(c),
        "ingest_v2_ratio_c": round(ours / c, 4),
    }


def floors(r):
    return [
        ("ingest_v2_ratio_c >= 0.1 (viper ingest_v2_fps / C mavlink_parse_char)",
         r["ingest_v2_ratio_c"] >= 0.1),
    ]


if __name__ == "__main__":
    results = run()
    print(json.dumps(results, indent=1))
    for text, ok in floors(results):
        print("%s: %s" % (text, "ok" if ok else "MISSED"))
