"""The soak: the unix vehicle heap-locked after start-up, two ground stations working it at
full link rate and a third flooding it, for a number of minutes.

    soak(storage, seconds) -> Result

The vehicle runs `--set heap_lock=1 --set application=0 --set heap_report_ms=1000` (the
simulator allocates, so the stack runs alone) on three udpout links, one per station,
and prints its heap in use and what mem_total() moved by every second. Stations A
(255/190) and B (254/190) each loop: ask for every stream at 50 Hz, list the
parameters (re-reading what the list missed, as a ground station does), set one and read
it back, upload a small mission and download it (a DENIED, while the other station's
transfer is open, is retried later). Station C floods: PARAM_REQUEST_LIST,
MISSION_REQUEST_LIST, REQUEST_DATA_STREAM, PING and REQUEST_MESSAGE from many system ids,
as fast as it can, reading nothing it does not have to.

Reports are read after an idle lead-in, during the load and after it (an idle tail),
so a test can tell the rare events' heap requests from a steady leak.
"""
import os
import random
import re
import socket
import threading
import time

from vehicle import Vehicle, free_udp_port

os.environ.setdefault("MAVLINK20", "1")
from pymavlink import mavutil  # noqa: E402
from pymavlink.dialects.v20 import common as mavlink2  # noqa: E402

LINK_BYTES_PER_S = 20000
STREAM_GROUPS = (6, 10, 11)  # MAV_DATA_STREAM POSITION, EXTRA1, EXTRA2: default streams only
IDLE_S = 4  # idle lead-in and tail: reports with no ground station talking
REPORT_RE = re.compile(r"mavstack: heap (\d+) moved (-?\d+) (locked|unlocked)")


