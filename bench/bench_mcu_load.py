"""What the whole vehicle costs the CPU on the emulated boards (boards/qemu_m3.py,
qemu_m0.py): SYS_STATUS.load under three workloads, the instructions of the loop's parts.

    mcu_load_permille_{idle,pilot,transfer}_{m3,m0}
        -icount shift=3,align=on (8 virtual ns an instruction: 125 MHz at an instruction a
        cycle, kept in step with the host's clock); the vehicle's SYS_STATUS.load, averaged
        over the workload, paced in the board's time (SYSTEM_TIME's time_boot_ms):
        idle: the default streams at a 57600-baud budget, a ground station's 1 Hz HEARTBEAT;
        pilot: idle plus MANUAL_CONTROL at 20 Hz;
        transfer: idle plus a parameter download and a 100-item mission upload and
        download, six times, the station's link at 57600 baud in board time too.
    mcu_instr_{poll,ticks_ms,link_poll,tick_<service>,tick_app}_{m3,m0}
        -icount shift=0 (a virtual ns an instruction), by the board's timer over many
        calls: one ep.poll() with nothing due, the emulated clock's ticks_ms(), one link's
        poll with nothing to read, one tick of each service and the application's.
"""
import os
import sys
import time

BENCH = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(BENCH)
for _d in (os.path.join(ROOT, "mcu"), os.path.join(ROOT, "tests")):
    if _d not in sys.path:
        sys.path.insert(0, _d)

import firmware  # noqa: E402

# MCU_LOAD_ICOUNT=shift=3 drops align=on where the host's QEMU stalls with it (seen on a
# restored VM: the guest stops at 2 s of board time); the loads are then read in a board
# time that runs ahead of the host's, and the ground station is paced in it all the same.
ICOUNT_LOAD = ["-icount", os.environ.get("MCU_LOAD_ICOUNT", "shift=3,align=on")]
ICOUNT_INSTR = ["-icount", "shift=0"]
BAUD = 57600
WARMUP_MS = 3000  # board time before the loads count (start-up, the first fit)
SPAN_MS = 12000  # board time a workload's loads are read over
TARGETS = {"idle": 20, "pilot": 50, "transfer": 100}  # per mille on the M3
# Rounds of the transfer workload. How fast the host's station turns each download request
# round, in board time, moves a run's figure by +-15 % (docs/testing.md); six rounds
# average more of that out than three.
TRANSFER_ROUNDS = 6

# One tick of each part, on the board, timed by its timer (shift=0: M3's CMSDK timer at
# 25 MHz counts 40 instructions, M0's nRF51 timer 32 us = 32,000 instructions).
INSTR = """import gc
import main
import board
from mavstack import qemu
qemu.UartTransport.write = lambda self, buf, n: n  # (the M0's UART is the REPL's too)
ep, app = main.build(board, {"options": {}})
clk = qemu._clock
PER = 40 if qemu.MODEL == "m3" else 32000
N = 400 if qemu.MODEL == "m3" else 2000
def span(a, b):
    d = (a - b) if qemu.MODEL == "m3" else (b - a)
    return d % (1000000000 if qemu.MODEL == "m3" else 0x1000000)
def timed(fn, arg):
    gc.collect()
    t = clk.read()
    for _ in range(N):
        fn(arg)
    return span(t, clk.read())
def nothing(arg):
    pass
now = qemu.ticks_ms()
ep.poll(now)
ep.poll(now)
base = timed(nothing, now)
def out(name, fn, arg):
    print("instr", name, (timed(fn, arg) - base) * PER // N)
out("poll", ep.poll, now)
out("ticks_ms", lambda a: qemu.ticks_ms(), 0)
out("link_poll", lambda link: link.poll(), ep.links[0])
for t in ep.tickers:
    out("tick_" + getattr(t, "NAME", "guard"), t.tick, now)
if app is not None:
    out("tick_app", app.tick, now)
"""


