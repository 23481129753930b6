"""Generate compact MicroPython dialect modules from MAVLink XML definitions.

    python host_tools/mavgen.py XML OUT.py [--name NAME] [--messages ID_OR_NAME,...]
    python host_tools/mavgen.py --all [--check]

Each dialect becomes two modules. OUT.py holds only what the board needs per
frame: CRC_LEN (crc_extra and payload lengths) and FMT (the payload's struct
format) by message id, so importing it costs little RAM. OUT_meta.py holds the
names: MSG_* ids and enum values as const(), and each message's name and field
names (MESSAGES), for host tools, tests and applications; mavstack.dialects.layout
turns FMT + field names back into (name, type, array length, offset).
Descriptions stay in the XML. Runs on CPython 3.11 with the standard library only.
"""
import argparse
import ast
import operator
import os
import sys
import xml.etree.ElementTree as ET

from mavgen_tables import info_block, target_lines

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DIALECTS = os.path.join(ROOT, "firmware", "mavstack", "dialects")

MAX_ID = 0xFFFFFF  # MAVLink 2 message ids are 24 bits
MAX_PAYLOAD = 255
MAX_FIELDS = 64

SIZES = {
    "uint64_t": 8, "int64_t": 8, "double": 8,
    "uint32_t": 4, "int32_t": 4, "float": 4,
    "uint16_t": 2, "int16_t": 2,
    "uint8_t": 1, "int8_t": 1, "char": 1,
}
# Only codes MicroPython's struct knows: no 'c' and no '?'.
CODES = {
    "uint64_t": "Q", "int64_t": "q", "double": "d",
    "uint32_t": "I", "int32_t": "i", "float": "f",
    "uint16_t": "H", "int16_t": "h",
    "uint8_t": "B", "int8_t": "b",
}


class MavgenError(Exception):
    pass


class Field:
    __slots__ = ("name", "type", "array_length", "extension")

    def __init__(self, name, type, array_length=0, extension=False):
        self.name = name
        self.type = type
        self.array_length = array_length
        self.extension = extension

    @property
    def size(self):
        return SIZES[self.type] * (self.array_length or 1)

    @property
    def fmt(self):
        if self.type == "char":
            return "%ds" % (self.array_length or 1)
        if self.array_length:
            return "%d%s" % (self.array_length, CODES[self.type])
        return CODES[self.type]


class Message:
    def __init__(self, name, id, fields, source=""):
        self.name = name
        self.id = id
        self.fields = fields  # XML order
        self.source = source

    def wire_fields(self):
        # Base fields sort largest element first (stable), extensions keep XML order.
        base = [f for f in self.fields if not f.extension]
        ext = [f for f in self.fields if f.extension]
        return sorted(base, key=lambda f: SIZES[f.type], reverse=True) + ext

    @property
    def len1(self):
        return sum(f.size for f in self.fields if not f.extension)

    @property
    def len2(self):
        return sum(f.size for f in self.fields)

    @property
    def fmt(self):
        return "<" + "".join(f.fmt for f in self.wire_fields())

    @property
    def crc_extra(self):
        data = bytearray((self.name + " ").encode())
        for f in self.wire_fields():
            if f.extension:
                break
            data += (f.type + " " + f.name + " ").encode()
            if f.array_length:
                data.append(f.array_length)
        crc = x25crc(data)
        return (crc & 0xFF) ^ (crc >> 8)


def x25crc(data, crc=0xFFFF):
    """CRC-16/MCRF4XX, the checksum MAVLink uses for frames and CRC_EXTRA."""
    for b in data:
        t = (b ^ crc) & 0xFF
        t = (t ^ (t << 4)) & 0xFF
        crc = ((crc >> 8) ^ (t << 8) ^ (t << 3) ^ (t >> 4)) & 0xFFFF
    return crc


def parse_type(text, where):
    """'uint16_t[8]' -> ('uint16_t', 8); spellings pymavlink also accepts."""
    n = 0
    if text.endswith("]") and "[" in text:
        text, _, count = text[:-1].partition("[")
        n = int(count)
        if n < 1:
            raise MavgenError("%s: bad array length %r" % (where, count))
        if n == 1 and text == "char":
            # FMT spells a scalar char '1s' (MicroPython's struct has no 'c'), so
            # char[1] would read back as a scalar: refuse rather than mislabel it.
            raise MavgenError("%s: char[1] is not supported, use char" % where)
    if text == "uint8_t_mavlink_version":
        text = "uint8_t"  # filled in by the sender, but an ordinary uint8_t on the wire
    elif text == "array":
        text = "int8_t"
    elif text + "_t" in SIZES:
        text += "_t"
    if text not in SIZES:
        raise MavgenError("%s: unknown type %r" % (where, text))
    return text, n


_OPS = {
    ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul,
    ast.Pow: operator.pow, ast.LShift: operator.lshift, ast.RShift: operator.rshift,
    ast.BitOr: operator.or_, ast.BitAnd: operator.and_, ast.USub: operator.neg,
}


