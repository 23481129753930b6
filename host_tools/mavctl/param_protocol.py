"""The parameter protocol as mavctl speaks it: reading, listing and setting a vehicle's
parameters (PARAM_REQUEST_READ/LIST, PARAM_SET, PARAM_VALUE), with integers carried
bytewise or cast to float as the vehicle's AUTOPILOT_VERSION capabilities say."""
import math
import struct
import sys
import time

from mavctl.errors import Failure, usage
from mavctl.mission_file import f32_text
from mavctl.names import enum_name, mavlink

# MAV_PARAM_TYPE ids that hold integers -> struct code for their bytes on the wire.
PARAM_INT_CODES = {1: "B", 2: "b", 3: "H", 4: "h", 5: "I", 6: "i"}
PARAM_REAL32 = 9


def payload(msg):
    """The message's payload bytes as received, zero-extended to its full length."""
    buf = msg.get_msgbuf()
    header = 10 if buf[0] == 0xFD else 6
    data = bytes(buf[header:header + buf[1]])
    return data + bytes(max(0, msg.unpacker.size - len(data)))


class ParamProtocol:
    """vehicle.Vehicle's parameter methods (it brings recv, mav, conn and the target ids)."""

    _param_encoding = None  # 'bytewise' or 'cast', once asked

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
