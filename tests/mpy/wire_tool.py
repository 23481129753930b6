"""The wire layer driven from files, identically on MicroPython and CPython.

    wire_tool.py parse DIALECT CHUNKS OUT IN...   each stream file IN through a fresh Parser
    wire_tool.py encode DIALECT IN OUT            frames for the payloads listed in IN
    wire_tool.py kernels IN OUT                   the byte kernels on the cases in IN

CHUNKS is a fixed chunk size, or rSEED for sizes from 1 byte to 4 KiB drawn from a
small LCG. Chunks are copied into one reused buffer, as a transport's readinto would.
Prints the kernel set in use. Output formats are read by tests/wire_oracle.py.
"""
import struct
import sys

from binascii import hexlify, unhexlify

from mavstack import kernels
from mavstack.parser import Parser
from mavstack.encoder import Encoder

STATS = ("frames", "crc_errors", "bytes_discarded", "unknown_ids", "bad_frames", "lost")
CHUNK_MAX = 4096


def load_dialect(name):
    if name == "common":
        from mavstack.dialects import common as d
    else:
        from mavstack.dialects import seed2012 as d
    return d


def hexs(b):
    return hexlify(b).decode() if len(b) else "-"


def pending(p):
    """Bytes a parser holds undecided: the candidate frame and bytes waiting for a rescan."""
    return p._cnt + p._rlen - p._rpos


class Chunks:
    def __init__(self, spec):
        self.fixed = 0 if spec[0] == "r" else int(spec)
        self.state = int(spec[1:]) if spec[0] == "r" else 0

    def next(self):
        if self.fixed:
            return self.fixed
        self.state = (self.state * 1103515245 + 12345) & 0x7FFFFFFF
        s = self.state >> 4
        return 1 + s % (1 << (s % 13))  # 1 .. 4096, log-uniform


def parse(dialect, chunks, out, paths):
    crc_len = dialect.CRC_LEN
    chunk = bytearray(CHUNK_MAX)
    for path in paths:
        with open(path, "rb") as f:
            data = f.read()
        out.write("B %s\n" % path)
        p = None

        def on_frame(msgid, payload):
            buf = p.buf
            hdr = 10 if p.version == 2 else 6
            wire = bytes(buf[:hdr + buf[1]])
            full = bytes(payload[:crc_len[msgid] >> 16])
            sig = bytes(p.signature) if p.signed else b""
            out.write("F %d %d %d %d %d %d %s %s %s\n" % (
                p.version, msgid, p.seq, p.sysid, p.compid, 1 if p.signed else 0,
                hexs(wire), hexs(full), hexs(sig)))

        p = Parser(crc_len, on_frame)
        src = Chunks(chunks)
        mv = memoryview(data)
        pos = 0
        while pos < len(data):
            n = min(src.next(), len(data) - pos)
            chunk[0:n] = mv[pos:pos + n]
            p.feed(chunk, n)
            pos += n
        out.write("S %s %d\n" % (" ".join(str(getattr(p, k)) for k in STATS), pending(p)))


def encode(dialect, src, out):
    """IN lines: VERSION MSGID SEQ SYSID COMPID PAYLOAD_HEX (the full payload).

    Each payload is unpacked with the dialect's FMT and packed again into the encoder's
    buffer, the way the stack packs messages; OUT gets the frame's hex, or '-' when
    the encoder refuses it.
    """
    fmt = dialect.FMT
    encoders = {1: Encoder(dialect.CRC_LEN, 1), 2: Encoder(dialect.CRC_LEN, 2)}
    for line in src:
        w = line.split()
        if not w:
            continue
        version, msgid, seq, sysid, compid = [int(x) for x in w[:5]]
        payload = unhexlify(w[5])
        enc = encoders[version]
        enc.seq = seq
        off = enc.begin()
        struct.pack_into(fmt[msgid], enc.buf, off, *struct.unpack_from(fmt[msgid], payload))
        n = enc.finish(msgid, sysid, compid)
        out.write((hexs(enc.buf[:n]) if n else "-") + "\n")


def run_kernels(src, out):
    """IN lines: crc HEX START END CRC | stx HEX POS END | copy DST SRC D S N | place DST SRC D N | zero HEX START END
    | scan SRC POS END BUF (out: the answer, then BUF after) | seal BUF INFO IDS MSGID (out:
    the frame) | info BLOCK MSGID (out: id_info's answer)."""
    crc16, find_stx, copy, zero = kernels.crc16, kernels.find_stx, kernels.copy, kernels.zero
    for line in src:
        w = line.split()
        if not w:
            continue
        op = w[0]
        a = bytearray(unhexlify(w[1])) if w[1] != "-" else bytearray()
        if op == "crc":
            out.write("%d\n" % crc16(a, int(w[2]), int(w[3]), int(w[4])))
        elif op == "stx":
            out.write("%d\n" % find_stx(a, int(w[2]), int(w[3])))
        elif op == "copy":
            s = bytes(unhexlify(w[2])) if w[2] != "-" else b""
            d, o, n = int(w[3]), int(w[4]), int(w[5])
            copy(a, s, d | o << 10, n)
            out.write(hexs(a) + "\n")
        elif op == "place":
            kernels.place(a, int(w[3]), bytes(unhexlify(w[2])), int(w[4]))
            out.write(hexs(a) + "\n")
        elif op == "zero":
            zero(a, int(w[2]), int(w[3]))
            out.write(hexs(a) + "\n")
        elif op == "seal":
            n = kernels.seal_v2(a, int(w[2]), int(w[3]), int(w[4]))
            out.write(hexs(a[:n]) + "\n")
        elif op == "info":
            out.write("%d\n" % kernels.id_info(a, int(w[2])))
        elif op == "scan":
            buf = bytearray(unhexlify(w[4]))
            r = kernels.scan(a, int(w[2]), int(w[3]), buf, load_dialect("common").CRC_LEN.block)
            out.write("%d %s\n" % (r, hexs(buf)))


class Lines:
    """Output collected and written in one go (a write per line is a system call)."""

    def __init__(self, path):
        self.path = path
        self.parts = []

    def write(self, s):
        self.parts.append(s)

    def close(self):
        with open(self.path, "w") as f:
            f.write("".join(self.parts))


def main(argv):
    cmd = argv[0]
    if cmd == "parse":
        out = Lines(argv[3])
        parse(load_dialect(argv[1]), argv[2], out, argv[4:])
    elif cmd == "encode":
        out = Lines(argv[3])
        with open(argv[2]) as src:  # read whole: MicroPython reads lines a byte at a time
            encode(load_dialect(argv[1]), src.read().split("\n"), out)
    elif cmd == "kernels":
        out = Lines(argv[2])
        with open(argv[1]) as src:
            run_kernels(src.read().split("\n"), out)
    out.close()
    return kernels.IMPL


if __name__ == "__main__":
    print(main(sys.argv[1:]))
