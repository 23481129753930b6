"""Picks the byte kernels once, at import: viper where the port has it, else portable.

MAVSTACK_PORTABLE=1 in the environment forces the portable ones (tests use it to
run the whole stack both ways). Reference (the kernels' contract): docs/core.md.
"""
from ..compat import MICROPYTHON, getenv

IMPL = "portable"
if MICROPYTHON and not getenv("MAVSTACK_PORTABLE"):
    try:
        from .bytes_viper import crc16, seal_v2, find_stx, copy, place, id_info, zero, scan, SLOTS, FIELDS, BUF_LEN

        IMPL = "viper"
    except Exception:  # a port built without the native emitter
        pass
if IMPL == "portable":
    from .bytes_portable import crc16, seal_v2, find_stx, copy, place, id_info, zero, scan, SLOTS, FIELDS, BUF_LEN


def crc_accumulate(crc, byte):
    t = (byte ^ crc) & 0xFF
    t = (t ^ (t << 4)) & 0xFF
    return ((crc >> 8) ^ (t << 8) ^ (t << 3) ^ (t >> 4)) & 0xFFFF
