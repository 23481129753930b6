"""The unix vehicle's half of its watchdog (the other: host_tools/watchdog.py, the
process that runs it): feeding it over UDP, on the port it names in
MAVSTACK_WATCHDOG_PORT (boards/unix.py, watchdog())."""
import socket

from mavstack.compat import ticks_add, ticks_diff, ticks_ms


class ProcessWatchdog:
    """A datagram with the timeout in ms, four times within it (one a pass of the loop
    would cost more than the rest of the pass); b"0" at a clean stop."""

    def __init__(self, port, ms):
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.addr = socket.getaddrinfo("127.0.0.1", port)[0][-1]
        self.beat = str(ms).encode()
        self.every = ms // 4
        self.next = ticks_ms()
        self.feed()

    def feed(self):
        now = ticks_ms()
        if ticks_diff(now, self.next) >= 0:
            self.next = ticks_add(now, self.every)
            self.sock.sendto(self.beat, self.addr)

    def stop(self):
        self.sock.sendto(b"0", self.addr)
        self.sock.close()
