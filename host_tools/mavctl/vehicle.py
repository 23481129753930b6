"""The MAVLink side of mavctl: one vehicle on one pymavlink connection, and the
protocols mavctl speaks with it (commands, parameters, missions), plus the names of
MAVLink enums and messages. Runs on CPython with pymavlink (common dialect, MAVLink 2).
"""
import math
import os
import struct
import sys
import time

os.environ["MAVLINK20"] = "1"  # before pymavlink loads its dialect

from pymavlink.dialects.v20 import common as mavlink  # noqa: E402

from mavctl.errors import EXIT_NO_HEARTBEAT, Failure, usage  # noqa: E402
from mavctl.mission_file import Item, f32_text  # noqa: E402

HEARTBEAT_PERIOD = 1.0
MAV_TYPE_GCS = 6
MISSION_TYPES = {"mission": 0, "fence": 1, "rally": 2}
# MAV_PARAM_TYPE ids that hold integers -> struct code for their bytes on the wire.
PARAM_INT_CODES = {1: "B", 2: "b", 3: "H", 4: "h", 5: "I", 6: "i"}
PARAM_REAL32 = 9

# --- names ------------------------------------------------------------------------

def enum_name(enum, value):
    entry = mavlink.enums.get(enum, {}).get(value)
    return entry.name if entry is not None else "%s(%d)" % (enum, value)


def enum_value(enum, text):
    """An enum value from a number or a name, with or without the enum's prefix."""
    try:
        return int(text, 0)
    except ValueError:
        pass
    name = text.upper()
    for value, entry in mavlink.enums.get(enum, {}).items():
        if entry.name == name or entry.name == enum + "_" + name:
            return value
    raise usage("unknown %s: %s" % (enum, text))


def message_id(text):
    try:
        msgid = int(text, 0)
    except ValueError:
        msgid = getattr(mavlink, "MAVLINK_MSG_ID_" + text.upper(), None)
    if msgid is None or msgid not in mavlink.mavlink_map:
        raise usage("unknown message: %s" % text)
    return msgid


def message_name(msgid):
    cls = mavlink.mavlink_map.get(msgid)
    return cls.msgname if cls is not None else str(msgid)


def payload(msg):
    """The message's payload bytes as received, zero-extended to its full length."""
    buf = msg.get_msgbuf()
    header = 10 if buf[0] == 0xFD else 6
    data = bytes(buf[header:header + buf[1]])
    return data + bytes(max(0, msg.unpacker.size - len(data)))


