"""The wire layer's per-frame paths under micropython.heap_lock(): parsing, encoding, and
a Link + Endpoint dispatching to handlers that read fields and answer.

    wire_heaplock.py STREAM OUT_DIR [ENCODE_COUNT]

STREAM is a file of frames with damage in between. Everything is set up first; then
each phase runs locked (MicroPython; on CPython the same code runs unlocked, so the
two can be compared). Prints one `name value...` line per result and writes what the
encoder and the link sent to OUT_DIR/encoded.bin and OUT_DIR/link_tx.bin.
"""
import struct
import sys

from mavstack import kernels
from mavstack.compat import MICROPYTHON
from mavstack.dialects import common
from mavstack.encoder import Encoder
from mavstack.endpoint import Endpoint
from mavstack.fields import cstr_len, f32_is_nan, i32, u16, u32
from mavstack.parser import Parser
from wire_kinds import pack_frame

if MICROPYTHON:
    import micropython

    lock, unlock = micropython.heap_lock, micropython.heap_unlock
else:

    def lock():
        pass

    unlock = lock

CHUNK = 4096

# What the handlers add up, by index (all small ints).
ACC = ("frames", "custom_mode", "nan_roll", "param_id_len", "lat", "command", "mission_x", "signed", "other")
acc = [0] * len(ACC)
parser = None


def read_fields(msgid, p):
    """Field reads of the kind services do, allocation-free (mavstack.fields)."""
    acc[0] += 1
    if msgid == 0:
        acc[1] += u32(p, 0)
    elif msgid == 30:
        if f32_is_nan(p, 4):
            acc[2] += 1
    elif msgid == 22:
        acc[3] += cstr_len(p, 8, 16)
    elif msgid == 24:
        acc[4] += i32(p, 8)
    elif msgid == 76:
        acc[5] += u16(p, 28)
    elif msgid == 73:
        acc[6] += i32(p, 16)
    else:
        acc[8] += 1


def on_frame(msgid, payload):
    read_fields(msgid, payload)
    if parser.signed:
        acc[7] += 1


def reset():
    for i in range(len(acc)):
        acc[i] = 0


def report(name, p):
    print(name, " ".join("%s=%d" % (k, v) for k, v in zip(ACC, acc)),
          "stats", p.frames, p.crc_errors, p.bytes_discarded, p.unknown_ids, p.bad_frames, p.lost)


def parse_locked(views, sizes):
    lock()
    try:
        for i in range(len(views)):
            parser.feed(views[i], sizes[i])
    finally:
        unlock()


# --- encoding ------------------------------------------------------------------------

def encode_locked(encoders, count, out, loop):
    """count frames (wire_kinds.py), alternately MAVLink 1 and 2; each frame is also fed
    to the loop parser and copied into out. Returns bytes written."""
    pos = 0
    lock()
    try:
        for i in range(count):
            enc = encoders[i & 1]
            n = pack_frame(enc, i)  # one source per encoder
            buf = enc.buf
            loop.feed(buf, n)
            for j in range(n):
                out[pos + j] = buf[j]
            pos += n
    finally:
        unlock()
    return pos


# --- a Link and an Endpoint ------------------------------------------------------------


class MemoryTransport:
    """The bytes a peer sent, read in the link's chunks; what the link writes is kept."""

    name = "memory"
    bytes_per_s = 1000000

    def __init__(self, data, out):
        self.data = data
        self.pos = 0
        self.out = out
        self.written = 0

    def readinto(self, buf):
        n = len(self.data) - self.pos
        if n > len(buf):
            n = len(buf)
        kernels.copy(buf, self.data, self.pos << 10, n)
        self.pos += n
        return n

    def write(self, buf, n):
        out = self.out
        w = self.written
        for j in range(n):
            out[w + j] = buf[j]
        self.written = w + n
        return n

    def close(self):
        pass


class Answers:
    """Handlers: read fields of everything; answer COMMAND_LONG with a COMMAND_ACK."""

    def __init__(self, ep):
        self.ep = ep
        self.acks = 0
        self.fmt_ack = ep.fmt(77)

    def any(self, link, payload):
        read_fields(link.rx.msgid, payload)
        if link.rx.signed:
            acc[7] += 1

    def command(self, link, payload):
        self.any(link, payload)
        off = link.begin()
        struct.pack_into(self.fmt_ack, link.txbuf, off, u16(payload, 28), 0, 0, 0,
                         link.rx.sysid, link.rx.compid)
        if link.send(77):
            self.acks += 1


def link_locked(ep, t):
    lock()
    try:
        now = 0
        while t.pos < len(t.data):
            ep.poll(now)
            now += 1
    finally:
        unlock()


def main(argv):
    global parser
    stream_path, out_dir = argv[0], argv[1]
    count = int(argv[2]) if len(argv) > 2 else 10000
    with open(stream_path, "rb") as f:
        data = f.read()
    print("kernels", kernels.IMPL)

    # 1. The parser alone, 4 KiB chunks.
    parser = Parser(common.CRC_LEN, on_frame)
    mv = memoryview(data)
    views = [mv[i:i + CHUNK] for i in range(0, len(data), CHUNK)]
    sizes = [len(v) for v in views]
    parser.feed(b"\xfe")  # warm up: the first feed and a rejected candidate
    parser.feed(bytes(20))
    parser.reset_stats()
    reset()
    parse_locked(views, sizes)
    report("parse", parser)

    # 2. The encoder, MAVLink 1 and 2, checked by a parser on the loop.
    reset()
    encoders = (Encoder(common.CRC_LEN, 1), Encoder(common.CRC_LEN, 2))
    loop = Parser(common.CRC_LEN, on_frame)
    parser = loop
    out = bytearray(count * 60)
    n = encode_locked(encoders, count, out, loop)
    report("encode", loop)
    with open(out_dir + "/encoded.bin", "wb") as f:
        f.write(out[:n])

    # 3. A Link in an Endpoint: transport -> parser -> dispatch -> handlers -> send.
    reset()
    ep = Endpoint(common, sysid=1, compid=1)
    tx = bytearray(len(data) + 4096)
    t = MemoryTransport(data, tx)
    link = ep.add_link(t)
    ans = Answers(ep)
    for msgid in common.CRC_LEN:
        ep.on(msgid, ans.command if msgid == 76 else ans.any)
    link_locked(ep, t)
    report("link", link.rx)
    print("link_tx", ans.acks, t.written, link.tx_bytes, link.version)
    with open(out_dir + "/link_tx.bin", "wb") as f:
        f.write(tx[:t.written])


if __name__ == "__main__":
    main(sys.argv[1:])
