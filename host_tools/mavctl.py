"""Drive a MAVLink vehicle from the PC over UDP or a serial cable: parameters,
missions, commands and live telemetry, one subcommand per run.

    python host_tools/mavctl.py --connect udpout:127.0.0.1:14550 params list
    python host_tools/mavctl.py --connect serial:/dev/ttyUSB0:57600 mission upload route.waypoints
    python host_tools/mavctl.py --connect udpin:0.0.0.0:14550 watch HEARTBEAT --seconds 5

Exit status: 0 done, 1 the vehicle refused (NACK) or did not answer, 2 usage or
connection error. Runs on CPython with pymavlink (common dialect, MAVLink 2).
"""
import argparse
import fnmatch
import math
import os
import struct
import sys
import time

os.environ["MAVLINK20"] = "1"  # before pymavlink loads its dialect

from pymavlink import mavutil  # noqa: E402
from pymavlink.dialects.v20 import common as mavlink  # noqa: E402

EXIT_OK, EXIT_REFUSED, EXIT_USAGE = 0, 1, 2
HEARTBEAT_PERIOD = 1.0
MAV_TYPE_GCS = 6
MISSION_TYPES = {"mission": 0, "fence": 1, "rally": 2}
# MAV_PARAM_TYPE ids that hold integers -> struct code for their bytes on the wire.
PARAM_INT_CODES = {1: "B", 2: "b", 3: "H", 4: "h", 5: "I", 6: "i"}
PARAM_REAL32 = 9
# COMMAND_INT / MISSION_ITEM_INT x, y: local frames carry metres * 1e4, others degrees * 1e7.
LOCAL_FRAMES = (1, 4, 7, 8, 9, 12, 20, 21)


class Failure(Exception):
    """Ends the run with a message and an exit status."""

    def __init__(self, message, status=EXIT_REFUSED):
        Exception.__init__(self, message)
        self.status = status


def usage(message):
    return Failure(message, EXIT_USAGE)


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


def f32_text(x):
    """Shortest text that reads back to the same float32."""
    if math.isnan(x) or math.isinf(x):
        return repr(x)
    want = struct.pack("<f", x)
    for digits in range(1, 10):
        short = float("%.*g" % (digits, x))
        if struct.pack("<f", short) == want:
            return repr(short)
    return repr(x)


def payload(msg):
    """The message's payload bytes as received, zero-extended to its full length."""
    buf = msg.get_msgbuf()
    header = 10 if buf[0] == 0xFD else 6
    data = bytes(buf[header:header + buf[1]])
    return data + bytes(max(0, msg.unpacker.size - len(data)))


# --- the connection -----------------------------------------------------------------

def open_link(spec, sysid, compid):
    """pymavlink connection for udpout:HOST:PORT, udpin:ADDR:PORT, tcp:HOST:PORT or
    serial:DEVICE[:BAUD]."""
    kind, _, rest = spec.partition(":")
    opts = dict(source_system=sysid, source_component=compid, dialect="common", autoreconnect=False)
    if kind == "serial":
        device, _, baud = rest.rpartition(":")
        if not baud.isdigit():
            device, baud = rest, "57600"
        if not device:
            raise usage("--connect serial:DEVICE:BAUD")
        target, opts["baud"] = device, int(baud)
    elif kind in ("udpout", "udpin", "udp", "tcp") and rest.rpartition(":")[2].isdigit():
        target = spec
    else:
        raise usage("--connect udpout:HOST:PORT, udpin:ADDR:PORT, tcp:HOST:PORT or serial:DEVICE:BAUD")
    try:
        return mavutil.mavlink_connection(target, **opts)
    except Exception as e:  # serial.SerialException, OSError, socket errors
        raise usage("cannot open %s: %s" % (spec, e))


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
            return msg
        raise usage("no HEARTBEAT from a vehicle within %g s" % timeout)

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

    def param_list(self, idle=1.0, tries=5):
        """Every parameter, by index: PARAM_REQUEST_LIST, then missing ones one by one."""
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

    def mission_upload(self, items, mtype, timeout=1.5, tries=5):
        """MISSION_COUNT, answer each MISSION_REQUEST(_INT), until the MISSION_ACK."""
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

    def mission_download(self, mtype, timeout=1.5, tries=5):
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
                break
            else:
                raise Failure("no answer for item %d of %d" % (seq, count))
        self.mav.mission_ack_send(self.target_system, self.target_component,
                                  mavlink.MAV_MISSION_ACCEPTED, mtype)
        return items

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


