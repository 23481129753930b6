"""Ingest driver for instruction counts (bench_wire_instr.py runs this under callgrind).

    mpy_instr.py STREAM FEED

Reads the stream, cuts it into 4 KiB views and makes the parser as mpy_wire.py does
(which cannot be imported: it runs on import); then, when FEED is 1, feeds the whole
stream once, else nothing, so that a run with FEED 0 counts all but the ingest.
Prints the kernels in use and the frames parsed.
"""
import sys

from mavstack import kernels
from mavstack.dialects import common
from mavstack.parser import Parser

CHUNK = 4096


def noop(msgid, payload):
    pass


def main(argv):
    with open(argv[0], "rb") as f:
        data = f.read()
    mv = memoryview(data)
    views = [mv[i:i + CHUNK] for i in range(0, len(data), CHUNK)]
    sizes = [len(v) for v in views]
    p = Parser(common.CRC_LEN, noop)
    if argv[1] == "1":
        for i in range(len(views)):
            p.feed(views[i], sizes[i])
    print(kernels.IMPL, p.frames)


main(sys.argv[1:])
