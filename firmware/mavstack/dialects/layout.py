"""A message's fields (name, C type, array length, offset) from a dialect's FMT and field names.

The runtime dialect module keeps only struct formats, the meta module only field
names; this joins the two when a host tool or an application wants the full
layout. Not generated: the same code serves every dialect.
"""

# struct code -> (C type, size in bytes). A char array is 'Ns'; a scalar char is
# '1s' (MicroPython's struct has no 'c'; mavgen refuses char[1], so '1s' is unambiguous).
_TYPES = {
    "B": ("uint8_t", 1), "b": ("int8_t", 1),
    "H": ("uint16_t", 2), "h": ("int16_t", 2),
    "I": ("uint32_t", 4), "i": ("int32_t", 4),
    "Q": ("uint64_t", 8), "q": ("int64_t", 8),
    "f": ("float", 4), "d": ("double", 8),
    "s": ("char", 1),
}


def fields(fmt, names):
    """[(name, type, array_length, offset), ...] in wire order; array_length 0 is a scalar.

    fmt is a FMT entry such as '<Q3hB', names the space separated field names
    from MESSAGES. Raises ValueError if the two do not describe the same fields.
    """
    if fmt[:1] != "<":
        raise ValueError("bad format %r" % fmt)
    names = names.split()
    out = []
    offset = 0
    count = -1  # -1: no repeat count before this code
    for i in range(1, len(fmt)):
        c = fmt[i]
        if "0" <= c <= "9":
            count = (0 if count < 0 else count * 10) + ord(c) - 48
        elif c in _TYPES:
            if len(out) == len(names):
                raise ValueError("more fields in format than names")
            ctype, size = _TYPES[c]
            n = 0 if count < 0 or (c == "s" and count == 1) else count
            out.append((names[len(out)], ctype, n, offset))
            offset += size * (n or 1)
            count = -1
        else:
            raise ValueError("bad format %r" % fmt)
    if len(out) != len(names) or count >= 0:
        raise ValueError("format and names disagree")
    return out


def message(runtime, meta, msgid):
    """(name, crc_extra, len1, len2, fmt, fields) of one message of a dialect.

    runtime is the dialect module (CRC_LEN, FMT), meta its _meta module (MESSAGES).
    """
    crc_len = runtime.CRC_LEN[msgid]
    fmt = runtime.FMT[msgid]
    name, names = meta.MESSAGES[msgid]
    return name, crc_len & 0xFF, crc_len >> 8 & 0xFF, crc_len >> 16, fmt, fields(fmt, names)