class Item:
    """One mission item as in a QGC WPL file: x, y in degrees (or metres in local frames)."""

    def __init__(self, seq, current, frame, command, p1, p2, p3, p4, x, y, z, autocontinue):
        self.seq, self.current, self.frame, self.command = seq, current, frame, command
        self.params = [p1, p2, p3, p4]
        self.x, self.y, self.z = x, y, z
        self.autocontinue = autocontinue

    def scale(self):
        return 1e4 if self.frame in LOCAL_FRAMES else 1e7

    @classmethod
    def from_message(cls, m):
        x, y = m.x, m.y
        if m.get_type() == "MISSION_ITEM_INT":
            digits = 4 if m.frame in LOCAL_FRAMES else 7
            x = Scaled(m.x, digits)
            y = Scaled(m.y, digits)
        return cls(m.seq, m.current, m.frame, m.command, m.param1, m.param2, m.param3, m.param4,
                   x, y, m.z, m.autocontinue)

    def to_int(self, mav, ts, tc, mtype):
        s = self.scale()
        x, y = round(float(self.x) * s), round(float(self.y) * s)
        return mav.mission_item_int_encode(ts, tc, self.seq, self.frame, self.command, self.current,
                                           self.autocontinue, *self.params, x, y, self.z, mtype)

    def to_float(self, mav, ts, tc, mtype):
        return mav.mission_item_encode(ts, tc, self.seq, self.frame, self.command, self.current,
                                       self.autocontinue, *self.params, float(self.x), float(self.y),
                                       self.z, mtype)

    def wpl_line(self):
        nums = [f32_text(p) for p in self.params]
        xy = [v.text() if isinstance(v, Scaled) else f32_text(v) for v in (self.x, self.y)]
        return "\t".join([str(self.seq), str(self.current), str(self.frame), str(self.command)]
                         + nums + xy + [f32_text(self.z), str(self.autocontinue)])


class Scaled:
    """An integer coordinate (degrees * 1e7, metres * 1e4) printed without rounding."""

    def __init__(self, i, digits):
        self.i = i
        self.digits = digits

    def __float__(self):
        return self.i / 10 ** self.digits

    def text(self):
        sign = "-" if self.i < 0 else ""
        whole, frac = divmod(abs(self.i), 10 ** self.digits)
        frac = ("%0*d" % (self.digits, frac)).rstrip("0")
        return sign + str(whole) + ("." + frac if frac else "")


WPL_HEADER = "QGC WPL 110"


def read_wpl(path):
    try:
        with open(path, encoding="utf-8") as f:
            lines = f.read().splitlines()
    except OSError as e:
        raise usage("%s: %s" % (path, e.strerror))
    if not lines or not lines[0].startswith("QGC WPL"):
        raise usage("%s: not a QGC WPL file (first line %r)" % (path, WPL_HEADER))
    if lines[0].split()[-1] != "110":
        raise usage("%s: only %r files are supported" % (path, WPL_HEADER))
    items = []
    for number, line in enumerate(lines[1:], 2):
        words = line.split()
        if not words:
            continue
        if len(words) != 12:
            raise usage("%s:%d: 12 columns expected, found %d" % (path, number, len(words)))
        try:
            ints = [int(w) for w in words[:4]] + [int(float(words[11]))]
            nums = [float(w) for w in words[4:11]]
        except ValueError as e:
            raise usage("%s:%d: %s" % (path, number, e))
        if ints[0] != len(items):
            raise usage("%s:%d: item %d where %d was due" % (path, number, ints[0], len(items)))
        item = Item(*ints[:4], *nums, ints[4])
        for v in (item.x, item.y):
            # MISSION_ITEM_INT carries x and y as int32 (degrees * 1e7, metres * 1e4).
            if not math.isfinite(v) or abs(round(v * item.scale())) >= 1 << 31:
                raise usage("%s:%d: x and y must be numbers within the int32 range" % (path, number))
        items.append(item)
    return items


