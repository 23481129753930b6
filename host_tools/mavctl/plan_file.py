"""QGroundControl plan files (.plan, JSON): the mission, the geofence (inclusion and
exclusion polygons and circles) and the rally points in one file, read and written as
Plans whose three parts (mission, fence, rally: MAVLink mission types 0, 1, 2) are lists
of mission_file.Items ready to upload; read_any() takes a .plan or a QGC WPL file. Only
"SimpleItem"s are read: a file holding one of QGroundControl's complex items (a survey,
a corridor scan) is refused with its index. Reference: docs/mavctl.md.
"""
import json
import math

from mavctl.errors import usage
from mavctl.mission_file import Item, read_wpl

MAV_FRAME_GLOBAL = 0
MAV_FRAME_GLOBAL_RELATIVE_ALT = 3
FENCE_RETURN = 5000
POLYGON_INCLUSION, POLYGON_EXCLUSION = 5001, 5002
CIRCLE_INCLUSION, CIRCLE_EXCLUSION = 5003, 5004
RALLY_POINT = 5100
MAV_AUTOPILOT_GENERIC = 0
MAV_TYPE_QUADROTOR = 2


class Plan:
    """A mission, a fence and rally points, as items; home as (lat, lon, alt)."""

    def __init__(self, mission=(), fence=(), rally=(), home=None, firmware=MAV_AUTOPILOT_GENERIC,
                 vehicle=MAV_TYPE_QUADROTOR):
        self.mission = list(mission)
        self.fence = list(fence)
        self.rally = list(rally)
        self.home = home
        self.firmware = firmware
        self.vehicle = vehicle

    def parts(self):
        """(mission type name, items) for the three parts."""
        return (("mission", self.mission), ("fence", self.fence), ("rally", self.rally))

    def polygons(self):
        """[(inclusion, [(lat, lon), ...])] from the fence items, in order."""
        out = []
        items = self.fence
        i = 0
        while i < len(items):
            item = items[i]
            if item.command not in (POLYGON_INCLUSION, POLYGON_EXCLUSION):
                i += 1
                continue
            count = max(1, int(item.params[0]))
            vertices = []
            while i < len(items) and items[i].command == item.command and len(vertices) < count:
                vertices.append((float(items[i].x), float(items[i].y)))
                i += 1
            out.append((item.command == POLYGON_INCLUSION, vertices))
        return out

    def circles(self):
        """[(inclusion, (lat, lon), radius in m)] from the fence items."""
        return [(item.command == CIRCLE_INCLUSION, (float(item.x), float(item.y)), item.params[0])
                for item in self.fence if item.command in (CIRCLE_INCLUSION, CIRCLE_EXCLUSION)]

    def return_point(self):
        for item in self.fence:
            if item.command == FENCE_RETURN:
                return float(item.x), float(item.y)
        return None


def item(seq, frame, command, p1=0.0, x=0.0, y=0.0, z=0.0):
    """A fence or rally item; autocontinue 0, as QGroundControl sends them (not a path)."""
    return Item(seq, 0, frame, command, p1, 0.0, 0.0, 0.0, x, y, z, 0)


# --- reading ------------------------------------------------------------------------

