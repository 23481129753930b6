"""Byte transports a link runs over. Each is loaded only where a board uses it, to spare
a small board's heap: udp.py (UDP to a ground station), udpin.py (the UDP server ground
stations call), serial.py (a tty or pty, or a board's machine.UART); the emulated
boards' UART is in ../qemu.py with their clock.

Every transport has the same small, non-blocking, allocation-free face:
    readinto(buf) -> bytes read (0 when none)
    write(buf, n) -> bytes taken from buf[0:n] (0 when it cannot take them now)
    bytes_per_s   what the medium carries: the link's byte budget (link.py)
    rx_peer       the address that sent what readinto returned last (UDP), or None
    heard(now)    optional: the link found a valid frame in it (UDP servers pick
                  their peers by this)
Specs as on the command line: udpout:HOST:PORT, udpin:ADDR:PORT, serial:DEVICE:BAUD.
Reference: docs/core.md.
"""


def open_transport(spec, udp_bytes_per_s=None, udp_rx_chunk=0):
    """Build a transport from udpout:HOST:PORT, udpin:ADDR:PORT or serial:DEVICE:BAUD
    (udp_bytes_per_s: a UDP link's budget, None for udp.UDP_BYTES_PER_S; udp_rx_chunk:
    bytes a UDP link reads at a time, 0 for UdpTransport.rx_chunk)."""
    kind, _, rest = spec.partition(":")
    # Imported here, not at the top, for RAM: a board loads only the transport it uses.
    if kind == "udpout":
        from .udp import UdpTransport

        host, _, port = rest.rpartition(":")
        return UdpTransport(kind, host, int(port), udp_bytes_per_s, udp_rx_chunk)
    if kind == "udpin":
        from .udpin import UdpServer

        host, _, port = rest.rpartition(":")
        return UdpServer(host or "0.0.0.0", int(port), udp_bytes_per_s, udp_rx_chunk)
    if kind == "serial":
        from .serial import SerialTransport

        device, _, baud = rest.rpartition(":")
        return SerialTransport(device, int(baud))
    raise ValueError("link spec: udpout:HOST:PORT, udpin:ADDR:PORT or serial:DEVICE:BAUD")
