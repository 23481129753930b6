"""MAVLink FTP's per-packet path in steady state under micropython.heap_lock().

    ftp_steady.py STORAGE [ROUNDS]

A file is open for reading (OpenFileRO, session 1) and one for writing (CreateFile,
session 2) before the steady state; then every round a ground station sends one of:
ReadFile at offsets across the file, WriteFile at offsets across the first 2 KB, a
BurstReadFile (whose replies stream out from the service's tick over the next rounds),
a request repeated byte for byte (answered again from the kept reply), a ReadFile past
the end (NAK EOF), a request on a session not open (NAK InvalidSession) and an unknown
opcode (NAK UnknownCommand). After a warm-up the rounds run twice: unlocked, counted with
micropython.mem_total(), then under heap_lock() (any allocation raises MemoryError).
Prints `OK rounds=N acks=A naks=K burst=B read_bytes=R requested=0` (the locked run's
figures; requested: bytes the unlocked run asked of the heap), or FAIL and the same.
"""
import struct
import sys

import micropython

from harness import Bench

_FTP = 110
_SIZE = 8000


def ftp(g, seq, session, opcode, size, offset, data=b""):
    p = bytearray(251)
    struct.pack_into("<HBBBBBBI", p, 0, seq, session, opcode, size, 0, 0, 0, offset)
    p[12:12 + len(data)] = data
    return g.frame(_FTP, 0, 1, 1, *p)


class Count:
    def __init__(self):
        self.acks = 0
        self.naks = 0
        self.burst = 0
        self.read_bytes = 0

    def watch(self, msgid, p):
        if msgid != _FTP:
            return
        if p[6] == 128:
            self.acks += 1
            if p[8] == 15:
                self.burst += 1
            if p[8] == 5 or p[8] == 15:
                self.read_bytes += p[7]
        elif p[6] == 129:
            self.naks += 1


class Steady:
    def __init__(self, b, frames):
        self.b = b
        self.frames = frames
        self.k = 0


def steady(s, rounds):
    i = 0
    while i < rounds:
        s.b.send(s.frames[s.k])
        s.k += 1
        if s.k == len(s.frames):
            s.k = 0
        s.b.run(1)
        i += 1


def main():
    storage = sys.argv[1]
    rounds = int(sys.argv[2]) if len(sys.argv) > 2 else 3000
    with open(storage + "/data.bin", "wb") as f:
        f.write(bytes(i & 0xFF for i in range(_SIZE)))
    b = Bench(services=("status", "ftp"), storage=storage)
    count = Count()
    b.watch = count.watch
    g = b.gcs()
    b.send(ftp(g, 1, 1, 4, 8, 0, b"data.bin"))  # OpenFileRO, session 1
    b.send(ftp(g, 2, 2, 6, 7, 0, b"out.bin"))  # CreateFile, session 2
    b.run(5)
    assert count.acks == 2, "open and create not acknowledged"
    frames = []
    seq = 10
    for k in range(12):
        frames.append(ftp(g, seq, 1, 5, 239, k * 650 % _SIZE))  # ReadFile
        frames.append(ftp(g, seq + 1, 2, 7, 100, k * 150, bytes(range(k, k + 100))))  # WriteFile
        seq += 2
    frames.append(frames[-1])  # the same request again: a repeat
    frames.append(ftp(g, seq, 1, 15, 239, 4000))  # BurstReadFile from 4000
    frames.append(ftp(g, seq + 1, 1, 5, 100, _SIZE + 10))  # past the end: NAK EOF
    frames.append(ftp(g, seq + 2, 7, 5, 100, 0))  # session 7 is not open: NAK InvalidSession
    frames.append(ftp(g, seq + 3, 0, 9, 3, 0, b"dir"))  # CreateDirectory: NAK UnknownCommand
    for _ in range(5):
        frames.append(ftp(g, seq + 4, 1, 5, 239, 100))  # room for the burst to stream out
    s = Steady(b, frames)
    steady(s, 400)  # warm up
    before = micropython.mem_total()
    steady(s, rounds)
    requested = micropython.mem_total() - before
    acks0, naks0, burst0, bytes0 = count.acks, count.naks, count.burst, count.read_bytes
    micropython.heap_lock()
    try:
        steady(s, rounds)
    finally:
        micropython.heap_unlock()
    print("%s rounds=%d acks=%d naks=%d burst=%d read_bytes=%d requested=%d"
          % ("FAIL" if requested else "OK", rounds, count.acks - acks0, count.naks - naks0,
             count.burst - burst0, count.read_bytes - bytes0, requested))


main()
