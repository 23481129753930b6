"""Fuzzing: frames per second through the MicroPython vehicles (tests/fuzz/engine.py, the
unix port's make-run board in both dialects over UDP, invariants checked every couple of
seconds; a short run on the saved corpus, which it does not grow), and what the saved
corpus reaches: the share of statements of firmware/mavstack (its generated dialects
left out) and of firmware/sim executed when it is replayed through the stack in-process
on CPython under coverage.py (tests/fuzz/replay.py).

    .venv/bin/python bench/bench_fuzz.py
"""
import json
import os
import subprocess
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PYTHON = os.path.join(ROOT, ".venv", "bin", "python")
SECONDS = 30
FLOOR_FRAMES_PER_S = 5000


def run():
    with tempfile.TemporaryDirectory() as work:
        report = os.path.join(work, "report.json")
        proc = subprocess.run([PYTHON, os.path.join(ROOT, "tests", "fuzz", "engine.py"), "--seconds",
                               str(SECONDS), "--report", report, "--no-grow"], cwd=work, capture_output=True,
                              text=True, timeout=SECONDS + 300)
        if proc.returncode != 0:
            raise RuntimeError("fuzz run failed\n" + proc.stdout[-2000:] + proc.stderr[-4000:])
        with open(report) as f:
            r = json.load(f)
    proc = subprocess.run([PYTHON, os.path.join(ROOT, "tests", "fuzz", "replay.py"), "--json"], cwd=ROOT,
                          capture_output=True, text=True, timeout=600)
    if proc.returncode != 0:
        raise RuntimeError("corpus replay failed\n" + proc.stdout[-2000:] + proc.stderr[-4000:])
    cov = json.loads(proc.stdout.strip().splitlines()[-1])
    return {"fuzz_frames_per_s": r["fuzz_frames_per_s"], "fuzz_batches_per_s": round(r["batches"] / r["seconds"], 1),
            "fuzz_coverage_pct_stack": cov["stack"], "fuzz_coverage_pct_sim": cov["sim"],
            "fuzz_corpus_inputs": cov["inputs"]}


def floors(r):
    return [("%d fuzzed frames/s through the MicroPython vehicles" % FLOOR_FRAMES_PER_S,
             r["fuzz_frames_per_s"] >= FLOOR_FRAMES_PER_S)]


if __name__ == "__main__":
    print(json.dumps(run(), indent=1))
