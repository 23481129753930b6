"""Flying a mission allocates nothing, on 32-bit boards too: runner.item, reached(),
DO_JUMP, next_nav() into a given Item, set_current().

    missions_runner_steady.py STORAGE [own]  STORAGE: a directory, or "ram"

Uploads a plan (before the check) whose waypoints sit past 2^30 in 1e7 degrees
(longitudes -122.4, 151.2, 179.9, +-180, latitude -90), two at z = -400 m, with two
DO_JUMPs (target 1 twice, target 5 once). Then harness.heap_requests flies it twice
over, counting heap requests with micropython.mem_total() and then under
micropython.heap_lock(): MISSION_START, then for each current item runner.item is
checked against what was sent (seq, command, is_nav, x and y by halves, and x, y, z in
the record's bytes), next_nav() fills a spare Item, reached() reports it (every
MISSION_ITEM_REACHED is checked); then set_current(0, reset) flies it again.
Prints `ok requested=0 order=0,1,2,1,2,1,2,4,5,5,7 reached=22 state=5` or what went
wrong (`fail requested=B ...` when only the heap requests were not 0).

With `own`, the bench's polling, the links' begin/send and the storage files are metered
apart and subtracted: `ok own=0 requested=B ...` needs only the runner's (and this
script's) own requests to be 0 (B: the whole stack's, for the work on the shared paths).
"""
import struct
import sys

from harness import Bench, heap_requests
from mavstack.fields import i32_cmp, u16
from mavstack.services.missions.runner import Item

_ITEM_INT = 73
_COUNT = 44
_REACHED = 46
_WAYPOINT = 16
_DELAY = 112
_JUMP = 177
_ACTIVE = 3
_COMPLETE = 5
# seq: command, x, y, z (x, y in 1e7 degrees, or the jump's target and repeat count)
PLAN = ((_WAYPOINT, 473977420, -1224000000, 10.0),
        (_WAYPOINT, -338567840, 1512000000, -400.0),
        (_WAYPOINT, 899000000, 1799000000, 10.0),
        (_JUMP, 1, 2, 0.0),
        (_WAYPOINT, -900000000, -1800000000, 10.0),
        (_DELAY, 0, 0, 0.0),
        (_JUMP, 5, 1, 0.0),
        (_WAYPOINT, 641466000, 1800000000, -400.0))
ORDER = bytes((0, 1, 2, 1, 2, 1, 2, 4, 5, 5, 7))

try:  # for the `own` meters
    from micropython import mem_total as _mem
except ImportError:  # CPython, or a port without it
    _mem = None


_out = [0]  # bytes requested inside calls out of the runner (a call within one: counted once)


class Out:
    """Wraps a call out of the runner (polling, links, files): its requests are apart."""

    def __init__(self, fn):
        self.fn = fn

    def call0(self):
        o = _out[0]
        t = _mem()
        r = self.fn()
        _out[0] = o + _mem() - t  # what calls inside this one added is in it
        return r

    def call1(self, a):
        o = _out[0]
        t = _mem()
        r = self.fn(a)
        _out[0] = o + _mem() - t
        return r


class OutFile:
    def __init__(self, f):
        self.seek = Out(f.seek).call1
        self.readinto = Out(f.readinto).call1
        self.write = Out(f.write).call1
        self.flush = Out(f.flush).call0


def meter(b):
    """Meter the calls out of the runner into _out."""
    b.run = Out(b.run).call1
    for link in b.ep.links:
        link.begin = Out(link.begin).call0
        link.send = Out(link.send).call1
    for store in b.ep.services["missions"].stores:
        if store is not None:
            store._files = [OutFile(f) for f in store._files]
    return _out


