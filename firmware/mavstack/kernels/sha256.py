"""SHA-256 over preallocated buffers, and the MAVLink 2 frame signature built on it.

Nothing here allocates once constructed, so frames can be signed and checked in the
receive and transmit paths. The compression is sha256_block from sha256_viper or
sha256_portable, chosen like the byte kernels (kernels.IMPL, MAVSTACK_PORTABLE=1).

    h = Sha256(); h.update(buf, start, end); ...; h.digest_into(out32)   (then reusable)
    s = Signature(); s.sign(key32, frame, n)  -> the 6 signature bytes at frame[n:n+6]
        over key + frame[0:n], where frame[0:n] is header, payload, CRC, link id, timestamp
    s.matches(key32, frame, n)  -> do frame[n:n+6] hold that signature?
Reference: docs/services/signing.md.
"""
from ..compat import const
from . import IMPL, copy, zero

# The same choice as the byte kernels: viper where they are viper, else portable.
SHA256_IMPL = "portable"
if IMPL == "viper":
    try:
        from .sha256_viper import sha256_block

        SHA256_IMPL = "viper"
    except Exception:  # machine code for another CPU
        pass
if SHA256_IMPL == "portable":
    from .sha256_portable import sha256_block

_BLOCK = const(64)
_H0 = b"\x6a\x09\xe6\x67\xbb\x67\xae\x85\x3c\x6e\xf3\x72\xa5\x4f\xf5\x3a\x51\x0e\x52\x7f\x9b\x05\x68\x8c\x1f\x83\xd9\xab\x5b\xe0\xcd\x19"
SIGNATURE_BYTES = const(6)


class Sha256:
    # Methods are small on purpose (docs/design.md): these run for every signed frame.
    def __init__(self):
        self.state = bytearray(32)
        self.block = bytearray(_BLOCK)
        self.n = 0  # bytes waiting in block
        self.total = 0  # bytes hashed so far (the length field needs total * 8 < 2^30)
        self.reset()

    def reset(self):
        copy(self.state, _H0, 0, 32)
        self.n = 0
        self.total = 0

    def update(self, buf, start, end):
        """Hash buf[start:end]."""
        self.total += end - start
        while start < end:
            start += self._fill(buf, start, end - start)

    def _fill(self, buf, start, k):
        # Up to k bytes from buf[start] into the block, compressed when full -> bytes taken.
        n = self.n
        if k > _BLOCK - n:
            k = _BLOCK - n
        copy(self.block, buf, n | start << 10, k)
        n += k
        if n == _BLOCK:
            sha256_block(self.state, self.block)
            n = 0
        self.n = n
        return k

    def digest_into(self, out):
        """Write the 32-byte digest to out[0:32] and start over."""
        block = self.block
        n = self.n
        block[n] = 0x80
        n += 1
        if n > _BLOCK - 8:
            zero(block, n, _BLOCK)
            sha256_block(self.state, block)
            n = 0
        zero(block, n, _BLOCK)
        _length(block, self.total << 3)
        sha256_block(self.state, block)
        copy(out, self.state, 0, 32)
        self.reset()


def _length(block, bits):
    # The message length in bits, big-endian, at the end of the (zeroed) last block.
    i = _BLOCK - 1
    while bits:
        block[i] = bits & 0xFF
        bits >>= 8
        i -= 1


class Signature:
    """MAVLink 2 signature: the first 6 bytes of SHA-256(secret key + frame)."""

    def __init__(self):
        self.sha = Sha256()
        self.digest = bytearray(32)

    def sign(self, key, frame, n):
        """Write the signature of key + frame[0:n] to frame[n:n+6]."""
        self._hash(key, frame, n)
        copy(frame, self.digest, n, SIGNATURE_BYTES)

    def matches(self, key, frame, n):
        """Do the 6 bytes at frame[n:n+6] sign key + frame[0:n]?"""
        self._hash(key, frame, n)
        d = self.digest
        for i in range(SIGNATURE_BYTES):
            if d[i] != frame[n + i]:
                return False
        return True

    def _hash(self, key, frame, n):
        sha = self.sha
        sha.update(key, 0, 32)
        sha.update(frame, 0, n)
        sha.digest_into(self.digest)
