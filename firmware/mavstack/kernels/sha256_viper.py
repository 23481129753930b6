"""SHA-256 compression compiled to machine code with @micropython.viper (MicroPython only).

Same contract as sha256_portable: tests run both against hashlib. Apart from the
byte kernels (bytes_viper) so that only boards that sign carry its machine code.
"""
import micropython

from .sha256_k import SHA256_K


@micropython.viper
def sha256_block(state: ptr8, block: ptr8):
    # Words are loaded byte by byte: SHA-256 is big-endian, the ports are not.
    # Viper ints are machine words (64-bit on the unix port): every sum and left
    # shift is masked back to 32 bits; uint keeps right shifts logical.
    k = ptr32(SHA256_K)
    m = uint(0xFFFF) << 16 | uint(0xFFFF)
    a = uint(state[0]) << 24 | uint(state[1]) << 16 | uint(state[2]) << 8 | uint(state[3])
    b = uint(state[4]) << 24 | uint(state[5]) << 16 | uint(state[6]) << 8 | uint(state[7])
    c = uint(state[8]) << 24 | uint(state[9]) << 16 | uint(state[10]) << 8 | uint(state[11])
    d = uint(state[12]) << 24 | uint(state[13]) << 16 | uint(state[14]) << 8 | uint(state[15])
    e = uint(state[16]) << 24 | uint(state[17]) << 16 | uint(state[18]) << 8 | uint(state[19])
    f = uint(state[20]) << 24 | uint(state[21]) << 16 | uint(state[22]) << 8 | uint(state[23])
    g = uint(state[24]) << 24 | uint(state[25]) << 16 | uint(state[26]) << 8 | uint(state[27])
    h = uint(state[28]) << 24 | uint(state[29]) << 16 | uint(state[30]) << 8 | uint(state[31])
    t = 0
    while t < 64:
        # The schedule is a ring of 16 words in block (W[t] needs only W[t-16..t-1]).
        i = (t & 15) << 2
        if t < 16:
            w = uint(block[i]) << 24 | uint(block[i + 1]) << 16 | uint(block[i + 2]) << 8 | uint(block[i + 3])
        else:
            j = ((t - 15) & 15) << 2
            x = uint(block[j]) << 24 | uint(block[j + 1]) << 16 | uint(block[j + 2]) << 8 | uint(block[j + 3])
            j = ((t - 2) & 15) << 2
            y = uint(block[j]) << 24 | uint(block[j + 1]) << 16 | uint(block[j + 2]) << 8 | uint(block[j + 3])
            j = ((t - 7) & 15) << 2
            z = uint(block[j]) << 24 | uint(block[j + 1]) << 16 | uint(block[j + 2]) << 8 | uint(block[j + 3])
            w = uint(block[i]) << 24 | uint(block[i + 1]) << 16 | uint(block[i + 2]) << 8 | uint(block[i + 3])
            s0 = ((x >> 7 | x << 25) ^ (x >> 18 | x << 14) ^ (x >> 3)) & m
            s1 = ((y >> 17 | y << 15) ^ (y >> 19 | y << 13) ^ (y >> 10)) & m
            w = (w + s0 + z + s1) & m
            block[i] = w >> 24
            block[i + 1] = w >> 16
            block[i + 2] = w >> 8
            block[i + 3] = w
        s1 = ((e >> 6 | e << 26) ^ (e >> 11 | e << 21) ^ (e >> 25 | e << 7)) & m
        ch = (e & f) ^ ((e ^ m) & g)
        t1 = (h + s1 + ch + (uint(k[t]) & m) + w) & m
        s0 = ((a >> 2 | a << 30) ^ (a >> 13 | a << 19) ^ (a >> 22 | a << 10)) & m
        maj = (a & b) ^ (a & c) ^ (b & c)
        h = g
        g = f
        f = e
        e = (d + t1) & m
        d = c
        c = b
        b = a
        a = (t1 + s0 + maj) & m
        t += 1
    i = 0
    while i < 32:
        if i == 0:
            x = a
        elif i == 4:
            x = b
        elif i == 8:
            x = c
        elif i == 12:
            x = d
        elif i == 16:
            x = e
        elif i == 20:
            x = f
        elif i == 24:
            x = g
        else:
            x = h
        x = ((uint(state[i]) << 24 | uint(state[i + 1]) << 16 | uint(state[i + 2]) << 8 | uint(state[i + 3])) + x) & m
        state[i] = x >> 24
        state[i + 1] = x >> 16
        state[i + 2] = x >> 8
        state[i + 3] = x
        i += 4