class BoardClock:
    """The board's time_boot_ms, read from its messages and run on between them at the
    rate it has kept against the host's clock."""

    def __init__(self):
        self.first = self.last = None  # (host s, board ms)

    def heard(self, board_ms):
        sample = (time.time(), board_ms)
        if self.first is None:
            self.first = sample
        self.last = sample

    def rate(self):
        (h0, b0), (h1, b1) = self.first, self.last
        return (b1 - b0) / (h1 - h0) if h1 > h0 and b1 > b0 else 1000.0

    def now(self):
        if self.last is None:
            return None
        return self.last[1] + (time.time() - self.last[0]) * self.rate()


class Workload:
    """A ground station on the board's MAVLink UART: its HEARTBEAT (and MANUAL_CONTROL)
    paced in board time from a message hook, SYS_STATUS.load collected with board times."""

    def __init__(self, gcs, pilot=False):
        self.gcs = gcs
        self.clock = BoardClock()
        self.loads = []  # (board ms, per mille)
        self.pilot = pilot
        self.next_beat = self.next_stick = None
        self.rx_rate = 0  # bytes/s: the downlink's, in board time (paced_writes)
        self.rx_free = 0.0  # the board time the messages read so far have all come by
        gcs.message_hooks.append(self._hook)

    def _hook(self, _m, msg):
        if msg.get_type() == "SYSTEM_TIME":  # (telemetry slots carry their writes' times)
            self.clock.heard(msg.time_boot_ms)
        if msg.get_type() == "SYS_STATUS" and self.clock.last is not None:
            self.loads.append((self.clock.now(), msg.load))
        now = self.clock.now()
        if self.rx_rate and now is not None:
            self.rx_free = max(self.rx_free, now) + len(msg.get_msgbuf()) * 1000.0 / self.rx_rate
        self.pace()

    def paced_writes(self, bytes_per_s):
        """The station's link as a radio's in board time: each write waits until the
        bytes before it would have gone, and _wait acts on a message only once the bytes
        read before it and its own would have come."""
        self.rx_rate = bytes_per_s
        write = self.gcs.write
        free = [0.0]

        def paced(buf):
            now = self.clock.now()
            if now is not None:
                at = max(free[0], now)
                while self.clock.now() < at:
                    time.sleep(0.0002)
                free[0] = at + len(buf) * 1000.0 / bytes_per_s
            return write(buf)

        self.gcs.write = paced

    def pace(self):
        now = self.clock.now()
        if now is None:
            return
        if self.next_beat is None:
            self.next_beat = self.next_stick = now
        if now >= self.next_beat:
            self.next_beat += 1000
            self.gcs.mav.heartbeat_send(6, 8, 0, 0, 4)  # a GCS
        while self.pilot and now >= self.next_stick:
            self.next_stick += 50
            self.gcs.mav.manual_control_send(1, 0, 0, 500, 0, 0)

    def run_for(self, ms):
        """Read and pace for ms of board time."""
        end = None
        while True:
            self.gcs.recv_msg()
            self.pace()
            now = self.clock.now()
            if now is not None:
                end = end if end is not None else now + ms
                if now >= end:
                    return
            time.sleep(0.002)

    def load(self, since, until):
        """The mean of the loads reported between these board times (per mille)."""
        got = [v for t, v in self.loads if since <= t <= until]
        if not got:
            raise RuntimeError("no SYS_STATUS after %d ms of board time" % since)
        return sum(got) / len(got)


def _wait(w, want, timeout=2.0):
    """The next message for which want(msg) holds -> it, None after timeout s. Read as
    fast as the host can: pymavlink's blocking reads wait in steps that, in board time
    (which runs faster than the host's here), are longer than a radio's round trip."""
    end = time.time() + timeout
    while time.time() < end:
        m = w.gcs.recv_msg()
        if m is None:
            w.pace()
            time.sleep(0.0001)
        elif want(m):
            while w.rx_rate and w.clock.now() < w.rx_free:
                time.sleep(0.0002)
            return m
    return None


