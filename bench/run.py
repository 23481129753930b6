"""`make bench`: run every benchmark in bench/, print a table, write bench/latest.json.

A benchmark is a module bench/bench_NAME.py with `run() -> {key: number}`; it may also
have `floors(results) -> [(description, ok)]` for the figures it promises. Each runs on
its own: one that fails or is missing is reported and the others still run.

    .venv/bin/python bench/run.py            all of them; latest.json holds their keys
    .venv/bin/python bench/run.py wire ...   just these; their keys are merged into latest.json

Exit status 1 if a benchmark failed or a floor was missed.
"""
import glob
import importlib.util
import json
import os
import sys
import time
import traceback

BENCH = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(BENCH)
LATEST = os.path.join(BENCH, "latest.json")


def available():
    return sorted(os.path.basename(p)[len("bench_"):-3] for p in glob.glob(os.path.join(BENCH, "bench_*.py")))


def load(name):
    path = os.path.join(BENCH, "bench_%s.py" % name)
    if not os.path.isfile(path):
        raise FileNotFoundError("no benchmark %s (bench/bench_%s.py)" % (name, name))
    spec = importlib.util.spec_from_file_location("bench_" + name, path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def run_one(name):
    """-> (results, floors, error text or None)"""
    start = time.time()
    try:
        mod = load(name)
        results = mod.run()
        bad = {k: v for k, v in results.items()
               if isinstance(v, bool) or not isinstance(v, (int, float))}
        if bad:
            raise TypeError("not numbers: %r" % bad)
        floors = mod.floors(results) if hasattr(mod, "floors") else []
    except Exception:
        return {}, [], traceback.format_exc()
    print("  %s: %.1f s" % (name, time.time() - start), flush=True)
    return results, floors, None


def main(argv):
    names = argv or available()
    merged = {}
    if argv and os.path.isfile(LATEST):
        with open(LATEST) as f:
            merged = json.load(f)
    rows, failed, missed = [], [], []
    for name in names:
        print("bench %s ..." % name, flush=True)
        results, floors, error = run_one(name)
        if error:
            print("bench %s FAILED\n%s" % (name, error), file=sys.stderr)
            failed.append(name)
            continue
        merged.update(results)
        rows += [(k, v, name) for k, v in results.items()]
        for text, ok in floors:
            rows.append(("  floor: " + text, "ok" if ok else "MISSED", name))
            if not ok:
                missed.append(text)
    width = max([len(r[0]) for r in rows] + [10])
    print("%-*s  %14s  %s" % (width, "key", "value", "benchmark"))
    for key, value, name in rows:
        shown = value if isinstance(value, str) else ("%.0f" % value if abs(value) >= 100 else "%g" % value)
        print("%-*s  %14s  %s" % (width, key, shown, name))
    with open(LATEST, "w") as f:
        json.dump(merged, f, indent=1, sort_keys=True)
        f.write("\n")
    print("wrote %s" % os.path.relpath(LATEST, ROOT))
    if failed:
        print("failed: %s" % ", ".join(failed))
    if missed:
        print("floors missed: %s" % "; ".join(missed))
    return 1 if failed or missed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
