"""One MicroPython vehicle under fuzz (live.py runs one per dialect): its process, the
fuzz's UDP port and sentinel, its ground station, what it handles (read off the same
board built in-process, rig.py), and its corpus.

`deliver(chunks)` sends a batch in whole datagrams and returns once the vehicle has
handled every byte of it (the sentinel's COMMAND_ACK came), with the features of what
the vehicle answered meanwhile. A batch that showed a new feature is cut down to the one
frame that shows it again, when one does, and saved to the corpus.
"""
import os
import tempfile
import time

from fuzz import corpus, frames, gcs, invariants, process, wire
from fuzz.rig import FuzzVehicle

ACK_WAIT_S = 0.1  # then the sentinel goes again (a reply the link's budget dropped)
DEAD_S = 20.0  # no sentinel answered for this long: the vehicle stopped answering
_MINIMIZE_FRAMES = 64
_EPOCH_2015 = 1420070400  # signing timestamps count from 2015 (unix seconds)


class Unanswered(AssertionError):
    """The vehicle stopped answering (and did not say why on its console)."""


def facts(dialect):
    """(handled message ids, command ids, parameter names) of the fuzzed board, built
    in-process from the same profile and services."""
    with tempfile.TemporaryDirectory() as d:
        v = FuzzVehicle(os.path.join(d, "st"), dialect=dialect, whole=True)
        out = (sorted(i for i, h in v.ep._handlers.items() if h), sorted(v.ep.commands), list(v.structured.names))
        v.ep.close()
    return out


