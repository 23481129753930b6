"""The ground-station side of the mission protocol for tests and benchmarks, on pymavlink:
upload, download, clear and partial transfers with retries (tests/relay.py has the lossy link).

    c = MissionClient(m)                       m: a pymavlink connection
    c.upload(items, mission_type=0) -> MISSION_ACK type, or None (no answer)
    c.download(mission_type=0) -> [item, ...], or None
    items are Item tuples (frame, command, current, autocontinue, p1, p2, p3, p4, x, y, z),
    with x, y ints (degrees * 1e7) in the int form, floats in the seed form (form="float").
"""
import time
from collections import namedtuple

Item = namedtuple("Item", "frame command current autocontinue p1 p2 p3 p4 x y z")

LAT0 = 473977420  # degrees * 1e7 around the simulator's home
LON0 = 85455940


def waypoint(i, tag=0, form="int"):
    """Item i of a test plan; tag (a float in param1) tells plans apart."""
    x, y = LAT0 + 1000 * (i % 97) - 3 * i, LON0 + 1000 * (i % 89) + 7 * i
    if form == "float":
        x, y = _f32(x / 1e7), _f32(y / 1e7)
    return Item(3, 16, 0, 1, float(tag), 2.0 + i % 5, 0.0, float(i % 360), x, y, float(10 + i % 50))


def plan(n, tag=0, form="int"):
    return [waypoint(i, tag, form) for i in range(n)]


def _f32(v):
    import struct

    return struct.unpack("<f", struct.pack("<f", v))[0]


def same(a, b):
    """Items equal field by field (floats as float32), but for `current`, which a
    vehicle sets on the item it flies now."""
    if len(a) != len(b):
        return False
    for p, q in zip(a, b):
        for u, v in zip(p._replace(current=0), q._replace(current=0)):
            if isinstance(u, float) or isinstance(v, float):
                if _f32(u) != _f32(v) and not (u != u and v != v):
                    return False
            elif u != v:
                return False
    return True


