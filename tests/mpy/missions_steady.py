"""Mission transfers under micropython.heap_lock().

    missions_steady.py STORAGE_DIR N

Builds the missions service (with its runner) in-process on the bench's in-memory link,
warms up with one transfer of each kind, then, with the heap locked: an upload of N
items as MISSION_ITEM_INT, its download with MISSION_REQUEST_INT, an upload in the
seed's MISSION_ITEM form (float coordinates, converted on the way in), its download
with MISSION_REQUEST (converted on the way out), a partial write and partial read,
a clear, and an upload the ground station abandons (re-requests, then the vehicle
cancels). Every frame the vehicle sends is checked as it arrives. Prints
`ok uploads=N downloads=N items=N` or what went wrong.
"""
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


class Seen:
    def __init__(self):
        self.req = -1  # last MISSION_REQUEST(_INT) seq
        self.reqs = 0
        self.ack = -1
        self.acks = 0
        self.count = -1
        self.items = 0
        self.item_seq = -1
        self.bad = 0
        self.tag_bits = 0  # param1 bits expected in items


def main():
    storage = sys.argv[1]
    n = int(sys.argv[2])
    b = Bench(services=("missions",), storage=storage)
    g = b.gcs(255, 190)
    s = Seen()

    def watch(msgid, p):
        if msgid == _REQUEST_INT or msgid == _REQUEST:
            s.req = u16(p, 0)
            s.reqs += 1
        elif msgid == _ACK:
            s.ack = p[2]
            s.acks += 1
        elif msgid == _COUNT:
            s.count = u16(p, 0)
        elif msgid == _ITEM_INT or msgid == _ITEM:
            seq = u16(p, 28)
            s.item_seq = seq
            s.items += 1
            if f32_bits(p, 0) != s.tag_bits or u16(p, 30) != 16:
                s.bad += 1
            if msgid == _ITEM_INT and (i32(p, 16) != LAT + 10 * seq or i32(p, 20) != LON - 10 * seq):
                s.bad += 1
            if msgid == _ITEM and (f32_bits(p, 16) != lat_bits[seq] or f32_bits(p, 20) != lon_bits[seq]):
                s.bad += 1

    import struct

    lat_f = [LAT / 1e7 + 1e-6 * k for k in range(n)]
    lon_f = [LON / 1e7 - 1e-6 * k for k in range(n)]
    lat_bits = [struct.unpack("<I", struct.pack("<f", v))[0] for v in lat_f]
    lon_bits = [struct.unpack("<I", struct.pack("<f", v))[0] for v in lon_f]
    one = 1.0
    two = 2.0
    ten = 10.0
    zero = 0.0
    tag_bits = struct.unpack("<I", struct.pack("<f", one))[0]
    count = g.frame(_COUNT, n, 1, 1, 0)
    count3 = g.frame(_COUNT, 3, 1, 1, 0)
    items = [g.frame(_ITEM_INT, one, two, zero, zero, LAT + 10 * k, LON - 10 * k, ten, k, 16, 1, 1, 3, 0, 1, 0)
             for k in range(n)]
    fitems = [g.frame(_ITEM, one, two, zero, zero, lat_f[k], lon_f[k], ten, k, 16, 1, 1, 3, 0, 1, 0)
              for k in range(n)]
    request_list = g.frame(_REQUEST_LIST, 1, 1, 0)
    reqs = [g.frame(_REQUEST_INT, k, 1, 1, 0) for k in range(n)]
    freqs = [g.frame(_REQUEST, k, 1, 1, 0) for k in range(n)]
    ack = g.frame(_ACK, 1, 1, 0, 0)
    clear = g.frame(_CLEAR_ALL, 1, 1, 0)
    write_partial = g.frame(_WRITE_PARTIAL, 2, 4, 1, 1, 0)
    request_partial = g.frame(_REQUEST_PARTIAL, 1, 5, 1, 1, 0)
    b.watch = watch

    def upload(frames):
        acks = s.acks
        b.send(count)
        b.run(2)
        for k in range(n):
            if s.req != k:
                return 1000 + k
            b.send(frames[k])
            b.run(2)
        if s.acks != acks + 1 or s.ack != 0:
            return 2000 + s.ack
        return 0

    def download(frames):
        items = s.items
        s.tag_bits = tag_bits
        b.send(request_list)
        b.run(2)
        if s.count != n:
            return 3000
        for k in range(n):
            b.send(frames[k])
            b.run(2)
            if s.item_seq != k or s.items != items + k + 1:
                return 4000 + k
        b.send(ack)
        b.run(2)
        return 0 if s.bad == 0 else 5000 + s.bad

    def partial():
        b.send(write_partial)
        b.run(2)
        for k in (2, 3, 4):
            if s.req != k:
                return 6000 + k
            b.send(items[k])
            b.run(2)
        if s.ack != 0:
            return 6100
        items0 = s.items
        b.send(request_partial)
        b.run(50)
        if s.items != items0 + 5 or s.item_seq != 5 or s.bad:
            return 6200
        b.send(clear)
        b.run(2)
        if s.ack != 0:
            return 6300
        return 0

    def abandoned():
        reqs0 = s.reqs
        b.send(count3)
        b.run(2)
        b.run(2000)  # 250 ms re-requests, then OPERATION_CANCELLED
        if s.reqs != reqs0 + 6 or s.ack != 15:
            return 7000 + s.reqs - reqs0
        return 0

    def session():
        return (upload(fitems) or download(freqs) or upload(items) or download(reqs)
                or partial() or abandoned())

    err = session()  # warm-up: anything allocated once is allocated now
    if err:
        print("warm-up failed", err)
        return
    s.reqs = s.acks = s.items = 0
    micropython.heap_lock()
    try:
        err = session()
    finally:
        micropython.heap_unlock()
    if err:
        print("failed", err, s.req, s.ack)
    else:
        print("ok uploads=%d downloads=%d items=%d" % (s.acks, s.count, s.items))


main()
