"""Status and command handling in steady state under micropython.heap_lock().

    status_steady.py SERVICES [STORAGE] [ROUNDS]
SERVICES is a comma list (status,commands[,params,...]). A ground station's heartbeat
every simulated second, and a burst of commands each 50 ms: arm/disarm, an unknown
command, REQUEST_MESSAGE (SYS_STATUS, AUTOPILOT_VERSION), COMMAND_INT, SET_MODE, PING,
a corrupted frame, a STATUSTEXT. After a warm-up the rounds run twice: unlocked, counted
with micropython.mem_total(), then under heap_lock() (any allocation raises MemoryError).
Prints `OK rounds=N acks=N ... requested=0` (the figures of the locked run; requested:
bytes the unlocked one asked of the heap), or FAIL and the same when that is not 0.
"""
import sys

import micropython

from harness import Bench


def build(services, storage):
    b = Bench(services=services, storage=storage)
    g = b.gcs()
    frames = (
        g.heartbeat(),
        g.command(400, 1.0),  # arm
        g.command(400, 0.0),  # disarm
        g.command(31000),  # unknown
        g.command(512, 1.0),  # REQUEST_MESSAGE SYS_STATUS
        g.command(512, 148.0),  # REQUEST_MESSAGE AUTOPILOT_VERSION
        g.command_int(176, 0, 1.0 + 16, 3.0),  # DO_SET_MODE as COMMAND_INT
        g.frame(11, 0, 1, 4 | 16),  # SET_MODE
        g.frame(4, 1234567, 9, 0, 0),  # PING request
        g.command(400, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1, 1, 1),  # arm, confirmation 1
        g.command(400, 0.0, 21196.0),  # forced disarm
    )
    bad = bytearray(frames[3])
    bad[-1] ^= 0xFF  # CRC error
    return b, frames[0], frames[1:], bad


class Steady:
    """The bench and its frames; steady() takes it whole (one argument, few locals: its
    frame stays off the heap, and the measured run counts everything)."""

    def __init__(self, b, hb, burst, bad):
        self.b = b
        self.hb = hb
        self.burst = burst
        self.bad = bad
        self.k = 0  # the next frame of the burst


def steady(s, rounds):
    s.k = 0
    i = 0
    while i < rounds:
        if i % 1000 == 0:
            s.b.send(s.hb)
        if i % 700 == 0:
            s.b.ep.statustext(6, b"steady state")
        if i % 50 == 0:
            burst(s)
        s.b.run(1)
        i += 1


def burst(s):
    s.b.send(s.burst[s.k])
    s.k += 1
    if s.k == len(s.burst):
        s.k = 0
        s.b.send_raw(s.bad)


def main():
    services = sys.argv[1].split(",") if len(sys.argv) > 1 else ("status", "commands")
    storage = sys.argv[2] if len(sys.argv) > 2 and sys.argv[2] != "-" else None
    rounds = int(sys.argv[3]) if len(sys.argv) > 3 else 5000
    s = Steady(*build(services, storage))
    b = s.b
    steady(s, 2000)  # warm up: first-time paths may allocate
    # The same rounds unlocked, counted with mem_total: the frame states the VM takes
    # from the heap for functions with many locals (under heap_lock they silently fall
    # back to the C stack) show here.
    before = micropython.mem_total()
    steady(s, rounds)
    requested = micropython.mem_total() - before
    acks0 = b.acks
    hb0 = b.seen[0]
    sys0 = b.seen[1]
    version0 = b.seen[148]
    ping0 = b.seen[4]
    unsupported0 = b.results[3]
    text0 = b.seen[253]
    micropython.heap_lock()
    try:
        steady(s, rounds)
    finally:
        micropython.heap_unlock()
    st = b.ep.services["status"]
    print("%s rounds=%d acks=%d heartbeats=%d sys_status=%d version=%d ping=%d errors_comm=%d unsupported=%d "
          "text=%d requested=%d" % ("FAIL" if requested else "OK", rounds, b.acks - acks0, b.seen[0] - hb0,
                                    b.seen[1] - sys0, b.seen[148] - version0, b.seen[4] - ping0, st.errors_comm,
                                    b.results[3] - unsupported0, b.seen[253] - text0, requested))


main()