class Vehicle:
    """One vehicle on one connection; heartbeats go out while we wait for answers."""

    def __init__(self, conn, target_system=None, target_component=None, echo_statustext=True):
        self.conn = conn
        self.mav = conn.mav
        self.target_system = target_system
        self.target_component = target_component
        self.echo_statustext = echo_statustext
        self._next_heartbeat = 0.0
        self._param_encoding = None
        self.heartbeat_msg = None  # the vehicle's first HEARTBEAT (type, autopilot)

    def heartbeat(self):
        now = time.monotonic()
        if now >= self._next_heartbeat:
            self._next_heartbeat = now + HEARTBEAT_PERIOD
            # MAV_TYPE_GCS, MAV_AUTOPILOT_INVALID, MAV_STATE_ACTIVE
            self.mav.heartbeat_send(MAV_TYPE_GCS, 8, 0, 0, 4)

    def connect(self, timeout):
        """Wait for the vehicle's HEARTBEAT (or its answer to our PING); learn its ids
        if not given."""
        deadline = time.monotonic() + timeout
        asked = False
        while time.monotonic() < deadline:
            self.heartbeat()
            msg = self.conn.recv_match(blocking=True, timeout=0.2)
            if msg is None:
                continue
            kind = msg.get_type()
            if kind == "PING":
                if (msg.target_system, msg.target_component) != (self.mav.srcSystem, self.mav.srcComponent):
                    continue
            elif kind != "HEARTBEAT" or msg.type == MAV_TYPE_GCS:
                if not asked:
                    # Rather than wait up to a second for the next beat, ask: PING to
                    # all (0/0) and a HEARTBEAT by REQUEST_MESSAGE. Sent once the link
                    # carries traffic (udpin learns its peer from it).
                    self.mav.ping_send(int(time.time() * 1e6), 0, 0, 0)
                    self.mav.command_long_send(0, 0, mavlink.MAV_CMD_REQUEST_MESSAGE, 0,
                                               mavlink.MAVLINK_MSG_ID_HEARTBEAT, 0, 0, 0, 0, 0, 0)
                    asked = True
                continue
            if self.target_system not in (None, msg.get_srcSystem()):
                continue
            if self.target_component not in (None, msg.get_srcComponent()):
                continue
            self.target_system = msg.get_srcSystem()
            self.target_component = msg.get_srcComponent()
            if kind == "HEARTBEAT":
                self.heartbeat_msg = msg
            return msg
        raise Failure("no HEARTBEAT from a vehicle within %g s: is it powered, on this link, "
                      "at this baud?" % timeout, EXIT_NO_HEARTBEAT)

    def recv(self, types, timeout, cond=None):
        """Next message from the vehicle whose type is in types (None: any) and that
        satisfies cond, or None after timeout seconds."""
        deadline = time.monotonic() + timeout
        while True:
            self.heartbeat()
            left = deadline - time.monotonic()
            if left <= 0:
                return None
            msg = self.conn.recv_match(blocking=True, timeout=min(left, 0.2))
            if msg is None or msg.get_srcSystem() != self.target_system:
                continue
            kind = msg.get_type()
            if kind == "STATUSTEXT" and self.echo_statustext and msg.severity <= 4:
                print("vehicle: %s: %s" % (enum_name("MAV_SEVERITY", msg.severity)[13:], msg.text),
                      file=sys.stderr)
            if (types is None or kind in types) and (cond is None or cond(msg)):
                return msg

    def for_me(self, msg):
        """A reply addressed to this ground station (0: broadcast)."""
        ts = getattr(msg, "target_system", 0)
        tc = getattr(msg, "target_component", 0)
        return ts in (0, self.mav.srcSystem) and tc in (0, self.mav.srcComponent)

    # --- commands

    def command(self, command, params=(), tries=3, timeout=1.5):
        """COMMAND_LONG until its final COMMAND_ACK -> the ack message."""
        p = (list(params) + [0.0] * 7)[:7]
        for confirmation in range(tries):
            self.mav.command_long_send(self.target_system, self.target_component, command,
                                       confirmation, *p)
            wait = timeout
            while True:
                ack = self.recv(("COMMAND_ACK",), wait,
                                lambda m: m.command == command and self.for_me(m))
                if ack is None or ack.result != mavlink.MAV_RESULT_IN_PROGRESS:
                    break
                print("%s: in progress %d%%" % (enum_name("MAV_CMD", command), ack.progress),
                      file=sys.stderr)
                wait = 30.0  # a long-running command reports progress, then its result
            if ack is not None:
                return ack
        raise Failure("no COMMAND_ACK for %s" % enum_name("MAV_CMD", command))

    # --- parameters

    def param_encoding(self):
        """'bytewise' or 'cast': how integer parameters travel in PARAM_VALUE's float."""
        if self._param_encoding is None:
            caps = self.capabilities()
            if caps & mavlink.MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_C_CAST and not (
                    caps & mavlink.MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE):
                self._param_encoding = "cast"
            else:
                self._param_encoding = "bytewise"
        return self._param_encoding

    def capabilities(self):
        """AUTOPILOT_VERSION.capabilities, 0 if the vehicle does not say."""
        requests = ((mavlink.MAV_CMD_REQUEST_MESSAGE, mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION),
                    (mavlink.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES, 1))
        for command, p1 in requests:
            self.mav.command_long_send(self.target_system, self.target_component, command, 0, p1,
                                       0, 0, 0, 0, 0, 0)
            # An ACK alone means the request was not run (refused, or taken for a
            # repeat of the last command): then try the other form at once.
            wait = 1.0
            while True:
                msg = self.recv(("AUTOPILOT_VERSION", "COMMAND_ACK"), wait,
                                lambda m: m.get_type() == "AUTOPILOT_VERSION" or m.command == command)
                if msg is None:
                    break
                if msg.get_type() == "AUTOPILOT_VERSION":
                    return msg.capabilities
                if msg.result != mavlink.MAV_RESULT_ACCEPTED:
                    break
                wait = 0.3
        return 0

    def param_from(self, msg):
        return Param(msg.param_id, msg.param_type, msg.param_index, msg.param_count,
                     payload(msg)[:4], self.param_encoding)

    def param_read(self, name, tries=3, timeout=1.0):
        for _ in range(tries):
            self.mav.param_request_read_send(self.target_system, self.target_component,
                                             name.encode(), -1)
            msg = self.recv(("PARAM_VALUE", "PARAM_ERROR"), timeout, lambda m: m.param_id == name)
            if msg is None:
                continue
            if msg.get_type() == "PARAM_ERROR":
                raise Failure("%s: %s" % (name, enum_name("MAV_PARAM_ERROR", msg.error)))
            return self.param_from(msg)
        raise Failure("no parameter %s (the vehicle did not answer)" % name)

    def param_list(self, idle=1.0, tries=5, progress=None):
        """Every parameter, by index: PARAM_REQUEST_LIST, then missing ones one by one.
        progress(done, total), if given, is told as values arrive."""
        params = {}
        count = None
        asked = 0
        self.mav.param_request_list_send(self.target_system, self.target_component)
        last = time.monotonic()
        while count is None or len(params) < count:
            msg = self.recv(("PARAM_VALUE",), 0.3)
            now = time.monotonic()
            if msg is not None:
                last = now
                count = msg.param_count
                if msg.param_index < count:
                    params[msg.param_index] = self.param_from(msg)
                    if progress is not None:
                        progress(len(params), count)
                continue
            if now - last < idle:
                continue
            asked += 1
            if asked > tries:
                if count is None:
                    raise Failure("no answer to PARAM_REQUEST_LIST")
                raise Failure("got %d of %d parameters" % (len(params), count))
            last = now
            if count is None:
                self.mav.param_request_list_send(self.target_system, self.target_component)
            else:
                for i in [i for i in range(count) if i not in params][:32]:
                    self.mav.param_request_read_send(self.target_system, self.target_component, b"", i)
        return [params[i] for i in sorted(params)]

    def param_set(self, name, raw, ptype, tries=3, timeout=1.5):
        """PARAM_SET with the value's 4 bytes as they go on the wire -> the Param echoed back."""
        for _ in range(tries):
            msg = self.mav.param_set_encode(self.target_system, self.target_component,
                                            name.encode(), 0.0, ptype)
            # pymavlink's float field cannot carry every int bit pattern (NaN payloads
            # change on the way through a double), so the payload is packed here.
            body = struct.pack("<4sBB16sB", raw, self.target_system, self.target_component,
                               name.encode(), ptype)
            self.conn.write(msg._pack(self.mav, msg.crc_extra, body))
            self.mav.seq = (self.mav.seq + 1) % 256
            reply = self.recv(("PARAM_VALUE", "PARAM_ERROR"), timeout, lambda m: m.param_id == name)
            if reply is None:
                continue
            if reply.get_type() == "PARAM_ERROR":
                raise Failure("%s: %s" % (name, enum_name("MAV_PARAM_ERROR", reply.error)))
            return self.param_from(reply)
        raise Failure("no answer to PARAM_SET %s" % name)

    # --- missions

    def mission_upload(self, items, mtype, timeout=1.5, tries=5, progress=None):
        """MISSION_COUNT, answer each MISSION_REQUEST(_INT), until the MISSION_ACK;
        progress(done, total), if given, is told as items go."""
        n = len(items)
        self.mav.mission_count_send(self.target_system, self.target_component, n, mtype)
        asked = 1
        sent = set()
        kinds = ("MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK")
        while True:
            msg = self.recv(kinds, timeout if not sent else 3 * timeout,
                            lambda m: m.mission_type == mtype and self.for_me(m))
            if msg is None:
                if sent or asked >= tries:
                    raise Failure("upload stalled after %d of %d items" % (len(sent), n))
                self.mav.mission_count_send(self.target_system, self.target_component, n, mtype)
                asked += 1
                continue
            if msg.get_type() == "MISSION_ACK":
                if msg.type != mavlink.MAV_MISSION_ACCEPTED:
                    raise Failure("upload refused: %s" % enum_name("MAV_MISSION_RESULT", msg.type))
                if len(sent) == n:
                    return
                continue  # an ACCEPTED left over from an earlier transfer
            if msg.seq >= n:
                continue
            item = items[msg.seq]
            if msg.get_type() == "MISSION_REQUEST_INT":
                self.mav.send(item.to_int(self.mav, self.target_system, self.target_component, mtype))
            else:
                self.mav.send(item.to_float(self.mav, self.target_system, self.target_component, mtype))
            sent.add(msg.seq)
            if progress is not None:
                progress(len(sent), n)

    def mission_download(self, mtype, timeout=1.5, tries=5, progress=None):
        """MISSION_REQUEST_LIST -> COUNT, MISSION_REQUEST_INT each item, MISSION_ACK."""
        mine = (lambda m: m.mission_type == mtype and self.for_me(m))
        count = None
        for _ in range(tries):
            self.mav.mission_request_list_send(self.target_system, self.target_component, mtype)
            msg = self.recv(("MISSION_COUNT", "MISSION_ACK"), timeout, mine)
            if msg is None:
                continue
            if msg.get_type() == "MISSION_ACK":
                raise Failure("download refused: %s" % enum_name("MAV_MISSION_RESULT", msg.type))
            count = msg.count
            break
        if count is None:
            raise Failure("no answer to MISSION_REQUEST_LIST")
        items = []
        kinds = ("MISSION_ITEM_INT", "MISSION_ITEM", "MISSION_ACK")
        for seq in range(count):
            for _ in range(tries):
                self.mav.mission_request_int_send(self.target_system, self.target_component, seq, mtype)
                msg = self.recv(kinds, timeout,
                                lambda m: mine(m) and (m.get_type() == "MISSION_ACK" or m.seq == seq))
                if msg is None:
                    continue
                if msg.get_type() == "MISSION_ACK":
                    raise Failure("download refused: %s" % enum_name("MAV_MISSION_RESULT", msg.type))
                items.append(Item.from_message(msg))
                if progress is not None:
                    progress(len(items), count)
                break
            else:
                raise Failure("no answer for item %d of %d" % (seq, count))
        self.mav.mission_ack_send(self.target_system, self.target_component,
                                  mavlink.MAV_MISSION_ACCEPTED, mtype)
        return items

    def home_position(self, timeout=1.5):
        """(lat, lon, alt) of the vehicle's HOME_POSITION, None if it does not say."""
        self.mav.command_long_send(self.target_system, self.target_component,
                                   mavlink.MAV_CMD_REQUEST_MESSAGE, 0,
                                   mavlink.MAVLINK_MSG_ID_HOME_POSITION, 0, 0, 0, 0, 0, 0)
        msg = self.recv(("HOME_POSITION",), timeout)
        if msg is None:
            return None
        return msg.latitude / 1e7, msg.longitude / 1e7, msg.altitude / 1e3

    def mission_clear(self, mtype, tries=3, timeout=1.5):
        for _ in range(tries):
            self.mav.mission_clear_all_send(self.target_system, self.target_component, mtype)
            ack = self.recv(("MISSION_ACK",), timeout, lambda m: m.mission_type == mtype and self.for_me(m))
            if ack is None:
                continue
            if ack.type != mavlink.MAV_MISSION_ACCEPTED:
                raise Failure("clear refused: %s" % enum_name("MAV_MISSION_RESULT", ack.type))
            return
        raise Failure("no answer to MISSION_CLEAR_ALL")

    def mission_set_current(self, seq, tries=3, timeout=1.5):
        """MAV_CMD_DO_SET_MISSION_CURRENT; MISSION_SET_CURRENT where the command is unknown."""
        try:
            ack = self.command(mavlink.MAV_CMD_DO_SET_MISSION_CURRENT, [seq])
        except Failure:
            ack = None
        if ack is not None and ack.result != mavlink.MAV_RESULT_UNSUPPORTED:
            if ack.result != mavlink.MAV_RESULT_ACCEPTED:
                raise Failure("refused: %s" % enum_name("MAV_RESULT", ack.result))
            return
        for _ in range(tries):
            self.mav.mission_set_current_send(self.target_system, self.target_component, seq)
            msg = self.recv(("MISSION_CURRENT", "MISSION_ACK"), timeout,
                            lambda m: m.get_type() == "MISSION_ACK" and self.for_me(m) or
                            m.get_type() == "MISSION_CURRENT" and m.seq == seq)
            if msg is None:
                continue
            if msg.get_type() == "MISSION_ACK":
                if msg.type == mavlink.MAV_MISSION_ACCEPTED:
                    continue
                raise Failure("refused: %s" % enum_name("MAV_MISSION_RESULT", msg.type))
            return
        raise Failure("the vehicle did not change its current item to %d" % seq)


