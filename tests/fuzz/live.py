"""The MicroPython engine (`make fuzz`): the unix port running the `make run` board with
signing and its simulator, one vehicle per dialect (common, seed2012), fuzzed over its
udpin link in turns, from this process.

Batches: mutated inputs of the saved corpus and valid frames of every message (raw
bytes), structured frames of every handled id (MAVLink 1 and 2; signed with the key in
force, another key or not at all once the fuzz turned signing on; frames for other
systems too), the two spliced. Every EXCHANGE_EVERY_S a checkpoint: the ground station's
exchanges succeed, what is stored is sane and is what is in force, a contained fault
was reported (a console line within REPORT_S of SYS_STATUS counting it), and a batch
aimed at another vehicle, or not signed with the key in force, changes nothing. Any
traceback or exit of a vehicle, a broken invariant or a failed exchange ends the run
(status 1, the last batches saved in the corpus' form next to the report).
"""
import collections
import json
import os
import random
import shutil
import sys
import tempfile
import time
import traceback

from fuzz import corpus, frames, gcs, invariants, target, wire

EXCHANGE_EVERY_S = 2.0
SEGMENT_S = 30.0  # each vehicle's turn
REPORT_S = 6.0  # faults.REPORT_MS and a second
MAX_FRAMES = 96  # structured frames in one batch
DIALECTS = ("common", "seed2012")


def _board():
    import unix

    return unix


