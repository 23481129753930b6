"""An endpoint in-process on an in-memory link, driven poll by poll: the bench for
heap-lock and in-process tests. Identical on MicroPython and CPython; once built,
sending frames, polling and reading the vehicle's answers allocate nothing, so a
test can run the steady state between micropython.heap_lock() and heap_unlock().

    import sys; sys.path.insert(0, "tests/mpy")   (run_mpy(..., path=[TESTS_MPY]) does it)
    from harness import Bench
    b = Bench(services=("status", "commands"), board=None, options=None, storage=None,
              sysid=1, version=2, app=None)   storage: a directory, or "ram" for storage_ram
    b.ep                         the Endpoint; its link 0 is the in-memory loop
    b.gcs(255, 190)              a Gcs frame builder for ground station sysid 255, compid 190
    f = g.frame(msgid, *fields)  a whole frame (bytearray), payload fields in FMT (wire) order;
                                 build frames before heap_lock
    f = g.command(cmd, p1..p7, target_system=1, target_component=1, confirmation=0)
    f = g.command_int(cmd, frame, p1, p2, p3, p4, x, y, z)
    f = g.heartbeat()            a GCS HEARTBEAT
    b.send(f)                    stamp the Gcs's next sequence number into f (and its CRC)
                                 and queue it for the vehicle; allocation-free
    b.send_raw(buf, n)           queue raw bytes (garbage, bad CRCs)
    b.run(n, step_ms=1)          n rounds of ep.poll(now) (+ app.tick) on a simulated clock
                                 that advances step_ms per round, then read what came out
    b.seen[msgid]                frames the vehicle sent, per id (every id preseeded)
    b.acks, b.ack_command, b.ack_result, b.results[MAV_RESULT]   COMMAND_ACKs received
    b.watch = fn(msgid, payload) called for every vehicle frame (tests that inspect fields)
    b.rx                         the Parser reading the vehicle's output (its version, sysid)

    heap_requests(fn[, arg])     bytes fn requested from the heap, unlocked (mem_total) and
                                 locked (heap_lock): every hot-path test's check

LoopTransport is the transport face (readinto/write/bytes_per_s/name/close) over two
Ring buffers; Bench uses one pair, tests may add more links with loop_pair().
"""
import struct

from mavstack.compat import ticks_add
from mavstack.endpoint import Endpoint
from mavstack.services import compose
from mavstack.encoder import Encoder
from mavstack.parser import Parser
from mavstack.kernels import crc16, crc_accumulate
from mavstack.fields import u16

_MSG_HEARTBEAT = 0
_MSG_COMMAND_INT = 75
_MSG_COMMAND_LONG = 76
_MSG_COMMAND_ACK = 77


_NO_ARG = object()


def _call(fn, arg):
    # fn(*args) would build a tuple: on MicroPython a star-args call allocates.
    if arg is _NO_ARG:
        fn()
    else:
        fn(arg)


def heap_requests(fn, arg=_NO_ARG):
    """Run fn() (or fn(arg)) twice and return the bytes it requested from the heap (0 passes).

    First unlocked, counted with micropython.mem_total(): that sees the frame states the
    VM puts on the heap for functions with many locals, which under heap_lock() silently
    fall back to the C stack. Then under heap_lock(), where any other allocation is a
    MemoryError. fn must leave the state as it found it, or be fine to run again.
    On CPython, or a port without mem_total, fn runs once and 0 is returned.
    """
    try:
        import micropython
    except ImportError:
        _call(fn, arg)
        return 0
    if not hasattr(micropython, "mem_total"):
        _call(fn, arg)
        return 0
    before = micropython.mem_total()
    _call(fn, arg)
    requested = micropython.mem_total() - before
    micropython.heap_lock()
    try:
        _call(fn, arg)
    finally:
        micropython.heap_unlock()
    return requested


class Ring:
    """A byte FIFO in one bytearray."""

    def __init__(self, size):
        self.buf = bytearray(size)
        self.head = 0
        self.count = 0

    # While loops and few locals: MicroPython takes a frame state of more than about 11
    # words (locals plus value stack; a for loop's iterator is four) from the heap on
    # every call, and these run for every read and write of the in-memory link.
    def put(self, src, n):
        buf = self.buf
        size = len(buf)
        if n > size - self.count:
            return 0
        i = (self.head + self.count) % size
        k = 0
        while k < n:
            buf[i] = src[k]
            i += 1
            if i == size:
                i = 0
            k += 1
        self.count += n
        return n

    def get(self, dst):
        n = self.count
        if n > len(dst):
            n = len(dst)
        buf = self.buf
        size = len(buf)
        i = self.head
        k = 0
        while k < n:
            dst[k] = buf[i]
            i += 1
            if i == size:
                i = 0
            k += 1
        self.head = i
        self.count -= n
        return n


class LoopTransport:
    """One end of an in-memory link: reads from `inbound`, writes to `outbound`.

    A write is taken whole or not at all (like a datagram), so a full ring shows up
    as the link's tx_dropped, the way a full UART buffer would.
    """

    def __init__(self, inbound, outbound, bytes_per_s=200000, name="loop"):
        self.inbound = inbound
        self.outbound = outbound
        self.bytes_per_s = bytes_per_s
        self.name = name

    def readinto(self, buf):
        return self.inbound.get(buf)

    def write(self, buf, n):
        return self.outbound.put(buf, n)

    def close(self):
        pass


def loop_pair(size=8192, bytes_per_s=200000, name="loop"):
    """(vehicle_end, gcs_end) of a fresh in-memory link."""
    up = Ring(size)  # ground station -> vehicle
    down = Ring(size)  # vehicle -> ground station
    return LoopTransport(up, down, bytes_per_s, name), LoopTransport(down, up, bytes_per_s, name + "-gcs")