def write_wpl(items, out):
    out.write(WPL_HEADER + "\n")
    for item in items:
        out.write(item.wpl_line() + "\n")


# --- subcommands --------------------------------------------------------------------

def result_status(what, ack):
    name = enum_name("MAV_RESULT", ack.result)
    extra = " (result_param2 %d)" % ack.result_param2 if getattr(ack, "result_param2", 0) else ""
    print("%s: %s%s" % (what, name, extra))
    return EXIT_OK if ack.result == mavlink.MAV_RESULT_ACCEPTED else EXIT_REFUSED


def send_command(v, command, params):
    return result_status(enum_name("MAV_CMD", command), v.command(command, params))


def cmd_params(v, args):
    if args.action == "list":
        params = v.param_list()
        pattern = args.name
        for p in params:
            if pattern is None or fnmatch.fnmatchcase(p.name, pattern):
                print("%-16s %s" % (p.name, p.text()))
        return EXIT_OK
    if args.action == "get":
        print("%-16s %s" % (args.name, v.param_read(args.name).text()))
        return EXIT_OK
    if args.action == "set":
        current = v.param_read(args.name)
        raw = current.encode(args.value)
        echoed = v.param_set(args.name, raw, current.type)
        if not echoed.same_value(raw):
            raise Failure("refused: %s stays %s" % (args.name, echoed.text()))
        print("%-16s %s" % (args.name, echoed.text()))
        return EXIT_OK
    # MAV_CMD_PREFLIGHT_STORAGE param1: 0 read from storage, 1 write, 2 reset to defaults.
    action = {"load": 0, "save": 1, "load-defaults": 2}[args.action]
    return result_status("params " + args.action,
                         v.command(mavlink.MAV_CMD_PREFLIGHT_STORAGE, [action]))


def cmd_mission(v, args):
    mtype = MISSION_TYPES[args.type]
    if args.action == "upload":
        v.mission_upload(args.items, mtype)
        print("uploaded %d %s items" % (len(args.items), args.type))
    elif args.action == "download":
        items = v.mission_download(mtype)
        if args.arg and args.arg != "-":
            with open(args.arg, "w", encoding="utf-8") as f:
                write_wpl(items, f)
            print("downloaded %d %s items to %s" % (len(items), args.type, args.arg))
        else:
            write_wpl(items, sys.stdout)
    elif args.action == "clear":
        v.mission_clear(mtype)
        print("cleared the %s" % args.type)
    elif args.action == "current":
        v.mission_set_current(args.seq)
        print("current item %d" % args.seq)
    return EXIT_OK


def parse_floats(words):
    try:
        return [float(w) for w in words]
    except ValueError as e:
        raise usage(str(e))


def cmd_command(v, args):
    return send_command(v, args.command, args.values)


def cmd_arm(v, args):
    # param2 21196: arm or disarm even if checks refuse (MAV_CMD_COMPONENT_ARM_DISARM).
    arm = 1.0 if args.subcommand == "arm" else 0.0
    return send_command(v, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, [arm, 21196.0 if args.force else 0.0])


def cmd_mode(v, args):
    return send_command(v, mavlink.MAV_CMD_DO_SET_MODE, args.values)


