"""The emulated Cortex-M3's clock and MAVLink UART in viper (qemu.py uses them where the
firmware has the native emitter; its Python is the portable fallback, with the same
results, which the Cortex-M0 runs): what a real board's port does in C, so that the
loop's cost on the emulated M3 is the stack's, not the emulation's. Registers: qemu.py.
"""
import micropython


@micropython.viper
def clock_update(st: ptr32) -> int:
    """CMSDK APB timer 0 (25 MHz, counting down, a wrap of 10^9 counts) into st: [last
    count, counts not yet a whole ms, ms, us, counts not yet a whole us] -> ms."""
    v = ptr32(0x40000004)[0]
    d = st[0] - v
    if d < 0:
        d += 1000000000
    st[0] = v
    sub = st[4] + d
    st[3] = (st[3] + sub // 25) & 0x3FFFFFFF
    st[4] = sub % 25
    sub = st[1] + d
    st[2] = (st[2] + sub // 25000) & 0x3FFFFFFF
    st[1] = sub % 25000
    return st[2]


@micropython.viper
def uart_drain(ring: ptr8, size: int, head: int, count: int) -> int:
    """CMSDK UART 1's received bytes into the ring while it has room -> the new count."""
    state = ptr32(0x40005004)
    data = ptr32(0x40005000)
    while count < size and (state[0] & 2):  # RXFULL
        i = head + count
        if i >= size:
            i -= size
        ring[i] = data[0]
        count += 1
    return count


@micropython.viper
def uart_write(buf: ptr8, n: int) -> int:
    """buf[0:n] out of CMSDK UART 1 -> bytes taken (fewer when TXFULL does not clear)."""
    state = ptr32(0x40005004)
    data = ptr32(0x40005000)
    i = 0
    while i < n:
        k = 0
        while state[0] & 1:  # TXFULL: QEMU's pty takes the byte at once
            k += 1
            if k > 10000:
                return i
        data[0] = buf[i]
        i += 1
    return n


@micropython.viper
def ring_take(ring: ptr8, size: int, h: int, dst: ptr8, n: int) -> int:
    """dst[0:n] = n bytes of the ring from h (wrapping) -> the new h."""
    i = 0
    while i < n:
        dst[i] = ring[h]
        h += 1
        if h == size:
            h = 0
        i += 1
    return h


@micropython.viper
def ticks_add(t: int, delta: int) -> int:
    """qemu.ticks_add: (t + delta) on the 30-bit ticks."""
    return (t + delta) & 0x3FFFFFFF


@micropython.viper
def ticks_diff(a: int, b: int) -> int:
    """qemu.ticks_diff: a - b on the 30-bit ticks, in [-2^29, 2^29)."""
    d = a - b
    if d >= 0x20000000:
        return d - 0x20000000 - 0x20000000
    if d + 0x20000000 < 0:
        return d + 0x20000000 + 0x20000000
    return d
