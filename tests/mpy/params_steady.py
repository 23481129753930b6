"""The parameter service's steady state under micropython.heap_lock().

    params_steady.py ENCODING VERSION BYTES_PER_S

A bench vehicle (status, params, commands) with the unix board's 100 parameters on an
in-memory link paced as BYTES_PER_S. After a warm-up, with the heap locked: a full
PARAM_REQUEST_LIST to the end (in index order, nothing else owed), PARAM_REQUEST_READ
by index and by name (16 and 15 characters), an unknown index (STATUSTEXT, no value),
accepted PARAM_SETs of a float and an integer, and DO_SET_PARAMETER.
Prints `ok values=N reads=N sets=N ms=N` or what went wrong.
"""
import struct
import sys

import micropython

import harness
from harness import Bench

sys.path.append("boards")
import unix_params  # noqa: E402


class Board(harness.Board):
    PARAMS = unix_params.PARAMS


class Ground:
    """Counts PARAM_VALUEs and checks that a list arrives in index order."""

    def __init__(self):
        self.values = 0
        self.next_index = 0
        self.errors = 0

    def on_frame(self, msgid, p):
        if msgid != 22:
            return
        if (p[6] | p[7] << 8) == self.next_index:
            self.next_index += 1
        else:
            self.errors += 1
        self.values += 1


def int_bits_as_float(v):
    return struct.unpack("<f", struct.pack("<i", v))[0]


def build(encoding, version, rate):
    b = Bench(services=("status", "params", "commands"), board=Board,
              options={"param_encoding": encoding}, version=version)
    b.ep.links[0].bytes_per_s = rate
    g = b.gcs()
    frames = {
        "list": g.frame(21, 1, 1),
        "reads": [
            g.frame(20, 7, 1, 1, b""),
            g.frame(20, -1, 1, 1, b"SIM_GPS_GLITCH_M"),
            g.frame(20, -1, 0, 0, b"RTL_LOIT_TIME_S"),
            g.frame(20, 99, 1, 0, b""),
        ],
        "unknown": g.frame(20, 100, 1, 1, b""),
        "sets": [
            g.frame(23, 7.5, 1, 1, b"SIM_SPEED", 9),
            g.frame(23, 6.5, 1, 1, b"SIM_SPEED", 9),
            g.frame(23, 6100.0 if encoding == "c_cast" else int_bits_as_float(6100), 1, 1, b"BATT_CAPACITY", 6),
            g.frame(23, 6200.0 if encoding == "c_cast" else int_bits_as_float(6200), 1, 1, b"BATT_CAPACITY", 6),
        ],
        "commands": [
            g.command(180, 20.0, 12.0),
            g.command(180, 20.0, 15.0),
        ],
    }
    return b, frames


def run_list(b, ground, frames, limit, out):
    ground.next_index = 0
    before = ground.values
    b.send(frames["list"])
    start = b.now
    n = 0
    while ground.values - before < 100 and n < limit:
        b.run(1)
        n += 1
    out[0] = ground.values - before
    out[1] = b.now - start


def one_each(b, ground, frames):
    """How many of the frames got exactly one PARAM_VALUE back."""
    ok = 0
    for f in frames:
        before = ground.values
        b.send(f)
        n = 0
        while ground.values == before and n < 200:  # paced: may wait for credit
            b.run(1)
            n += 1
        b.run(20)
        if ground.values == before + 1:
            ok += 1
    return ok


def quiet(b, ground, f):
    before = ground.values
    b.send(f)
    b.run(3)
    return ground.values - before


def steady(b, ground, frames, out):
    """Fills out (a list: returning a tuple would allocate)."""
    run_list(b, ground, frames, 100000, out)
    out[2] = ground.errors
    out[3] = one_each(b, ground, frames["reads"])
    out[4] = quiet(b, ground, frames["unknown"])
    out[5] = one_each(b, ground, frames["sets"])
    acks = b.results[0]
    out[6] = one_each(b, ground, frames["commands"])
    out[7] = b.results[0] - acks


def main():
    encoding = sys.argv[1]
    version = int(sys.argv[2])
    rate = int(sys.argv[3])
    ground = Ground()
    b, frames = build(encoding, version, rate)
    b.watch = ground.on_frame
    b.run(10)
    out = [0] * 8
    steady(b, ground, frames, out)  # warm-up: first-time paths may allocate
    ground.errors = 0
    micropython.heap_lock()
    try:
        steady(b, ground, frames, out)
    finally:
        micropython.heap_unlock()
    listed, ms, errors, reads, unknown, sets, commands, accepted = out
    params = b.ep.services["params"]
    if (listed, errors, reads, unknown, sets, commands, accepted) != (100, 0, 4, 0, 4, 2, 2):
        print("fail", out)
        return
    if params.get("SIM_SPEED") != 6.5 or params.get("BATT_CAPACITY") != 6200 or params.get("SIM_SPEED") == 0:
        print("fail values", params.get("SIM_SPEED"), params.get("BATT_CAPACITY"))
        return
    print("ok values=%d reads=%d sets=%d commands=%d ms=%d" % (listed, reads, sets, commands, ms))


main()
