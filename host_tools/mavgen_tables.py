"""Per-id tables for mavgen's runtime modules, as bytes constants (flash, when frozen):
the block behind CRC_LEN (info_block), and for routing, where each message's
target_system and target_component sit in its payload (TARGETS, TARGETS_HIGH)."""


def info_block(infos):
    """{id: crc_extra | len1 << 8 | len2 << 16} -> the block an InfoTable reads
    (mavstack/dialects/table.py): 3 bytes (crc_extra, len1, len2) for each id below 256,
    zeros where there is no such message; the number of ids from 256 up (2 bytes); then
    6 bytes for each of those, ascending: the id (3 bytes, little end first), its 3 bytes."""
    block = bytearray(770)
    high = sorted(i for i in infos if i > 255)
    block[768:770] = len(high).to_bytes(2, "little")
    for msgid, info in infos.items():
        if not 0 <= msgid < 1 << 24 or not info >> 16:
            raise ValueError("message %d: no length, or an id past 24 bits" % msgid)
        if msgid < 256:
            block[3 * msgid : 3 * msgid + 3] = info.to_bytes(3, "little")
    for msgid in high:
        block += msgid.to_bytes(3, "little") + infos[msgid].to_bytes(3, "little")
    return bytes(block)


def _offsets(m):
    """(target_system offset + 1, target_component offset + 1) in m's payload, 0 for none
    (as MAVLink's C library's message entries: MANUAL_CONTROL's `target` is a system)."""
    ts = tc = off = 0
    for f in m.wire_fields():
        if f.name == "target_system" or (m.name == "MANUAL_CONTROL" and f.name == "target"):
            ts = off + 1
        elif f.name == "target_component":
            tc = off + 1
        off += f.size
    return ts, tc


def targets(msgs):
    """(TARGETS, TARGETS_HIGH) as bytes: see render_runtime."""
    low = bytearray(512)
    high = bytearray()
    for m in msgs:
        ts, tc = _offsets(m)
        if not ts and not tc:
            continue
        if m.id < 256:
            low[2 * m.id] = ts
            low[2 * m.id + 1] = tc
        else:
            high += bytes((m.id & 0xFF, (m.id >> 8) & 0xFF, m.id >> 16, ts, tc))
    return bytes(low), bytes(high)


def bytes_literal(data):
    """A bytes literal in lines of 32 bytes (one constant: it stays in flash when frozen)."""
    if not data:
        return 'b""'
    rows = []
    for i in range(0, len(data), 32):
        rows.append('    b"%s"' % "".join("\\x%02x" % b for b in data[i:i + 32]))
    return "(\n" + "\n".join(rows) + "\n)"


def target_lines(msgs):
    """The runtime module's lines for TARGETS and TARGETS_HIGH."""
    low, high = targets(msgs)
    return [
        "# Routing (mavstack/router.py): where target_system and target_component sit in a",
        "# payload, each as offset + 1 (0: the message has no such field). TARGETS: two bytes",
        "# per id < 256; TARGETS_HIGH: five per id >= 256 (id, 3 bytes little-endian, then the two).",
        "TARGETS = %s" % bytes_literal(low),
        "TARGETS_HIGH = %s" % bytes_literal(high),
    ]
