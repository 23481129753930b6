"""Frame i of the wire tests' encoded traffic (wire_heaplock.py on the unix port,
wire_uart.py on the emulated boards): six kinds in turn, HEARTBEAT, ATTITUDE,
GPS_RAW_INT, PARAM_VALUE, COMMAND_LONG and MISSION_ITEM_INT, with i in their fields,
sent as system 1, component 1 + (i & 1). The host checks them with pymavlink.

Each kind's payload is packed once with its constant fields (a template); frame i
copies it into place and packs only what varies, a few values per call: a
struct.pack_into of a whole message would make a frame state MicroPython takes from
the heap on every call (past about 11 words of locals and value stack), and the
tests require the encoding to ask the heap for nothing.
"""
import struct
from struct import pack_into

from mavstack.dialects import common

FMT = common.FMT
NAME = b"SYSID_THISMAV"
FLOATS = (0.0, 1.5, -2.25, float("nan"), float("inf"), 3.0e38, -0.0)
IDS = (0, 30, 24, 22, 76, 73)


def _template(msgid, fields):
    buf = bytearray(common.CRC_LEN[msgid] >> 16)
    struct.pack_into(FMT[msgid], buf, 0, *fields)
    return buf


# The whole payloads, in FMT (wire) order, with 0 where frame i packs its own values.
TEMPLATES = (
    _template(0, (0, 2, 3, 81, 4, 3)),
    _template(30, (0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)),
    _template(24, (0, 0, 0, 0, 0, 0, 0, 0, 3, 9, 0, 0, 0, 0, 0, 0)),
    _template(22, (0.0, 300, 0, NAME, 9)),
    _template(76, (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 400, 1, 1, 0)),
    _template(73, (0.0, 0.0, 0.0, 0.0, 0, 0, 0.0, 0, 16, 1, 1, 3, 0, 1, 0)),
)


def _heartbeat(b, off, i, x):
    pack_into("<I", b, off, i)  # custom_mode


def _attitude(b, off, i, x):
    pack_into("<I", b, off, i)  # time_boot_ms
    pack_into("<fff", b, off + 4, x, x, x)  # roll, pitch, yaw


def _gps_raw_int(b, off, i, x):
    pack_into("<Q", b, off, i * 1000)  # time_usec
    pack_into("<ii", b, off + 8, -i, i)  # lat, lon


def _param_value(b, off, i, x):
    pack_into("<f", b, off, x)  # param_value
    pack_into("<H", b, off + 6, i & 0xFFFF)  # param_index


def _command_long(b, off, i, x):
    pack_into("<f", b, off, x)  # param1
    pack_into("<H", b, off + 28, 400 + (i & 7))  # command


def _mission_item_int(b, off, i, x):
    pack_into("<f", b, off + 4, x)  # param2
    pack_into("<ii", b, off + 16, i, -i)  # x, y
    pack_into("<f", b, off + 24, x)  # z
    pack_into("<H", b, off + 28, i & 0xFFFF)  # seq


FILL = (_heartbeat, _attitude, _gps_raw_int, _param_value, _command_long, _mission_item_int)


def pack_frame(enc, i):
    """Encode frame i with enc -> its length (the frame is enc.buf[0:n])."""
    k = i % 6
    off = enc.load(TEMPLATES[k], len(TEMPLATES[k]))
    FILL[k](enc.buf, off, i, FLOATS[i % 7])
    return enc.finish(IDS[k], 1, 1 + (i & 1))