class Board:
    """Board profile settings for a bench vehicle (a board module works as well)."""

    NAME = "bench"
    MAV_TYPE = 2
    MAV_AUTOPILOT = 0
    GCS_TIMEOUT_MS = 5000
    OPERATOR_PASSKEY = None
    PARAMS = ()


class Gcs:
    """Frames from one ground station identity (sysid, compid) in one MAVLink version."""

    def __init__(self, dialect, sysid=255, compid=190, version=2):
        self.dialect = dialect
        self.sysid = sysid
        self.compid = compid
        self.enc = Encoder(dialect.CRC_LEN, version)
        self.seq = 0

    def frame(self, msgid, *fields):
        enc = self.enc
        off = enc.clear(self.dialect.CRC_LEN[msgid] >> 16)
        struct.pack_into(self.dialect.FMT[msgid], enc.buf, off, *fields)
        n = enc.finish(msgid, self.sysid, self.compid)
        return bytearray(enc.buf[:n])

    def heartbeat(self):
        return self.frame(_MSG_HEARTBEAT, 0, 6, 8, 0, 0, 3)  # MAV_TYPE_GCS, MAV_AUTOPILOT_INVALID

    def command(self, command, p1=0.0, p2=0.0, p3=0.0, p4=0.0, p5=0.0, p6=0.0, p7=0.0,
                target_system=1, target_component=1, confirmation=0):
        return self.frame(_MSG_COMMAND_LONG, p1, p2, p3, p4, p5, p6, p7, command,
                          target_system, target_component, confirmation)

    def command_int(self, command, frame=0, p1=0.0, p2=0.0, p3=0.0, p4=0.0, x=0, y=0, z=0.0,
                    target_system=1, target_component=1):
        return self.frame(_MSG_COMMAND_INT, p1, p2, p3, p4, x, y, z, command,
                          target_system, target_component, frame, 0, 0)

    def stamp(self, f):
        """Give frame f this station's next sequence number and a matching CRC."""
        if f[0] == 0xFD:
            f[4] = self.seq
            end = 10 + f[1]
            msgid = f[7] | f[8] << 8 | f[9] << 16
        else:
            f[2] = self.seq
            end = 6 + f[1]
            msgid = f[5]
        self.seq = (self.seq + 1) & 0xFF
        crc = crc_accumulate(crc16(f, 1, end, 0xFFFF), self.dialect.CRC_LEN[msgid] & 0xFF)
        f[end] = crc & 0xFF
        f[end + 1] = crc >> 8
        return end + 2


class Bench:
    def __init__(self, services=("status", "commands"), board=None, options=None, storage=None,
                 sysid=1, compid=1, version=2, app=None, dialect=None, ring=8192, ram_storage_kb=48):
        if dialect is None:
            from mavstack.dialects import common as dialect
        self.dialect = dialect
        ep = Endpoint(dialect, sysid, compid)
        ep.board = board if board is not None else Board
        ep.options = options or {}
        if storage == "ram":  # files in memory (storage_ram.py), as on the emulated boards
            from mavstack.storage_ram import RamStorage

            ep.storage = RamStorage(bytearray(ram_storage_kb * 1024))
        elif storage is not None:
            from mavstack.storage import Storage

            ep.storage = Storage(storage)
        self.vehicle_end, self.gcs_end = loop_pair(ring)
        ep.add_link(self.vehicle_end)
        why = compose(ep, services)
        if why:
            raise ValueError(why)
        self.ep = ep
        self.app = app(ep) if app is not None else None
        self.version = version
        self.now = ep.now
        self.seen = {}
        for msgid in dialect.CRC_LEN:
            self.seen[msgid] = 0
        self.acks = 0
        self.ack_command = -1
        self.ack_result = -1
        self.results = [0] * 10
        self.watch = None
        self.rx = Parser(dialect.CRC_LEN, self._on_frame)
        self._buf = bytearray(512)
        self._gcs = {}

    def gcs(self, sysid=255, compid=190, version=None):
        """The frame builder for one ground station (one per identity, kept)."""
        key = sysid << 8 | compid
        g = self._gcs.get(key)
        if g is None:
            g = self._gcs[key] = Gcs(self.dialect, sysid, compid, version or self.version)
        return g

    def send(self, f, gcs=None):
        g = gcs if gcs is not None else self._sender(f)
        n = g.stamp(f)
        return self.gcs_end.write(f, n)

    def _sender(self, f):
        if f[0] == 0xFD:
            key = f[5] << 8 | f[6]
        else:
            key = f[3] << 8 | f[4]
        return self._gcs[key]

    def send_raw(self, buf, n=-1):
        return self.gcs_end.write(buf, len(buf) if n < 0 else n)

    def run(self, n=1, step_ms=1):
        ep = self.ep
        app = self.app
        for _ in range(n):
            self.now = ticks_add(self.now, step_ms)
            ep.poll(self.now)
            if app is not None:
                app.tick(self.now)
            self.drain()

    def drain(self):
        buf = self._buf
        while True:
            n = self.gcs_end.readinto(buf)
            if not n:
                return
            self.rx.feed(buf, n)

    def _on_frame(self, msgid, p):
        self.seen[msgid] += 1
        if msgid == _MSG_COMMAND_ACK:
            self.acks += 1
            self.ack_command = u16(p, 0)
            self.ack_result = p[2]
            if p[2] < 10:
                self.results[p[2]] += 1
        if self.watch is not None:
            self.watch(msgid, p)
