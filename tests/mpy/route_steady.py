"""Routing in steady state under micropython.heap_lock(): frames forwarded between three
in-memory links, nothing taken from the heap.

    route_steady.py [ROUNDS]
Link 0 has a ground station (255/190), link 1 a camera of the vehicle's own system
(1/100), link 2 a companion computer (42/191). Every round (one poll), in turn: the
station's broadcast PING, its COMMAND_LONG to the companion and to the camera, the
companion's HEARTBEAT, its SYSTEM_TIME (time_boot_ms past 2^30, growing) followed by a
MAVLink 1 ATTITUDE, the camera's NAMED_VALUE_INT to the station; RADIO_STATUS from a
radio on link 0 now and then (never forwarded; its txbuf low, very low and high in turn:
radio flow control steps link 0's budget and reports LINK_FLOW). After a warm-up the rounds run twice:
unlocked, counted with mem_total(), then under heap_lock(). Prints `OK rounds=N
forwarded=N not_sent=N routes=N table=N requested=0` (the locked run's figures; table: the
heap a 16-route table holds; requested: bytes the unlocked run asked of the heap), or FAIL
and the same when that is not 0.
"""
import gc
import sys

import micropython

from harness import Bench, loop_pair
from mavstack.router import Router
from mavstack.encoder import Encoder


class Net:
    def __init__(self):
        b = Bench(services=("status", "commands"))
        ep = b.ep
        self.ends = [None]
        for i in (1, 2):
            v, g = loop_pair(8192, name="loop%d" % i)
            ep.add_link(v)
            self.ends.append(g)
        gc.collect()
        before = gc.mem_alloc()
        router = Router(16, 10000, 0)
        gc.collect()
        self.table = gc.mem_alloc() - before  # the heap a 16-route table holds
        self.router = ep.add(router)
        self.b = b
        self.buf = bytearray(512)
        gcs, cam, comp = b.gcs(255, 190), b.gcs(1, 100), b.gcs(42, 191)
        radio = b.gcs(51, 68)
        comp1 = Encoder(b.dialect.CRC_LEN, 1)  # the companion's MAVLink 1 frames
        off = comp1.begin()
        comp1.buf[off] = 1  # ATTITUDE: time_boot_ms 1, the rest zero
        self.att_v1 = bytearray(comp1.buf[: comp1.finish(30, 42, 191)])
        self.time = comp.frame(2, 0, 0x40000000)  # SYSTEM_TIME: time_boot_ms past 2^30
        self.radio = radio.frame(109, 0, 0, 100, 90, 95, 10, 20)  # RADIO_STATUS, txbuf 95
        # (link index, builder, frame)
        self.frames = (
            (0, gcs, gcs.frame(4, 1234567, 9, 0, 0)),  # PING, broadcast
            (2, comp, comp.frame(0, 0, 18, 8, 0, 0, 3)),  # HEARTBEAT, onboard controller
            (1, cam, cam.frame(0, 0, 30, 8, 0, 0, 3)),  # HEARTBEAT, camera
            (0, gcs, gcs.command(512, 1.0, target_system=42, target_component=191)),
            (2, comp, self.time),
            (0, gcs, gcs.command(512, 1.0, target_system=1, target_component=100)),
            (1, cam, cam.frame(252, 1, 7, b"RANGE")),  # NAMED_VALUE_INT
            (0, radio, self.radio),
        )

    def send(self, i, g, f):
        n = g.stamp(f)
        if i == 0:
            self.b.gcs_end.write(f, n)
        else:
            self.ends[i].write(f, n)

    def drain(self):
        i = 1
        while i < 3:
            while self.ends[i].readinto(self.buf):
                pass
            i += 1


def steady(net, rounds):
    i = 0
    while i < rounds:
        one(net, net.frames[i % len(net.frames)])
        i += 1


def one(net, f):
    if f[2] is net.time:
        grow(net.time)
    elif f[2] is net.radio:
        # txbuf (frame byte 16): low, very low, full in turn; flow control steps on each
        net.radio[16] = 40 if net.radio[16] == 95 else 10 if net.radio[16] == 40 else 95
    net.send(f[0], f[1], f[2])
    if f[2] is net.time:
        net.ends[2].write(net.att_v1, len(net.att_v1))
    net.b.run(1)
    net.drain()


def grow(t):
    # time_boot_ms (frame bytes 18..21) grows by 256 ms
    t[19] = (t[19] + 1) & 0xFF
    if t[19] == 0:
        t[20] += 1


def main():
    rounds = int(sys.argv[1]) if len(sys.argv) > 1 else 4000
    net = Net()
    steady(net, 2500)  # warm up (over two simulated seconds): first-time paths may allocate
    before = micropython.mem_total()
    steady(net, rounds)
    requested = micropython.mem_total() - before
    r = net.router
    fwd0, not0 = r.forwarded, r.not_sent
    micropython.heap_lock()
    try:
        steady(net, rounds)
    finally:
        micropython.heap_unlock()
    routes = len(r.routes())
    assert net.b.ep.links[0].radio_reports > 0 and net.b.seen[252] > 0  # flow control ran
    ok = requested == 0 and r.forwarded - fwd0 > rounds
    print("%s rounds=%d forwarded=%d not_sent=%d routes=%d table=%d requested=%d"
          % ("OK" if ok else "FAIL", rounds, r.forwarded - fwd0, r.not_sent - not0, routes, net.table, requested))


main()
