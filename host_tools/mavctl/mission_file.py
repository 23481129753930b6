"""Mission files: QGroundControl's "QGC WPL 110" text format, and the mission item
they hold (as it travels in MISSION_ITEM_INT / MISSION_ITEM)."""
import math
import struct

from mavctl.errors import usage

# COMMAND_INT / MISSION_ITEM_INT x, y: local frames carry metres * 1e4, others degrees * 1e7.
LOCAL_FRAMES = (1, 4, 7, 8, 9, 12, 20, 21)


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


class Item:
    """One mission item as in a QGC WPL file: x, y in degrees (or metres in local frames)."""

    def __init__(self, seq, current, frame, command, p1, p2, p3, p4, x, y, z, autocontinue):
        self.seq, self.current, self.frame, self.command = seq, current, frame, command
        self.params = [p1, p2, p3, p4]
        self.x, self.y, self.z = x, y, z
        self.autocontinue = autocontinue

    def scale(self):
        return 1e4 if self.frame in LOCAL_FRAMES else 1e7

    def check_xy(self, failure):
        """Raise failure(why) unless x and y fit MISSION_ITEM_INT's int32 (degrees * 1e7,
        metres * 1e4)."""
        for v in (self.x, self.y):
            v = float(v)
            if not math.isfinite(v) or abs(round(v * self.scale())) >= 1 << 31:
                raise failure("x and y must be numbers within the int32 range")

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
        item.check_xy(lambda what: usage("%s:%d: %s" % (path, number, what)))
        items.append(item)
    return items


def write_wpl(items, out):
    out.write(WPL_HEADER + "\n")
    for item in items:
        out.write(item.wpl_line() + "\n")