class _Reader:
    """Walks the JSON with a path for messages: 'route.plan: mission.items[3].params: ...'."""

    def __init__(self, path):
        self.path = path

    def fail(self, where, what):
        return usage("%s: %s: %s" % (self.path, where, what))

    def get(self, obj, key, where, kind, default=None, required=True):
        if not isinstance(obj, dict):
            raise self.fail(where, "an object expected")
        if key not in obj:
            if required:
                raise self.fail(where, "the key %r is missing" % key)
            return default
        value = obj[key]
        if kind is float:
            return self.number(value, "%s.%s" % (where, key))
        if kind is bool and not isinstance(value, bool):
            raise self.fail("%s.%s" % (where, key), "true or false expected")
        if kind is list and not isinstance(value, list):
            raise self.fail("%s.%s" % (where, key), "a list expected")
        if kind is int and (isinstance(value, bool) or not isinstance(value, int)):
            raise self.fail("%s.%s" % (where, key), "an integer expected")
        return value

    def number(self, value, where, null_ok=False):
        if value is None and null_ok:
            return math.nan  # QGroundControl writes NaN ("no change") as null
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(where, "a number expected, found %s" % json.dumps(value))
        return float(value)

    def latlon(self, value, where, n=2):
        if not isinstance(value, list) or len(value) < n:
            raise self.fail(where, "[latitude, longitude%s] expected" % (", altitude" if n == 3 else ""))
        lat, lon = (self.number(v, "%s[%d]" % (where, i)) for i, v in enumerate(value[:2]))
        if not (-90 <= lat <= 90 and -180 <= lon <= 180):
            raise self.fail(where, "latitude %g, longitude %g out of range" % (lat, lon))
        rest = [self.number(v, "%s[%d]" % (where, i + 2)) for i, v in enumerate(value[2:n])]
        return (lat, lon, *rest)

    def mission(self, doc):
        m = self.get(doc, "mission", "mission", dict, default={}, required=False)
        items = []
        for i, entry in enumerate(self.get(m, "items", "mission", list, default=[], required=False)):
            where = "mission.items[%d]" % i
            kind = self.get(entry, "type", where, str)
            if kind != "SimpleItem":
                raise self.fail(where, "%s items are not supported (only SimpleItem): let "
                                "QGroundControl upload it, then download it here" % kind)
            params = self.get(entry, "params", where, list)
            if len(params) != 7:
                raise self.fail(where + ".params", "7 values expected, found %d" % len(params))
            p = [self.number(v, "%s.params[%d]" % (where, j), null_ok=True) for j, v in enumerate(params)]
            frame = self.get(entry, "frame", where, int)
            command = self.get(entry, "command", where, int)
            auto = self.get(entry, "autoContinue", where, bool, default=True, required=False)
            it = Item(i, 0, frame, command, *p, int(auto))
            it.check_xy(lambda what: self.fail(where + ".params", what))
            items.append(it)
        home = m.get("plannedHomePosition") if isinstance(m, dict) else None
        if home is not None:
            home = self.latlon(home, "mission.plannedHomePosition", 3)
        return items, home

    def fence(self, doc):
        fence = self.get(doc, "geoFence", "geoFence", dict, default={}, required=False)
        items = []
        for i, entry in enumerate(self.get(fence, "polygons", "geoFence", list, default=[], required=False)):
            where = "geoFence.polygons[%d]" % i
            inclusion = self.get(entry, "inclusion", where, bool, default=True, required=False)
            vertices = self.get(entry, "polygon", where, list)
            if len(vertices) < 3:
                raise self.fail(where + ".polygon", "at least 3 vertices expected, found %d" % len(vertices))
            command = POLYGON_INCLUSION if inclusion else POLYGON_EXCLUSION
            for j, vertex in enumerate(vertices):
                lat, lon = self.latlon(vertex, "%s.polygon[%d]" % (where, j))
                items.append(item(len(items), MAV_FRAME_GLOBAL, command, len(vertices), lat, lon))
        for i, entry in enumerate(self.get(fence, "circles", "geoFence", list, default=[], required=False)):
            where = "geoFence.circles[%d]" % i
            inclusion = self.get(entry, "inclusion", where, bool, default=True, required=False)
            circle = self.get(entry, "circle", where, dict)
            center = self.get(circle, "center", where + ".circle", list)
            lat, lon = self.latlon(center, where + ".circle.center")
            radius = self.get(circle, "radius", where + ".circle", float)
            if not radius > 0:
                raise self.fail(where + ".circle.radius", "a radius > 0 expected")
            command = CIRCLE_INCLUSION if inclusion else CIRCLE_EXCLUSION
            items.append(item(len(items), MAV_FRAME_GLOBAL, command, radius, lat, lon))
        ret = fence.get("breachReturn") if isinstance(fence, dict) else None
        if ret is not None:
            lat, lon, alt = self.latlon(ret, "geoFence.breachReturn", 3)
            items.append(item(len(items), MAV_FRAME_GLOBAL_RELATIVE_ALT, FENCE_RETURN, 0.0, lat, lon, alt))
        return items

    def rally(self, doc):
        rally = self.get(doc, "rallyPoints", "rallyPoints", dict, default={}, required=False)
        items = []
        for i, point in enumerate(self.get(rally, "points", "rallyPoints", list, default=[], required=False)):
            lat, lon, alt = self.latlon(point, "rallyPoints.points[%d]" % i, 3)
            items.append(item(i, MAV_FRAME_GLOBAL_RELATIVE_ALT, RALLY_POINT, 0.0, lat, lon, alt))
        return items