def parse_value(text, where):
    """An enum value: decimal, 0x.., 0b.. or a small integer expression like 2**3."""
    def ev(node):
        if isinstance(node, ast.Constant) and type(node.value) is int:
            return node.value
        if isinstance(node, ast.BinOp) and type(node.op) in _OPS:
            return _OPS[type(node.op)](ev(node.left), ev(node.right))
        if isinstance(node, ast.UnaryOp) and type(node.op) in _OPS:
            return _OPS[type(node.op)](ev(node.operand))
        raise ValueError

    try:
        return ev(ast.parse(text.strip(), mode="eval").body)
    except (SyntaxError, ValueError):
        raise MavgenError("%s: bad enum value %r" % (where, text)) from None


def load(xml_path):
    """Read a dialect and everything it includes -> (messages, enums).

    messages is a list of Message in definition order (included files first);
    enums maps enum name -> [(entry name, value), ...], entries of an enum split
    across files merged into one list.
    """
    messages, enums = [], {}
    _load(os.path.abspath(xml_path), messages, enums, set())
    by_id, by_name = {}, {}
    for m in messages:
        if not 0 <= m.id <= MAX_ID:
            raise MavgenError("%s: message %s id %d out of range" % (m.source, m.name, m.id))
        if m.id in by_id:
            raise MavgenError("%s: message id %d used by %s and %s"
                              % (m.source, m.id, by_id[m.id].name, m.name))
        if m.name in by_name:
            raise MavgenError("%s: message %s defined twice" % (m.source, m.name))
        by_id[m.id] = by_name[m.name] = m
    return messages, enums


def _load(path, messages, enums, seen):
    real = os.path.realpath(path)
    if real in seen:
        return
    seen.add(real)
    root = ET.parse(path).getroot()
    label = os.path.basename(path)
    # Includes first, so a file's definitions follow the ones it builds on.
    for inc in root.iterfind("include"):
        _load(os.path.join(os.path.dirname(path), inc.text.strip()), messages, enums, seen)
    for e in root.iterfind("enums/enum"):
        entries = enums.setdefault(e.get("name"), [])
        for entry in e.iterfind("entry"):
            where = "%s: %s" % (label, entry.get("name"))
            if entry.get("value") is None:
                # As pymavlink: one above the highest value so far, and at least 1.
                value = max([0] + [v for _, v in entries]) + 1
            else:
                value = parse_value(entry.get("value"), where)
            entries.append((entry.get("name"), value))
    for m in root.iterfind("messages/message"):
        name = m.get("name")
        where = "%s: %s" % (label, name)
        fields, ext = [], False
        for child in m:
            if child.tag == "extensions":
                ext = True
            elif child.tag == "field":
                t, n = parse_type(child.get("type"), where)
                fields.append(Field(child.get("name"), t, n, ext))
        names = [f.name for f in fields]
        if len(set(names)) != len(names):
            raise MavgenError("%s: duplicate field name" % where)
        if len(fields) > MAX_FIELDS:
            raise MavgenError("%s: more than %d fields" % (where, MAX_FIELDS))
        try:
            mid = int(m.get("id"))
        except (TypeError, ValueError):
            raise MavgenError("%s: bad message id %r" % (where, m.get("id"))) from None
        msg = Message(name, mid, fields, label)
        if msg.len2 > MAX_PAYLOAD:
            raise MavgenError("%s: payload of %d bytes" % (where, msg.len2))
        messages.append(msg)


def select(messages, wanted):
    """Keep only the messages named (or numbered) in wanted."""
    by_key = {}
    for m in messages:
        by_key[m.name] = by_key[str(m.id)] = m
    keep = set()
    for w in wanted:
        m = by_key.get(w.strip().upper())
        if m is None:
            raise MavgenError("no message %r in this dialect" % w)
        keep.add(m.id)
    return [m for m in messages if m.id in keep]


# FMT as an IdTable (constant tuples: flash when frozen) from this many messages; a
# dialect of fewer (--messages) keeps a dict, which costs less than IdTable's code.
ID_TABLE_MIN = 64


def render_runtime(messages, name, source_label):
    """The runtime module: only the per-id tables the stack reads on the board."""
    msgs = sorted(messages, key=lambda m: m.id)
    block = info_block({m.id: m.crc_extra | m.len1 << 8 | m.len2 << 16 for m in msgs})
    out = [
        '"""MAVLink dialect %s (runtime tables), generated by host_tools/mavgen.py from %s.'
        ' Do not edit."""' % (name, source_label),
        "from mavstack.dialects.table import InfoTable\n",
        "# id -> crc_extra | len1 << 8 | len2 << 16, one block read in place (flash, when frozen)",
        "CRC_LEN = InfoTable(",
    ]
    out += ['    b"%s"' % "".join("\\x%02x" % c for c in block[k : k + 24]) for k in range(0, len(block), 24)]
    out.append(")")
    out.append("# id -> struct format of the full MAVLink 2 payload (wire order, extensions last)")
    if len(msgs) < ID_TABLE_MIN:
        out += ["FMT = {"] + ["    %d: %r," % (m.id, m.fmt) for m in msgs] + ["}"]
    else:
        # Looked up at start-up only: two constant tuples (flash, when frozen), not a dict.
        out[1] = "from mavstack.dialects.table import IdTable, InfoTable\n"
        out.append("FMT = IdTable((")
        out += ["    %s," % ", ".join(str(m.id) for m in msgs[k : k + 12]) for k in range(0, len(msgs), 12)]
        out += ["), ("] + ["    %r," % m.fmt for m in msgs] + ["))"]
    out += target_lines(msgs)
    return "\n".join(out) + "\n"


