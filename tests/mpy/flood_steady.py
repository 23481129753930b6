"""Held-back COMMAND_ACKs in steady state under micropython.heap_lock(): a flood from many
system ids and a ground station asking for more than its share, on a 57600 baud radio.

    flood_steady.py [ROUNDS]
The link is budgeted at 5760 B/s. A ground station (255/190) sends a HEARTBEAT every
simulated second, has every stream at 10 Hz, and sends REQUEST_MESSAGE SYS_STATUS every
40 ms (more than its share: some of its ACKs are held back, late=, and sent by later
ticks, each followed by its SYS_STATUS, in_order=); every millisecond a flood sends
REQUEST_MESSAGE (confirmation 0, or 1: a retry), or PING, from system ids 2..250 in turn
(their held-back ACKs crowd the queue: dropped=, the station's kept). After a warm-up the
rounds run twice: unlocked, counted with mem_total(), then under heap_lock(). Prints
`OK rounds=N asked=N acked=N late=N in_order=N held=N dropped=N flood_acks=N
heartbeats=N requested=0` (the locked run's figures; requested: bytes the unlocked run
asked of the heap), or FAIL and the same when that is not 0.
"""
import sys

import micropython

from harness import Bench

_STATION = 255


class Flood:
    """The bench, the frames and what the station got (one argument for steady())."""

    def __init__(self):
        b = Bench(services=("status", "commands", "streams"))
        b.ep.links[0].bytes_per_s = 5760
        self.b = b
        g = b.gcs(_STATION, 190)
        self.hb = g.heartbeat()
        self.ask = g.command(512, 1.0)  # REQUEST_MESSAGE SYS_STATUS
        self.streams = g.frame(66, 10, 1, 1, 0, 1)  # REQUEST_DATA_STREAM: all at 10 Hz
        f = b.gcs(2, 190)  # one builder; each frame's sysid is set before it goes
        self.f = f
        self.flood = (f.command(512, 1.0), f.frame(4, 1234567, 9, 0, 0), f.command(512, 1.0, confirmation=1))
        self.sysid = 2
        self.asked = 0
        self.acked = 0  # ACKs to the station
        self.late = 0  # ... that did not go in the poll its command came in
        self.in_order = 0  # ... each followed by its SYS_STATUS before the next ACK
        self.flood_acks = 0
        self.owed = 0  # the station's ACK seen, its SYS_STATUS not yet


def watch(msgid, p):
    s = STATE
    if msgid == 77:
        if p[8] == _STATION:
            s.acked += 1
            s.owed += 1
        else:
            s.flood_acks += 1
    elif msgid == 1 and s.owed:
        s.owed -= 1
        s.in_order += 1


def steady(s, rounds):
    i = 0
    while i < rounds:
        if i % 1000 == 0:
            s.b.send(s.hb)
        acked = s.acked
        if i % 40 == 0:
            s.b.send(s.ask)
            s.asked += 1
        f = s.flood[i % 3]
        f[5] = s.sysid  # (MAVLink 2: the sender's system id)
        s.b.send(f, s.f)
        s.sysid = s.sysid + 1 if s.sysid < 250 else 2
        s.b.run(1)
        if i % 40 == 0 and s.acked == acked:
            s.late += 1
        i += 1


def main():
    global STATE
    rounds = int(sys.argv[1]) if len(sys.argv) > 1 else 6000
    s = STATE = Flood()
    s.b.watch = watch
    commands = s.b.ep.services["commands"]
    s.b.send(s.streams)
    steady(s, 2000)  # warm up: first-time paths may allocate
    before = micropython.mem_total()
    steady(s, rounds)
    requested = micropython.mem_total() - before
    s.b.run(1000)  # the held-back ACKs go out
    s.asked = s.acked = s.late = s.in_order = s.flood_acks = 0
    held0 = commands.acks_held
    dropped0 = commands.acks_dropped
    hb0 = s.b.seen[0]
    micropython.heap_lock()
    try:
        steady(s, rounds)
        s.b.run(1000)
    finally:
        micropython.heap_unlock()
    print("%s rounds=%d asked=%d acked=%d late=%d in_order=%d held=%d dropped=%d flood_acks=%d heartbeats=%d "
          "requested=%d"
          % ("FAIL" if requested else "OK", rounds, s.asked, s.acked, s.late, s.in_order, commands.acks_held - held0,
             commands.acks_dropped - dropped0, s.flood_acks, s.b.seen[0] - hb0, requested))


STATE = None
main()
