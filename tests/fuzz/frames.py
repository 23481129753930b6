"""Frames for the fuzzer: every message's layout in a dialect, a plain encoder (MAVLink 1
and 2, optionally signed), structured frames whose fields hold random values biased
towards what the services look at, and the seed corpus of valid frames of every message
of the dialect.

The encoder is written out here (not the stack's own) so that a fault in the stack's
encoder cannot hide the same fault in its parser.
"""
import hashlib
import math
import struct

from mavstack.dialects.layout import message
from mavstack.kernels import crc16, crc_accumulate

# The well-behaved ground station of the exchanges (rig.py, gcs.py) and the fuzzer's
# sentinel (wire.py): fuzz frames never speak as them. One that did, numbered ahead of
# the station, would make its next frames read as late ones (parser.late_at), and a
# mission upload ignores late items, as it should a copy the link held back. (Unsigned
# MAVLink cannot tell a forger from the real station; signed, the forger's frames are
# dropped before they are counted.)
EXCHANGE_GCS = (250, 191)
SENTINEL = (250, 192)
RESERVED = (EXCHANGE_GCS, SENTINEL)


class Layout:
    """One message: name, CRC_EXTRA, payload lengths and fields by name."""

    def __init__(self, runtime, meta, msgid):
        name, extra, len1, len2, fmt, fields = message(runtime, meta, msgid)
        self.msgid = msgid
        self.name = name
        self.crc_extra = extra
        self.len1 = len1  # MAVLink 1 payload (no extensions)
        self.len2 = len2  # full MAVLink 2 payload
        self.fmt = fmt
        self.fields = {f[0]: f for f in fields}  # name -> (name, ctype, array length, offset)


_TABLES = {}


def layouts(dialect="common"):
    """{msgid: Layout} of a dialect of firmware/mavstack/dialects (made once)."""
    if dialect not in _TABLES:
        runtime = __import__("mavstack.dialects." + dialect, None, None, ("CRC_LEN",))
        meta = __import__("mavstack.dialects.%s_meta" % dialect, None, None, ("MESSAGES",))
        _TABLES[dialect] = {msgid: Layout(runtime, meta, msgid) for msgid in sorted(runtime.CRC_LEN)}
    return _TABLES[dialect]


LAYOUTS = layouts("common")
IDS = sorted(LAYOUTS)


def encode(msgid, payload, sysid=255, compid=190, seq=0, version=2, key=None, link_id=0, stamp=0,
           table=LAYOUTS):
    """One frame as bytes. MAVLink 2 payloads lose their trailing zeros (at least one byte
    stays); key (32 bytes) signs it with the given link id and 48-bit timestamp. table:
    the dialect's layouts."""
    lay = table[msgid]
    if version == 1:
        body = bytes(payload[:lay.len1]).ljust(lay.len1, b"\0")
        head = bytes((0xFE, len(body), seq & 0xFF, sysid, compid, msgid))
    else:
        body = bytes(payload[:lay.len2]).rstrip(b"\0") or b"\0"
        flags = 1 if key is not None else 0
        head = bytes((0xFD, len(body), flags, 0, seq & 0xFF, sysid, compid,
                      msgid & 0xFF, msgid >> 8 & 0xFF, msgid >> 16))
    frame = head + body
    crc = crc_accumulate(crc16(frame, 1, len(frame), 0xFFFF), lay.crc_extra)
    frame += bytes((crc & 0xFF, crc >> 8))
    if key is not None and version == 2:
        frame += bytes((link_id,)) + stamp.to_bytes(6, "little")
        frame += hashlib.sha256(bytes(key) + frame).digest()[:6]
    return frame


def put(payload, lay, name, value, index=0):
    """Write one field (or one array element) of payload by its name."""
    f = lay.fields.get(name)
    if f is None:
        return
    _, ctype, n, offset = f
    code = _CODES[ctype]
    size = struct.calcsize(code)
    if ctype == "char":
        raw = value.encode() if isinstance(value, str) else bytes(value)
        payload[offset:offset + (n or 1)] = raw[:n or 1].ljust(n or 1, b"\0")
        return
    if code in "BbHhIiQq":  # wrapped into the field's type, as a C cast would
        bits = 8 * size
        value = int(value) & ((1 << bits) - 1)
        if code.islower() and value >> (bits - 1):
            value -= 1 << bits
    struct.pack_into("<" + code, payload, offset + index * size, value)


_CODES = {"uint8_t": "B", "int8_t": "b", "uint16_t": "H", "int16_t": "h", "uint32_t": "I",
          "int32_t": "i", "uint64_t": "Q", "int64_t": "q", "float": "f", "double": "d",
          "char": "s"}

# Values a float field is drawn from besides random bits: the edges services must refuse.
SPECIAL_FLOATS = (0.0, -0.0, 1.0, -1.0, 0.5, 2.0, 6.0, 7.0, 100.0, 1e7, -1e7, 2.0 ** 31, 2.0 ** 32,
                  3.4e38, -3.4e38, 1e-45, math.nan, math.inf, -math.inf, 21196.0, 400.0, 245.0)


