"""Pictures for what people would rather look at than read, drawn with matplotlib's Agg
backend (no display needed):

    mavctl mission show FILE|--vehicle [--png OUT]   the mission path with item numbers,
        the fence and the rally points, in metres from home; the item table is printed
    mavctl log plot TLOG --png OUT                   flown track, altitude, speed and
        battery over time, from a telemetry log (`mavctl watch --tlog`, MAVProxy, QGC)
"""
import math
import os
import sys

from mavctl import link as mavctl_link
from mavctl.args import group
from mavctl.errors import EXIT_OK, Failure, usage
from mavctl.mission_protocol import MISSION_TYPES
from mavctl.names import enum_name
from mavctl.mission_file import LOCAL_FRAMES
from mavctl.plan_file import Plan, read_any

EARTH_M_PER_DEG = 111319.49  # metres per degree of latitude (WGS-84 equatorial radius)
DEFAULT_SIZE = (1000, 800)
DPI = 100
NO_POSITION = (2,)  # MAV_FRAME_MISSION: x, y are no place


# --- geometry ---------------------------------------------------------------------------

class Flat:
    """Latitude/longitude to metres north and east of an origin (equirectangular: exact
    enough over the few kilometres a mission spans)."""

    def __init__(self, lat, lon):
        self.lat, self.lon = lat, lon
        self.k = math.cos(math.radians(lat))

    def ne(self, lat, lon):
        return (lat - self.lat) * EARTH_M_PER_DEG, (lon - self.lon) * EARTH_M_PER_DEG * self.k


def has_place(item):
    x, y = float(item.x), float(item.y)
    return (item.frame not in LOCAL_FRAMES and item.frame not in NO_POSITION
            and math.isfinite(x) and math.isfinite(y) and not (x == 0 and y == 0))


def origin(plan):
    """Home: the plan's, else item 0 of a WPL file in the global frame (where ArduPilot
    and MAVProxy keep home), else the first item with a place; None if nothing has one."""
    if plan.home is not None:
        return plan.home[0], plan.home[1], "home"
    placed = [i for i in plan.mission + plan.rally + plan.fence if has_place(i)]
    if not placed:
        return None
    first = placed[0]
    what = "home (item 0)" if plan.mission and first is plan.mission[0] and first.frame == 0 \
        else "item %d" % first.seq
    return float(first.x), float(first.y), what


def short(enum, value, prefix):
    return enum_name(enum, value).replace(prefix, "")


def command_name(command):
    name = short("MAV_CMD", command, "MAV_CMD_")
    return name[4:] if name.startswith("NAV_") else name


def item_table(plan, flat):
    """The printed table: every item of every part, with north/east from home and legs."""
    lines = ["%-7s %4s %-30s %-20s %12s %12s %8s %9s %9s %8s" % (
        "PART", "SEQ", "COMMAND", "FRAME", "LAT", "LON", "ALT", "NORTH m", "EAST m", "LEG m")]
    for part, items in plan.parts():
        last = None
        for item in items:
            north = east = leg = ""
            if flat is not None and has_place(item):
                n, e = flat.ne(float(item.x), float(item.y))
                north, east = "%.1f" % n, "%.1f" % e
                if last is not None and part == "mission":
                    leg = "%.1f" % math.hypot(n - last[0], e - last[1])
                last = (n, e)
            lines.append("%-7s %4d %-30s %-20s %12.7f %12.7f %8.1f %9s %9s %8s" % (
                part, item.seq, command_name(item.command)[:30],
                short("MAV_FRAME", item.frame, "MAV_FRAME_")[:20],
                float(item.x), float(item.y), item.z, north, east, leg))
    return lines


# --- drawing ----------------------------------------------------------------------------

def pyplot():
    import matplotlib
    matplotlib.use("Agg")  # files only: no display, no GUI toolkit
    import matplotlib.pyplot as plt
    return plt


def figure(size):
    plt = pyplot()
    return plt, plt.figure(figsize=(size[0] / DPI, size[1] / DPI), dpi=DPI)


def save(plt, fig, out):
    try:
        fig.savefig(out, dpi=DPI)
    except OSError as e:
        raise Failure("%s: %s" % (out, e.strerror), 2)
    finally:
        plt.close(fig)