def render_meta(messages, enums, name, source_label):
    """The metadata module: message ids, enum values and field names, for hosts and applications."""
    msgs = sorted(messages, key=lambda m: m.id)
    out = [
        '"""MAVLink dialect %s (names and enums), generated by host_tools/mavgen.py from %s.'
        ' Do not edit."""' % (name, source_label),
        "try:",
        "    from micropython import const",
        "except ImportError:",
        "    def const(x):",
        "        return x",
        "",
        "# Messages: id",
    ]
    taken = {"const": None, "MESSAGES": None}
    for m in msgs:
        out.append("MSG_%s = const(%d)" % (m.name, m.id))
        taken["MSG_" + m.name] = m.id
    out.append("")
    out.append("# Enums")
    for enum, entries in enums.items():
        for entry, value in entries:
            if entry in taken:
                if taken[entry] != value:
                    print("mavgen: %s.%s = %d skipped: %s is already %r"
                          % (enum, entry, value, entry, taken[entry]), file=sys.stderr)
                continue
            taken[entry] = value
            out.append("%s = const(%d)" % (entry, value))
    out.append("")
    out.append("# id -> (name, field names in wire order, space separated)")
    out.append("MESSAGES = {")
    for m in msgs:
        names = " ".join(f.name for f in m.wire_fields())
        out.append("    %d: (%r, %r)," % (m.id, m.name, names))
    out.append("}")
    return "\n".join(out) + "\n"


def render(messages, enums, name, source_label):
    """(runtime module text, meta module text). Deterministic: same input, same bytes."""
    return (render_runtime(messages, name, source_label),
            render_meta(messages, enums, name, source_label))


def generate(xml_path, name=None, wanted=None):
    messages, enums = load(xml_path)
    if wanted:
        messages = select(messages, wanted)
    label = os.path.basename(xml_path)
    if name is None:
        name = os.path.splitext(label)[0]
    return render(messages, enums, name, label)


def meta_path(out):
    """Where the metadata module of runtime module `out` goes: X.py -> X_meta.py."""
    base = out[:-3] if out.endswith(".py") else out
    return base + "_meta.py"


def committed():
    """The dialects kept in the repository: [(name, xml path, module path)]."""
    import pymavlink  # only to find the XML it ships

    pym = os.path.join(os.path.dirname(pymavlink.__file__), "dialects", "v20")
    seed = os.path.join(ROOT, "..", "shared", "spec", "common-2012.xml")
    return [
        ("common", os.path.join(pym, "common.xml"), os.path.join(DIALECTS, "common.py")),
        ("seed2012", seed, os.path.join(DIALECTS, "seed2012.py")),
        # common and the messages on their way into it (standard modes: AVAILABLE_MODES,
        # CURRENT_MODE), for ground stations built with them (--set dialect=development)
        ("development", os.path.join(pym, "development.xml"), os.path.join(DIALECTS, "development.py")),
    ]


def main(argv=None):
    ap = argparse.ArgumentParser(description="Generate MicroPython MAVLink dialect modules.")
    ap.add_argument("xml", nargs="?", help="MAVLink XML definition")
    ap.add_argument("out", nargs="?", help="runtime module to write (OUT_meta.py goes beside it)")
    ap.add_argument("--name", help="dialect name (default: XML file name)")
    ap.add_argument("--messages", help="comma-separated message names or ids to keep")
    ap.add_argument("--all", action="store_true", help="regenerate the committed dialects")
    ap.add_argument("--check", action="store_true",
                    help="write nothing; exit 1 if a module differs from what would be generated")
    args = ap.parse_args(argv)
    if args.all:
        if args.xml or args.name or args.messages:
            ap.error("--all takes no XML, OUT, --name or --messages")
    elif not args.out:
        ap.error("give XML and OUT, or --all")

    if args.all:
        jobs = committed()
    else:
        jobs = [(args.name, args.xml, args.out)]
    wanted = args.messages.split(",") if args.messages else None
    stale = []
    try:
        for name, xml_path, out in jobs:
            texts = generate(xml_path, name, wanted)
            for path, text in zip((out, meta_path(out)), texts):
                if args.check:
                    try:
                        with open(path, encoding="utf-8") as f:
                            same = f.read() == text
                    except OSError:
                        same = False
                    if not same:
                        stale.append(os.path.relpath(path))
                else:
                    with open(path, "w", encoding="utf-8", newline="\n") as f:
                        f.write(text)
    except (MavgenError, OSError, ET.ParseError) as e:
        print("mavgen: %s" % e, file=sys.stderr)
        return 2
    for path in stale:
        print("stale: %s (run `make dialects`)" % path, file=sys.stderr)
    return 1 if stale else 0


if __name__ == "__main__":
    sys.exit(main())