def cmd_reboot(v, args):
    return send_command(v, mavlink.MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN, [1.0])


def cmd_stream(v, args):
    return result_status("stream %s" % message_name(args.values[0]),
                         v.command(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, args.values))


def cmd_watch(v, args):
    wanted = args.wanted
    v.echo_statustext = False
    start = time.monotonic()
    end = start + args.seconds if args.seconds else math.inf
    counts = {}
    table_at = start + 1.0
    live_table = args.rates and sys.stdout.isatty()
    try:
        while True:
            now = time.monotonic()
            if now >= end:
                break
            msg = v.recv(wanted, min(0.5, end - now))
            if msg is not None:
                if args.rates:
                    counts[msg.get_type()] = counts.get(msg.get_type(), 0) + 1
                else:
                    print(msg, flush=True)
            if live_table and time.monotonic() >= table_at:
                table_at += 1.0
                sys.stdout.write("\x1b[H\x1b[2J")
                print_rates(counts, time.monotonic() - start)
    except KeyboardInterrupt:
        pass
    if args.rates:
        print_rates(counts, time.monotonic() - start)
    return EXIT_OK


def print_rates(counts, seconds):
    print("%-28s %8s %8s" % ("MESSAGE", "COUNT", "HZ"))
    for name in sorted(counts):
        print("%-28s %8d %8.2f" % (name, counts[name], counts[name] / max(seconds, 1e-3)))
    sys.stdout.flush()


def check(args):
    """Turn the arguments into values, so that usage errors show before connecting."""
    cmd = args.subcommand
    if cmd == "params":
        if args.action in ("get", "set") and not args.name:
            raise usage("params %s NAME%s" % (args.action, " VALUE" if args.action == "set" else ""))
        if args.action == "set" and args.value is None:
            raise usage("params set NAME VALUE")
        if args.action != "list" and args.name and len(args.name.encode()) > 16:
            raise usage("parameter names have at most 16 characters")
    elif cmd == "mission":
        if args.action == "upload":
            if not args.arg:
                raise usage("mission upload FILE")
            args.items = read_wpl(args.arg)
        elif args.action == "current":
            try:
                args.seq = int(args.arg)
            except (TypeError, ValueError):
                raise usage("mission current N")
    elif cmd == "command":
        if len(args.params) > 7:
            raise usage("a command has at most 7 parameters")
        args.command = enum_value("MAV_CMD", args.name)
        args.values = parse_floats(args.params)
    elif cmd == "mode":
        if len(args.custom) > 2:
            raise usage("mode BASE [CUSTOM [SUBMODE]]")
        base = 0
        for word in args.base.split("|"):
            try:
                base |= enum_value("MAV_MODE", word)
            except Failure:
                base |= enum_value("MAV_MODE_FLAG", word)
        args.values = [base] + parse_floats(args.custom)
    elif cmd == "stream":
        msgid = message_id(args.message)
        rate = args.hz.lower()
        if rate in ("off", "stop"):
            interval = -1.0
        elif rate == "default":
            interval = 0.0
        else:
            hz = parse_floats([rate])[0]
            if hz < 0 or not math.isfinite(hz):
                raise usage("HZ: a rate >= 0, 'default' or 'off'")
            interval = -1.0 if hz == 0 else round(1e6 / hz)
        args.values = [msgid, interval]
    elif cmd == "watch":
        args.wanted = {message_name(message_id(m)) for m in args.messages} or None


