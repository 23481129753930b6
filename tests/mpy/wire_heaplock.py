"""The wire layer's per-frame paths under micropython.heap_lock(): parsing, encoding, and
a Link + Endpoint dispatching to handlers that read fields and answer.

    wire_heaplock.py STREAM OUT_DIR [ENCODE_COUNT]

STREAM is a file of frames with damage in between. Everything is set up first; then
each phase runs twice on fresh objects: unlocked, its heap requests counted with
micropython.mem_total() (which sees the frame states the VM takes from the heap for
functions with many locals; under heap_lock they silently fall back to the C stack),
then locked (MicroPython; on CPython the same code runs unlocked, so the two can be
compared). Prints one `name value...` line per result of the locked runs,
`requested parse=B encode=B link=B` (0 on CPython), and writes what the encoder and
the link sent to OUT_DIR/encoded.bin and OUT_DIR/link_tx.bin.

The phases' own functions keep their frames within the limit too (while loops, one
argument, few locals): what is counted is the whole phase.
"""
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


def parse_all(chunks):
    views, sizes = chunks
    i = 0
    while i < len(views):
        parser.feed(views[i], sizes[i])
        i += 1


def requested(fn, arg):
    """Bytes fn(arg) asked of the heap, counted with micropython.mem_total (0 on CPython)."""
    if not MICROPYTHON:
        fn(arg)
        return 0
    before = micropython.mem_total()
    fn(arg)
    return micropython.mem_total() - before


def locked(fn, arg):
    lock()
    try:
        fn(arg)
    finally:
        unlock()


# --- encoding ------------------------------------------------------------------------

class Encoding:
    """count frames (wire_kinds.py), alternately MAVLink 1 and 2, from fresh encoders;
    each frame is also fed to a loop parser and copied into out[0:pos]."""

    def __init__(self, count):
        self.count = count
        self.encoders = (Encoder(common.CRC_LEN, 1), Encoder(common.CRC_LEN, 2))
        self.loop = Parser(common.CRC_LEN, on_frame)
        self.out = bytearray(count * 60)
        self.pos = 0


def encode_all(e):
    i = 0
    while i < e.count:
        enc = e.encoders[i & 1]
        n = pack_frame(enc, i)  # one source per encoder
        e.loop.feed(enc.buf, n)
        keep(e, enc.buf, n)
        i += 1


def keep(e, buf, n):
    e.pos = append(e.out, e.pos, buf, n)


def append(out, pos, buf, n):
    """out[pos:pos+n] = buf[0:n] (no slice objects) -> pos + n."""
    j = 0
    while j < n:
        out[pos + j] = buf[j]
        j += 1
    return pos + n


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
        self.written = append(self.out, self.written, buf, n)
        return n

    def close(self):
        pass


class Answers:
    """Handlers: read fields of everything; answer COMMAND_LONG with a COMMAND_ACK."""

    def __init__(self, ep):
        self.ep = ep
        self.acks = 0

    def any(self, link, payload):
        read_fields(link.rx.msgid, payload)
        if link.rx.signed:
            acc[7] += 1

    def command(self, link, payload):
        self.any(link, payload)
        self.ack(link, u16(payload, 28))

    def ack(self, link, command):
        # COMMAND_ACK (command, result 0, progress 0, result_param2 0, target_system,
        # target_component), field by field: few values on the stack at a time.
        off = link.tx.clear(10)
        buf = link.txbuf
        buf[off] = command & 0xFF
        buf[off + 1] = command >> 8
        buf[off + 8] = link.rx.sysid
        buf[off + 9] = link.rx.compid
        if link.send(77):
            self.acks += 1


class Linked:
    """A Link in an Endpoint on a MemoryTransport of the stream, handlers attached."""

    def __init__(self, data):
        self.ep = Endpoint(common, sysid=1, compid=1)
        self.tx = bytearray(len(data) + 4096)
        self.t = MemoryTransport(data, self.tx)
        self.link = self.ep.add_link(self.t)
        self.ans = Answers(self.ep)
        for msgid in common.CRC_LEN:
            self.ep.on(msgid, self.ans.command if msgid == 76 else self.ans.any)


def link_all(x):
    ep = x.ep
    t = x.t
    now = 0
    while t.pos < len(t.data):
        ep.poll(now)
        now += 1


def new_parser():
    global parser
    parser = Parser(common.CRC_LEN, on_frame)
    parser.feed(b"\xfe")  # warm up: the first feed and a rejected candidate
    parser.feed(bytes(20))
    parser.reset_stats()
    reset()


def main(argv):
    global parser
    stream_path, out_dir = argv[0], argv[1]
    count = int(argv[2]) if len(argv) > 2 else 10000
    with open(stream_path, "rb") as f:
        data = f.read()
    print("kernels", kernels.IMPL)

    # 1. The parser alone, 4 KiB chunks.
    mv = memoryview(data)
    views = [mv[i:i + CHUNK] for i in range(0, len(data), CHUNK)]
    chunks = (views, [len(v) for v in views])
    new_parser()
    req_parse = requested(parse_all, chunks)
    new_parser()
    locked(parse_all, chunks)
    report("parse", parser)

    # 2. The encoder, MAVLink 1 and 2, checked by a parser on the loop.
    e = Encoding(count)
    parser = e.loop
    req_encode = requested(encode_all, e)
    e = Encoding(count)
    parser = e.loop
    reset()
    locked(encode_all, e)
    report("encode", e.loop)
    with open(out_dir + "/encoded.bin", "wb") as f:
        f.write(e.out[:e.pos])

    # 3. A Link in an Endpoint: transport -> parser -> dispatch -> handlers -> send.
    req_link = requested(link_all, Linked(data))
    x = Linked(data)
    reset()
    locked(link_all, x)
    report("link", x.link.rx)
    print("link_tx", x.ans.acks, x.t.written, x.link.tx_bytes, x.link.version)
    with open(out_dir + "/link_tx.bin", "wb") as f:
        f.write(x.tx[:x.t.written])
    print("requested parse=%d encode=%d link=%d" % (req_parse, req_encode, req_link))


if __name__ == "__main__":
    main(sys.argv[1:])
