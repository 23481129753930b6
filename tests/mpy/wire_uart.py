"""The wire layer on an emulated board, through its MAVLink UART (tests/test_mcu.py).

    wire_uart.py STREAM_BYTES ENCODE_COUNT

Twice, first with the heap unlocked and counted by micropython.mem_total() (which sees
the frame states the VM puts on the heap), then under heap_lock() (where anything else
is a MemoryError):
  parse   read STREAM_BYTES bytes of a damaged stream from the UART into a Parser; each
          delivered frame's id and full-length payload go into a CRC-16 digest
  encode  ENCODE_COUNT frames of six kinds (wire_kinds.py), alternately MAVLink 1 and 2,
          written to the UART for the host to decode with pymavlink
Prints `parse N digest D stats ...`, `requested B` and `encode N` per round.
"""
import micropython

from mavstack.compat import ticks_ms, ticks_diff
from mavstack.dialects import common
from mavstack.encoder import Encoder
from mavstack.kernels import crc16, IMPL
from mavstack.parser import Parser
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
    for i in range(count):
        enc = encoders[i & 1]
        uart.write(enc.buf, pack_frame(enc, i))


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
