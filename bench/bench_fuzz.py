"""Fuzzing throughput: structured and raw frames per second through the in-process vehicle,
invariants checked after every batch (tests/fuzz/engine.py, a short run).

    .venv/bin/python bench/bench_fuzz.py
"""
import json
import os
import subprocess
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PYTHON = os.path.join(ROOT, ".venv", "bin", "python")
SECONDS = 20


def run():
    with tempfile.TemporaryDirectory() as work:
        report = os.path.join(work, "report.json")
        proc = subprocess.run([PYTHON, os.path.join(ROOT, "tests", "fuzz", "engine.py"), "--seconds",
                               str(SECONDS), "--report", report], cwd=work, capture_output=True, text=True,
                              timeout=SECONDS + 300)
        if proc.returncode != 0:
            raise RuntimeError("fuzz run failed\n" + proc.stdout[-2000:] + proc.stderr[-4000:])
        with open(report) as f:
            r = json.load(f)
    return {"fuzz_frames_per_s": r["fuzz_frames_per_s"], "fuzz_batches_per_s": round(r["batches"] / r["seconds"], 1)}


if __name__ == "__main__":
    print(json.dumps(run(), indent=1))
