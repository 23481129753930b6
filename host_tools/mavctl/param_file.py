"""Parameter files in the two formats ground stations write:

- QGroundControl `.params`: `#` comment lines, then one tab-separated line a parameter:
  vehicle id, component id, name, value, MAV_PARAM_TYPE;
- MAVProxy / Mission Planner `.parm` (any other name): `NAME VALUE` a line (a comma also
  separates), `#` starts a comment; pymavlink's mavparm reads and writes it.

read_params(path) -> [(name, value text, MAV_PARAM_TYPE or None, line number)], checked
line by line (a malformed line is one usage error naming the file and line);
write_params(path, params, sysid, compid) writes param_protocol.Param values.
"""
import math

from mavctl.errors import usage

NAME_LEN = 16
QGC_HEADER = "# Vehicle-Id Component-Id Name Value Type"
PARAM_TYPES = range(1, 11)  # MAV_PARAM_TYPE_UINT8 .. REAL64


def is_qgc(path):
    return str(path).lower().endswith(".params")


def check_value(text, fail):
    """The value's text if it is a number (decimal, float, 0x hex), else fail()."""
    try:
        if text.lower().startswith(("0x", "-0x")):
            int(text, 16)
        elif not math.isfinite(float(text)) and text.lower() not in ("nan", "inf", "-inf"):
            raise ValueError
    except ValueError:
        raise fail("%r is not a number" % text)
    return text


def read_params(path):
    try:
        with open(path, encoding="utf-8") as f:
            lines = f.read().splitlines()
    except OSError as e:
        raise usage("%s: %s" % (path, e.strerror))
    except UnicodeDecodeError:
        raise usage("%s: not a text file" % path)
    qgc = is_qgc(path)
    out = []
    seen = {}
    for number, line in enumerate(lines, 1):
        def fail(what):
            return usage("%s:%d: %s" % (path, number, what))
        if qgc:
            if line.startswith("#") or not line.strip():
                continue
            words = line.split("\t") if "\t" in line else line.split()
            if len(words) != 5:
                raise fail("5 tab-separated columns expected (vehicle, component, name, value, "
                           "type), found %d" % len(words))
            name, value, ptype = words[2].strip(), words[3].strip(), words[4].strip()
            try:
                ptype = int(ptype)
                int(words[0]), int(words[1])
            except ValueError:
                raise fail("vehicle id, component id and type must be integers")
            if ptype not in PARAM_TYPES:
                raise fail("%s: unknown MAV_PARAM_TYPE %d" % (name, ptype))
        else:
            text = line.split("#", 1)[0].replace(",", " ").strip()
            if not text:
                continue
            words = text.split()
            if len(words) != 2:
                raise fail("NAME VALUE expected, found %d words" % len(words))
            (name, value), ptype = words, None
        if not name or len(name.encode()) > NAME_LEN:
            raise fail("%r: a parameter name has 1 to %d characters" % (name, NAME_LEN))
        if name in seen:
            raise fail("%s: already set on line %d" % (name, seen[name]))
        seen[name] = number
        out.append((name, check_value(value, fail), ptype, number))
    return out


def write_params(path, params, sysid=1, compid=1):
    """Write Params (name, type, text()) to path in the format its name says."""
    with open(path, "w", encoding="utf-8") as f:
        if is_qgc(path):
            f.write("# Onboard parameters for Vehicle %d\n#\n%s\n" % (sysid, QGC_HEADER))
            for p in params:
                f.write("%d\t%d\t%s\t%s\t%d\n" % (sysid, compid, p.name, p.text(), p.type))
        else:
            for p in params:
                f.write("%-16s %s\n" % (p.name, p.text()))
