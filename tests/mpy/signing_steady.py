"""Signed traffic in steady state: the vehicle verifies N signed PINGs (plus tampered,
replayed and unsigned ones it must drop) and signs everything it sends, which the
bench checks, all between heap_lock() and heap_unlock() when LOCK is given.

    signing_steady.py N [LOCK]   prints: impl accepted bad replayed unsigned pings good_out bad_out
"""
import sys

from harness import Bench
from mavstack.encoder import Encoder
from mavstack.services.sha256 import Signature, SHA256_IMPL

try:
    import micropython
except ImportError:
    micropython = None

KEY = bytes(range(1, 33))
_PING = 4


class Stamper:
    """The ground station's signer: link id 0, its own rising timestamp."""

    def __init__(self):
        self.sig = Signature()
        self.ts = 1000

    def sign(self, buf, end):
        self.ts += 1
        buf[end] = 0
        t = self.ts
        for i in range(6):
            buf[end + 1 + i] = (t >> (8 * i)) & 0xFF
        self.sig.compute(KEY, buf, end + 7, buf, end + 7)
        return 13


class OutputCheck:
    """verify hook on the bench's parser: every vehicle frame must be signed with KEY."""

    def __init__(self):
        self.sig = Signature()
        self.good = 0
        self.bad = 0

    def verify(self, buf, plen, signed):
        if signed and self.sig.matches(KEY, buf, 10 + plen + 2 + 7):
            self.good += 1
        else:
            self.bad += 1
        return True


def frames(n, dialect):
    enc = Encoder(dialect.CRC_LEN, 2)
    enc.sign = Stamper().sign
    out = []
    for i in range(n):
        off = enc.begin()
        for k in range(14):
            enc.buf[off + k] = 0
        enc.buf[off] = i & 0xFF
        enc.buf[off + 8] = i & 0xFF  # seq
        m = enc.finish(_PING, 255, 190)
        out.append(bytearray(enc.buf[:m]))
    return out


def main(n, lock):
    b = Bench(services=("signing", "status"))
    svc = b.ep.services["signing"]
    svc.set_key(KEY)
    good = frames(n, b.dialect)
    tampered = bytearray(good[0])
    tampered[-1] ^= 1
    unsigned = b.gcs(255, 190).frame(_PING, 0, 0, 0, 0)
    check = OutputCheck()
    b.rx.verify = check.verify
    b.run(2, 10)
    pings = b.seen[_PING]
    check.good = check.bad = 0

    def steady():
        for i in range(n):
            f = good[i]
            b.send_raw(f, len(f))
            if i % 100 == 0:
                b.send_raw(tampered, len(tampered))
                b.send_raw(good[0], len(good[0]))  # replayed
                b.send_raw(unsigned, len(unsigned))
            b.run(1, 10)

    if lock:
        micropython.heap_lock()
    steady()
    if lock:
        micropython.heap_unlock()
    print(SHA256_IMPL, svc.accepted, svc.bad_signature, svc.replayed, svc.unsigned,
          b.seen[_PING] - pings, check.good, check.bad)


main(int(sys.argv[1]), len(sys.argv) > 2)
