"""Routing: machine instructions per frame forwarded, counted by callgrind, and the heap
a route table holds.

The unix port runs bench/mpy_route.py (viper kernels) under valgrind --tool=callgrind
with the same 12,000 frames fed to an endpoint's link with a router and without one;
instructions per frame = (Ir(router) - Ir(none)) / frames. Streams: a companion's
telemetry (broadcast: each forwarded to the two other links), MAVLink 2 and 1, and a
ground station's frames for the vehicle (COMMAND_LONG, PARAM_REQUEST_READ to 1/1:
learnt, not forwarded). route_table_bytes: gc.mem_alloc() taken by Router(16) on the unix
port (64-bit; tests/mpy/route_steady.py prints it on the emulated boards as table=).

    .venv/bin/python bench/bench_route.py
"""
import json
import os
import subprocess
import sys
import tempfile

BENCH = os.path.dirname(os.path.abspath(__file__))
if BENCH not in sys.path:
    sys.path.insert(0, BENCH)

import wire_streams  # noqa: E402
from bench_wire_instr import find_valgrind  # noqa: E402

DRIVER = os.path.join(BENCH, "mpy_route.py")
FRAMES = 12000


def pack(kind, count):
    """count frames: "telemetry" from 42/191 (MAVLink 2 or 1: "telemetry1"), or "local"
    (a ground station's frames for 1/1)."""
    from pymavlink.dialects.v20 import common as m

    frames = bytearray()

    class Sink:
        def write(self, b):
            frames.extend(b)

    v1 = kind == "telemetry1"
    mav = m.MAVLink(Sink(), 255, 190) if kind == "local" else m.MAVLink(Sink(), 42, 191)
    send = mav.send
    mav.send = lambda msg, force_mavlink1=False: send(msg, force_mavlink1=v1)
    for i in range(count):
        k = i % 4
        if kind == "local":
            if k & 1:
                mav.command_long_send(1, 1, 512, 0, 33.0, 0, 0, 0, 0, 0, 0)
            else:
                mav.param_request_read_send(1, 1, b"PARAM_%03d" % (i % 300), -1)
        elif k == 0:
            mav.heartbeat_send(18, 8, 0, 0, 4, 3)
        elif k == 1:
            mav.attitude_send(i, 0.01 * i, -0.02, 1.5, 0.001, 0.002, -0.003)
        elif k == 2:
            mav.named_value_float_send(i, b"RANGE", 0.25 * i)
        else:
            mav.command_ack_send(400, 0, 0, 0, 255, 190)  # targeted: to link 1 only
    return bytes(frames)


def instructions(valgrind, stream, mode, tmp):
    out = os.path.join(tmp, "callgrind.out.%s" % mode)
    env = dict(os.environ)
    env["MICROPYPATH"] = wire_streams.FIRMWARE
    env.pop("MAVSTACK_PORTABLE", None)
    p = subprocess.run([valgrind, "--tool=callgrind", "--callgrind-out-file=" + out,
                        wire_streams.MICROPYTHON, "-X", "heapsize=32M", DRIVER, stream, mode],
                       cwd=wire_streams.ROOT, env=env, capture_output=True, text=True, timeout=600)
    if p.returncode != 0:
        raise RuntimeError("callgrind run failed\n" + p.stdout + p.stderr)
    impl, frames, forwarded, table = p.stdout.split()[-4:]
    assert impl == "viper", impl
    assert int(frames) == (FRAMES if mode != "0" else 0), frames
    with open(out) as f:
        for line in f:
            if line.startswith("summary:"):
                return int(line.split()[1]), int(forwarded), int(table)
    raise RuntimeError("no summary: line in " + out)


def run():
    valgrind = find_valgrind()
    if not valgrind:
        print("  valgrind not found and not installable here: instructions per frame not counted")
        return {}
    r = {}
    with tempfile.TemporaryDirectory() as tmp:
        for kind, key in (("telemetry", "route_v2_instr_per_frame"), ("telemetry1", "route_v1_instr_per_frame"),
                          ("local", "route_local_instr_per_frame")):
            stream = os.path.join(tmp, kind + ".bin")
            with open(stream, "wb") as f:
                f.write(pack(kind, FRAMES))
            plain, _, table = instructions(valgrind, stream, "1", tmp)
            routed, forwarded, _ = instructions(valgrind, stream, "2", tmp)
            r[key] = round((routed - plain) / FRAMES)
            want = {"telemetry": FRAMES * 7 // 4, "telemetry1": FRAMES * 7 // 4, "local": 0}[kind]
            assert forwarded == want, (kind, forwarded, want)
            r["route_table_bytes"] = table
    return r


if __name__ == "__main__":
    print(json.dumps(run(), indent=1))
