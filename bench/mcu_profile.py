"""Where the emulated M3's instructions go under a workload of bench_mcu_load.py: the
vehicle built as main.py builds it, its parts wrapped in counters read from the board's
timer (-icount shift=0: 40 instructions a count), main.run itself run for a span of
board time (its sleep timed, and left at the span's end) while the ground station paces
its frames in that time. Prints, per part, its calls, instructions per call and
instructions per board second (inclusive: a part's figure holds the parts it calls; the
counters' own cost is taken out).

    .venv/bin/python bench/mcu_profile.py [idle|pilot|transfer] [seconds] [detail]

detail: also the handlers by message id, the parsers, the encoders and the missions
service's store and transfer.

A diagnostic for the note of a change to the loop, not a `make bench` key.
"""
import os
import sys

BENCH = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, BENCH)

import bench_mcu_load  # noqa: E402  (its paths, its Workload)

BOARD = """import main
import board
from mavstack import qemu
ep, app = main.build(board, {"options": {"baud_budget": "57600"}})
clk = qemu._clock
acc = {}
def span(a, b):
    return (a - b) % 1000000000
def wrapped(f, key, n=1):
    # Fixed arities: a *args wrapper would allocate on every call.
    cell = acc.get(key)
    if cell is None:
        cell = acc[key] = [0, 0, 0]
    def w0():
        t = clk.read()
        r = f()
        cell[1] += span(t, clk.read())
        cell[0] += 1
        if cell[1] > 0x10000000:  # (a small int under the locked heap: carried)
            cell[1] -= 0x10000000
            cell[2] += 1
        return r
    def w1(a):
        t = clk.read()
        r = f(a)
        cell[1] += span(t, clk.read())
        cell[0] += 1
        if cell[1] > 0x10000000:  # (a small int under the locked heap: carried)
            cell[1] -= 0x10000000
            cell[2] += 1
        return r
    def w2(a, b=-1):
        t = clk.read()
        r = f(a, b)
        cell[1] += span(t, clk.read())
        cell[0] += 1
        if cell[1] > 0x10000000:  # (a small int under the locked heap: carried)
            cell[1] -= 0x10000000
            cell[2] += 1
        return r
    def w3(a, b, c):
        t = clk.read()
        r = f(a, b, c)
        cell[1] += span(t, clk.read())
        cell[0] += 1
        if cell[1] > 0x10000000:  # (a small int under the locked heap: carried)
            cell[1] -= 0x10000000
            cell[2] += 1
        return r
    return (w0, w1, w2, w3)[n]
def wrap(obj, name, key, n=1):
    setattr(obj, name, wrapped(getattr(obj, name), key, n))
t = clk.read()
for _ in range(200):
    span(t, clk.read())
over = span(t, clk.read()) // 200
busy = [0, 0]
status = ep.services.get("status")
idle = status.idle
end = [0]
class Done(Exception):
    pass
DONE = Done()
def timed_idle(ms, sleep):
    # main.run's sleep, the board's clock read around it; at the span's end, out of main.run
    a = clk.read()
    idle(ms, sleep)
    busy[0] += span(a, clk.read())
    busy[1] += 1
    if qemu.ticks_diff(end[0], qemu.ticks_ms()) <= 0:
        raise DONE
status.idle = timed_idle
def loop(ms):
    # main.run itself (heap locked: the board's HEAP_LOCK), for ms of board time
    t0 = clk.read()
    end[0] = qemu.ticks_add(qemu.ticks_ms(), ms)
    try:
        main.run(ep, app)
    except Done:
        pass
    return span(t0, clk.read())
loop(2000)
wrap(ep, "poll", "ep.poll")
wrap(ep, "dispatch", "ep.dispatch", 3)
for i, link in enumerate(ep.links):
    wrap(link, "poll", "link%d.poll" % i, 0)
    wrap(link, "send", "link%d.send" % i, 2)
    wrap(link.transport, "write", "link%d.transport.write" % i, 2)
for t in ep.tickers:
    wrap(t, "tick", "tick." + getattr(t, "NAME", "guard"))
streams = ep.services.get("streams")
for ls in (streams.links if streams is not None else ()):
    for st in ls.streams:
        if st.send is not None:
            wrap(st, "send", "stream%d.%d" % (ls.link.index, st.msgid))
if app is not None:
    wrap(app, "tick", "tick.app")
if DETAIL:  # the handlers by message id, the parsers, the mission stores and transfer
    for msgid in list(ep._handlers):
        hs = ep._handlers[msgid]  # (the ticker it wakes, handlers...)
        ep._handlers[msgid] = hs[:1] + tuple(wrapped(h, "handler.%d" % msgid, 2) for h in hs[1:])
    for i, link in enumerate(ep.links):
        wrap(link.rx, "feed", "link%d.rx.feed" % i, 2)
        wrap(link, "begin", "link%d.begin" % i, 0)
        wrap(link.tx, "finish", "link%d.tx.finish" % i, 3)
    missions = ep.services.get("missions")
    if missions is not None:
        for st in missions.stores:
            wrap(st, "read", "missions.store.read", 2)
            wrap(st, "put", "missions.store.put", 2)
        wrap(missions.transfer, "_take", "missions.upload._take", 3)
        wrap(missions.transfer, "_got", "missions.upload._got", 2)
busy[0] = busy[1] = 0
total = loop(SPAN)
print("profile total", total * 40, "sleep", busy[0] * 40, "passes", busy[1], "over", over * 40)
for k, c in acc.items():
    print("profile", k, c[0], (c[2] * 0x10000000 + c[1] - c[0] * over) * 40)
"""


