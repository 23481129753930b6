"""The traffic the wire benchmarks share: FRAMES frames of six kinds packed by pymavlink
(MAVLink 1 and 2), written to files, and our ingest and encode of them on the unix port
(bench/mpy_wire.py), with the viper or the portable kernels."""
import json
import os
import subprocess

BENCH = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(BENCH)
FIRMWARE = os.path.join(ROOT, "firmware")
MICROPYTHON = os.path.join(ROOT, ".venv", "bin", "micropython")
FRAMES = 20000
ENCODE = 20000


def pack_stream(version, count):
    """count frames of the six kinds in turn, values changing, as pymavlink sends them."""
    if version == 2:
        from pymavlink.dialects.v20 import common as m
    else:
        from pymavlink.dialects.v10 import common as m
    frames = bytearray()

    class Sink:
        def write(self, b):
            frames.extend(b)

    mav = m.MAVLink(Sink(), 1, 1)
    for i in range(count):
        k = i % 6
        if k == 0:
            mav.heartbeat_send(2, 3, 81, i, 4, 3)
        elif k == 1:
            mav.attitude_send(i, 0.01 * i, -0.02, 1.5, 0.001, 0.002, -0.003)
        elif k == 2:
            mav.gps_raw_int_send(i * 1000, 3, 473977418 + i, 85455939, 488000, 120, 150, 500, 9000, 12)
        elif k == 3:
            mav.param_value_send(b"PARAM_%03d" % (i % 300), 0.5 * i, 9, 300, i % 300)
        elif k == 4:
            mav.mission_item_int_send(1, 1, i & 0xFFFF, 3, 16, 0, 1, 0.0, 2.0, 0.0, 0.0,
                                      473977418, 85455939, 50.0)
        else:
            mav.command_long_send(1, 1, 400, 0, 1.0, 0, 0, 0, 0, 0, 0)
    return bytes(frames)


def mpy_wire(v1_path, v2_path, portable):
    """mpy_wire.py's figures on the streams in these files (portable: without viper)."""
    env = dict(os.environ)
    env["MICROPYPATH"] = os.pathsep.join([FIRMWARE, ".frozen"])
    env.pop("MAVSTACK_PORTABLE", None)
    if portable:
        env["MAVSTACK_PORTABLE"] = "1"
    p = subprocess.run([MICROPYTHON, "-X", "heapsize=32M", os.path.join(BENCH, "mpy_wire.py"),
                        v1_path, v2_path, str(ENCODE)],
                       cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)
    if p.returncode != 0:
        raise RuntimeError("mpy_wire.py failed\n" + p.stdout + p.stderr)
    got = json.loads(p.stdout.strip().split("\n")[-1])
    assert got.pop("kernels") == ("portable" if portable else "viper")
    return got


def write_streams(tmp):
    """The v1 and v2 streams of FRAMES frames as files in tmp -> (v1, v2, v1_path, v2_path)."""
    os.environ.setdefault("MAVLINK20", "1")
    v1 = pack_stream(1, FRAMES)
    v2 = pack_stream(2, FRAMES)
    v1_path, v2_path = os.path.join(tmp, "v1.bin"), os.path.join(tmp, "v2.bin")
    with open(v1_path, "wb") as f:
        f.write(v1)
    with open(v2_path, "wb") as f:
        f.write(v2)
    return v1, v2, v1_path, v2_path