def draw_mission(plan, flat, where, out, size, title):
    from matplotlib.patches import Circle, Polygon
    plt, fig = figure(size)
    ax = fig.add_subplot(1, 1, 1)
    for inclusion, vertices in plan.polygons():
        pts = [flat.ne(lat, lon)[::-1] for lat, lon in vertices]
        ax.add_patch(Polygon(pts, closed=True, fill=not inclusion, alpha=0.25 if not inclusion else 1,
                             edgecolor="green" if inclusion else "red",
                             facecolor="red" if not inclusion else "none", linewidth=1.5,
                             label="fence: inclusion" if inclusion else "fence: exclusion"))
    for inclusion, (lat, lon), radius in plan.circles():
        n, e = flat.ne(lat, lon)
        ax.add_patch(Circle((e, n), radius, fill=not inclusion, alpha=0.25 if not inclusion else 1,
                            edgecolor="green" if inclusion else "red",
                            facecolor="red" if not inclusion else "none", linewidth=1.5))
    path = [(item.seq, flat.ne(float(item.x), float(item.y))) for item in plan.mission
            if has_place(item) and item.command < 1000]
    if path:
        ax.plot([e for _, (n, e) in path], [n for _, (n, e) in path], "-o", color="tab:blue",
                markersize=5, label="mission")
        labels = {}  # items at one place share one label ("0,1,5": home, takeoff, land)
        for seq, (n, e) in path:
            labels.setdefault((round(n, 1), round(e, 1)), []).append(str(seq))
        for (n, e), seqs in labels.items():
            ax.annotate(",".join(seqs), (e, n), textcoords="offset points", xytext=(6, 6), fontsize=9)
    for item in plan.rally:
        n, e = flat.ne(float(item.x), float(item.y))
        ax.plot([e], [n], "^", color="darkorange", markersize=9,
                label="rally point" if item is plan.rally[0] else None)
        ax.annotate("R%d" % item.seq, (e, n), textcoords="offset points", xytext=(6, -12), fontsize=9)
    ret = plan.return_point()
    if ret is not None:
        n, e = flat.ne(*ret)
        ax.plot([e], [n], "x", color="red", markersize=9, label="fence return")
    ax.plot([0], [0], "*", color="black", markersize=14, label=where)
    ax.set_aspect("equal", adjustable="datalim")
    ax.autoscale_view()
    ax.set_xlabel("east of %s (m)" % where)
    ax.set_ylabel("north of %s (m)" % where)
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    save(plt, fig, out)


# --- mission show -----------------------------------------------------------------------

def vehicle_plan(args):
    with mavctl_link.vehicle(args) as v:
        parts = {name: v.mission_download(MISSION_TYPES[name]) for name in ("mission", "fence", "rally")}
        return Plan(home=v.home_position(), **parts)


def run_show(args):
    plan = vehicle_plan(args) if args.vehicle else args.plan
    home = origin(plan)
    flat = Flat(home[0], home[1]) if home is not None else None
    for line in item_table(plan, flat):
        print(line)
    if args.png:
        if flat is None:
            raise Failure("nothing to draw: no item has a position", 1)
        title = "the vehicle's plan" if args.vehicle else os.path.basename(args.file)
        draw_mission(plan, flat, home[2], args.png, args.size, "%s: %d mission items, %d fence, %d rally"
                     % (title, len(plan.mission), len(plan.fence), len(plan.rally)))
        print("drawn to %s" % args.png, file=sys.stderr)
    return EXIT_OK


def check_show(args):
    if (args.file is None) == (not args.vehicle):
        raise usage("mission show FILE or mission show --vehicle")
    if args.file is not None:
        args.plan = read_any(args.file)


# --- log plot ---------------------------------------------------------------------------

def read_log(path):
    """Series from a telemetry log: {name: ([t], [value])}, t in s from the first frame."""
    from pymavlink import mavutil
    if not os.path.isfile(path):
        raise usage("%s: no such file" % path)
    try:
        log = mavutil.mavlink_connection(path, dialect="common", notimestamps=False)
    except Exception as e:
        raise usage("%s: cannot read: %s" % (path, e))
    wanted = ["HEARTBEAT", "GLOBAL_POSITION_INT", "VFR_HUD", "BATTERY_STATUS", "SYS_STATUS", "HOME_POSITION"]
    series = {}
    vehicle = None
    t0 = None
    home = None
    try:
        while True:
            msg = log.recv_match(type=wanted)
            if msg is None:
                break
            kind = msg.get_type()
            if kind == "HEARTBEAT":
                if vehicle is None and msg.type != 6:  # not a ground station's
                    vehicle = msg.get_srcSystem()
                continue
            if vehicle is None or msg.get_srcSystem() != vehicle:
                continue
            t = msg._timestamp
            t0 = t if t0 is None else t0
            t -= t0

            def add(name, value):
                ts, vs = series.setdefault(name, ([], []))
                ts.append(t)
                vs.append(value)
            if kind == "GLOBAL_POSITION_INT":
                add("lat", msg.lat / 1e7)
                add("lon", msg.lon / 1e7)
                add("alt", msg.relative_alt / 1e3)
                add("speed_gpi", math.hypot(msg.vx, msg.vy) / 100.0)
            elif kind == "VFR_HUD":
                add("speed", msg.groundspeed)
            elif kind == "BATTERY_STATUS":
                cells = [c for c in msg.voltages if c != 0xFFFF]
                if cells:
                    add("volts", sum(cells) / 1000.0)
                if msg.battery_remaining >= 0:
                    add("remaining", msg.battery_remaining)
            elif kind == "SYS_STATUS" and "BATTERY_STATUS" not in log.messages:
                add("volts", msg.voltage_battery / 1000.0)
                if msg.battery_remaining >= 0:
                    add("remaining", msg.battery_remaining)
            elif kind == "HOME_POSITION" and home is None:
                home = (msg.latitude / 1e7, msg.longitude / 1e7)
    finally:
        log.close()
    if "lat" not in series:
        raise usage("%s: no GLOBAL_POSITION_INT from a vehicle: not a telemetry log of a flight?" % path)
    return series, home


