"""The parameter service's steady state under micropython.heap_lock().

    params_steady.py ENCODING VERSION BYTES_PER_S

Builds an endpoint in-process with the unix board's parameter table and an
in-memory link, warms up with one full list, then, with the heap locked: a paced
PARAM_REQUEST_LIST to the end, PARAM_REQUEST_READ by index and by name (a 16-char
name and a 15-char one), and an unknown index refused without a reply. Prints
`ok values=N reads=N ms=N` or the error.
"""
import struct
import sys

import micropython

from mavstack.dialects import common
from mavstack.encoder import Encoder
from mavstack.endpoint import Endpoint
from mavstack.parser import Parser
from mavstack.services.params import Params

sys.path.append("boards")
import unix_params  # noqa: E402


class LoopTransport:
    """Frames in from a prebuilt buffer, frames out into a parser; nothing allocated."""

    name = "loop"

    def __init__(self, bytes_per_s, on_frame):
        self.bytes_per_s = bytes_per_s
        self.inbox = bytearray(600)
        self.n_in = 0
        self.out = Parser(common.CRC_LEN, on_frame)

    def readinto(self, buf):
        n = self.n_in
        for i in range(n):
            buf[i] = self.inbox[i]
        self.n_in = 0
        return n

    def write(self, buf, n):
        self.out.feed(buf, n)
        return n

    def close(self):
        pass


class Ground:
    """Counts the vehicle's PARAM_VALUEs and checks their index order."""

    def __init__(self):
        self.values = 0
        self.next_index = 0
        self.errors = 0
        self.last_index = -1
        self.last_type = 0

    def on_frame(self, msgid, p):
        if msgid != 22:
            return
        index = p[6] | p[7] << 8
        self.last_index = index
        self.last_type = p[24]
        if index == self.next_index:
            self.next_index += 1
        else:
            self.errors += 1
        self.values += 1


def frame(enc, transport, msgid, fmt, *fields):
    off = enc.begin()
    enc.clear(255)
    struct.pack_into(fmt, enc.buf, off, *fields)
    n = enc.finish(msgid, 255, 190)
    for i in range(n):
        transport.inbox[transport.n_in + i] = enc.buf[i]
    transport.n_in += n


def prepare(enc, frames):
    """Prebuilt request frames (made before the lock): msgid, bytes."""
    out = []
    for msgid, fmt, fields in frames:
        off = enc.begin()
        enc.clear(255)
        struct.pack_into(fmt, enc.buf, off, *fields)
        n = enc.finish(msgid, 255, 190)
        out.append(bytes(enc.buf[:n]))
    return out


def inject(transport, data):
    n = transport.n_in
    for i in range(len(data)):
        transport.inbox[n + i] = data[i]
    transport.n_in = n + len(data)


def run_list(ep, transport, ground, request, start, limit):
    ground.next_index = 0
    inject(transport, request)
    now = start
    count = ground.values
    while ground.values - count < 100 and now - start < limit:
        ep.poll(now)
        now += 1
    return now - start


def reads(ep, transport, ground, frames, now):
    """Each read frame answered with exactly one PARAM_VALUE."""
    ok = 0
    for data in frames:
        before = ground.values
        inject(transport, data)
        ep.poll(now)
        if ground.values == before + 1:
            ok += 1
    return ok


def main():
    encoding = sys.argv[1]
    version = int(sys.argv[2])
    rate = int(sys.argv[3])
    ground = Ground()
    ep = Endpoint(common, 1, 1)
    transport = LoopTransport(rate, ground.on_frame)
    ep.add_link(transport, version)
    params = ep.add(Params(unix_params.PARAMS, encoding))
    enc = Encoder(common.CRC_LEN, version)
    request = prepare(enc, [(21, "<BB", (1, 1))])[0]
    read_frames = prepare(
        enc,
        [
            (20, "<hBB16s", (7, 1, 1, b"")),
            (20, "<hBB16s", (-1, 1, 1, b"SIM_GPS_GLITCH_M")),
            (20, "<hBB16s", (-1, 0, 0, b"RTL_LOIT_TIME_S")),
            (20, "<hBB16s", (99, 1, 0, b"")),
        ],
    )
    refused = prepare(enc, [(20, "<hBB16s", (100, 1, 1, b""))])
    # Warm-up: every code path once, so that lazily created state exists.
    run_list(ep, transport, ground, request, 0, 100000)
    reads(ep, transport, ground, read_frames, 100000)
    reads(ep, transport, ground, refused, 100001)
    ground.errors = 0
    before = ground.values
    micropython.heap_lock()
    try:
        ms = run_list(ep, transport, ground, request, 200000, 100000)
        listed = ground.values - before
        errors = ground.errors
        got = reads(ep, transport, ground, read_frames, 300000)
        bad = reads(ep, transport, ground, refused, 300001)
    finally:
        micropython.heap_unlock()
    if listed != 100 or errors or got != len(read_frames) or bad != 0:
        print("fail listed=%d errors=%d reads=%d refused_answered=%d" % (listed, errors, got, bad))
        return
    print("ok values=%d reads=%d ms=%d count=%d" % (listed, got, ms, params.count))


main()
