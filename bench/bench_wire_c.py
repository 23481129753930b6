"""Wire layer against MAVLink's C library: how far our ingest is from C.

pymavlink's mavgen generates the C headers for the common dialect (MAVLink 2) into a
temporary directory; bench/c_ingest.c, built with gcc -O2, reads the same 20,000 mixed
frames bench_wire.py uses (the MAVLink 1 stream and the MAVLink 2 one) and calls
mavlink_parse_char on every byte, pass after pass for at least 0.2 s; the median of 3
runs counts. Our figures are the viper ingest on the unix port, measured in the same
run by bench/mpy_wire.py. bench_wire.py makes the same comparison within its own run
(compare() below); this one is for running it alone.

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

import wire_streams  # noqa: E402

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


def compare(v1_path, v2_path, ours):
    """C's frames/s on both streams and our ratios to them; ours holds our
    ingest_v1_fps and ingest_v2_fps measured in the same run."""
    frames = wire_streams.FRAMES
    with tempfile.TemporaryDirectory() as tmp:
        exe = build(tmp)
        c1 = c_fps(exe, v1_path, frames)
        c2 = c_fps(exe, v2_path, frames)
    return {
        "c_ingest_v1_fps": round(c1),
        "c_ingest_v2_fps": round(c2),
        "ingest_v1_ratio_c": round(ours["ingest_v1_fps"] / c1, 4),
        "ingest_v2_ratio_c": round(ours["ingest_v2_fps"] / c2, 4),
    }


def run():
    with tempfile.TemporaryDirectory() as tmp:
        _v1, _v2, v1_path, v2_path = wire_streams.write_streams(tmp)
        ours = wire_streams.mpy_wire(v1_path, v2_path, False)
        r = {"ingest_v1_fps": ours["ingest_v1_fps"], "ingest_v2_fps": ours["ingest_v2_fps"]}
        r.update(compare(v1_path, v2_path, ours))
    return r


def floors(r):
    text = "ingest_v%d_fps >= 0.1 x C's c_ingest_v%d_fps, same run (ratio %.3f)"
    return [(text % (v, v, r["ingest_v%d_ratio_c" % v]), r["ingest_v%d_ratio_c" % v] >= 0.1)
            for v in (1, 2)]


if __name__ == "__main__":
    results = run()
    print(json.dumps(results, indent=1))
    for text, ok in floors(results):
        print("%s: %s" % (text, "ok" if ok else "MISSED"))
