"""SHA-256 compression in plain Python: the fallback where viper is unavailable, and CPython.

  sha256_block(state, block)   one SHA-256 compression: state is the 8 hash words as 32
                               big-endian bytes (so it is the digest when done); block is
                               64 bytes of message (sha256_viper keeps its schedule there,
                               so callers count it as overwritten)

Same contract as sha256_viper. Apart from the byte kernels (bytes_portable) so that
only boards that sign carry it; loaded by kernels/sha256.py.

No 32-bit word is ever a Python int here (docs/design.md): every word is two 16-bit
halves (hi, lo). Sums of halves carry from lo into hi; a rotation is shifts across the
halves, XORed together unmasked and masked once; no term is shifted left as far as 2^30.
The schedule and working variables live in lists made once at import, and functions keep
small frames. Not reentrant: one compression at a time (no threads or interrupts sign).
"""
from array import array

from .sha256_k import SHA256_K

# K as halves, K[t] = (_K[2t], _K[2t+1]) (SHA256_K is little-endian); made once, at import.
_K = array("H", (SHA256_K[(2 * i ^ 2) + 1] << 8 | SHA256_K[2 * i ^ 2] for i in range(128)))

# The whole schedule W[0..63]: W[t] = (_W[2t], _W[2t+1]).
_W = [0] * 128

# The working variables a..h as a ring of 8 slots that turns one slot per round (a is
# in slot -t & 7 in round t, h's slot becomes the next a), so a round writes only the
# new a and e. Slot j: hi at _V[j], lo at _V[j + 16], each mirrored at +8 so that slot
# a + 7 reads without wrapping.
_V = [0] * 32


def _load(w, b):
    for i in range(32):
        w[i] = b[2 * i] << 8 | b[2 * i + 1]


def _sched(w, i):
    # W[t] = s1(W[t-2]) + W[t-7] + s0(W[t-15]) + W[t-16], at i = 2t.
    h = w[i - 30]
    l = w[i - 29]
    lo = (l >> 7 ^ h << 9 ^ h >> 2 ^ l << 14 ^ l >> 3 ^ h << 13) & 0xFFFF
    hi = (h >> 7 ^ l << 9 ^ l >> 2 ^ h << 14 ^ h >> 3) & 0xFFFF
    h = w[i - 4]
    l = w[i - 3]
    # rotr 17 keeps only the low bit of the half it shifts left by 15: only that bit is
    # shifted, so no term reaches 2^30.
    lo += (h >> 1 ^ (l & 1) << 15 ^ h >> 3 ^ l << 13 ^ l >> 10 ^ h << 6) & 0xFFFF
    hi += (l >> 1 ^ (h & 1) << 15 ^ l >> 3 ^ h << 13 ^ h >> 10) & 0xFFFF
    lo += w[i - 13] + w[i - 31]
    w[i + 1] = lo & 0xFFFF
    w[i] = (hi + w[i - 14] + w[i - 32] + (lo >> 16)) & 0xFFFF


def _t1(v, i):
    # Round i // 2, first half: T1 = h + S1(e) + Ch(e, f, g) + K + W, into h's slot.
    e = (4 - (i >> 1)) & 7
    h = v[e]
    l = v[e + 16]
    s = v[e + 18]
    s = (v[e + 17] ^ s) & l ^ s  # Ch = g ^ e & (f ^ g)
    s += v[e + 19]
    s += _K[i + 1]
    s += _W[i + 1]
    s += (l >> 6 ^ h << 10 ^ l >> 11 ^ h << 5 ^ h >> 9 ^ l << 7) & 0xFFFF
    x = v[e + 2]
    x = (v[e + 1] ^ x) & h ^ x
    x += v[e + 3]
    x += _K[i]
    x += _W[i]
    x += (h >> 6 ^ l << 10 ^ h >> 11 ^ l << 5 ^ l >> 9 ^ h << 7) & 0xFFFF
    x = (x + (s >> 16)) & 0xFFFF
    s &= 0xFFFF
    e = (e + 3) & 7
    v[e] = v[e + 8] = x
    e += 16
    v[e] = v[e + 8] = s


def _t2(v, i):
    # Round i // 2, second half: d += T1, and a = T1 + S0(a) + Maj(a, b, c) in h's
    # slot (d is slot a + 3, h slot a + 7).
    a = -(i >> 1) & 7
    s = v[a + 19]
    s += v[a + 23]
    x = v[a + 3]
    x += v[a + 7]
    x = (x + (s >> 16)) & 0xFFFF
    s &= 0xFFFF
    h = (a + 3) & 7
    v[h] = v[h + 8] = x
    h += 16
    v[h] = v[h + 8] = s
    h = v[a]
    l = v[a + 16]
    x = v[a + 17]
    s = (x | l) & v[a + 18] | x & l  # Maj = (a | b) & c | a & b
    x = v[a + 1]
    x = (x | h) & v[a + 2] | x & h
    a = (a + 7) & 7
    s += v[a + 16]
    s += (l >> 2 ^ h << 14 ^ l >> 13 ^ h << 3 ^ h >> 6 ^ l << 10) & 0xFFFF
    x += (h >> 2 ^ l << 14 ^ h >> 13 ^ l << 3 ^ l >> 6 ^ h << 10) & 0xFFFF
    x += v[a]
    x = (x + (s >> 16)) & 0xFFFF
    s &= 0xFFFF
    v[a] = v[a + 8] = x
    a += 16
    v[a] = v[a + 8] = s


def _start(v, state):
    for j in range(8):
        v[j] = v[j + 8] = state[4 * j] << 8 | state[4 * j + 1]
        v[j + 16] = v[j + 24] = state[4 * j + 2] << 8 | state[4 * j + 3]


def _finish(state, v):
    # After 64 rounds the ring is back where it started: slot j holds word j.
    for j in range(8):
        o = 4 * j
        lo = (state[o + 2] << 8 | state[o + 3]) + v[j + 16]
        hi = (state[o] << 8 | state[o + 1]) + v[j] + (lo >> 16)
        state[o] = (hi >> 8) & 0xFF
        state[o + 1] = hi & 0xFF
        state[o + 2] = (lo >> 8) & 0xFF
        state[o + 3] = lo & 0xFF


def sha256_block(state, block):
    w = _W
    v = _V
    _load(w, block)
    for i in range(32, 128, 2):
        _sched(w, i)
    _start(v, state)
    for i in range(0, 128, 2):
        _t1(v, i)
        _t2(v, i)
    _finish(state, v)