class Structured:
    """Frames of handled messages with random field values, valid CRC.

    `rng` is a random.Random (or anything with randrange/random/choice). Fields the
    services read are biased: target system/component (ours, broadcast, another),
    command ids from the vehicle's table, parameter names from its table, plan types,
    small sequence numbers and counts."""

    def __init__(self, handled_ids, commands, param_names, sysid=1, compid=1, table=LAYOUTS):
        self.table = table
        self.ids = sorted(i for i in handled_ids if i in table)
        self.commands = sorted(commands)
        self.names = list(param_names)
        self.sysid = sysid
        self.compid = compid

    def payload(self, rng, msgid, foreign=False):
        lay = self.table[msgid]
        p = bytearray(rng.randbytes(lay.len2)) if hasattr(rng, "randbytes") else \
            bytearray(rng.randrange(256) for _ in range(lay.len2))
        for name, (_, ctype, n, offset) in lay.fields.items():
            if ctype == "float" and rng.random() < 0.5:
                for k in range(n or 1):
                    put(p, lay, name, rng.choice(SPECIAL_FLOATS), k)
        if foreign:
            put(p, lay, "target_system", rng.choice((2, 3, 254)))
        else:
            put(p, lay, "target_system", rng.choice((self.sysid, self.sysid, 0, 2)))
        put(p, lay, "target_component", rng.choice((self.compid, self.compid, 0, 190)))
        if "command" in lay.fields and self.commands and rng.random() < 0.8:
            command = rng.choice(self.commands)
            put(p, lay, "command", command)
            if command == _CMD_REBOOT_SHUTDOWN and rng.random() < 0.9:
                put(p, lay, "param1", 0.0)  # a reboot costs the vehicle's start-up: rarer
        if "param_id" in lay.fields and self.names and rng.random() < 0.7:
            put(p, lay, "param_id", rng.choice(self.names))
        if "param_index" in lay.fields and rng.random() < 0.5:
            put(p, lay, "param_index", rng.randrange(-2, len(self.names) + 3))
        if "mission_type" in lay.fields and rng.random() < 0.8:
            put(p, lay, "mission_type", rng.choice((0, 1, 2, 3, 255)))
        for name in ("seq", "count", "start_index", "end_index"):
            if name in lay.fields and rng.random() < 0.8:
                put(p, lay, name, rng.randrange(0, 12) if rng.random() < 0.8 else rng.randrange(65536))
        if "confirmation" in lay.fields and rng.random() < 0.7:
            put(p, lay, "confirmation", rng.randrange(3))
        return p

    def frame(self, rng, seq, foreign=False, key=None, stamp=0):
        msgid = rng.choice(self.ids)
        if msgid == _MSG_SETUP_SIGNING and rng.random() < 0.8:
            msgid = rng.choice(self.ids)  # rarer: each new key makes the frames after it wrongly signed
        version = 1 if msgid < 256 and rng.random() < 0.2 and key is None else 2
        sysid = rng.choice((255, 255, 254, 1, 2, rng.randrange(256)))
        compid = rng.choice((190, 0, 1, rng.randrange(256)))
        if (sysid, compid) in RESERVED:
            compid = 190
        return encode(msgid, self.payload(rng, msgid, foreign), sysid, compid, seq, version, key,
                      rng.randrange(3) if key is not None else 0, stamp, self.table)


_CMD_REBOOT_SHUTDOWN = 246
_MSG_SETUP_SIGNING = 256


def corpus(rng, sysid=1, compid=1, table=LAYOUTS):
    """Valid frames of every message of the dialect (MAVLink 2; MAVLink 1 too where the id
    fits): the seed inputs, one frame each."""
    out = []
    for msgid in sorted(table):
        lay = table[msgid]
        p = bytearray(rng.randbytes(lay.len2))
        put(p, lay, "target_system", sysid)
        put(p, lay, "target_component", compid)
        out.append(encode(msgid, p, 255, 190, len(out), table=table))
        if msgid < 256:
            out.append(encode(msgid, p, 255, 190, len(out), version=1, table=table))
    return out


def count_valid(data, table=LAYOUTS):
    """How many frames of the dialect a parser finds in data (CRC-valid, whole)."""
    n = 0
    o = 0
    end = len(data)
    while o < end:
        b = data[o]
        if b == 0xFD and o + 12 <= end:
            size = 12 + data[o + 1] + (13 if data[o + 2] & 1 else 0)
            msgid = data[o + 7] | data[o + 8] << 8 | data[o + 9] << 16
            body = 10 + data[o + 1]
        elif b == 0xFE and o + 8 <= end:
            size = 8 + data[o + 1]
            msgid = data[o + 5]
            body = 6 + data[o + 1]
        else:
            o += 1
            continue
        lay = table.get(msgid)
        if lay is not None and o + size <= end:
            crc = crc_accumulate(crc16(data, o + 1, o + body, 0xFFFF), lay.crc_extra)
            if data[o + body] == crc & 0xFF and data[o + body + 1] == crc >> 8:
                n += 1
                o += size
                continue
        o += 1
    return n
