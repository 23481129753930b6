"""Signed traffic in steady state, with real-world timestamps (48-bit, units of 10 us
since 2015: always past 2^30). Two pymavlink-like signers (link ids 0 and 1, timestamps
from the time of day, one up per frame) send PINGs the vehicle must verify; tampered,
replayed, too-old, a day ahead and unsigned frames it must drop; it signs everything it
sends, which the bench checks (signature, timestamps rising and past 2^32). The vehicle's
clock runs from the time of day.

First harness.heap_requests() (mem_total unlocked, then heap_lock) on the signing
service's own paths (verify, replay rejection, sign, clock tick with time-of-day sync, a
save into a plain storage stub), on a stretch of the whole steady state, and on the
first save into storage_ram; then, with LOCK, N frames between heap_lock() and
heap_unlock().

    signing_steady.py N [LOCK]

Prints `ok impl=viper|portable accepted=N bad=K replayed=2K unsigned=K pings=N future=K
out=M bad_out=0 own=0 requested=B ram_save=B copy=B locked=ok saved=1 ms=T` (K = N / 100:
tampered, replayed old frames and too old new streams, unsigned; out: vehicle frames
checked good), or `fail` and the same fields. own: bytes the service's own paths asked
of the heap, which must be 0; requested: the whole steady state's per 100 frames
(shared paths too), ram_save: storage_ram's first save, copy: one call of the shared
copy kernel (the portable one's frame may come from the heap; then a small stand-in
takes its place while own is measured), all printed for the zero-heap work elsewhere;
ms: the N frames' time.
"""
import sys

from harness import Bench, Board, heap_requests
from mavstack.compat import ticks_add, ticks_diff, ticks_ms
from mavstack.kernels import copy
from mavstack.kernels import sha256
from mavstack.services import signing
from mavstack.kernels.sha256 import Signature, SHA256_IMPL

try:
    import micropython
except ImportError:
    micropython = None

KEY = bytes(range(1, 33))
_PING = 4
UNIX_USEC = 1767225600000000  # 2026-01-01, the vehicle's time of day
GCS_TS = 34715520000000  # the ground station's: 2026-01-01 minus 1 s, in 10 us since 2015


class SigningBoard(Board):
    SIGNING_SAVE_MS = 3600000  # no save in the steady state: save() is checked on its own


def _le6(v):
    # Set-up only: the ints here are heap objects on a 32-bit board.
    return bytearray((v >> (8 * i)) & 0xFF for i in range(6))


class Station:
    """A pymavlink-like signer on one link id: a PING frame, re-sent with the next
    sequence number, a new time_usec byte and the next timestamp, signed in place."""

    def __init__(self, bench, link_id, ts):
        self.g = bench.gcs(255, 190)
        f = self.g.frame(_PING, 0, 1, 0, 0)  # seq 1 keeps the payload from truncating
        self.f = bytearray(len(f) + 13)
        for i in range(len(f)):
            self.f[i] = f[i]
        self.f[2] |= 1  # IFLAG_SIGNED
        self.n = len(self.f)
        self.link_id = link_id
        self.ts = _le6(ts)
        self.sig = Signature()
        self.count = 0

    def next(self):
        f = self.f
        self.count += 1
        f[10] = self.count & 0xFF  # time_usec's low byte
        end = self.g.stamp(f)  # sequence number and CRC
        f[end] = self.link_id
        ts = self.ts
        for i in range(6):  # + 1, bytewise
            ts[i] = (ts[i] + 1) & 0xFF
            if ts[i]:
                break
        for i in range(6):
            f[end + 1 + i] = ts[i]
        self.sig.sign(KEY, f, end + 7)
        return f


def _copy(dst, src, n):
    for i in range(n):
        dst[i] = src[i]


class OutputCheck:
    """verify hook on the bench's parser: every vehicle frame signed with KEY, its
    timestamp rising and past 2^32."""

    def __init__(self):
        self.sig = Signature()
        self.last = bytearray(6)
        self.good = 0
        self.bad = 0

    def verify(self, buf, plen, signed):
        s = 10 + plen + 3  # the timestamp
        if signed and self.sig.matches(KEY, buf, s + 6) and self._rising(buf, s):
            self.good += 1
        else:
            self.bad += 1
        return True

    def _rising(self, buf, s):
        last = self.last
        i = 5
        while i > 0 and buf[s + i] == last[i]:
            i -= 1
        if buf[s + i] <= last[i] or not (buf[s + 4] | buf[s + 5]):
            return False
        for i in range(6):
            last[i] = buf[s + i]
        return True


class _Rx:
    """What check() reads of the parser, for the direct calls."""
    sysid = 255
    compid = 190
    msgid = _PING