def read_plan(path):
    try:
        with open(path, encoding="utf-8") as f:
            text = f.read()
    except OSError as e:
        raise usage("%s: %s" % (path, e.strerror))
    except UnicodeDecodeError:
        raise usage("%s: not a text file" % path)
    try:
        doc = json.loads(text)
    except ValueError as e:
        line, col = getattr(e, "lineno", 0), getattr(e, "colno", 0)
        raise usage("%s:%d:%d: not valid JSON: %s" % (path, line, col, getattr(e, "msg", e)))
    r = _Reader(path)
    if r.get(doc, "fileType", "the file", str) != "Plan":
        raise r.fail("fileType", "'Plan' expected")
    mission, home = r.mission(doc)
    m = doc.get("mission") or {}
    return Plan(mission, r.fence(doc), r.rally(doc), home,
                m.get("firmwareType", MAV_AUTOPILOT_GENERIC), m.get("vehicleType", MAV_TYPE_QUADROTOR))


def is_plan(path):
    return path.lower().endswith(".plan")


def read_any(path, mission_type="mission"):
    """A Plan from a .plan file, or from a QGC WPL file holding the given part."""
    if is_plan(path):
        return read_plan(path)
    plan = Plan()
    setattr(plan, mission_type, read_wpl(path))
    return plan


# --- writing ------------------------------------------------------------------------

def number(x):
    """A JSON value for x: null for NaN (as QGroundControl writes it)."""
    x = float(x)
    return None if math.isnan(x) else (int(x) if x.is_integer() and abs(x) < 1e15 else x)


def plan_document(plan):
    items = []
    for seq, it in enumerate(plan.mission):
        items.append({
            "autoContinue": bool(it.autocontinue),
            "command": it.command,
            "doJumpId": seq + 1,
            "frame": it.frame,
            "params": [number(v) for v in it.params + [it.x, it.y, it.z]],
            "type": "SimpleItem",
        })
    home = plan.home
    if home is None:
        first = next((it for it in plan.mission if it.frame != 2 and float(it.x)), None)
        home = (float(first.x), float(first.y), 0.0) if first else (0.0, 0.0, 0.0)
    polygons = [{"inclusion": inc, "polygon": [[number(a), number(b)] for a, b in vertices], "version": 1}
                for inc, vertices in plan.polygons()]
    circles = [{"circle": {"center": [number(c[0]), number(c[1])], "radius": number(r)},
                "inclusion": inc, "version": 1} for inc, c, r in plan.circles()]
    fence = {"circles": circles, "polygons": polygons, "version": 2}
    ret = [it for it in plan.fence if it.command == FENCE_RETURN]
    if ret:
        fence["breachReturn"] = [number(ret[0].x), number(ret[0].y), number(ret[0].z)]
    return {
        "fileType": "Plan",
        "geoFence": fence,
        "groundStation": "QGroundControl",  # as QGroundControl checks it on load
        "mission": {
            "cruiseSpeed": 15,
            "firmwareType": plan.firmware,
            "globalPlanAltitudeMode": 1,
            "hoverSpeed": 5,
            "items": items,
            "plannedHomePosition": [number(v) for v in home],
            "vehicleType": plan.vehicle,
            "version": 2,
        },
        "rallyPoints": {"points": [[number(it.x), number(it.y), number(it.z)] for it in plan.rally],
                        "version": 2},
        "version": 1,
    }


def write_plan(plan, out):
    """Write plan as JSON to a path or an open text file."""
    text = json.dumps(plan_document(plan), indent=4, sort_keys=True) + "\n"
    if hasattr(out, "write"):
        out.write(text)
    else:
        with open(out, "w", encoding="utf-8") as f:
            f.write(text)
