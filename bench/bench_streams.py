"""Telemetry streams: the scheduler's cost per tick, and how well rates are kept.

sched_tick_us: mean wall time of one endpoint poll on MicroPython's unix port with
ten streams running (1..50 Hz) and every telemetry slot written each tick: reading
the idle in-memory link, then the scheduler's tick with the frames it sends
(tests/mpy/streams_steady.py, simulated clock; median of 3 runs of 10,000 ticks).

rate_error_pct: the worst relative error between requested and received rate over
four streams (50, 20, 10 and 5 Hz) set with MAV_CMD_SET_MESSAGE_INTERVAL on the
unix vehicle, measured for 6 s by pymavlink over UDP from arrival times.

    .venv/bin/python bench/bench_streams.py
"""
import json
import os
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tests"))
from vehicle import Vehicle  # noqa: E402
MICROPYTHON = os.path.join(ROOT, ".venv", "bin", "micropython")
STEADY = os.path.join(ROOT, "tests", "mpy", "streams_steady.py")
STREAMS = {"ATTITUDE": (30, 50), "GLOBAL_POSITION_INT": (33, 20), "VFR_HUD": (74, 10), "SCALED_IMU": (26, 5)}
SECONDS = 6.0


def sched_tick_us():
    env = dict(os.environ)
    env["MICROPYPATH"] = os.pathsep.join(
        [os.path.join(ROOT, "tests", "mpy"), os.path.join(ROOT, "firmware"), ".frozen"])
    runs = []
    for _ in range(3):
        out = subprocess.run([MICROPYTHON, STEADY, "2", "200000", "10000", "1", "bench"], cwd=ROOT, env=env,
                             capture_output=True, text=True, timeout=120).stdout.strip()
        if not out.startswith("ok "):
            raise RuntimeError("streams_steady.py: " + out)
        runs.append(int(dict(w.split("=") for w in out.split()[1:4])["us"]))
    return sorted(runs)[1]


def rate_error_pct():
    import tempfile

    with tempfile.TemporaryDirectory() as storage:
        v = Vehicle(storage).start()
        try:
            m = v.gcs()
            for msgid, hz in STREAMS.values():
                m.mav.command_long_send(1, 1, 511, 0, msgid, 1e6 / hz, 0, 0, 0, 0, 0)
                if m.recv_match(type="COMMAND_ACK", blocking=True, timeout=5) is None:
                    raise RuntimeError("SET_MESSAGE_INTERVAL not acknowledged")
            times = {name: [] for name in STREAMS}
            settle = time.time() + 0.5
            end = settle + SECONDS
            beat = 0
            while time.time() < end:
                if time.time() > beat:
                    beat = time.time() + 0.5
                    m.mav.heartbeat_send(6, 8, 0, 0, 0)
                msg = m.recv_match(blocking=True, timeout=0.05)
                if msg is not None and msg.get_type() in times and time.time() > settle:
                    times[msg.get_type()].append(time.time())
        finally:
            v.stop()
    worst = 0.0
    for name, (_, hz) in STREAMS.items():
        ts = times[name]
        got = (len(ts) - 1) / (ts[-1] - ts[0]) if len(ts) > 1 else 0.0
        worst = max(worst, abs(got - hz) / hz * 100)
    return round(worst, 2)


def run():
    return {"sched_tick_us": sched_tick_us(), "rate_error_pct": rate_error_pct()}


def floors(results):
    return [
        ("rate_error_pct <= 5 (rates kept within 5%)", results["rate_error_pct"] <= 5),
        ("sched_tick_us < 1000 (a tick fits a 1 ms loop)", results["sched_tick_us"] < 1000),
    ]


if __name__ == "__main__":
    print(json.dumps(run(), indent=1))
