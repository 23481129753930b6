"""SHA-256 compression in plain Python: the fallback where viper is unavailable, and CPython.

  sha256_block(state, block)   one SHA-256 compression: state is the 8 hash words as 32
                               big-endian bytes (so it is the digest when done); block is
                               64 bytes of message, overwritten (it holds the schedule)

Same contract as sha256_viper. Apart from the byte kernels (bytes_portable) so that
only boards that sign carry it; loaded by mavstack.services.sha256.
"""
from .sha256_k import SHA256_K


def _word(b, i):
    return b[i] << 24 | b[i + 1] << 16 | b[i + 2] << 8 | b[i + 3]


def _put(b, i, w):
    b[i] = w >> 24
    b[i + 1] = (w >> 16) & 0xFF
    b[i + 2] = (w >> 8) & 0xFF
    b[i + 3] = w & 0xFF


def sha256_block(state, block):
    # The message schedule lives in block as a ring of 16 words: W[t] needs only
    # W[t-16..t-1], so no scratch buffer is needed.
    k = SHA256_K
    a = _word(state, 0)
    b = _word(state, 4)
    c = _word(state, 8)
    d = _word(state, 12)
    e = _word(state, 16)
    f = _word(state, 20)
    g = _word(state, 24)
    h = _word(state, 28)
    for t in range(64):
        i = (t & 15) << 2
        if t < 16:
            w = _word(block, i)
        else:
            x = _word(block, ((t - 15) & 15) << 2)
            y = _word(block, ((t - 2) & 15) << 2)
            s0 = ((x >> 7 | x << 25) ^ (x >> 18 | x << 14) ^ (x >> 3)) & 0xFFFFFFFF
            s1 = ((y >> 17 | y << 15) ^ (y >> 19 | y << 13) ^ (y >> 10)) & 0xFFFFFFFF
            w = (_word(block, i) + s0 + _word(block, ((t - 7) & 15) << 2) + s1) & 0xFFFFFFFF
            _put(block, i, w)
        s1 = ((e >> 6 | e << 26) ^ (e >> 11 | e << 21) ^ (e >> 25 | e << 7)) & 0xFFFFFFFF
        ch = (e & f) ^ (~e & g)
        t1 = (h + s1 + ch + k[t] + w) & 0xFFFFFFFF
        s0 = ((a >> 2 | a << 30) ^ (a >> 13 | a << 19) ^ (a >> 22 | a << 10)) & 0xFFFFFFFF
        maj = (a & b) ^ (a & c) ^ (b & c)
        h = g
        g = f
        f = e
        e = (d + t1) & 0xFFFFFFFF
        d = c
        c = b
        b = a
        a = (t1 + s0 + maj) & 0xFFFFFFFF
    _put(state, 0, (_word(state, 0) + a) & 0xFFFFFFFF)
    _put(state, 4, (_word(state, 4) + b) & 0xFFFFFFFF)
    _put(state, 8, (_word(state, 8) + c) & 0xFFFFFFFF)
    _put(state, 12, (_word(state, 12) + d) & 0xFFFFFFFF)
    _put(state, 16, (_word(state, 16) + e) & 0xFFFFFFFF)
    _put(state, 20, (_word(state, 20) + f) & 0xFFFFFFFF)
    _put(state, 24, (_word(state, 24) + g) & 0xFFFFFFFF)
    _put(state, 28, (_word(state, 28) + h) & 0xFFFFFFFF)
