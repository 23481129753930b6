"""What the fuzz reaches: the saved corpus (tests/fuzz/corpus/) replayed through the stack
in-process on CPython under coverage.py, as the share of statements executed.

Each dialect's inputs go, in their saved order, into the `make run` board's vehicle with
signing and its simulator (rig.FuzzVehicle(whole=True)), time passing between them as
it does for the MicroPython vehicle (abandoned transfers time out, saves fall due).
Measured: firmware/mavstack (its generated dialect tables left out) and firmware/sim,
every file, imported or not. `--baseline` replays nothing: what starting the vehicles
and letting them run alone executes, to set the corpus' share against.

    .venv/bin/python tests/fuzz/replay.py [--baseline] [--json]
"""
import argparse
import json
import os
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
TESTS = os.path.dirname(HERE)
ROOT = os.path.dirname(TESTS)
STACK = os.path.join(ROOT, "firmware", "mavstack")
SIM = os.path.join(ROOT, "firmware", "sim")
DIALECTS = ("common", "seed2012")


def replay(dialect, inputs, storage):
    from fuzz.rig import FuzzVehicle

    v = FuzzVehicle(storage, dialect=dialect, whole=True)
    v.poll(200, 10)  # two seconds alone: streams, heartbeats, the simulator
    for data in inputs:
        v.feed(data)
        v.poll(5, 2)
    v.settle()
    v.quiesce(6000)  # transfers the inputs left open time out; saves fall due
    v.ep.close()


def measure(baseline=False):
    """-> {"stack": percent, "sim": percent, "inputs": n, "stack_statements": n, ...}"""
    import coverage

    cov = coverage.Coverage(source=[STACK, SIM], omit=[os.path.join(STACK, "dialects", "*")],
                            data_file=None, branch=False)
    cov.start()
    try:
        for p in (TESTS, os.path.join(ROOT, "firmware")):
            if p not in sys.path:
                sys.path.insert(0, p)
        from fuzz import corpus

        n = 0
        with tempfile.TemporaryDirectory() as work:
            for dialect in DIALECTS:
                inputs = [] if baseline else corpus.load(dialect)[0]
                n += len(inputs)
                replay(dialect, inputs, os.path.join(work, dialect))
    finally:
        cov.stop()
    out = {"inputs": n}
    for name, top in (("stack", STACK), ("sim", SIM)):
        statements = missing = 0
        for path in _sources(top):
            _, stmts, _, miss, _ = cov.analysis2(path)
            statements += len(stmts)
            missing += len(miss)
        out[name] = round(100.0 * (statements - missing) / statements, 1) if statements else 0.0
        out[name + "_statements"] = statements
        out[name + "_executed"] = statements - missing
    return out


def _sources(top):
    for dirpath, dirnames, filenames in os.walk(top):
        dirnames[:] = sorted(d for d in dirnames if d not in ("__pycache__", "dialects"))
        for f in sorted(filenames):
            if f.endswith(".py"):
                yield os.path.join(dirpath, f)


def main(argv):
    ap = argparse.ArgumentParser()
    ap.add_argument("--baseline", action="store_true")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    r = measure(args.baseline)
    if args.json:
        print(json.dumps(r))
    else:
        print("%s: firmware/mavstack %.1f%% of %d statements, firmware/sim %.1f%% of %d (%d inputs)"
              % ("start-up alone" if args.baseline else "the saved corpus", r["stack"], r["stack_statements"],
                 r["sim"], r["sim_statements"], r["inputs"]))


if __name__ == "__main__":
    main(sys.argv[1:])