def _transfers(w, rounds=TRANSFER_ROUNDS):
    """A parameter download, a 100-item mission upload and download, `rounds` times, by a
    station that answers at once -> the board times (ms) the transfers started and ended."""
    from mission_gcs import MissionClient, plan

    client = MissionClient(w.gcs)  # (its encoders only)
    items = plan(100)
    start = w.clock.now()
    for _ in range(rounds):
        w.gcs.mav.param_request_list_send(1, 1)
        got = set()
        while len(got) < 100:
            m = _wait(w, lambda m: m.get_type() == "PARAM_VALUE")
            if m is None:
                raise RuntimeError("the parameter download gave %d of 100" % len(got))
            got.add(m.param_index)
        client._send("mission_count", 1, 1, len(items), 0)
        while True:
            m = _wait(w, lambda m: m.get_type() in ("MISSION_REQUEST_INT", "MISSION_ACK"))
            if m is None or m.get_type() == "MISSION_ACK" and m.type != 0:
                raise RuntimeError("the mission upload failed: %s" % m)
            if m.get_type() == "MISSION_ACK":
                break
            client.send_item(m.seq, items[m.seq])
        client._send("mission_request_list", 1, 1, 0)
        if _wait(w, lambda m: m.get_type() == "MISSION_COUNT") is None:
            raise RuntimeError("no MISSION_COUNT")
        for seq in range(len(items)):
            for _ in range(5):
                client._send("mission_request_int", 1, 1, seq, 0)
                if _wait(w, lambda m: m.get_type() == "MISSION_ITEM_INT" and m.seq == seq, 1.0):
                    break
            else:
                raise RuntimeError("the mission download stopped at item %d" % seq)
        client._send("mission_ack", 1, 1, 0, 0)
    return start, w.clock.now()


def load(board, kind):
    """SYS_STATUS.load (per mille) of the vehicle on this board under this workload."""
    from mcu_rig import EmulatedBoard

    with EmulatedBoard(board, qemu_args=ICOUNT_LOAD) as b:
        gcs = b.start_vehicle({"baud_budget": BAUD})
        w = Workload(gcs, pilot=(kind == "pilot"))
        w.run_for(WARMUP_MS)
        if kind == "transfer":
            w.paced_writes(BAUD // 10)
            start, end = _transfers(w)
            w.run_for(1500)  # the report of the transfers' last second
            # Reports whose second lies within the transfers (the first is partly idle).
            since, until = start + 1000, end + 1000
        else:
            since = w.clock.now() + 1000
            w.run_for(SPAN_MS)
            until = w.clock.now()
        gcs.message_hooks.clear()
        if os.environ.get("LOADS"):
            print(kind, since, until, [(round(t), v) for t, v in w.loads])
        return round(w.load(since, until), 1)


def instructions(board):
    """-> {part: instructions} of one call each, on the board under shift=0."""
    from mcu_rig import EmulatedBoard

    with EmulatedBoard(board, qemu_args=ICOUNT_INSTR) as b:
        out = b.exec(INSTR, timeout=300)
    got = {}
    for line in out.splitlines():
        words = line.split()
        if len(words) == 3 and words[0] == "instr":
            got[words[1]] = int(words[2])
    return got


def run():
    if firmware.tools_missing():
        raise RuntimeError("MCU tools missing (make mcu-deps): %s" % firmware.tools_missing())
    out = {}
    for board, tag in (("qemu_m3", "m3"), ("qemu_m0", "m0")):
        for part, n in instructions(board).items():
            out["mcu_instr_%s_%s" % (part, tag)] = n
        for kind in ("idle", "pilot", "transfer"):
            try:  # a workload that fails loses its key (a missed floor), not the others'
                out["mcu_load_permille_%s_%s" % (kind, tag)] = load(board, kind)
            except Exception as e:
                print("mcu_load %s %s: %s" % (board, kind, e), file=sys.stderr)
    return out


def floors(results):
    return [("mcu_load_permille_%s_m3 <= %d" % (k, v), results.get("mcu_load_permille_%s_m3" % k, 1e9) <= v)
            for k, v in TARGETS.items()]


if __name__ == "__main__":
    import json

    board = sys.argv[1] if len(sys.argv) > 1 else "qemu_m3"
    kinds = sys.argv[2:] or ["instr", "idle", "pilot", "transfer"]
    res = {}
    for k in kinds:
        if k == "instr":
            res.update(instructions(board))
        else:
            res[k] = load(board, k)
        print(k, res, flush=True)
    print(json.dumps(res, indent=1))
