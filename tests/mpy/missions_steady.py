"""Mission transfers allocate nothing, on 32-bit boards too.

    missions_steady.py STORAGE N [own]  STORAGE: a directory, or "ram" (storage_ram.py,
                                        the emulated boards' storage)

Builds the missions service (with its runner) in-process on the bench's in-memory link
and warms up with one round of everything. Then harness.heap_requests runs the round
twice, counting heap requests with micropython.mem_total() and then under
micropython.heap_lock(): an upload of N items in the seed's MISSION_ITEM form (float
degrees, converted to 1e7 integers on the way in), its download with MISSION_REQUEST
(converted back), an upload through a link that loses one item (Ground.lossy: the
re-request, the probe, a station walked in order), an upload as MISSION_ITEM_INT and its download with
MISSION_REQUEST_INT, a partial write and a partial read, a clear, and an upload the
ground station abandons (re-requests, then the vehicle cancels). Every frame the
vehicle sends is checked as it arrives; items must come back bit for bit.

The coordinates are where a 32-bit board's small ints end (2^30 in 1e7 degrees is
107.37 degrees): longitudes -122.4, 151.2, 179.9 and -180, the latitude bounds +-90,
altitudes down to -400 m. The mission store is seeded with a generation just below
2^30, so the commits of the round carry it past 2^30; a second store, seeded at
0xC000FFFF, loads and commits under the same check.

Prints `ok requested=0 uploads=6 items=2N+5 requests=... gen=XXXXXXXX gen_store=XXXXXXXX`
(the generations reached, hex), or what went wrong: `fail requested=B` followed by
the bytes each stage asked the heap for (frame states of functions over 11 words
included) and the rest of the `ok` line, when only that check failed.

With `own`, what the missions code asks for itself is counted apart: its handlers and
tick are metered, less what the code they call asks for (link.begin/send, the storage
files, the copy kernel), in one more pass (unlocked: under heap_lock, mem_total counts
the attempts too), and `ok own=0 requested=B ...` needs only that to be 0 (B: the whole
stack's, printed for the work on the shared paths; the generations are 4 and 1 higher).

(The ground station lives in a class: calling a closure over more than a few
variables allocates on MicroPython, calling a method does not. Its frames are made
once and patched in place (seq, x, y, z), so that N items cost a few bytes each; its
functions, like the vehicle's, keep to 11 words of locals and stack.)
"""
import struct
import sys

from harness import Bench, heap_requests
from mavstack.fields import u16
from mavstack.kernels import crc16
from mavstack.services.missions.store import HEADER_SIZE, RECORD_SIZE, MissionStore

_COUNT = 44
_ITEM = 39
_REQUEST = 40
_REQUEST_LIST = 43
_ACK = 47
_REQUEST_INT = 51
_ITEM_INT = 73
_CLEAR_ALL = 45
_WRITE_PARTIAL = 38
_REQUEST_PARTIAL = 37
_P = 10  # a MAVLink 2 frame's payload offset
_XYZ = 26  # x, y, z (12 bytes) in an item frame: payload offset 16

# Item k takes its place from k % 4, moved 10 (1e-4 degrees) toward 0 per round of four:
# the first four sit on the bounds. Float degrees: |lat| >= 1, where float32 is coarser
# than 1e-7, so they go in and come out bit for bit.
LAT_E7 = (473977420, -338567840, 900000000, -900000000)
LON_E7 = (-1224000000, 1512000000, 1799000000, -1800000000)
LAT = (47.397742, -33.856784, 90.0, -89.99)
LON = (-122.4, 151.2, 179.9, -180.0)
Z = (-400.0, 10.0, -400.0, 35.5)
STAGES = ("upload_float", "download_float", "upload_lossy", "upload_int", "download_int", "partial",
          "abandoned", "gen_store")
_LOST = 5  # the item the lossy upload loses on its first send
_STACK = 64  # requests the lossy upload's station keeps
GEN = 0x3FFFFFFA  # the mission store's seeded generation: the round's commits pass 2^30
STORE_GEN = 0xC000FFFF


