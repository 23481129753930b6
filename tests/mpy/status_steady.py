"""Status and command handling in steady state under micropython.heap_lock().

    status_steady.py SERVICES [STORAGE] [ROUNDS] [MODE [PORT]]
SERVICES is a comma list (status,commands[,params,...]). A ground station's heartbeat
every simulated second, and a burst of commands each 50 ms: arm/disarm, an unknown
command, REQUEST_MESSAGE (SYS_STATUS, AUTOPILOT_VERSION), COMMAND_INT, SET_MODE, PING,
a corrupted frame, a STATUSTEXT, the flight-mode requests (standard modes, PX4's
encoding) and what tells the link's convention (REQUEST_DATA_STREAM: ArduPilot's numbers;
PX4's sub mode: PX4's, turn about). SYS_STATUS carries the pre-arm and geofence bits the
status service fills from the arming check (a hook here) and the fence. After a warm-up the rounds run twice: unlocked, counted
with micropython.mem_total(), then under heap_lock() (any allocation raises MemoryError).
Prints `OK rounds=N acks=N ... requested=0` (the figures of the locked run; requested:
bytes the unlocked one asked of the heap), or FAIL and the same when that is not 0.

MODE "radio": the link is budgeted as a 57600 baud radio (5760 B/s) and a second
station floods PINGs every round, so the budget refuses frames (held=, the PING answers
beyond it) on the counted path. MODE "udpin": a second link, a real udpin UDP socket on
127.0.0.1:PORT, with two ground stations on sockets of their own (heartbeats, commands and
PINGs from both; each hears the vehicle: udp_a=, udp_b= bytes received), so the peer
reads, the valid-frame notice and the writes to every peer are on it too.
"""
import sys

import micropython

from harness import Bench


def build(services, storage):
    b = Bench(services=services, storage=storage)
    st = b.ep.services["status"]
    # Modes as the unix board's table has them: number, name, flags, PX4 main/sub, standard.
    st.custom_modes = ((0, "STABILIZE", 64 | 16, 7, 0, 0), (3, "AUTO", 4 | 16, 4, 4, 6), (6, "RTL", 4 | 16, 4, 5, 5))
    st.arm_check = _no_objection  # asked once a second for SYS_STATUS's pre-arm health
    g = b.gcs()
    frames = (
        g.heartbeat(),
        g.command(400, 1.0),  # arm
        g.command(400, 0.0),  # disarm
        g.command(31000),  # unknown
        g.command(512, 1.0),  # REQUEST_MESSAGE SYS_STATUS
        g.command(512, 148.0),  # REQUEST_MESSAGE AUTOPILOT_VERSION
        g.frame(66, 4, 1, 1, 0, 1),  # REQUEST_DATA_STREAM: the link reads ArduPilot's numbers
        g.command_int(176, 0, 1.0 + 16, 3.0),  # DO_SET_MODE as COMMAND_INT, custom mode 3: AUTO
        g.frame(11, 99, 1, 1),  # SET_MODE to custom mode 99, which is refused (a STATUSTEXT)
        g.frame(4, 1234567, 9, 0, 0),  # PING request
        g.command(400, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1, 1, 1),  # arm, confirmation 1
        g.command(400, 0.0, 21196.0),  # forced disarm
        g.command(262, 5.0),  # DO_SET_STANDARD_MODE SAFE_RECOVERY: RTL
        g.command(262, 2.0),  # ... ORBIT, which it has not: UNSUPPORTED
        g.frame(11, 4 << 16 | 4 << 24, 1, 1),  # SET_MODE PX4-encoded AUTO.MISSION: PX4's from now on
        g.command(176, 1.0, 4.0, 5.0),  # DO_SET_MODE, PX4's way (a sub mode): AUTO.RTL
    )
    bad = bytearray(frames[3])
    bad[-1] ^= 0xFF  # CRC error
    return b, frames[0], frames[1:], bad


def _no_objection(arm):
    return None


class Steady:
    """The bench and its frames; steady() takes it whole (one argument, few locals: its
    frame stays off the heap, and the measured run counts everything)."""

    def __init__(self, b, hb, burst, bad):
        self.b = b
        self.hb = hb
        self.burst = burst
        self.bad = bad
        self.k = 0  # the next frame of the burst
        self.flood = None  # a PING another station sends every round (MODE radio)
        self.udp = None  # MODE udpin


