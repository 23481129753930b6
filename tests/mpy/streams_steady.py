"""The telemetry steady state: every slot written every tick, ten streams scheduled.

    streams_steady.py VERSION BYTES_PER_S TICKS [SCALE [bench]]

An endpoint with the commands and streams services on the in-memory link
(tests/mpy/harness.py), ten streams at 1..50 Hz, a REQUEST_DATA_STREAM every 100
ticks (a group none of them is in, stopped), a simulated clock that starts
5 s before ticks_ms wraps (rates multiplied by SCALE, to overload a slow link).
After a warm-up, TICKS ticks run between
micropython.heap_lock() and heap_unlock() (on CPython, without the lock).
Before the locked run, the same ticks run unlocked with micropython.mem_total()
counting: requested= the bytes the polls (link, scheduler, producers, sends, the
in-memory link) asked of the heap, which must be 0 (frame states the VM takes from
the heap for functions with many locals show there: under heap_lock they silently
fall back to the C stack); app= those the application's slot writes asked for
(a setter with nine or more parameters has more locals than fit, see telemetry.py).
Prints `ok ticks=N bytes=N us=N requested=0 app=N MSGID:COUNT ...` (frames of each
stream received over the locked run), `fail ...` the same when requested is not 0,
or the error. With `bench`, us is the mean wall time of one poll (reading the idle
link and the scheduler's tick, its sends included).
"""
import sys

try:
    import micropython
except ImportError:
    micropython = None
from mavstack.compat import ticks_add, ticks_us, ticks_diff as us_diff
from harness import Bench

# (message id, Hz): ten streams of telemetry slots.
RATES = ((30, 50), (31, 25), (33, 20), (32, 10), (24, 5), (74, 4), (26, 10), (65, 2), (36, 2), (147, 1))
WARMUP = 1500


class Values:
    """What an application would hold: ints and floats made once."""

    def __init__(self):
        self.f = 0.125
        self.g = -1.5
        self.chans = [1500, 1500, 1100, 1500, 1900, 1500, 1000, 1000]
        self.servos = [1200, 1210, 1190, 1205]
        self.cells = [4100, 4104, 4098]


def write_slots(tm, v, i):
    f = v.f
    g = v.g
    tm.attitude(f, g, f, g, f, g)
    tm.attitude_quaternion(f, g, f, g, f, g, f)
    tm.global_position(473977420 + i, 85455940 - i, 488000, i & 0xFFFF, 100, -50, 3, 9000)
    tm.local_position(f, g, f, g, f, g)
    tm.gps_raw(3, 473977420, 85455940, 488000, 80, 120, 150, 9000, 12)
    tm.vfr_hud(f, f, 90, 42, g, f)
    tm.scaled_imu(1, 2, -1000, 4, 5, 6, 210, 0, 430)
    tm.rc_channels(v.chans, 230)
    tm.servo_output(v.servos)
    tm.battery(12300, 450, 87, 120, v.cells)


class State:
    """What the loops below take whole (one argument, few locals: their frames stay off
    the heap, so what is counted is what the stack and the slots ask for)."""

    def __init__(self, b, v):
        self.b = b
        self.v = v
        self.tm = b.ep.telemetry
        self.us = 0  # spent polling
        self.stack = 0  # bytes the polls asked of the heap (counted runs)
        self.app = 0  # ... and the slot setters
        # A ground station's REQUEST_DATA_STREAM every 100 ticks (RAW_CONTROLLER, stop: a
        # group none of the measured messages is in), handled on the counted path too.
        self.request = b.gcs().frame(66, 0, 1, 1, 4, 0)
        self.k = 0


def poll(s):
    b = s.b
    s.k += 1
    if s.k % 100 == 0:
        b.send(s.request)
    b.now = ticks_add(b.now, 1)
    t0 = ticks_us()
    b.ep.poll(b.now)
    s.us += us_diff(ticks_us(), t0)
    b.drain()


def run(s, ticks):
    """ticks rounds of: write every slot, poll, read what came out."""
    i = 0
    while i < ticks:
        write_slots(s.tm, s.v, i)
        poll(s)
        i += 1


def run_counted(s, ticks):
    """run(), unlocked, with micropython.mem_total() counting the polls (s.stack) and the
    application's slot writes (s.app) apart."""
    mem = micropython.mem_total
    i = 0
    while i < ticks:
        m = mem()
        write_slots(s.tm, s.v, i)
        s.app += mem() - m
        m = mem()
        poll(s)
        s.stack += mem() - m
        i += 1


def main():
    version = int(sys.argv[1])
    bps = int(sys.argv[2])
    ticks = int(sys.argv[3])
    scale = int(sys.argv[4]) if len(sys.argv) > 4 else 1
    bench = len(sys.argv) > 5 and sys.argv[5] == "bench"
    b = Bench(services=("commands", "streams"), version=version)
    link = b.ep.links[0]
    link.bytes_per_s = bps
    if version == 2:
        link.tx.version = 2
        link.negotiate = False
    streams = b.ep.services["streams"]
    counting = micropython is not None and hasattr(micropython, "mem_total")
    # The wrap falls inside the locked run (after the warm-up and the counted run).
    b.now = ticks_add(0, -(WARMUP + (ticks if counting else 0) + 5000))
    s = State(b, Values())
    for msgid, hz in RATES:
        streams.set_rate(link, msgid, hz * scale)
    run(s, WARMUP)
    if counting:
        run_counted(s, ticks)
    before = [b.seen[msgid] for msgid, _ in RATES]
    tx = link.tx_bytes
    s.us = 0
    if micropython is not None:
        micropython.heap_lock()
    try:
        run(s, ticks)
    finally:
        if micropython is not None:
            micropython.heap_unlock()
    counts = " ".join("%d:%d" % (RATES[k][0], b.seen[RATES[k][0]] - before[k]) for k in range(len(RATES)))
    per_tick = s.us // ticks if bench else 0
    print("%s ticks=%d bytes=%d us=%d requested=%d app=%d %s" % (
        "fail" if s.stack else "ok", ticks, link.tx_bytes - tx, per_tick, s.stack, s.app, counts))


main()