def draw_log(series, home, out, size, title):
    plt, fig = figure(size)
    lat_t, lats = series["lat"]
    _, lons = series["lon"]
    where = "home" if home is not None else "start"
    flat = Flat(*(home if home is not None else (lats[0], lons[0])))
    ne = [flat.ne(a, b) for a, b in zip(lats, lons)]
    track = fig.add_subplot(2, 2, 1)
    track.plot([e for n, e in ne], [n for n, e in ne], color="tab:blue")
    track.plot([ne[0][1]], [ne[0][0]], "o", color="green", label="start")
    track.plot([ne[-1][1]], [ne[-1][0]], "s", color="red", label="end")
    track.plot([0], [0], "*", color="black", markersize=12, label=where)
    track.set_aspect("equal", adjustable="datalim")
    track.set_xlabel("east of %s (m)" % where)
    track.set_ylabel("north (m)")
    track.set_title("track")
    track.legend(fontsize=8)
    alt = fig.add_subplot(2, 2, 2)
    alt.plot(*series["alt"], color="tab:purple")
    alt.set_ylabel("altitude above home (m)")
    alt.set_title("altitude")
    speed = fig.add_subplot(2, 2, 3)
    speed.plot(*series.get("speed", series["speed_gpi"]), color="tab:orange")
    speed.set_ylabel("ground speed (m/s)")
    speed.set_title("speed")
    bat = fig.add_subplot(2, 2, 4)
    if "volts" in series:
        bat.plot(*series["volts"], color="tab:red")
        bat.set_ylabel("battery (V)", color="tab:red")
    if "remaining" in series:
        right = bat.twinx()
        right.plot(*series["remaining"], color="tab:green")
        right.set_ylabel("remaining (%)", color="tab:green")
    bat.set_title("battery")
    for ax in (alt, speed, bat):
        ax.set_xlabel("time (s)")
        ax.grid(True, alpha=0.3)
    track.grid(True, alpha=0.3)
    fig.suptitle(title)
    fig.tight_layout()
    save(plt, fig, out)


def run_log_plot(args):
    series, home = read_log(args.tlog)
    t = series["lat"][0]
    draw_log(series, home, args.png, args.size, "%s: %.0f s, %d positions"
             % (os.path.basename(args.tlog), t[-1] - t[0], len(t)))
    print("drawn to %s" % args.png)
    return EXIT_OK


# --- command line -----------------------------------------------------------------------

def size_arg(text):
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise usage("--size WIDTHxHEIGHT in pixels, e.g. 1000x800")
    if not (100 <= w <= 8000 and 100 <= h <= 8000):
        raise usage("--size: 100 to 8000 pixels each way")
    return w, h


def check_size(args):
    args.size = size_arg(args.size_text) if args.size_text else DEFAULT_SIZE


def register(sub):
    p = group(sub, "mission").add_parser(
        "show", help="the item table, and with --png a map of the path, fence and rally points")
    p.add_argument("file", nargs="?", help="a .plan or QGC WPL 110 file")
    p.add_argument("--vehicle", action="store_true", help="the vehicle's plan (mission, fence, rally)")
    p.add_argument("--png", metavar="OUT", help="draw the plan to this PNG")
    p.add_argument("--size", dest="size_text", metavar="WxH", help="image size in pixels (default 1000x800)")
    p.set_defaults(func=run_show, check=lambda a: (check_size(a), check_show(a)))
    p = group(sub, "log", help="telemetry logs").add_parser(
        "plot", help="flown track, altitude, speed and battery from a .tlog, to a PNG")
    p.add_argument("tlog", metavar="TLOG")
    p.add_argument("--png", metavar="OUT", required=True)
    p.add_argument("--size", dest="size_text", metavar="WxH", help="image size in pixels (default 1000x800)")
    p.set_defaults(func=run_log_plot, check=check_size)