class Station(threading.Thread):
    """A well-behaved ground station on its own link; counts what it completed."""

    def __init__(self, name, port, sysid, param, until, seed):
        threading.Thread.__init__(self, daemon=True)
        self.name = name
        self.param = param
        self.until = until
        self.rng = random.Random(seed)
        self.m = mavutil.mavlink_connection("udpin:127.0.0.1:%d" % port, source_system=sysid,
                                            source_component=190, dialect="common")
        self.heartbeats = []
        self.stats = {"param_lists": 0, "param_sets": 0, "uploads": 0, "downloads": 0, "denied": 0, "cancelled": 0,
                      "stream_requests": 0, "failures": 0}
        self.errors = []
        self.longest = {}  # operation -> its longest time (s)

    def recv(self, types, cond=None, timeout=2.0):
        deadline = time.time() + timeout
        while True:
            left = deadline - time.time()
            if left <= 0:
                return None
            msg = self.m.recv_match(blocking=True, timeout=min(left, 0.2))
            if msg is None:
                continue
            t = msg.get_type()
            if t == "HEARTBEAT" and msg.get_srcSystem() == 1:
                self.heartbeats.append(time.time())
            if t in types and (cond is None or cond(msg)):
                return msg

    def run(self):
        if self.recv(("HEARTBEAT",), timeout=10) is None:
            self.errors.append("no heartbeat at start")
            return
        ops = (self.streams, self.param_list, self.param_set, self.mission)
        while time.time() < self.until:
            for op in ops:
                if time.time() >= self.until:
                    break
                start = time.time()
                try:
                    ok = op()
                except Exception as e:  # a broken station must show, not hang the soak
                    ok = False
                    self.errors.append("%s: %r" % (op.__name__, e))
                if ok is False:
                    self.stats["failures"] += 1
                    self.errors.append("%s failed at %.1f s" % (op.__name__, start))
                took = time.time() - start
                self.longest[op.__name__] = max(self.longest.get(op.__name__, 0), took)
        # Keep reading heartbeats for a moment, so the gap check covers the whole run.
        self.recv((), timeout=1.5)

    def streams(self):
        # Every stream at 50 Hz once, as a ground station does on connecting, then the
        # default streams' groups again and again: more than the link carries. (Stream 0
        # over and over would make the service try, each time, to make on the locked heap
        # the streams it had no room for: no rare event.)
        for stream_id in ((0,) if not self.stats["stream_requests"] else ()) + STREAM_GROUPS:
            self.m.mav.request_data_stream_send(1, 1, stream_id, 50, 1)
        self.stats["stream_requests"] += 1
        self.recv(("HEARTBEAT",), timeout=0.3)
        return True

    def param_list(self):
        self.m.mav.param_request_list_send(1, 1)
        seen = set()
        count = None
        for _ in range(6):
            while True:
                msg = self.recv(("PARAM_VALUE",), timeout=1.0)
                if msg is None:
                    break
                count = msg.param_count
                seen.add(msg.param_index)
                if len(seen) >= count:
                    self.stats["param_lists"] += 1
                    return True
            if count is None:
                self.m.mav.param_request_list_send(1, 1)
                continue
            for i in range(count):  # what the list missed, by index
                if i not in seen:
                    self.m.mav.param_request_read_send(1, 1, b"", i)
        return False

    def param_set(self):
        value = round(self.rng.uniform(1.0, 20.0), 2)
        for _ in range(5):
            self.m.mav.param_set_send(1, 1, self.param.encode(), value, 9)
            msg = self.recv(("PARAM_VALUE",), lambda m: m.param_id == self.param
                            and abs(m.param_value - value) < 1e-3, timeout=1.0)
            if msg is not None:
                self.stats["param_sets"] += 1
                return True
        return False

    def mission(self):
        n = self.rng.randrange(2, 6)
        base = self.rng.randrange(100000)
        if not self._upload(n, base):
            return None  # denied (the other station's transfer): not a failure
        return self._download(n, base)

    def _upload(self, n, base):
        kinds = ("MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK")
        got = None
        for _ in range(5):
            self.m.mav.mission_count_send(1, 1, n, 0)
            got = self.recv(kinds, timeout=1.0)
            if got is not None:
                break
        for _ in range(6 * n + 6):
            if got is None:
                raise AssertionError("upload: vehicle silent")
            if got.get_type() == "MISSION_ACK":
                if got.type == 0:
                    self.stats["uploads"] += 1
                    return True
                if got.type == 14:  # MAV_MISSION_DENIED
                    self.stats["denied"] += 1
                    time.sleep(self.rng.uniform(0.1, 0.5))
                    return False
                if got.type == 15:  # MAV_MISSION_OPERATION_CANCELLED: clean, but counted
                    self.stats["cancelled"] += 1
                    return False
                raise AssertionError("upload: MISSION_ACK %d" % got.type)
            seq = got.seq
            self.m.mav.mission_item_int_send(1, 1, seq, 3, 16, 0, 1, 0, 2, 0, 0, 473977420 + base + seq,
                                             85455940, 20.0 + seq, 0)
            got = self.recv(kinds, timeout=3.0)
        raise AssertionError("upload: no final MISSION_ACK")

    def _download(self, n, base):
        count = None
        for _ in range(5):
            self.m.mav.mission_request_list_send(1, 1, 0)
            count = self.recv(("MISSION_COUNT", "MISSION_ACK"), timeout=1.0)
            if count is not None:
                break
        if count is None or count.get_type() == "MISSION_ACK":
            self.stats["denied"] += 1
            return None
        if count.count != n:
            # The other station may have uploaded in between: a different plan is not wrong.
            return None
        for seq in range(n):
            item = None
            for _ in range(5):
                self.m.mav.mission_request_int_send(1, 1, seq, 0)
                item = self.recv(("MISSION_ITEM_INT", "MISSION_ACK"),
                                 lambda m: m.get_type() == "MISSION_ACK" or m.seq == seq, timeout=1.0)
                if item is not None:
                    break
            if item is None:
                raise AssertionError("download: item %d not sent" % seq)
            if item.get_type() == "MISSION_ACK":  # the transfer was ended (the other's upload)
                self.stats["denied"] += 1
                return None
            if item.x != 473977420 + base + seq:
                return None  # replaced by the other station's upload meanwhile
        self.m.mav.mission_ack_send(1, 1, 0, 0)
        self.stats["downloads"] += 1
        return True

    def close(self):
        self.m.close()