class Live:
    def __init__(self, seconds, seed=1, report=None, dialects=DIALECTS, grow=True):
        self.work = tempfile.mkdtemp(prefix="mavfuzz-")
        self.seconds = seconds
        self.report_path = report
        self.rng = random.Random(seed)
        self.board = _board()
        self.targets = [target.Target(self.work, d, grow) for d in dialects]
        self.stats = collections.Counter()
        self.frames_by = collections.Counter()
        self.found = collections.Counter()  # contained faults: their console line, counted
        self.history = collections.deque(maxlen=12)  # (dialect, chunks) of the last batches
        self.pools = {}
        self.seq = 0
        self.start = time.time()
        self.checks = 0

    # --- the run ----------------------------------------------------------------------------
    def run(self):
        for t in self.targets:
            t.start()
            self.pools[t.dialect] = t.saved + frames.corpus(self.rng, table=t.table)
            t.fault_state[0], t.fault_state[2] = t.vehicle.starts, time.time()
        self.start = time.time()
        end = self.start + self.seconds
        turn = min(SEGMENT_S, max(self.seconds / len(self.targets), EXCHANGE_EVERY_S))
        k = 0
        while time.time() < end:
            t = self.targets[k % len(self.targets)]
            k += 1
            seg_end = min(end, time.time() + turn)
            while time.time() < seg_end:
                until = min(seg_end, time.time() + EXCHANGE_EVERY_S)
                while time.time() < until:
                    self.batch(t)
                at = time.time()
                self.checkpoint(t)
                self.stats["checkpoint_s"] += time.time() - at
        for t in self.targets:
            status = t.stop()
            trouble = t.vehicle.bad
            if status != 0 or trouble:
                raise invariants.Broken("the %s vehicle ended with status %s:\n%s"
                                        % (t.dialect, status, t.vehicle.console()))

    # --- a batch ----------------------------------------------------------------------------
    def batch(self, t):
        rng = self.rng
        r = rng.random()
        if r < 0.25:
            pool = self.pools[t.dialect]
            data = corpus.mutate(rng, rng.choice(pool), pool)
            chunks = wire.split(data)
            counted = frames.count_valid(data, t.table)
            self.stats["raw_bytes"] += len(data)
        else:
            chunks = self.structured(t, 1 + rng.randrange(MAX_FRAMES), splice=r > 0.8)
            counted = len(chunks)
        self.history.append((t.dialect, chunks))
        if t.deliver(chunks):
            self.stats["frames"] += counted
            self.frames_by[t.dialect] += counted
        else:
            self.stats["reboots"] += 1
        self.stats["batches"] += 1
        t.read_key()
        new = t.new_features()
        if new:
            t.keep(chunks, new)
        t.previous = chunks

    def structured(self, t, n, splice=False, foreign=False, forged=False):
        rng = self.rng
        pool = self.pools[t.dialect]
        out = []
        for _ in range(n):
            key, stamp = self.forged(t) if forged else self.signature(t)
            self.seq += 1
            f = t.structured.frame(rng, self.seq, foreign=foreign, key=key, stamp=stamp)
            if splice and rng.random() < 0.3:
                s = rng.choice(pool)
                k = rng.randrange(len(s) + 1)
                f = (s[:k] + f) if rng.random() < 0.5 else (f[:rng.randrange(len(f))] + s[:k] + f)
            out.append(f[:wire.DATAGRAM - len(wire.PAD)])
        return out

    def signature(self, t):
        """With signing on: mostly the key in force (fresh, replayed or far-future
        timestamps), some another key, some unsigned."""
        key = t.signing.key
        if key is None:
            return None, 0
        rng = self.rng
        r = rng.random()
        if r < 0.2:
            return None, 0
        ts = t.signing.seen
        stamp = max(0, ts + rng.choice((1, 100, -1, -10 ** 6, 10 ** 8, rng.randrange(1 << 48) - ts)))
        stamp &= (1 << 48) - 1
        if r < 0.35:
            return rng.randbytes(32), stamp
        self.stats["signed_frames"] += 1
        return key, stamp

    def forged(self, t):
        """Unsigned, or signed with a key that is not the one in force."""
        rng = self.rng
        if rng.random() < 0.3:
            return None, 0
        key = bytearray(t.signing.key)
        key[rng.randrange(32)] ^= 1 << rng.randrange(8)
        return bytes(key), t.signing.seen + rng.randrange(1, 10 ** 6)

    # --- a checkpoint -------------------------------------------------------------------------
    def checkpoint(self, t):
        for other in self.targets:
            trouble = other.vehicle.trouble()
            if trouble:
                raise target.Unanswered(trouble)
        self.note_faults()
        g = t.gcs
        g.heartbeat()
        g.param_exchange(self.rng)
        g.command_exchange()  # parameters saved: storage holds what is in force
        g.mission_exchange(self.rng, self.rng.randrange(1, 6))
        held, params, plans = self.in_force(t)
        self.fault_check(t, g.sys_status())
        if self.checks % 2 == 0:
            self.nothing_changes(t, held)
        self.checks += 1
        if t.signing.key is not None and self.rng.random() < 0.85:
            for _ in range(5):  # (else the next batches run signed)
                g.signing_off()
                t.deliver([])  # handled, and the vehicle's clock seen again
                t.read_key()
                if t.signing.key is None:
                    break
            else:
                raise gcs.ExchangeFailed("SETUP_SIGNING with a zero key, signed, left signing on")
        self.stats["exchanges"] += 1

    def in_force(self, t):
        """Stored sane and equal to what the vehicle says is in force -> (stored, params, plans)."""
        types = 3 if t.gcs.common else 1
        held = invariants.stored(t.vehicle.storage, self.board, types)
        params = t.gcs.params(t.param_count)
        plans = [t.gcs.plan_count(k) for k in range(types)]
        invariants.in_force(self.board, held, params, plans)
        t.read_key()
        if (held["key"] is not None and any(held["key"])) != (t.signing.key is not None):
            raise invariants.Broken("signing key stored %s, in force %s" % (held["key"], t.signing.key))
        return held, params, plans

    def nothing_changes(self, t, held):
        """Frames aimed at another vehicle, or (signing on) not signed with the key in force,
        change nothing stored and nothing in force."""
        forged = t.signing.key is not None and self.rng.random() < 0.5
        before = invariants.snapshot(t.vehicle.storage)
        chunks = self.structured(t, 1 + self.rng.randrange(MAX_FRAMES), foreign=not forged, forged=forged)
        self.history.append((t.dialect, chunks))
        if not t.deliver(chunks):
            return  # (a restart: nothing to compare)
        t.deliver([])
        self.stats["forged_batches" if forged else "foreign_batches"] += 1
        self.stats["frames"] += len(chunks)
        self.frames_by[t.dialect] += len(chunks)
        after = invariants.snapshot(t.vehicle.storage)
        changed = set(invariants.changed(before, after))
        if "signing_key" in changed and before["signing_key"][:32] == after.get("signing_key", b"")[:32]:
            changed.discard("signing_key")  # the timestamp's periodic save
        if changed:
            raise invariants.Broken("frames aimed at another vehicle, or not signed with the key in "
                                    "force, changed storage: %s" % sorted(changed))
        types = 3 if t.gcs.common else 1
        invariants.in_force(self.board, held, t.gcs.params(t.param_count),
                            [t.gcs.plan_count(k) for k in range(types)])

    def note_faults(self):
        for t in self.targets:
            for _, line in t.vehicle.faults[t.faults_noted:]:
                self.found["%s %s" % (t.dialect, line.rsplit(" (", 1)[0])] += 1
            t.faults_noted = len(t.vehicle.faults)

    def fault_check(self, t, status):
        """A fault SYS_STATUS counts (errors_count2..4) is told on the console within
        REPORT_S: never silent."""
        total = status["errors_count2"] + status["errors_count3"] + status["errors_count4"]
        now = time.time()
        st = t.fault_state  # [starts, total, when, pending [(since, deadline)]]
        if t.vehicle.starts != st[0]:
            st[0] = t.vehicle.starts
        elif total > st[1]:
            st[3].append((st[2], now + REPORT_S))
        st[1], st[2] = total, now
        told = [when for when, _ in t.vehicle.faults]
        for since, deadline in list(st[3]):
            if any(w > since for w in told):
                st[3].remove((since, deadline))
            elif now > deadline:
                raise invariants.Broken("a fault counted in SYS_STATUS (errors_count2..4: %d) was never "
                                        "reported" % total)

    # --- the end --------------------------------------------------------------------------------
    def report(self):
        seconds = time.time() - self.start
        out = dict(self.stats)
        out["seconds"] = round(seconds, 2)
        out["fuzz_frames_per_s"] = round(out.get("frames", 0) / seconds, 1) if seconds > 0 else 0
        out["engine"] = "micropython"
        out["frames_by_dialect"] = dict(self.frames_by)
        out["corpus_added"] = sum(t.added for t in self.targets)
        out["corpus_inputs"] = sum(len(t.saved) for t in self.targets)
        out["faults"] = dict(self.found)
        out["checkpoint_s"] = round(out.get("checkpoint_s", 0), 1)
        for t in self.targets:
            out["reboots_" + t.dialect] = t.vehicle.starts - 1
            out["resends_" + t.dialect] = t.resends
        return out

    def finish(self, status):
        self.note_faults()
        out = self.report()
        if self.report_path:
            with open(self.report_path, "w") as f:
                json.dump(out, f, indent=1)
        print("fuzz:", json.dumps(out), flush=True)
        if status == 0:
            shutil.rmtree(self.work, ignore_errors=True)
        return status

    def save_history(self):
        where = os.path.dirname(os.path.abspath(self.report_path or "x"))
        path = os.path.join(where, "fuzz-crash.txt")
        with open(path, "w") as f:
            for dialect, chunks in self.history:
                f.write("%s %s\n" % (dialect, b"".join(chunks).hex()))
        print("fuzz: the last %d batches saved to %s (dialect, bytes)" % (len(self.history), path), flush=True)


def main(seconds, seed=1, report=None, grow=True):
    fz = Live(seconds, seed, report, grow=grow)
    try:
        fz.run()
    except (AssertionError, OSError):
        traceback.print_exc()
        fz.save_history()
        for t in fz.targets:
            print("--- the %s vehicle's console (work %s):\n%s" % (t.dialect, fz.work, t.vehicle.console()),
                  flush=True)
            t.stop()
        return fz.finish(1)
    return fz.finish(0)


if __name__ == "__main__":
    sys.exit(main(float(sys.argv[1]) if len(sys.argv) > 1 else 60))
