"""`mavctl mission`: upload, download and clear the mission, the geofence and the rally
points, from and to QGroundControl .plan files (plan_file.py, all three parts) and QGC WPL 110
files (mission_file.py, one part); set the current item."""
import sys

from mavctl.args import group
from mavctl.progress import progress
from mavctl.mission_protocol import MISSION_TYPES
from mavctl.mission_file import read_wpl, write_wpl
from mavctl.plan_file import MAV_AUTOPILOT_GENERIC, MAV_TYPE_QUADROTOR, Plan, is_plan, read_plan, write_plan


def transfer(what, run):
    with progress(what) as bar:
        return run(bar)


def mission_upload(v, args):
    counts = []
    for name, items in args.parts:
        transfer("upload %s" % name,
                 lambda bar: v.mission_upload(items, MISSION_TYPES[name], progress=bar))
        counts.append("%d %s" % (len(items), name))
    print("uploaded %s items" % ", ".join(counts))


def mission_download(v, args):
    if args.file and is_plan(args.file):
        parts = {}
        for name in (("mission", "fence", "rally") if args.type is None else (args.type,)):
            parts[name] = transfer("download %s" % name,
                                   lambda bar: v.mission_download(MISSION_TYPES[name], progress=bar))
        hb = v.heartbeat_msg
        plan = Plan(home=v.home_position(),
                    firmware=hb.autopilot if hb else MAV_AUTOPILOT_GENERIC,
                    vehicle=hb.type if hb else MAV_TYPE_QUADROTOR, **parts)
        write_plan(plan, args.file)
        print("downloaded %s items to %s" % (", ".join("%d %s" % (len(items), name)
                                                        for name, items in parts.items()), args.file))
        return
    mtype = args.type or "mission"
    items = transfer("download %s" % mtype,
                     lambda bar: v.mission_download(MISSION_TYPES[mtype], progress=bar))
    if args.file and args.file != "-":
        with open(args.file, "w", encoding="utf-8") as f:
            write_wpl(items, f)
        print("downloaded %d %s items to %s" % (len(items), mtype, args.file))
    else:
        write_wpl(items, sys.stdout)


def mission_clear(v, args):
    names = ("mission", "fence", "rally") if args.type == "all" else (args.type or "mission",)
    for name in names:
        v.mission_clear(MISSION_TYPES[name])
    print("cleared the %s" % ", ".join(names))


def mission_current(v, args):
    v.mission_set_current(args.seq)
    print("current item %d" % args.seq)


def check_upload(args):
    """Read the whole file before connecting: a malformed one sends nothing."""
    if is_plan(args.file):
        plan = read_plan(args.file)
        args.parts = [(name, items) for name, items in plan.parts()
                      if args.type is None or name == args.type]
    else:
        args.parts = [(args.type or "mission", read_wpl(args.file))]


def register(sub):
    mission = group(sub, "mission", help="upload, download, clear a mission, fence or rally points")
    types = tuple(MISSION_TYPES)

    def add(action, run, help, check=None, choices=types):
        p = mission.add_parser(action, help=help)
        p.add_argument("--type", choices=choices, default=None,
                       help="which part (default: the mission; a .plan: all three)")
        p.set_defaults(run=run, check=check)
        return p

    add("upload", mission_upload, "send a .plan (mission, fence, rally) or a QGC WPL 110 file",
        check_upload).add_argument("file")
    add("download", mission_download, "fetch into a .plan (all three parts) or a QGC WPL 110 "
        "file").add_argument("file", nargs="?", help="FILE.plan, FILE (QGC WPL 110) or - (stdout)")
    add("clear", mission_clear, "remove every item", choices=types + ("all",))
    p = mission.add_parser("current", help="make item N the current one")
    p.add_argument("seq", type=int, metavar="N")
    p.set_defaults(run=mission_current)