class MissionClient:
    def __init__(self, m, target=(1, 1), timeout=1.0, retries=8, form="int"):
        self.m = m
        self.ts, self.tc = target
        self.timeout = timeout
        self.retries = retries
        self.form = form  # "int": MISSION_ITEM_INT family, "float": the seed's MISSION_ITEM
        self.last_ack = None

    def _recv(self, types, timeout, mission_type):
        deadline = time.time() + timeout
        while True:
            left = deadline - time.time()
            if left <= 0:
                return None
            msg = self.m.recv_match(type=types, blocking=True, timeout=left)
            if msg is None:
                return None
            if getattr(msg, "mission_type", 0) != mission_type and msg.get_type() != "MISSION_ACK":
                continue
            if msg.get_type() == "MISSION_ACK" and getattr(msg, "mission_type", 0) not in (mission_type, 255):
                continue
            if hasattr(msg, "target_system") and msg.target_system not in (0, self.m.mav.srcSystem):
                continue
            return msg

    def _send(self, name, *args):
        """pymavlink's NAME_send; a MAVLink 1 encoder has no extension arguments."""
        f = getattr(self.m.mav, name + "_send")
        names = f.__code__.co_varnames[1:f.__code__.co_argcount]
        f(*args[:len([n for n in names if n != "force_mavlink1"])])

    def drain(self, seconds=0.0):
        """Forget whatever is queued (late copies from a lossy link)."""
        end = time.time() + seconds
        while True:
            msg = self.m.recv_match(blocking=seconds > 0, timeout=max(0.001, end - time.time()))
            if msg is None and time.time() >= end:
                return

    def send_item(self, seq, item, mission_type=0, as_int=None):
        if as_int is None:
            as_int = self.form == "int"
        x, y = item.x, item.y
        if as_int and isinstance(x, float):
            x, y = round(x * 1e7), round(y * 1e7)
        elif not as_int and isinstance(x, int):
            x, y = x / 1e7, y / 1e7
        self._send("mission_item_int" if as_int else "mission_item", self.ts, self.tc, seq, item.frame,
                   item.command, item.current, item.autocontinue, item.p1, item.p2, item.p3, item.p4,
                   x, y, item.z, mission_type)

    def upload(self, items, mission_type=0, start=None, end=None):
        """Full upload (MISSION_COUNT), or a partial one (MISSION_WRITE_PARTIAL_LIST start..end,
        items then being the new items start..end) -> the MISSION_ACK type, None if none came."""
        m = self.m
        partial = start is not None

        def begin():
            if partial:
                self._send("mission_write_partial_list", self.ts, self.tc, start, end, mission_type)
            else:
                self._send("mission_count", self.ts, self.tc, len(items), mission_type)

        first = start if partial else 0
        last = end if partial else len(items) - 1
        begin()
        requested = False
        sent_last = last < first  # nothing to send: count 0 clears
        misses = 0
        while misses <= self.retries:
            msg = self._recv(["MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK"], self.timeout, mission_type)
            if msg is None:
                misses += 1
                if sent_last and items:
                    self.send_item(last, items[last - first], mission_type)  # our last item or its ACK got lost
                elif not requested:
                    begin()
                continue
            if msg.get_type() == "MISSION_ACK":
                if msg.type != 0 or sent_last:
                    self.last_ack = msg
                    return msg.type
                continue  # an ACCEPTED before our last item: a late copy of an earlier one
            seq = msg.seq
            if first <= seq <= last:
                requested = True
                misses = 0
                self.send_item(seq, items[seq - first], mission_type, msg.get_type() == "MISSION_REQUEST_INT")
                sent_last = sent_last or seq == last
        return None

    def count(self, mission_type=0):
        for _ in range(self.retries + 1):
            self._send("mission_request_list", self.ts, self.tc, mission_type)
            msg = self._recv(["MISSION_COUNT", "MISSION_ACK"], self.timeout, mission_type)
            if msg is not None:
                return msg if msg.get_type() == "MISSION_COUNT" else msg
        return None

    def download(self, mission_type=0, ack=True):
        c = self.count(mission_type)
        if c is None or c.get_type() != "MISSION_COUNT":
            return None
        items = []
        as_int = self.form == "int"
        want = "MISSION_ITEM_INT" if as_int else "MISSION_ITEM"
        for seq in range(c.count):
            for _ in range(self.retries + 1):
                self._send("mission_request_int" if as_int else "mission_request", self.ts, self.tc, seq,
                           mission_type)
                msg = self._recv_item(want, seq, mission_type)
                if msg is not None:
                    break
            else:
                return None
            items.append(Item(msg.frame, msg.command, msg.current, msg.autocontinue, msg.param1, msg.param2,
                              msg.param3, msg.param4, msg.x, msg.y, msg.z))
        if ack:
            self._send("mission_ack", self.ts, self.tc, 0, mission_type)
        return items

    def _recv_item(self, want, seq, mission_type):
        deadline = time.time() + self.timeout
        while True:
            msg = self._recv([want], max(0.0, deadline - time.time()), mission_type)
            if msg is None or msg.seq == seq:
                return msg

    def clear(self, mission_type=0):
        for _ in range(self.retries + 1):
            self._send("mission_clear_all", self.ts, self.tc, mission_type)
            msg = self._recv(["MISSION_ACK"], self.timeout, mission_type)
            if msg is not None:
                return msg.type
        return None


def mavlink1(m):
    """Make a pymavlink connection a MAVLink 1 ground station of the seed's era: frames
    in MAVLink 1, encoded from definitions without extension fields (pymavlink's v2
    module forced to MAVLink 1 would still append them)."""
    from pymavlink.dialects.v10 import common as v10

    mav = v10.MAVLink(m, srcSystem=m.mav.srcSystem, srcComponent=m.mav.srcComponent)
    mav.robust_parsing = m.mav.robust_parsing
    m.mav = mav
    m.WIRE_PROTOCOL_VERSION = "1.0"
    return m
