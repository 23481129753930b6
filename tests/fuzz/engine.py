"""The fuzzer's command. `make fuzz` runs the MicroPython engine (live.py: the unix port's
vehicles over UDP); this module is also the second engine, in-process on CPython, where
an input's first byte picks how it is read: 0 raw bytes into the parser, 1 structured
frames (valid CRC, random fields, generated from the input), 2 the two spliced, 3 frames
aimed at another vehicle or (signing on) not signed with the key in force, which must
change nothing. After every batch the invariants are checked; every couple of seconds a
ground station's exchanges must succeed. Inputs come from libFuzzer (atheris), guided by
coverage of the stack, or from a seeded mutator. Every engine writes a report (JSON:
frames, batches, exchanges, reboots, seconds, fuzz_frames_per_s); a failure ends the
run, status 1.

    .venv/bin/python tests/fuzz/engine.py --seconds 60 [--seed 1] [--report FILE]
        [--engine micropython|atheris|mutate] [--storage DIR] [--no-grow]
"""
import argparse
import json
import os
import random
import shutil
import sys
import tempfile
import time
import traceback

HERE = os.path.dirname(os.path.abspath(__file__))
TESTS = os.path.dirname(HERE)
ROOT = os.path.dirname(TESTS)
for _p in (TESTS, os.path.join(ROOT, "firmware")):
    if _p not in sys.path:
        sys.path.insert(0, _p)

EXCHANGE_EVERY_S = 2.0
MAX_FRAMES = 48  # structured frames in one batch


class Fuzz:
    def __init__(self, storage, seed, seconds, report):
        from fuzz import invariants, rig

        self.inv = invariants
        self.rig = rig
        self.v = rig.FuzzVehicle(storage, seed)
        self.storage = storage
        self.seconds = seconds
        self.report_path = report
        self.start = time.time()
        self.next_exchange = self.start + EXCHANGE_EVERY_S
        self.stats = {"frames": 0, "raw_bytes": 0, "batches": 0, "exchanges": 0, "reboots": 0,
                      "foreign_batches": 0, "forged_batches": 0, "signed_frames": 0}
        self.seq = 0
        self.last = None
        self.work = None  # the run's scratch directory, removed after a clean run

    # --- one input --------------------------------------------------------------------
    def one(self, data):
        self.last = data
        if not data:
            return
        v = self.v
        mode = data[0] & 3
        if mode == 3:  # held against what the earlier batches' bytes have done, all of it
            v.settle()
        before = self.inv.snapshot(self.storage)
        held = self.inv.state(v)
        dirty = v.params.dirty
        signing = v.signing.enabled
        if mode == 0:
            self._raw(data[1:])
        else:
            self._structured(data, mode)
        v.poll(v.rng.randrange(1, 5), v.rng.choice((1, 5, 20)))
        after = self.inv.snapshot(self.storage)
        self.inv.check(v, after)
        if mode == 3 and v.reboots == self.stats["reboots"]:
            self._nothing_changed(before, after, held, dirty, signing)
        self.stats["batches"] += 1
        self.stats["reboots"] = v.reboots
        now = time.time()
        if now >= self.next_exchange:
            self.exchanges()
            self.next_exchange = time.time() + EXCHANGE_EVERY_S
        if now - self.start >= self.seconds:
            self.finish(0)

    def _raw(self, data):
        v = self.v
        o = 0
        while o < len(data):
            n = v.rng.randrange(1, 300)
            v.feed(data[o:o + n])
            v.poll(1, v.rng.choice((0, 1, 3)))
            o += n
        self.stats["raw_bytes"] += len(data)

    def _structured(self, data, mode):
        v = self.v
        rng = random.Random(data)
        n = 1 + data[1] % MAX_FRAMES if len(data) > 1 else 1
        splice = data[2:] if mode == 2 else b""
        # Mode 3 with signing on: half the time the frames are aimed at this vehicle but
        # unsigned or signed with a wrong key, which must change nothing just the same.
        forged = mode == 3 and v.signing.enabled and rng.random() < 0.5
        for _ in range(n):
            key, stamp = self._forged(rng) if forged else self._signature(rng)
            self.seq += 1
            f = v.structured.frame(rng, self.seq, foreign=(mode == 3 and not forged), key=key, stamp=stamp)
            if splice and rng.random() < 0.3:
                k = rng.randrange(len(splice) + 1)
                f = (splice[:k] + f) if rng.random() < 0.5 else (f[:rng.randrange(len(f))] + splice[:k] + f)
            v.feed(f)
            v.poll(1, rng.choice((0, 1, 1, 2, 5)))
        self.stats["frames"] += n
        if mode == 3:
            self.stats["forged_batches" if forged else "foreign_batches"] += 1

    def _forged(self, rng):
        """Unsigned, or signed with a key that is not the one in force."""
        if rng.random() < 0.3:
            return None, 0
        key = bytearray(self.v.signing.key)
        key[rng.randrange(32)] ^= 1 << rng.randrange(8)
        ts = int.from_bytes(bytes(self.v.signing.ts), "little")
        return bytes(key), (ts + rng.randrange(1, 10 ** 6)) & ((1 << 48) - 1)

    def _signature(self, rng):
        """With signing on: mostly frames signed with the key in force (fresh, replayed or
        far-future timestamps), some with a wrong key, some unsigned."""
        sg = self.v.signing
        if not sg.enabled:
            return None, 0
        r = rng.random()
        if r < 0.2:
            return None, 0
        ts = int.from_bytes(bytes(sg.ts), "little")
        stamp = max(0, ts + rng.choice((1, 100, -1, -10 ** 6, 10 ** 8, rng.randrange(1 << 48) - ts)))
        stamp &= (1 << 48) - 1
        if r < 0.35:
            return bytes(rng.randrange(256) for _ in range(32)), stamp
        self.stats["signed_frames"] += 1
        return bytes(sg.key), stamp

    def _nothing_changed(self, before, after, held, dirty, signing):
        files = self.inv.changed(before, after)
        allowed = set()
        if dirty:
            allowed.add("params")  # an autosave that fell due: its content is checked
        if signing:
            allowed.add("signing_key")  # the periodic timestamp save
        if set(files) - allowed:
            raise self.inv.Broken("frames aimed at another vehicle, or not signed with the key in force, "
                                  "changed storage: %s" % files)
        if self.inv.state(self.v) != held:
            raise self.inv.Broken("frames aimed at another vehicle, or not signed with the key in force, "
                                  "changed parameters, plans or key")

    def exchanges(self):
        v = self.v
        v.quiesce()
        v.param_exchange()
        v.command_exchange()
        v.mission_exchange(v.rng.randrange(1, 6))
        v.quiesce(3000)  # the parameter's autosave
        if v.rng.random() < 0.85:
            v.signing_off()  # (else the next batches run signed)
        self.inv.check(v, self.inv.snapshot(self.storage))
        self.stats["exchanges"] += 1

    # --- the end ----------------------------------------------------------------------
    def report(self):
        seconds = time.time() - self.start
        out = dict(self.stats)
        out["seconds"] = round(seconds, 2)
        out["fuzz_frames_per_s"] = round(out["frames"] / seconds, 1) if seconds > 0 else 0
        out["engine"] = ENGINE
        return out

    def finish(self, status):
        """Report and end the process (libFuzzer does not hand control back)."""
        if status == 0 and self.work:
            shutil.rmtree(self.work, ignore_errors=True)
        out = self.report()
        if self.report_path:
            with open(self.report_path, "w") as f:
                json.dump(out, f, indent=1)
        print("fuzz:", json.dumps(out), flush=True)
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(status)


