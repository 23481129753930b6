"""The wire layer on an emulated board, through its MAVLink UART (tests/test_mcu.py).

    wire_uart.py STREAM_BYTES ENCODE_COUNT

Twice, first with the heap unlocked and counted by micropython.mem_total() (which sees
the frame states the VM puts on the heap), then under heap_lock() (where anything else
is a MemoryError):
  parse   read STREAM_BYTES bytes of a damaged stream from the UART into a Parser; each
          delivered frame's id and full-length payload go into a CRC-16 digest
  encode  ENCODE_COUNT frames of six kinds, alternately MAVLink 1 and 2, written to the
          UART for the host to decode with pymavlink
Prints `parse N digest D stats ...`, `requested B` and `encode N` per round.
"""
import micropython

from mavstack.compat import ticks_ms, ticks_diff
from mavstack.dialects import common
from mavstack.encoder import Encoder
from mavstack.kernels import crc16, IMPL
from mavstack.parser import Parser
from mavstack.qemu import UartTransport

import sys
import struct

CRC_LEN = common.CRC_LEN
FMT = common.FMT
NAME = b"SYSID_THISMAV"
FLOATS = (0.0, 1.5, -2.25, float("nan"), float("inf"), 3.0e38, -0.0)


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


def parse(uart, parser, buf, total):
    got = 0
    quiet = ticks_ms()
    while got < total:
        n = uart.readinto(buf, total - got)  # what follows is the next round's
        if n:
            parser.feed(buf, n)
            got += n
            quiet = ticks_ms()
        elif ticks_diff(ticks_ms(), quiet) > 5000:
            return got
    return got


def encode(uart, encoders, count):
    f_hb, f_att, f_gps = FMT[0], FMT[30], FMT[24]
    f_pv, f_cmd, f_mi = FMT[22], FMT[76], FMT[73]
    fl = FLOATS
    for i in range(count):
        enc = encoders[i & 1]
        off = enc.begin()
        buf = enc.buf
        k = i % 6
        x = fl[i % 7]
        if k == 0:
            struct.pack_into(f_hb, buf, off, i, 2, 3, 81, 4, 3)
            msgid = 0
        elif k == 1:
            struct.pack_into(f_att, buf, off, i, x, x, x, 0.0, 0.0, 0.0)
            msgid = 30
        elif k == 2:
            struct.pack_into(f_gps, buf, off, i * 1000, -i, i, 0, 0, 0, 0, 0, 3, 9, 0, 0, 0, 0, 0, 0)
            msgid = 24
        elif k == 3:
            struct.pack_into(f_pv, buf, off, x, 300, i & 0xFFFF, NAME, 9)
            msgid = 22
        elif k == 4:
            struct.pack_into(f_cmd, buf, off, x, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 400 + (i & 7), 1, 1, 0)
            msgid = 76
        else:
            struct.pack_into(f_mi, buf, off, 0.0, x, 0.0, 0.0, i, -i, x, i & 0xFFFF, 16, 1, 1, 3, 0, 1, 0)
            msgid = 73
        n = enc.finish(msgid, 1, 1 + (i & 1))
        uart.write(buf, n)


def main(total, count):
    print("kernels", IMPL)
    uart = UartTransport()
    buf = bytearray(512)
    encoders = (Encoder(CRC_LEN, 1), Encoder(CRC_LEN, 2))
    for locked in (False, True):
        d = Digest()
        parser = Parser(CRC_LEN, d.on_frame)
        d.parser = parser
        before = micropython.mem_total()
        if locked:
            micropython.heap_lock()
        try:
            got = parse(uart, parser, buf, total)
            encode(uart, encoders, count)
        finally:
            if locked:
                micropython.heap_unlock()
        requested = micropython.mem_total() - before
        print("round", "locked" if locked else "unlocked", "bytes", got, "requested", 0 if locked else requested)
        print("parse", d.frames, "digest", d.crc, "signed", d.signed, "stats", parser.frames, parser.crc_errors,
              parser.bytes_discarded, parser.unknown_ids, parser.bad_frames)
        print("encode", count)


main(int(sys.argv[1]), int(sys.argv[2]))