def parser():
    ap = argparse.ArgumentParser(
        prog="mavctl", description="Drive a MAVLink vehicle: parameters, missions, commands, telemetry.",
        epilog="Exit status: 0 done, 1 refused or unanswered, 2 usage or connection error.")
    ap.add_argument("--connect", required=True, metavar="LINK",
                    help="udpout:HOST:PORT, udpin:ADDR:PORT, tcp:HOST:PORT or serial:DEVICE:BAUD")
    ap.add_argument("--sysid", type=int, default=255, help="our system id (default 255)")
    ap.add_argument("--compid", type=int, default=190, help="our component id (default 190, a GCS)")
    ap.add_argument("--target-system", type=int, help="the vehicle's system id (default: first heard)")
    ap.add_argument("--target-component", type=int, help="the vehicle's component id")
    ap.add_argument("--timeout", type=float, default=10.0, help="seconds to wait for a HEARTBEAT")
    sub = ap.add_subparsers(dest="subcommand", required=True, metavar="SUBCOMMAND")

    p = sub.add_parser("params", help="list, get, set, save, load, load-defaults parameters")
    p.add_argument("action", choices=("list", "get", "set", "save", "load", "load-defaults"))
    p.add_argument("name", nargs="?", help="parameter name (list: a pattern such as 'SR_*')")
    p.add_argument("value", nargs="?")
    p.set_defaults(run=cmd_params)

    p = sub.add_parser("mission", help="upload, download, clear a mission, fence or rally points")
    p.add_argument("action", choices=("upload", "download", "clear", "current"))
    p.add_argument("arg", nargs="?", metavar="FILE|N",
                   help="QGC WPL 110 file (download: default stdout); current: the item number")
    p.add_argument("--type", choices=tuple(MISSION_TYPES), default="mission")
    p.set_defaults(run=cmd_mission)

    p = sub.add_parser("command", help="send a COMMAND_LONG, print the COMMAND_ACK result")
    p.add_argument("name", metavar="NAME_OR_ID", help="MAV_CMD name (NAV_TAKEOFF) or number")
    p.add_argument("params", nargs="*", metavar="P", help="param1 .. param7 (default 0; nan allowed)")
    p.set_defaults(run=cmd_command)

    for name in ("arm", "disarm"):
        p = sub.add_parser(name, help="%s the vehicle" % name)
        p.add_argument("--force", action="store_true", help="override the vehicle's checks")
        p.set_defaults(run=cmd_arm)

    p = sub.add_parser("mode", help="MAV_CMD_DO_SET_MODE")
    p.add_argument("base", metavar="BASE",
                   help="base mode: number, MAV_MODE name, or MAV_MODE_FLAG names joined by |")
    p.add_argument("custom", nargs="*", metavar="CUSTOM", help="custom mode [custom sub mode]")
    p.set_defaults(run=cmd_mode)

    p = sub.add_parser("reboot", help="reboot the vehicle's autopilot")
    p.set_defaults(run=cmd_reboot)

    p = sub.add_parser("watch", help="print telemetry until Ctrl-C")
    p.add_argument("messages", nargs="*", metavar="MSG", help="message names (default: all)")
    p.add_argument("--seconds", type=float, help="stop after this long")
    p.add_argument("--rates", action="store_true", help="a table of message rates instead of messages")
    p.set_defaults(run=cmd_watch)

    p = sub.add_parser("stream", help="MAV_CMD_SET_MESSAGE_INTERVAL: a message at HZ")
    p.add_argument("message", metavar="MSG", help="message name or id")
    p.add_argument("hz", metavar="HZ", help="rate in Hz, 'default' or 'off'")
    p.set_defaults(run=cmd_stream)
    return ap


def main(argv=None):
    args = parser().parse_args(argv)
    conn = None
    try:
        check(args)
        conn = open_link(args.connect, args.sysid, args.compid)
        v = Vehicle(conn, args.target_system, args.target_component)
        v.connect(args.timeout)
        return args.run(v, args)
    except Failure as e:
        print("mavctl: %s" % e, file=sys.stderr)
        return e.status
    except KeyboardInterrupt:
        print("mavctl: interrupted", file=sys.stderr)
        return EXIT_USAGE
    except BrokenPipeError:
        return EXIT_OK
    finally:
        if conn is not None:
            conn.close()


if __name__ == "__main__":
    sys.exit(main())