def steady(s, rounds):
    s.k = 0
    i = 0
    while i < rounds:
        if i % 1000 == 0:
            s.b.send(s.hb)
        if i % 700 == 0:
            s.b.ep.statustext(6, b"steady state")
        if i % 50 == 0:
            burst(s)
        if s.flood is not None:
            s.b.send(s.flood)
        if s.udp is not None and i % 50 == 25:
            s.udp.talk(i)
        s.b.run(1)
        if s.udp is not None:
            s.udp.listen()
        i += 1


class Udp:
    """A udpin link of the vehicle and two ground stations on their own sockets."""

    def __init__(self, b, port):
        import socket

        from mavstack.transport.udpin import UdpServer

        self.port = port
        b.ep.add_link(UdpServer("127.0.0.1", self.port))
        vehicle = socket.getaddrinfo("127.0.0.1", self.port)[0][-1]
        self.a = _peer(socket, vehicle)
        self.b = _peer(socket, vehicle)
        ga = b.gcs(255, 190)
        gb = b.gcs(254, 190)
        self.ga = ga
        self.gb = gb
        self.hb_a = ga.heartbeat()
        self.hb_b = gb.heartbeat()
        self.cmd_a = ga.command(512, 1.0)  # REQUEST_MESSAGE SYS_STATUS
        self.cmd_b = gb.command(31000)  # unknown: UNSUPPORTED
        self.ping_b = gb.frame(4, 7654321, 3, 0, 0)
        self.rbuf = bytearray(4096)
        self.got_a = 0
        self.got_b = 0

    def talk(self, i):
        if i % 1000 == 25:
            self._put(self.a, self.ga, self.hb_a)
            self._put(self.b, self.gb, self.hb_b)
        self._put(self.a, self.ga, self.cmd_a)
        self._put(self.b, self.gb, self.cmd_b)
        self._put(self.b, self.gb, self.ping_b)

    def _put(self, sock, g, f):
        g.stamp(f)
        sock.write(f)

    def listen(self):
        self.got_a += self._drain(self.a)
        self.got_b += self._drain(self.b)

    def _drain(self, sock):
        n = 0
        k = sock.readinto(self.rbuf)
        while k:
            n += k
            k = sock.readinto(self.rbuf)
        return n


def burst(s):
    s.b.send(s.burst[s.k])
    s.k += 1
    if s.k == len(s.burst):
        s.k = 0
        s.b.send_raw(s.bad)


def _peer(socket, vehicle):
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(socket.getaddrinfo("127.0.0.1", 0)[0][-1])
    s.connect(vehicle)
    s.setblocking(False)
    return s


def main():
    services = sys.argv[1].split(",") if len(sys.argv) > 1 else ("status", "commands")
    storage = sys.argv[2] if len(sys.argv) > 2 and sys.argv[2] != "-" else None
    rounds = int(sys.argv[3]) if len(sys.argv) > 3 else 5000
    mode = sys.argv[4] if len(sys.argv) > 4 else ""
    s = Steady(*build(services, storage))
    b = s.b
    if mode == "radio":
        b.ep.links[0].bytes_per_s = 5760
        s.flood = b.gcs(200, 190).frame(4, 1, 1, 0, 0)  # PING requests, every round
    elif mode == "udpin":
        s.udp = Udp(b, int(sys.argv[5]))
    steady(s, 2000)  # warm up: first-time paths may allocate
    # The same rounds unlocked, counted with mem_total: the frame states the VM takes
    # from the heap for functions with many locals (under heap_lock they silently fall
    # back to the C stack) show here.
    before = micropython.mem_total()
    steady(s, rounds)
    requested = micropython.mem_total() - before
    acks0 = b.acks
    hb0 = b.seen[0]
    sys0 = b.seen[1]
    version0 = b.seen[148]
    ping0 = b.seen[4]
    unsupported0 = b.results[3]
    text0 = b.seen[253]
    micropython.heap_lock()
    try:
        steady(s, rounds)
    finally:
        micropython.heap_unlock()
    st = b.ep.services["status"]
    held = b.ep.links[0].tx_held
    udp_a = s.udp.got_a if s.udp is not None else 0
    udp_b = s.udp.got_b if s.udp is not None else 0
    print("%s rounds=%d acks=%d heartbeats=%d sys_status=%d version=%d ping=%d errors_comm=%d unsupported=%d "
          "text=%d held=%d udp_a=%d udp_b=%d requested=%d"
          % ("FAIL" if requested else "OK", rounds, b.acks - acks0, b.seen[0] - hb0, b.seen[1] - sys0,
             b.seen[148] - version0, b.seen[4] - ping0, st.errors_comm, b.results[3] - unsupported0,
             b.seen[253] - text0, held, udp_a, udp_b, requested))


main()