class Flood(threading.Thread):
    """Requests from many system ids as fast as one thread sends them."""

    def __init__(self, port, until, seed):
        threading.Thread.__init__(self, daemon=True)
        self.until = until
        self.rng = random.Random(seed)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", port))
        self.sent = 0
        self.received = 0

    def run(self):
        self.sock.settimeout(10)
        try:
            _, vehicle = self.sock.recvfrom(4096)
        except OSError:
            return
        self.sock.setblocking(False)
        mavs = [mavlink2.MAVLink(None, srcSystem=s, srcComponent=190) for s in range(100, 140)]
        while time.time() < self.until:
            mav = self.rng.choice(mavs)
            kind = self.rng.randrange(5)
            if kind == 0:
                msg = mav.param_request_list_encode(1, 1)
            elif kind == 1:
                msg = mav.mission_request_list_encode(1, 1, 0)
            elif kind == 2:
                # (Not stream 0: on a locked heap each would try again to make the streams it
                # has no room for, and the flood would make that no rare event.)
                msg = mav.request_data_stream_encode(1, 1, self.rng.choice(STREAM_GROUPS), 50, 1)
            elif kind == 3:
                msg = mav.ping_encode(int(time.time() * 1e6), 0, 0, 0)
            else:
                msg = mav.command_long_encode(1, 1, 512, 0, 148, 0, 0, 0, 0, 0, 0)
            try:
                self.sock.sendto(msg.pack(mav), vehicle)
                self.sent += 1
            except OSError:
                pass
            self._drain()
            if self.sent % 4 == 0:
                time.sleep(0.001)

    def _drain(self):
        while True:
            try:
                self.received += len(self.sock.recv(65536))
            except OSError:
                return

    def close(self):
        self.sock.close()


class Result:
    def __init__(self):
        self.reports = []  # (phase, heap in use, mem_total moved, locked)
        self.output = ""
        self.alive = False
        self.stations = []
        self.flood_sent = 0
        self.seconds = 0.0


def soak(storage, seconds, seed=1):
    ports = [free_udp_port() for _ in range(3)]
    v = Vehicle(storage, links=["udpout:127.0.0.1:%d" % p for p in ports],
                args=["--set", "heap_lock=1", "--set", "application=0", "--set", "heap_report_ms=1000",
                      "--set", "param_autosave_ms=0",
                      "--set", "udp_bytes_per_s=%d" % LINK_BYTES_PER_S])
    result = Result()
    lines = []
    phase = ["start"]
    stations = []
    flood = None
    v.start()
    reader = threading.Thread(target=_read_output, args=(v.proc, lines, result, phase), daemon=True)
    reader.start()
    try:
        _wait_ready(v, lines)
        # The stations' sockets are there from the idle lead-in on (a closed port makes
        # every read of the vehicle's an error), silent until the load starts.
        stations = [Station("A", ports[0], 255, "SIM_SPEED", 0, seed),
                    Station("B", ports[1], 254, "SIM_ACCEL", 0, seed + 1)]
        flood = Flood(ports[2], 0, seed + 2)
        phase[0] = "idle"
        time.sleep(IDLE_S)
        phase[0] = "load"
        start = time.time()
        for t in stations + [flood]:
            t.until = start + seconds
            t.start()
        for t in stations + [flood]:
            t.join(seconds + 60)
        result.seconds = time.time() - start
        phase[0] = "tail"
        time.sleep(IDLE_S)
        phase[0] = "end"
        result.alive = v.proc.poll() is None
    finally:
        for t in stations:
            t.close()
        if flood is not None:
            result.flood_sent = flood.sent
            flood.close()
        v.stop()
        reader.join(5)
    result.output = "\n".join(lines)
    result.stations = stations
    return result


def _wait_ready(v, lines, timeout=30):
    deadline = time.time() + timeout
    while time.time() < deadline:
        if any("ready" in line for line in lines):
            return
        v.check_alive()
        time.sleep(0.1)
    raise AssertionError("vehicle not ready\n" + "\n".join(lines))


def _read_output(proc, lines, result, phase):
    for line in proc.stdout:
        line = line.rstrip("\n")
        lines.append(line)
        m = REPORT_RE.search(line)
        if m:
            result.reports.append((phase[0], int(m.group(1)), int(m.group(2)), m.group(3) == "locked"))