class Pilot:
    def __init__(self, b):
        self.b = b
        self.runner = b.ep.services["missions"].runner
        self.spare = Item()  # for next_nav() to fill
        # What each item must read as: x, y, z bytes (12 an item), x and y by halves.
        self.xyz = bytearray(12 * len(PLAN))
        self.halves = []
        for k, (cmd, x, y, z) in enumerate(PLAN):
            if cmd != _JUMP:
                struct.pack_into("<iif", self.xyz, 12 * k, x, y, z)
            self.halves.append((x >> 16, x & 0xFFFF, y >> 16, y & 0xFFFF))
        self.order = bytearray(2 * len(ORDER))
        self.n = 0
        self.reached = 0
        self.bad = 0
        self.err = 0
        b.watch = self.watch

    def watch(self, msgid, p):
        if msgid == _REACHED:
            if self.reached >= self.n or u16(p, 0) != self.order[self.reached]:
                self.bad += 1
            self.reached += 1

    def upload(self):
        b = self.b
        g = b.gcs()
        b.send(g.frame(_COUNT, len(PLAN), 1, 1, 0))
        b.run(2)
        for k, (cmd, x, y, z) in enumerate(PLAN):
            frame = 3  # MAV_FRAME_GLOBAL_RELATIVE_ALT
            p1 = p2 = 0.0
            if cmd == _JUMP:
                p1, p2, x, y, frame = float(x), float(y), 0, 0, 2
            elif cmd == _DELAY:
                p1, frame = 1.0, 2
            b.send(g.frame(_ITEM_INT, p1, p2, 0.0, 0.0, x, y, z, k, cmd, 1, 1, frame, 0, 1, 0))
            b.run(2)
        return self.runner.store.count == len(PLAN)

    # --- flying (allocation-free) -----------------------------------------------
    def check(self, item):
        k = item.seq
        h = self.halves[k]
        if item.command != PLAN[k][0] or item.is_nav != (item.command < 100):
            return 1
        if item.command == _JUMP:
            return 2  # the runner steps over DO_JUMPs itself
        if item.x_hi != h[0] or item.x_lo != h[1] or item.y_hi != h[2] or item.y_lo != h[3]:
            return 3
        if i32_cmp(item.rec, 16, h[0], h[1]) != 0:
            return 4
        for j in range(12):
            if item.rec[16 + j] != self.xyz[12 * k + j]:
                return 5
        return 0

    def step(self):
        r = self.runner
        item = r.item
        self.order[self.n] = item.seq
        self.n += 1
        self.err = self.check(item)
        nxt = r.next_nav(-1, self.spare)
        if nxt is not None and not nxt.is_nav:
            self.err = 6
        r.reached()
        self.b.run(1)

    def fly(self):
        """Fly the plan from MISSION_START, then again from set_current(0, reset)."""
        r = self.runner
        self.n = self.reached = self.bad = 0
        r.start()
        while r.state == _ACTIVE and self.n < len(ORDER) and not self.err:
            self.step()
        if not self.err and r.set_current(0, True):
            while r.state == _ACTIVE and self.n < 2 * len(ORDER) and not self.err:
                self.step()


def main():
    b = Bench(services=("missions",), storage=sys.argv[1])
    p = Pilot(b)
    if not p.upload():
        print("upload failed")
        return
    outs = meter(b) if len(sys.argv) > 2 and sys.argv[2] == "own" and _mem is not None else None
    p.fly()  # warm-up
    own = 0
    if outs is not None:  # a pass of its own: under heap_lock mem_total counts attempts too
        _out[0] = 0
        t = _mem()
        p.fly()
        own = _mem() - t - _out[0]
    requested = heap_requests(p.fly)
    r = p.runner
    order = ",".join(str(k) for k in p.order[:len(ORDER)])
    if p.err or p.bad or p.order != ORDER + ORDER or r.state != _COMPLETE:
        print("failed err=%d bad=%d order=%s state=%d" % (p.err, p.bad, list(p.order[:p.n]), r.state))
        return
    rest = "order=%s reached=%d state=%d" % (order, p.reached, r.state)
    if outs is not None:
        print("%s own=%d requested=%d %s" % ("fail" if own else "ok", own, requested, rest))
    elif requested:
        print("fail requested=%d %s" % (requested, rest))
    else:
        print("ok requested=0 " + rest)


main()
