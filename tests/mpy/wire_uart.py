"""The wire layer on an emulated board, through its MAVLink UART (tests/test_mcu.py).

    wire_uart.py STREAM_BYTES ENCODE_COUNT

Twice, first with the heap unlocked and counted by micropython.mem_total() (which sees
the frame states the VM puts on the heap), then under heap_lock() (where anything else
is a MemoryError):
  parse   read STREAM_BYTES bytes of a damaged stream from the UART into a Parser; each
          delivered frame's id and full-length payload go into a CRC-16 digest
  encode  ENCODE_COUNT frames of six kinds (wire_kinds.py), alternately MAVLink 1 and 2,
          written to the UART for the host to decode with pymavlink
The locked round starts the parser's and encoders' counters just below their wrap
(parser.COUNT_WRAP): past 2^30 they would be heap objects on this 32-bit board, and the
lock would fail on the first count. Its stats are printed as counted from there.
Prints `parse N digest D stats ...`, `requested B` and `encode N` per round.
"""
import micropython

from mavstack.compat import ticks_ms, ticks_diff
from mavstack.dialects import common
from mavstack.encoder import Encoder
from mavstack.kernels import crc16, IMPL
from mavstack.parser import Parser, COUNT_WRAP
from mavstack.qemu import UartTransport
from wire_kinds import pack_frame

import sys

CRC_LEN = common.CRC_LEN


class Digest:
    def __init__(self):
        self.crc = 0xFFFF
        self.frames = 0
        self.signed = 0
        self.parser = None

    def on_frame(self, msgid, payload):
        self.frames += 1
        self.crc = crc16(payload, 0, CRC_LEN[msgid] >> 16, self.crc ^ (msgid & 0xFF))
        if self.parser.signed:
            self.signed += 1


class Round:
    """One round's state: a fresh parser (digest on), the UART and what to do. The
    functions below take it whole: with few locals their frames stay off the heap,
    and the unlocked round counts everything they ask for."""

    def __init__(self, uart, buf, encoders, total, count):
        self.uart = uart
        self.buf = buf
        self.encoders = encoders
        self.total = total
        self.count = count
        self.got = 0
        self.d = Digest()
        self.parser = Parser(CRC_LEN, self.d.on_frame)
        self.d.parser = self.parser


def parse(r):
    quiet = ticks_ms()
    while r.got < r.total:
        n = r.uart.readinto(r.buf, r.total - r.got)  # what follows is the next round's
        if n:
            r.parser.feed(r.buf, n)
            r.got += n
            quiet = ticks_ms()
        elif ticks_diff(ticks_ms(), quiet) > 5000:
            return


def encode(r):
    i = 0
    while i < r.count:
        enc = r.encoders[i & 1]
        r.uart.write(enc.buf, pack_frame(enc, i))
        i += 1


def run(r):
    parse(r)
    encode(r)


STATS = ("frames", "crc_errors", "bytes_discarded", "unknown_ids", "bad_frames", "lost")


def main(total, count):
    print("kernels", IMPL)
    uart = UartTransport()
    buf = bytearray(512)
    encoders = (Encoder(CRC_LEN, 1), Encoder(CRC_LEN, 2))
    for locked in (False, True):
        r = Round(uart, buf, encoders, total, count)
        start = COUNT_WRAP - 2 if locked else 0
        for name in STATS:
            setattr(r.parser, name, start)
        for enc in encoders:
            enc.frames = start
        before = micropython.mem_total()
        if locked:
            micropython.heap_lock()
        try:
            run(r)
        finally:
            if locked:
                micropython.heap_unlock()
        requested = micropython.mem_total() - before
        print("round", "locked" if locked else "unlocked", "bytes", r.got, "requested", 0 if locked else requested)
        d = r.d
        parser = r.parser
        stats = [(getattr(parser, name) - start) & COUNT_WRAP for name in STATS[:5]]
        print("parse", d.frames, "digest", d.crc, "signed", d.signed, "stats", *stats)
        assert all(getattr(parser, name) <= COUNT_WRAP for name in STATS)
        assert all(0 <= (enc.frames - start) & COUNT_WRAP <= count for enc in encoders)
        print("encode", count)


main(int(sys.argv[1]), int(sys.argv[2]))