class Traffic:
    def __init__(self, n):
        b = self.b = Bench(services=("signing", "status"), board=SigningBoard, storage="ram",
                           ram_storage_kb=4)
        self.svc = b.ep.services["signing"]
        b.ep.services["status"].set_clock(UNIX_USEC)
        self.svc.set_key(KEY)
        self.streams = (Station(b, 0, GCS_TS), Station(b, 1, GCS_TS + 5000))
        # A third link's frame two minutes behind the vehicle: a new stream too far back;
        # a fourth's a day ahead of the vehicle's time of day: refused, not taken.
        self.stale = Station(b, 2, GCS_TS - 12000000).next()
        self.ahead = Station(b, 3, GCS_TS + 8640000000).next()
        first = self.streams[0].next()
        self.replay = bytearray(first)  # accepted once below, replayed from then on
        self.tampered = bytearray(len(first))
        self.unsigned = b.gcs(255, 190).frame(_PING, 0, 0, 0, 0)
        self.check = OutputCheck()
        b.rx.verify = self.check.verify
        b.send_raw(first, len(first))
        b.run(200, 10)
        self.out = bytearray(64)
        self.rx = _Rx()

    def bad_ones(self, f):
        # A tampered copy of a good frame, the old frame again, a too old stream, unsigned.
        b = self.b
        t = self.tampered
        _copy(t, f, len(t))
        t[len(t) - 1] ^= 1
        b.send_raw(t, len(t))
        b.send_raw(self.replay, len(self.replay))
        b.send_raw(self.stale, len(self.stale))
        b.send_raw(self.ahead, len(self.ahead))
        b.send_raw(self.unsigned, len(self.unsigned))

    def steady(self, n):
        for i in range(n):
            self.frame(i)
            self.b.run(1, 10)

    def frame(self, i):
        f = self.streams[i & 1].next()
        self.b.send_raw(f, len(f))
        if i % 100 == 0:
            self.bad_ones(f)

    def stretch(self):
        self.steady(100)

    def paths(self):
        # The service's own per-frame and per-tick work, called directly: two good
        # frames, a replay, a too old new stream, an unsigned one; a frame signed; a
        # tick past the clock's step and the time-of-day sync (not the save: save()).
        self._verify(self.streams[0].next(), True)
        self._verify(self.streams[1].next(), True)
        self._verify(self.replay, True)
        self._verify(self.stale, True)
        self._verify(self.ahead, True)
        self._verify(self.unsigned, False)
        out = self.out
        _copy(out, self.unsigned, len(self.unsigned))
        self.svc.sign(out, 10 + out[1] + 2, 0)
        self.b.now = ticks_add(self.b.now, 10000)
        self.svc.tick(self.b.now)

    def copy6(self):
        copy(self.out, self.unsigned, 0, 6)

    def _verify(self, f, signed):
        self.svc.check(self.rx, f, f[1], signed)

    def save(self):
        self.svc._save()

    def save_to(self, storage):
        # A save into the given storage -> bytes requested ("MemoryError": allocated locked).
        ep = self.b.ep
        kept = ep.storage
        ep.storage = storage
        try:
            return heap_requests(self.save)
        except MemoryError:
            return "MemoryError"
        finally:
            ep.storage = kept


class FlatStorage:
    """The storage face at its plainest (one preallocated file): what the service's own
    save costs, apart from any storage's."""

    def __init__(self):
        self.data = bytearray(64)
        self.n = 0
        self.commits = 0

    def open_new(self, name, size=None):
        self.n = 0
        return self

    def write(self, buf):
        for i in range(len(buf)):
            self.data[i] = buf[i]
        self.n = len(buf)
        return self.n

    def close(self):
        pass

    def commit(self, name):
        self.commits += 1


def own_requests(t):
    # The service's own paths: verify, reject, sign, tick with sync, save into a stub.
    flat = FlatStorage()
    own = heap_requests(t.paths)
    saved = t.save_to(flat)
    if not (flat.commits and flat.n == 42):
        return "unsaved"
    return saved if saved == "MemoryError" else own + saved


def main(n, lock):
    t = Traffic(n)
    svc = t.svc
    copy_heap = heap_requests(t.copy6)
    own = own_requests(t)
    requested = heap_requests(t.stretch)
    ram_save = t.save_to(t.b.ep.storage)
    saved = t.b.ep.storage.exists("signing_key")
    svc.accepted = svc.bad_signature = svc.replayed = svc.future = svc.unsigned = 0
    pings = t.b.seen[_PING]
    t.check.good = t.check.bad = 0
    start = ticks_ms()
    if lock:
        micropython.heap_lock()
    try:
        t.steady(n)
        locked = "ok"
    except MemoryError:
        locked = "MemoryError"
    if lock:
        micropython.heap_unlock()
    ms = ticks_diff(ticks_ms(), start)
    k = n // 100
    got = (svc.accepted, svc.bad_signature, svc.replayed, svc.unsigned, t.b.seen[_PING] - pings, svc.future)
    good = (locked == "ok" and own == 0 and saved and got == (n, k, 2 * k, k, n, k)
            and t.check.good >= n and t.check.bad == 0)
    print("%s impl=%s accepted=%d bad=%d replayed=%d unsigned=%d pings=%d future=%d out=%d bad_out=%d "
          "own=%s requested=%d ram_save=%s copy=%d locked=%s saved=%d ms=%d" % (
              "ok" if good else "fail", SHA256_IMPL, got[0], got[1], got[2], got[3], got[4], got[5],
              t.check.good, t.check.bad, own, requested, ram_save, copy_heap, locked, saved, ms))


main(int(sys.argv[1]), len(sys.argv) > 2)