def profile(kind="pilot", seconds=10, detail=False):
    from mcu_rig import EmulatedBoard

    span_ms = int(seconds * 1000)
    # (a heap larger than the vehicle's smallest: the counters and wrappers live there too)
    with EmulatedBoard("qemu_m3", 96, qemu_args=bench_mcu_load.ICOUNT_INSTR) as b:
        os.environ["MAVLINK20"] = "1"
        from pymavlink import mavutil

        b.start_script(BOARD.replace("SPAN", str(span_ms)).replace("DETAIL", str(detail)))
        gcs = mavutil.mavlink_connection(b.ptys[-1], baud=115200, source_system=255, source_component=190)
        w = bench_mcu_load.Workload(gcs, pilot=(kind == "pilot"))
        w.run_for(2000)
        if kind == "transfer":  # (paced as bench_mcu_load paces it)
            w.paced_writes(bench_mcu_load.BAUD // 10)
            bench_mcu_load._transfers(w, rounds=1)
        else:
            w.run_for(span_ms)
        out = b.finish_script(None, None, timeout=600)
    rows = []
    total = sleep = passes = 0
    for line in out.splitlines():
        words = line.split()
        if words[:2] == ["profile", "total"]:
            total, sleep, passes = int(words[2]), int(words[4]), int(words[6])
        elif words[:1] == ["profile"] and len(words) == 4:
            rows.append((words[1], int(words[2]), int(words[3])))
    per_s = 1000.0 / span_ms
    print("%s on qemu_m3: %d ms of board time, %d passes; busy %.1f M instructions/s "
          "(%.1f per mille of 125 MHz)" % (kind, span_ms, passes, (total - sleep) * per_s / 1e6,
                                           (total - sleep) * per_s / 125e3))
    print("%-24s %8s %12s %14s" % ("part", "calls/s", "instr/call", "M instr/s"))
    for name, calls, instr in sorted(rows, key=lambda r: -r[2]):
        if calls:
            print("%-24s %8.1f %12d %14.3f" % (name, calls * per_s, instr // calls, instr * per_s / 1e6))


if __name__ == "__main__":
    profile(sys.argv[1] if len(sys.argv) > 1 else "pilot", float(sys.argv[2]) if len(sys.argv) > 2 else 10,
            "detail" in sys.argv[3:])
