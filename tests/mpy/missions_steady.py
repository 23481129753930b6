"""Mission transfers under micropython.heap_lock().

    missions_steady.py STORAGE_DIR N

Builds the missions service (with its runner) in-process on the bench's in-memory link,
warms up with one round of everything, then, with the heap locked: an upload of N items
in the seed's MISSION_ITEM form (float coordinates, converted on the way in), its
download with MISSION_REQUEST (converted on the way out), an upload as MISSION_ITEM_INT
and its download with MISSION_REQUEST_INT, a partial write and a partial read, a clear,
and an upload the ground station abandons (re-requests, then the vehicle cancels).
Every frame the vehicle sends is checked as it arrives. Prints
`ok uploads=N items=N requests=N` or what went wrong.

(The ground station lives in a class: calling a closure over more than a few
variables allocates on MicroPython, calling a method does not.)
"""
import struct
import sys

import micropython

from harness import Bench
from mavstack.fields import u16, i32, f32_bits

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
LAT = 473977420
LON = 85455940


def _bits(v):
    return struct.unpack("<I", struct.pack("<f", v))[0]


class Ground:
    def __init__(self, b, n):
        self.b = b
        self.n = n
        g = b.gcs(255, 190)
        one, two, ten, zero = 1.0, 2.0, 10.0, 0.0
        lat_f = [LAT / 1e7 + 1e-6 * k for k in range(n)]
        lon_f = [LON / 1e7 - 1e-6 * k for k in range(n)]
        self.lat_bits = [_bits(v) for v in lat_f]
        self.lon_bits = [_bits(v) for v in lon_f]
        self.tag_bits = _bits(one)
        self.count = g.frame(_COUNT, n, 1, 1, 0)
        self.count3 = g.frame(_COUNT, 3, 1, 1, 0)
        self.items = [g.frame(_ITEM_INT, one, two, zero, zero, LAT + 10 * k, LON - 10 * k, ten, k, 16, 1, 1, 3, 0, 1, 0)
                      for k in range(n)]
        self.fitems = [g.frame(_ITEM, one, two, zero, zero, lat_f[k], lon_f[k], ten, k, 16, 1, 1, 3, 0, 1, 0)
                       for k in range(n)]
        self.request_list = g.frame(_REQUEST_LIST, 1, 1, 0)
        self.reqs = [g.frame(_REQUEST_INT, k, 1, 1, 0) for k in range(n)]
        self.freqs = [g.frame(_REQUEST, k, 1, 1, 0) for k in range(n)]
        self.ack = g.frame(_ACK, 1, 1, 0, 0)
        self.clear = g.frame(_CLEAR_ALL, 1, 1, 0)
        self.write_partial = g.frame(_WRITE_PARTIAL, 2, 4, 1, 1, 0)
        self.request_partial = g.frame(_REQUEST_PARTIAL, 1, 5, 1, 1, 0)
        # What the vehicle sent.
        self.req = -1
        self.reqs_seen = 0
        self.ack_type = -1
        self.acks = 0
        self.count_seen = -1
        self.items_seen = 0
        self.item_seq = -1
        self.bad = 0
        b.watch = self.watch

    def watch(self, msgid, p):
        if msgid == _REQUEST_INT or msgid == _REQUEST:
            self.req = u16(p, 0)
            self.reqs_seen += 1
        elif msgid == _ACK:
            self.ack_type = p[2]
            self.acks += 1
        elif msgid == _COUNT:
            self.count_seen = u16(p, 0)
        elif msgid == _ITEM_INT or msgid == _ITEM:
            seq = u16(p, 28)
            self.item_seq = seq
            self.items_seen += 1
            if f32_bits(p, 0) != self.tag_bits or u16(p, 30) != 16:
                self.bad += 1
            if msgid == _ITEM_INT:
                if i32(p, 16) != LAT + 10 * seq or i32(p, 20) != LON - 10 * seq:
                    self.bad += 1
            elif f32_bits(p, 16) != self.lat_bits[seq] or f32_bits(p, 20) != self.lon_bits[seq]:
                self.bad += 1

    def upload(self, frames):
        b = self.b
        acks = self.acks
        b.send(self.count)
        b.run(2)
        for k in range(self.n):
            if self.req != k:
                return 1000 + k
            b.send(frames[k])
            b.run(2)
        if self.acks != acks + 1 or self.ack_type != 0:
            return 2000 + self.ack_type
        return 0

    def download(self, frames):
        b = self.b
        seen = self.items_seen
        b.send(self.request_list)
        b.run(2)
        if self.count_seen != self.n:
            return 3000
        for k in range(self.n):
            b.send(frames[k])
            b.run(2)
            if self.item_seq != k or self.items_seen != seen + k + 1:
                return 4000 + k
        b.send(self.ack)
        b.run(2)
        return 0 if self.bad == 0 else 5000 + self.bad

    def partial(self):
        b = self.b
        b.send(self.write_partial)
        b.run(2)
        for k in (2, 3, 4):
            if self.req != k:
                return 6000 + k
            b.send(self.items[k])
            b.run(2)
        if self.ack_type != 0:
            return 6100
        seen = self.items_seen
        b.send(self.request_partial)
        b.run(50)
        if self.items_seen != seen + 5 or self.item_seq != 5 or self.bad:
            return 6200
        b.send(self.clear)
        b.run(2)
        return 6300 if self.ack_type != 0 else 0

    def abandoned(self):
        seen = self.reqs_seen
        self.b.send(self.count3)
        self.b.run(2000)  # a request, 5 re-requests 250 ms apart, then OPERATION_CANCELLED
        if self.reqs_seen != seen + 6 or self.ack_type != 15:
            return 7000 + self.reqs_seen - seen
        return 0

    def session(self):
        return (self.upload(self.fitems) or self.download(self.freqs) or self.upload(self.items)
                or self.download(self.reqs) or self.partial() or self.abandoned())


def main():
    n = int(sys.argv[2])
    b = Bench(services=("missions",), storage=sys.argv[1])
    g = Ground(b, n)
    err = g.session()  # warm-up: whatever is allocated once is allocated now
    if err:
        print("warm-up failed", err)
        return
    g.reqs_seen = g.acks = g.items_seen = 0
    micropython.heap_lock()
    try:
        err = g.session()
    finally:
        micropython.heap_unlock()
    if err:
        print("failed", err, g.req, g.ack_type)
    else:
        print("ok uploads=%d items=%d requests=%d" % (g.acks, g.items_seen, g.reqs_seen))


main()
