"""A minimal vehicle on real transports, for link tests (MicroPython or CPython).

    wire_peer.py SPEC [SPEC ...] [--lock] [--seconds N]

SPEC as on main.py's command line (udpin:, udpout:, serial:DEVICE:BAUD). The vehicle
sends HEARTBEAT on every link every 50 ms, answers COMMAND_LONG with COMMAND_ACK
(command echoed, addressed to the sender) and stops after acknowledging command
STOP_COMMAND. With --lock (MicroPython) the loop runs under heap_lock once every link
has heard its peer. Prints `ready`, then at the end one line per link:
    link NAME frames crc_errors bytes_discarded unknown_ids bad_frames lost acks version locked
"""
import struct
import sys

from mavstack.compat import MICROPYTHON, sleep_ms, ticks_add, ticks_diff, ticks_ms
from mavstack.dialects import common
from mavstack.endpoint import Endpoint
from mavstack.fields import u16
from mavstack.transport import open_transport

STOP_COMMAND = 31999
HEARTBEAT_MS = 50


class Peer:
    def __init__(self, specs):
        self.ep = Endpoint(common, sysid=1, compid=1)
        for spec in specs:
            self.ep.add_link(open_transport(spec))
        self.acks = [0] * len(self.ep.links)
        self.stop = False
        self.fmt_hb = self.ep.fmt(0)
        self.fmt_ack = self.ep.fmt(77)
        self.ep.on(76, self.command)

    def command(self, link, p):
        cmd = u16(p, 28)
        off = link.begin()
        struct.pack_into(self.fmt_ack, link.txbuf, off, cmd, 0, 0, 0, link.rx.sysid, link.rx.compid)
        if link.send(77):
            self.acks[link.index] += 1
        if cmd == STOP_COMMAND:
            self.stop = True

    def heartbeat(self):
        for link in self.ep.links:
            off = link.begin()
            struct.pack_into(self.fmt_hb, link.txbuf, off, link.rx.frames, 2, 3, 81, 4, 3)
            link.send(0)

    def run(self, seconds, lock):
        start = next_hb = ticks_ms()
        locked = False
        try:
            while not self.stop:
                now = ticks_ms()
                if ticks_diff(now, start) > seconds * 1000:
                    break
                self.ep.poll(now)
                if ticks_diff(now, next_hb) >= 0:
                    self.heartbeat()
                    next_hb = ticks_add(now, HEARTBEAT_MS)
                if lock and not locked and self.heard_all():
                    import micropython

                    micropython.heap_lock()
                    locked = True
                sleep_ms(1)
        finally:
            if locked:
                import micropython

                micropython.heap_unlock()
        return locked

    def heard_all(self):
        for link in self.ep.links:
            if not link.rx.frames:
                return False
        return True


def main(argv):
    specs = [a for a in argv if ":" in a]
    seconds = int(argv[argv.index("--seconds") + 1]) if "--seconds" in argv else 30
    peer = Peer(specs)
    print("ready")
    if not MICROPYTHON:
        sys.stdout.flush()
    locked = peer.run(seconds, "--lock" in argv and MICROPYTHON)
    for link in peer.ep.links:
        rx = link.rx
        print("link", link.name, rx.frames, rx.crc_errors, rx.bytes_discarded, rx.unknown_ids,
              rx.bad_frames, rx.lost, peer.acks[link.index], link.version, 1 if locked else 0)
    peer.ep.close()


if __name__ == "__main__":
    main(sys.argv[1:])