try:  # for the `own` meters
    from micropython import mem_total as _mem
except ImportError:  # CPython, or a port without it
    _mem = None


def _toward_zero(v, d):
    return v - d if v > 0 else v + d


def _same(a, ao, b, bo, n):
    while n:
        n -= 1
        if a[ao + n] != b[bo + n]:
            return False
    return True


def seed(storage, name, gen, size):
    """Slot NAME.1 holds a valid empty plan (type 0) of generation gen, NAME.0 nothing."""
    blank = bytearray(HEADER_SIZE)
    if storage.exists(name + ".0"):
        f = storage.open(name + ".0", "r+b", size=size)
        f.write(blank)
        f.close()
    name += ".1"
    h = bytearray(HEADER_SIZE)
    h[0:4] = b"MSN\x01"
    h[5] = RECORD_SIZE
    struct.pack_into("<HIH", h, 6, 0, gen, 0xFFFF)  # count, generation, CRC of no records
    struct.pack_into("<H", h, 14, crc16(h, 0, 14, 0xFFFF))
    f = storage.open(name, "r+b" if storage.exists(name) else "wb", size=size)
    f.seek(0)
    f.write(h)
    f.flush()
    f.close()


class Ground:
    def __init__(self, b, n):
        self.b = b
        self.n = n
        g = b.gcs(255, 190)
        # x, y, z of each item, 12 bytes an item, as MISSION_ITEM_INT and as MISSION_ITEM.
        self.xyz_int = bytearray(12 * n)
        self.xyz_flt = bytearray(12 * n)
        for k in range(n):
            i = k % 4
            struct.pack_into("<iif", self.xyz_int, 12 * k, _toward_zero(LAT_E7[i], 10 * (k // 4)),
                             _toward_zero(LON_E7[i], 10 * (k // 4)), Z[i])
            struct.pack_into("<fff", self.xyz_flt, 12 * k, _toward_zero(LAT[i], 1e-4 * (k // 4)),
                             _toward_zero(LON[i], 1e-4 * (k // 4)), Z[i])
        one, two, ten, zero = 1.0, 2.0, 10.0, 0.0
        self.item = g.frame(_ITEM_INT, one, two, zero, zero, 0, 0, ten, 0, 16, 1, 1, 3, 0, 1, 0)
        self.fitem = g.frame(_ITEM, one, two, zero, zero, zero, zero, ten, 0, 16, 1, 1, 3, 0, 1, 0)
        self.req = g.frame(_REQUEST_INT, 0, 1, 1, 0)
        self.freq = g.frame(_REQUEST, 0, 1, 1, 0)
        self.count = g.frame(_COUNT, n, 1, 1, 0)
        self.count3 = g.frame(_COUNT, 3, 1, 1, 0)
        self.request_list = g.frame(_REQUEST_LIST, 1, 1, 0)
        self.ack = g.frame(_ACK, 1, 1, 0, 0)
        self.clear = g.frame(_CLEAR_ALL, 1, 1, 0)
        self.write_partial = g.frame(_WRITE_PARTIAL, 2, 4, 1, 1, 0)
        self.request_partial = g.frame(_REQUEST_PARTIAL, 1, 5, 1, 1, 0)
        # What the vehicle sent.
        self.asked = bytearray(n)  # item k has been asked for (several fly at once)
        self.times = bytearray(n)  # how often item k was asked for (up to 255)
        self.stack = bytearray(2 * _STACK)  # the lossy station's requests, newest on top
        self.top = -1  # -1: requests are not kept; else how many are
        self.overflows = 0
        self.req_seq = -1
        self.reqs_seen = 0
        self.ack_type = -1
        self.acks = 0
        self.count_seen = -1
        self.items_seen = 0
        self.item_seq = -1
        self.bad = 0
        self.err = 0
        self.heap = [0] * len(STAGES)  # bytes each stage asked the heap for
        b.watch = self.watch

    # --- the vehicle's frames ---------------------------------------------------
    def watch(self, msgid, p):
        if msgid == _REQUEST_INT or msgid == _REQUEST:
            self.req_seq = u16(p, 0)
            if self.req_seq < self.n:
                self.asked[self.req_seq] = 1
                self.times[self.req_seq] += self.times[self.req_seq] < 255
                self.keep(self.req_seq)
            self.reqs_seen += 1
        elif msgid == _ACK:
            self.ack_type = p[2]
            self.acks += 1
        elif msgid == _COUNT:
            self.count_seen = u16(p, 0)
        elif msgid == _ITEM_INT or msgid == _ITEM:
            self.got_item(msgid, p)

    def got_item(self, msgid, p):
        seq = u16(p, 28)
        self.item_seq = seq
        self.items_seen += 1
        # param1 as sent, command NAV_WAYPOINT, and x, y, z bit for bit in the form asked for
        if not _same(p, 0, self.item, _P, 4) or u16(p, 30) != 16:
            self.bad += 1
        elif not _same(p, 16, self.xyz_int if msgid == _ITEM_INT else self.xyz_flt, 12 * seq, 12):
            self.bad += 1

    # --- the ground station's side ----------------------------------------------
    def put_item(self, f, xyz, k):
        """Item k's seq, x, y, z into frame f (MISSION_ITEM_INT or MISSION_ITEM)."""
        f[_P + 28] = k & 0xFF
        f[_P + 29] = k >> 8
        o = 12 * k
        for j in range(12):
            f[_XYZ + j] = xyz[o + j]

    def send_item(self, f, xyz, k):
        self.put_item(f, xyz, k)
        self.b.send(f)
        self.b.run(2)

    def forget(self):
        """A new upload: nothing asked for yet."""
        for k in range(self.n):
            self.asked[k] = 0
            self.times[k] = 0

    def keep(self, seq):
        """The lossy station keeps each request on its stack (a full one: the oldest go)."""
        if self.top < 0:
            return
        if self.top == _STACK:
            self.overflows += 1
            return
        self.stack[2 * self.top] = seq & 0xFF
        self.stack[2 * self.top + 1] = seq >> 8
        self.top += 1

    def lossy(self):
        """An upload through a link that loses item _LOST's first send, from a station
        that answers the newest request first. The vehicle asks _LOST again once later
        items are in, then, past it, probes the item after it (which came before it):
        answered at once, alone, the station is taken for one that serves in order and
        walked forward a request at a time. Its stale requests are answered last."""
        acks = self.acks
        self.forget()
        self.top = 0
        self.b.send(self.count)
        self.b.run(2)
        lost = steps = self.overflows = 0
        while self.acks == acks and steps < 8 * self.n:
            steps += 1
            if self.top == 0:
                self.b.run(50)  # nothing asked: the vehicle's timer
                continue
            self.top -= 1
            k = self.stack[2 * self.top] | self.stack[2 * self.top + 1] << 8
            if k == _LOST and not lost:
                lost = 1
                continue
            self.send_item(self.item, self.xyz_int, k)
        self.top = -1
        if self.acks != acks + 1 or self.ack_type != 0 or self.overflows:
            return 8000 + self.ack_type
        if self.times[_LOST] < 2 or self.times[_LOST + 1] < 2:
            return 8100 + self.times[_LOST + 1]  # no re-request, or no probe
        return 0 if self.b.ep.services["missions"].transfer.strict else 8200  # found by it

    def upload(self, f, xyz):
        acks = self.acks
        self.forget()
        self.b.send(self.count)
        self.b.run(2)
        err = self.send_items(f, xyz, 0, self.n)
        if err == 0 and (self.acks != acks + 1 or self.ack_type != 0):
            err = 2000 + self.ack_type
        return err

    def send_items(self, f, xyz, k, end):
        """Items k .. end - 1, in order, each once the vehicle has asked for it."""
        while k < end:
            if not self.asked[k]:
                return 1000 + k
            self.send_item(f, xyz, k)
            k += 1
        return 0

    def download(self, f):
        seen = self.items_seen
        self.b.send(self.request_list)
        self.b.run(2)
        if self.count_seen != self.n:
            return 3000
        for k in range(self.n):
            f[_P] = k & 0xFF
            f[_P + 1] = k >> 8
            self.b.send(f)
            self.b.run(2)
            if self.item_seq != k or self.items_seen != seen + k + 1:
                return 4000 + k
        self.b.send(self.ack)
        self.b.run(2)
        return 0 if self.bad == 0 else 5000 + self.bad

    def partial(self):
        self.forget()
        self.b.send(self.write_partial)
        self.b.run(2)
        if self.send_items(self.item, self.xyz_int, 2, 5) or self.ack_type != 0:
            return 6100
        seen = self.items_seen
        self.b.send(self.request_partial)
        self.b.run(50)
        if self.items_seen != seen + 5 or self.item_seq != 5 or self.bad:
            return 6200
        self.b.send(self.clear)
        self.b.run(2)
        return 6300 if self.ack_type != 0 else 0

    def abandoned(self):
        seen = self.reqs_seen
        self.b.send(self.count3)
        # Items 0 and 1 asked (the last one waits for them), asked again after 250 and
        # 500 ms, then every 1000 (no round trip measured yet; backing off to the
        # ceiling), then OPERATION_CANCELLED 5 s after the start.
        self.b.run(5100)
        if self.reqs_seen != seen + 14 or self.ack_type != 15:
            return 7000 + self.reqs_seen - seen
        return 0

    def session(self):
        """One round of everything; the counts and self.err are this round's."""
        self.reqs_seen = self.acks = self.items_seen = 0
        self.err = 0
        for k in range(len(STAGES) - 1):
            if not self.err:
                self.stage(k)

    def stage(self, k):
        t = _mem() if _mem is not None else 0
        self.err = self.run_stage(k)
        if _mem is not None:
            self.heap[k] += _mem() - t

    def run_stage(self, k):
        if k == 0:
            return self.upload(self.fitem, self.xyz_flt)
        if k == 1:
            return self.download(self.freq)
        if k == 2:
            return self.lossy()
        if k == 3:
            return self.upload(self.item, self.xyz_int)
        if k == 4:
            return self.download(self.req)
        return self.partial() if k == 5 else self.abandoned()


class StoreCycle:
    """A store seeded with a generation of 2^30 or more: load, stage, commit, read back."""

    def __init__(self, store, heap):
        self.store = store
        self.heap = heap  # the Ground's: this is its last stage
        self.rec = bytearray(RECORD_SIZE)
        self.back = bytearray(RECORD_SIZE)
        self.err = 0

    def run(self):
        t = _mem() if _mem is not None else 0
        self.cycle()
        if _mem is not None:
            self.heap[len(STAGES) - 1] += _mem() - t

    def cycle(self):
        s = self.store
        s.load()
        self.err = 0 if not s.corrupt else 1
        s.begin()
        for k in range(3):
            self.rec[0] = k
            s.put(k, self.rec)
        if not (s.seal(3) and s.commit()):
            self.err = 2
        for k in range(3):
            if not s.read(k, self.back) or self.back[0] != k:
                self.err = 3


class Meter:
    """Heap requests inside the missions service's entry points (own), and inside the
    calls it makes out of it (out, subtracted from own)."""

    def __init__(self):
        self.own = 0
        self.out = 0


class Own:
    """Wraps a missions entry point: handler(link, payload) or tick(now)."""

    def __init__(self, meter, fn):
        self.m = meter
        self.fn = fn

    def call1(self, a):
        t = _mem() - self.m.out
        self.fn(a)
        self.m.own += _mem() - self.m.out - t

    def call2(self, a, b):
        t = _mem() - self.m.out
        self.fn(a, b)
        self.m.own += _mem() - self.m.out - t


class Out:
    """Wraps a call out of missions: its requests are not the service's."""

    def __init__(self, meter, fn):
        self.m = meter
        self.fn = fn

    def call0(self):
        t = _mem()
        r = self.fn()
        self.m.out += _mem() - t
        return r

    def call1(self, a):
        t = _mem()
        r = self.fn(a)
        self.m.out += _mem() - t
        return r

    def call2(self, a, b):
        t = _mem()
        r = self.fn(a, b)
        self.m.out += _mem() - t
        return r


_copy = None  # the copy kernel, metered by copy_out (a function: 4 arguments in a method's
_meter = None  # frame would take more than 11 words, and its frame would count as own)


def copy_out(a, b, c, d):
    t = _mem()
    _copy(a, b, c, d)
    _meter.out += _mem() - t


class OutFile:
    """A storage file whose calls are not the service's."""

    def __init__(self, meter, f):
        self.seek = Out(meter, f.seek).call1
        self.readinto = Out(meter, f.readinto).call1
        self.write = Out(meter, f.write).call1
        self.flush = Out(meter, f.flush).call0


def meter(b, stores):
    """Meter the missions service of bench b (its only service)."""
    import mavstack.services.missions.items as items
    import mavstack.services.missions.transfer as module

    global _copy, _meter
    m = _meter = Meter()
    ep = b.ep
    for msgid in ep._handlers:  # per message id: the ticker it wakes, then its handlers
        hs = ep._handlers[msgid]
        ep._handlers[msgid] = hs[:1] + tuple(Own(m, h).call2 for h in hs[1:])
    missions = ep.services["missions"]
    missions.tick = Own(m, missions.tick).call1
    for link in ep.links:
        link.begin = Out(m, link.begin).call0
        link.send = Out(m, link.send).call1
        link.can_send = Out(m, link.can_send).call2
    _copy = module.copy
    module.copy = copy_out
    items.copy = copy_out
    for store in stores:
        if store is not None:
            store._files = [OutFile(m, f) for f in store._files]
    return m


def _hex(store):
    return "%04x%04x" % (store.gen_hi, store.gen_lo)


def main():
    n = int(sys.argv[2])
    b = Bench(services=("missions",), storage=sys.argv[1])
    storage = b.ep.storage
    mission = b.ep.services["missions"].stores[0]
    seed(storage, "mission", GEN, HEADER_SIZE + mission.capacity * RECORD_SIZE)
    mission.load()
    if mission.gen != GEN:
        print("seeded generation not loaded", _hex(mission))
        return
    seed(storage, "gen", STORE_GEN, HEADER_SIZE + 8 * RECORD_SIZE)
    g = Ground(b, n)
    cycle = StoreCycle(MissionStore(storage, "gen", 0, 8), g.heap)
    if cycle.store.gen != STORE_GEN:
        print("seeded store generation not loaded", _hex(cycle.store))
        return
    own = None
    if len(sys.argv) > 3 and sys.argv[3] == "own":
        if _mem is None:
            print("own: needs micropython.mem_total")
            return
        own = meter(b, b.ep.services["missions"].stores + [cycle.store])
    g.session()  # warm-up: whatever is allocated once is allocated now
    cycle.run()
    if g.err or cycle.err:
        print("warm-up failed", g.err, cycle.err)
        return
    if own is not None:  # a pass of its own: under heap_lock mem_total counts attempts too
        own.own = own.out = 0
        g.session()
        cycle.run()
        if g.err or cycle.err:
            print("metered pass failed", g.err, cycle.err)
            return
    for k in range(len(STAGES)):
        g.heap[k] = 0
    requested = heap_requests(g.session)
    if g.err:
        print("failed", g.err, g.req_seq, g.ack_type)
        return
    requested += heap_requests(cycle.run)
    if cycle.err:
        print("store failed", cycle.err)
        return
    rest = "uploads=%d items=%d requests=%d gen=%s gen_store=%s" % (
        g.acks, g.items_seen, g.reqs_seen, _hex(mission), _hex(cycle.store))
    if own is not None:
        print("%s own=%d requested=%d %s" % ("fail" if own.own else "ok", own.own, requested, rest))
        return
    if requested:
        print("fail requested=%d %s | %s" % (requested, " ".join(
            "%s=%d" % (STAGES[k], g.heap[k]) for k in range(len(STAGES))), rest))
        return
    print("ok requested=0 " + rest)


main()
