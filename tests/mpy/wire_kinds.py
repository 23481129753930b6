"""Frame i of the wire tests' encoded traffic (wire_heaplock.py on the unix port,
wire_uart.py on the emulated boards): six kinds in turn, HEARTBEAT, ATTITUDE,
GPS_RAW_INT, PARAM_VALUE, COMMAND_LONG and MISSION_ITEM_INT, with i in their fields,
sent as system 1, component 1 + (i & 1). The host checks them with pymavlink."""
import struct

from mavstack.dialects import common

FMT = common.FMT
NAME = b"SYSID_THISMAV"
FLOATS = (0.0, 1.5, -2.25, float("nan"), float("inf"), 3.0e38, -0.0)


def pack_frame(enc, i):
    """Encode frame i with enc -> its length (the frame is enc.buf[0:n])."""
    off = enc.begin()
    buf = enc.buf
    k = i % 6
    x = FLOATS[i % 7]
    if k == 0:
        struct.pack_into(FMT[0], buf, off, i, 2, 3, 81, 4, 3)
        msgid = 0
    elif k == 1:
        struct.pack_into(FMT[30], buf, off, i, x, x, x, 0.0, 0.0, 0.0)
        msgid = 30
    elif k == 2:
        struct.pack_into(FMT[24], buf, off, i * 1000, -i, i, 0, 0, 0, 0, 0, 3, 9, 0, 0, 0, 0, 0, 0)
        msgid = 24
    elif k == 3:
        struct.pack_into(FMT[22], buf, off, x, 300, i & 0xFFFF, NAME, 9)
        msgid = 22
    elif k == 4:
        struct.pack_into(FMT[76], buf, off, x, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 400 + (i & 7), 1, 1, 0)
        msgid = 76
    else:
        struct.pack_into(FMT[73], buf, off, 0.0, x, 0.0, 0.0, i, -i, x, i & 0xFFFF, 16, 1, 1, 3, 0, 1, 0)
        msgid = 73
    return enc.finish(msgid, 1, 1 + (i & 1))