def seeds(rng):
    """The seed inputs: the corpus of valid frames (raw mode), and a few of each other mode."""
    from fuzz import frames

    out = [b"\x00" + f for f in frames.corpus(rng)]
    out.append(b"\x00" + b"".join(frames.corpus(rng)[:40]))
    for mode in (1, 2, 3):
        for k in range(8):
            out.append(bytes((mode, k * 7)) + rng.randbytes(8))
    return out


ENGINE = "mutate"


def main(argv):
    global ENGINE
    ap = argparse.ArgumentParser()
    ap.add_argument("--seconds", type=float, default=60)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--report")
    ap.add_argument("--storage")
    ap.add_argument("--engine", choices=("micropython", "atheris", "mutate"), default="micropython")
    ap.add_argument("--no-grow", action="store_true", help="leave the saved corpus as it is")
    args = ap.parse_args(argv)
    engine = args.engine
    if engine == "micropython":
        from fuzz import live

        sys.exit(live.main(args.seconds, args.seed, args.report, grow=not args.no_grow))
    ENGINE = engine
    work = tempfile.mkdtemp(prefix="mavfuzz-")
    storage = args.storage or os.path.join(work, "storage")
    os.makedirs(storage, exist_ok=True)
    if engine == "atheris":
        import atheris

        with atheris.instrument_imports(include=["mavstack", "simulator"]):
            import mavstack.parser  # noqa: F401
            from fuzz import rig  # noqa: F401
    fz = Fuzz(storage, args.seed, args.seconds, args.report)
    fz.work = work if not args.storage else None
    rng = random.Random(args.seed)
    pool = seeds(rng)
    from fuzz.corpus import mutate

    def test_one(data):
        try:
            fz.one(bytes(data))
        except Exception:
            traceback.print_exc()
            crash = os.path.join(os.path.dirname(os.path.abspath(args.report or "x")), "fuzz-crash.bin")
            with open(crash, "wb") as f:
                f.write(fz.last or b"")
            print("fuzz: failing input saved to %s (%d bytes)" % (crash, len(fz.last or b"")), flush=True)
            fz.finish(1)

    if engine == "atheris":
        corpus = os.path.join(work, "corpus")
        os.makedirs(corpus)
        for i, data in enumerate(pool):
            with open(os.path.join(corpus, "seed%04d" % i), "wb") as f:
                f.write(data)
        atheris.Setup([sys.argv[0], corpus, "-max_total_time=%d" % (args.seconds + 60), "-seed=%d" % args.seed,
                       "-max_len=4096", "-artifact_prefix=%s/" % work, "-print_final_stats=0",
                       "-close_fd_mask=0"], test_one)
        atheris.Fuzz()  # returns only if libFuzzer stops first (its own time limit)
    else:
        for data in pool:
            test_one(data)
        while True:
            test_one(mutate(rng, rng.choice(pool), pool))
    fz.finish(0)


if __name__ == "__main__":
    main(sys.argv[1:])