class Target:
    def __init__(self, work, dialect, grow=True):
        self.dialect = dialect
        self.table = frames.layouts(dialect)
        self.vehicle = process.UnixVehicle(work, dialect)
        ids, commands, names = facts(dialect)
        self.handled = ids
        self.structured = frames.Structured(ids, commands, names, 1, 1, self.table)
        self.param_count = len(names)
        self.signing = wire.Signing()
        self.features = corpus.Features(self.table, commands)
        self.saved, self.known = corpus.load(dialect)
        self.grow = grow
        self.added = 0
        self.resends = 0  # sentinels sent again (unanswered within ACK_WAIT_S)
        self.faults_noted = 0  # console fault lines the engine has counted
        # SYS_STATUS' fault counts as last seen: [starts then, their sum, when, and the
        # increases not yet told on the console: [(since, deadline)]] (live.fault_check)
        self.fault_state = [0, 0, 0.0, []]
        self.answers = set()  # the features of the batch being delivered
        self.previous = []  # the batch before (live.py keeps it)
        self.port = self.sentinel = self.gcs = None

    def start(self):
        self.vehicle.start()
        self.port = wire.Port(self.vehicle.port)
        self.sentinel = wire.Sentinel(self.table, self.signing)
        self.gcs = gcs.Gcs(self.vehicle.port, self.dialect, self.signing)
        self.read_key()
        # What the vehicle says unasked (streams, heartbeats) is no one input's finding.
        self.deliver([], keep=False)
        time.sleep(1.2)
        self.deliver([], keep=False)
        self.known |= self.answers

    def read_key(self):
        """The signing key in force, as the vehicle stored it."""
        data = invariants.read_file(os.path.join(self.vehicle.storage, "signing_key"))
        key = data[:32] if data is not None and len(data) == 42 else None
        self.signing.key = key if key is not None and any(key) else None

    # --- a batch ---------------------------------------------------------------------------
    def deliver(self, chunks, keep=True):
        """Send chunks (frames or raw bytes, each at most wire.DATAGRAM - 300 bytes) and wait
        until the vehicle has handled them -> True if it did without restarting."""
        self.answers = set()
        self._take(self.port.received())  # what came before: answers to earlier batches
        starts = self.vehicle.starts
        faults = len(self.vehicle.faults)
        # The sentinel signed with the key in force; and, when the batch may have changed
        # the key, one with the new key and one unsigned (only the one accepted is answered).
        cmds, tail = self._sentinels(wire.setup_signing(chunks))
        whole = True
        for d in wire.pack(list(chunks) + [wire.PAD + tail]):
            whole = self.port.send(d) and whole
        given_up = time.time() + DEAD_S
        while not self._acked(cmds, time.time() + ACK_WAIT_S):
            trouble = self.vehicle.trouble()
            if trouble:
                raise Unanswered(trouble)
            if time.time() > given_up:
                raise Unanswered("no answer from the %s vehicle for %d s:\n%s"
                                 % (self.dialect, DEAD_S, self.vehicle.console()))
            self.read_key()  # the batch may have set another key
            self.resends += 1
            cmds, tail = self._sentinels(None)
            self.port.send(wire.PAD + tail)
        for _, line in self.vehicle.faults[faults:]:
            self.answers.add(corpus.fault(line))
        return whole and self.vehicle.starts == starts

    def _sentinels(self, setup):
        """-> (their command ids, their frames) for the end of a batch."""
        cmd, tail = self.sentinel.next()
        cmds = [cmd]
        if setup is not None:
            key, stamp = setup
            now = int((time.time() - _EPOCH_2015) * 100000)  # the vehicle's clock, 10 us units
            stamp = max(stamp, now, self.signing.seen) + 1 + self.sentinel.k  # (k: each above the last)
            for k in ((key if any(key) else None), None):
                cmd, f = self.sentinel.next(k, stamp)
                cmds.append(cmd)
                tail += f
        return cmds, tail

    def _acked(self, cmds, deadline):
        while time.time() < deadline:
            if self._take(self.port.received(0.02), cmds):
                return True
        return False

    def _take(self, dgrams, cmds=()):
        """Note the features of what the vehicle sent -> whether a sentinel of cmds was acked."""
        acked = False
        for d in dgrams:
            for msgid, _s, _c, payload, f in wire.scan(d):
                self.signing.saw(f)
                c = wire.ack_command(msgid, payload)
                if c is not None and c >= wire.CMD_BASE:
                    acked = acked or c in cmds
                    continue
                self.answers.add(self.features.of(msgid, payload))
        return acked

    # --- the corpus --------------------------------------------------------------------------
    def new_features(self):
        return self.answers - self.known

    def keep(self, chunks, new):
        """A batch showed features not seen before (an answer may come a batch late): the
        smallest run of its frames and the batch before's that shows one again, halving,
        is saved (at most MAX_LINE_BYTES of it), else the batch itself."""
        self.known |= new
        if self.grow:
            time.sleep(0.1)  # the senders' answer allowances refill (link.py), queued texts go
            self._take(self.port.received())
            while new:
                run = self._shrink(list(self.previous) + list(chunks), new)
                found = (self.answers & new) if run is not None else new
                data = b"".join(run if run is not None else chunks)[:corpus.MAX_LINE_BYTES]
                corpus.save(self.dialect, data, found)
                self.saved.append(data)
                self.added += 1
                new = new - found

    def _shrink(self, run, new):
        while len(run) > 1:
            half = len(run) // 2
            for part in (run[:half], run[half:]):
                if self._shows(part, new):
                    run = part
                    break
            else:  # (a half's other answers may crowd out the one: the vehicle queues 8 texts)
                for frame in run[-_MINIMIZE_FRAMES:]:
                    if self._shows([frame], new):
                        return [frame]
                return None
        return run if self._shows(run, new) else None

    def _shows(self, run, new):
        """Deliver a run again -> whether its answers (a queued STATUSTEXT a moment later
        too) hold one of the new features."""
        self.deliver(run)
        answers = self.answers
        self._take(self.port.received(0.01))
        time.sleep(0.01)
        self._take(self.port.received())
        self.answers |= answers
        return bool(self.answers & new)

    def stop(self):
        status = self.vehicle.stop()
        for p in (self.port, self.gcs.port if self.gcs else None):
            if p is not None:
                p.close()
        return status