class Param:
    """A parameter as the vehicle reported it; raw is the 4 bytes of param_value.

    encoding() says how integers travel ('bytewise' or 'cast'); it is asked only
    when an integer parameter is shown or set.
    """

    def __init__(self, name, ptype, index, count, raw, encoding):
        self.name = name
        self.type = ptype
        self.index = index
        self.count = count
        self.raw = raw
        self._encoding = encoding

    @property
    def encoding(self):
        return self._encoding() if self.type in PARAM_INT_CODES else None

    @property
    def value(self):
        code = PARAM_INT_CODES.get(self.type)
        f = struct.unpack("<f", self.raw)[0]
        if code is None:
            return f
        if self.encoding == "bytewise":
            return struct.unpack_from("<" + code, self.raw)[0]
        return int(f) if math.isfinite(f) else f

    def text(self):
        v = self.value
        return str(v) if isinstance(v, int) else f32_text(v)

    def encode(self, text):
        """The 4 wire bytes for a new value given as text, in this parameter's type."""
        code = PARAM_INT_CODES.get(self.type)
        if code is None:
            try:
                value = float(text)
            except ValueError:
                raise usage("%s takes a number, not %r" % (self.name, text))
            if self.type != PARAM_REAL32:
                kind = enum_name("MAV_PARAM_TYPE", self.type)
                print("mavctl: %s is %s, sent as a float32" % (self.name, kind), file=sys.stderr)
            try:
                return struct.pack("<f", value)
            except OverflowError:
                raise usage("%s: %s is beyond a float32" % (self.name, text))
        try:
            value = int(text, 0)
        except ValueError:
            try:
                f = float(text)
            except ValueError:
                f = math.nan
            if not f.is_integer():
                kind = enum_name("MAV_PARAM_TYPE", self.type)[15:]
                raise usage("%s is %s: an integer, not %r" % (self.name, kind, text))
            value = int(f)
        bits = 8 * struct.calcsize(code)
        lo, hi = (0, (1 << bits) - 1) if code.isupper() else (-(1 << bits - 1), (1 << bits - 1) - 1)
        if not lo <= value <= hi:
            raise usage("%s: %d is outside %d..%d" % (self.name, value, lo, hi))
        if self.encoding == "bytewise":
            return struct.pack("<" + code, value).ljust(4, b"\0")
        return struct.pack("<f", value)

    def same_value(self, raw):
        if self.type in PARAM_INT_CODES or self.raw == raw:
            return self.raw == raw
        a, b = struct.unpack("<f", self.raw)[0], struct.unpack("<f", raw)[0]
        return a == b or (math.isnan(a) and math.isnan(b))
