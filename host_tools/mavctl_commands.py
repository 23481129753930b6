"""mavctl's own subcommands: params, mission, command, arm/disarm, mode, reboot, stream,
watch (line output) and ports. Registered like any plug-in (see mavctl_cli)."""
import fnmatch
import math
import sys
import time

import mavctl_link
from mavctl_cli import group, taken
from mavctl_errors import EXIT_OK, EXIT_REFUSED, Failure, usage
from mavctl_vehicle import MISSION_TYPES, enum_name, enum_value, mavlink, message_id, message_name
from mavctl_progress import progress
from mission_files import read_wpl, write_wpl
from param_files import read_params, write_params
from plan_files import MAV_AUTOPILOT_GENERIC, MAV_TYPE_QUADROTOR, Plan, is_plan, read_plan, write_plan


def result_status(what, ack):
    name = enum_name("MAV_RESULT", ack.result)
    extra = " (result_param2 %d)" % ack.result_param2 if getattr(ack, "result_param2", 0) else ""
    print("%s: %s%s" % (what, name, extra))
    return EXIT_OK if ack.result == mavlink.MAV_RESULT_ACCEPTED else EXIT_REFUSED


def send_command(v, command, params):
    return result_status(enum_name("MAV_CMD", command), v.command(command, params))


def parse_floats(words):
    try:
        return [float(w) for w in words]
    except ValueError as e:
        raise usage(str(e))


# --- params -------------------------------------------------------------------------

def params_list(v, args):
    for p in v.param_list():
        if args.pattern is None or fnmatch.fnmatchcase(p.name, args.pattern):
            print("%-16s %s" % (p.name, p.text()))


def params_get(v, args):
    print("%-16s %s" % (args.name, v.param_read(args.name).text()))


def params_set(v, args):
    current = v.param_read(args.name)
    raw = current.encode(args.value)
    echoed = v.param_set(args.name, raw, current.type)
    if not echoed.same_value(raw):
        raise Failure("refused: %s stays %s" % (args.name, echoed.text()))
    print("%-16s %s" % (args.name, echoed.text()))


def check_name(args):
    if len(args.name.encode()) > 16:
        raise usage("parameter names have at most 16 characters")


def params_storage(v, args):
    # MAV_CMD_PREFLIGHT_STORAGE param1: 0 read from storage, 1 write, 2 reset to defaults.
    action = {"load": 0, "save": 1, "load-defaults": 2}[args.action]
    return result_status("params " + args.action,
                         v.command(mavlink.MAV_CMD_PREFLIGHT_STORAGE, [action]))


def all_params(v):
    with progress("parameters") as bar:
        return v.param_list(progress=bar)


def params_save(v, args):
    if args.file is None:
        return params_storage(v, args)
    params = all_params(v)
    write_params(args.file, params, v.target_system, v.target_component)
    print("saved %d parameters to %s" % (len(params), args.file))


def wanted_values(args, current):
    """[(Param on the vehicle, 4 wire bytes wanted)] for the file's lines; any name the
    vehicle lacks or value its type cannot hold stops the run before anything is sent."""
    out = []
    for name, value, _ptype, line in args.values:
        where = "%s:%d: %s" % (args.file, line, name)
        p = current.get(name)
        if p is None:
            raise usage("%s: no such parameter on this vehicle" % where)
        try:
            out.append((p, p.encode(value)))
        except Failure as e:
            raise usage("%s:%d: %s" % (args.file, line, e))
    return out


def params_load(v, args):
    if args.file is None:
        return params_storage(v, args)
    current = {p.name: p for p in all_params(v)}
    wanted = wanted_values(args, current)
    changes = [(p, raw) for p, raw in wanted if not p.same_value(raw)]
    refused = []
    with progress("set parameters", len(changes)) as bar:
        for done, (p, raw) in enumerate(changes, 1):
            try:
                echoed = v.param_set(p.name, raw, p.type)
            except Failure as e:
                refused.append("%s (%s)" % (p.name, e))
                continue
            if echoed.same_value(raw):
                print("%-16s %s -> %s" % (p.name, p.text(), echoed.text()))
            else:
                refused.append("%s (stays %s)" % (p.name, echoed.text()))
            bar(done)
    print("%s: %d changed, %d unchanged, %d refused%s" % (
        args.file, len(changes) - len(refused), len(wanted) - len(changes), len(refused),
        ": " + ", ".join(refused) if refused else ""))
    return EXIT_REFUSED if refused else EXIT_OK


def params_diff(v, args):
    current = {p.name: p for p in all_params(v)}
    other = args.values
    label = args.file or "defaults (%s)" % args.board
    differ = 0
    print("%-16s %-14s %s" % ("NAME", "VEHICLE", label))
    for name, value, _ptype, _line in other:
        p = current.get(name)
        if p is None:
            print("%-16s %-14s %s" % (name, "-", value))
            differ += 1
            continue
        try:
            same = p.same_value(p.encode(value))
        except Failure:
            same = False
        if not same:
            print("%-16s %-14s %s" % (name, p.text(), value))
            differ += 1
    if args.defaults:
        for name in sorted(set(current) - {row[0] for row in other}):
            print("%-16s %-14s %s" % (name, current[name].text(), "-"))
            differ += 1
    print("%d of %d parameters differ" % (differ, len(current)), file=sys.stderr)


def check_params_file(args):
    if args.file is not None:
        args.values = read_params(args.file)


def check_diff(args):
    if (args.file is None) == (not args.defaults):
        raise usage("params diff FILE, or params diff --defaults [--board BOARD]")
    if args.defaults:
        args.values = board_defaults(args.board)
    else:
        args.values = read_params(args.file)


def board_defaults(board):
    """[(name, default as text, type, 0)] from the board profile's parameter table in
    this checkout (boards/BOARD.py PARAMS): what the vehicle starts with before any change."""
    import os
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    if not os.path.isfile(os.path.join(root, "boards", board + ".py")):
        raise usage("no board profile boards/%s.py" % board)
    paths = [os.path.join(root, "firmware"), os.path.join(root, "boards")]
    sys.path[:0] = paths
    try:
        table = __import__(board).PARAMS
    except Exception as e:
        raise usage("boards/%s.py: cannot read its PARAMS: %s" % (board, e))
    finally:
        del sys.path[:len(paths)]
    return [(row[0], repr(row[2]), row[1], 0) for row in table]


def register_params(sub):
    params = group(sub, "params", help="list, get, set parameters; save, load, diff files")
    p = params.add_parser("list", help="every parameter, or those matching a pattern")
    p.add_argument("pattern", nargs="?", help="a pattern such as 'SR_*'")
    p.set_defaults(run=params_list)
    p = params.add_parser("get", help="one parameter")
    p.add_argument("name")
    p.set_defaults(run=params_get, check=check_name)
    p = params.add_parser("set", help="set one parameter")
    p.add_argument("name")
    p.add_argument("value")
    p.set_defaults(run=params_set, check=check_name)
    files = "FILE.params (QGroundControl) or FILE.parm (MAVProxy)"
    p = params.add_parser("save", help="all parameters into FILE; no FILE: into the vehicle's storage")
    p.add_argument("file", nargs="?", help=files)
    p.set_defaults(run=params_save)
    p = params.add_parser("load", help="set the values of FILE that differ; no FILE: reload the "
                          "vehicle's storage")
    p.add_argument("file", nargs="?", help=files)
    p.set_defaults(run=params_load, check=check_params_file)
    p = params.add_parser("load-defaults", help="reset the vehicle's parameters to their defaults")
    p.set_defaults(run=params_storage)
    p = params.add_parser("diff", help="the vehicle's values that differ from FILE or the defaults")
    p.add_argument("file", nargs="?", help=files)
    p.add_argument("--defaults", action="store_true", help="compare with the board's defaults")
    p.add_argument("--board", default="unix", help="board profile for --defaults (default unix)")
    p.set_defaults(run=params_diff, check=check_diff)


# --- mission ------------------------------------------------------------------------

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


def register_mission(sub):
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


# --- commands -----------------------------------------------------------------------

def cmd_command(v, args):
    return send_command(v, args.command, args.values)


def check_command(args):
    if len(args.params) > 7:
        raise usage("a command has at most 7 parameters")
    args.command = enum_value("MAV_CMD", args.name)
    args.values = parse_floats(args.params)


def cmd_arm(v, args):
    # param2 21196: arm or disarm even if checks refuse (MAV_CMD_COMPONENT_ARM_DISARM).
    arm = 1.0 if args.subcommand == "arm" else 0.0
    return send_command(v, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, [arm, 21196.0 if args.force else 0.0])


def cmd_mode(v, args):
    return send_command(v, mavlink.MAV_CMD_DO_SET_MODE, args.values)


def check_mode(args):
    if len(args.custom) > 2:
        raise usage("mode BASE [CUSTOM [SUBMODE]]")
    base = 0
    for word in args.base.split("|"):
        try:
            base |= enum_value("MAV_MODE", word)
        except Failure:
            base |= enum_value("MAV_MODE_FLAG", word)
    args.values = [base] + parse_floats(args.custom)


def cmd_reboot(v, args):
    return send_command(v, mavlink.MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN, [1.0])


def cmd_stream(v, args):
    return result_status("stream %s" % message_name(args.values[0]),
                         v.command(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, args.values))


def check_stream(args):
    msgid = message_id(args.message)
    rate = args.hz.lower()
    if rate in ("off", "stop"):
        interval = -1.0
    elif rate == "default":
        interval = 0.0
    else:
        hz = parse_floats([rate])[0]
        if hz < 0 or not math.isfinite(hz):
            raise usage("HZ: a rate >= 0, 'default' or 'off'")
        interval = -1.0 if hz == 0 else round(1e6 / hz)
    args.values = [msgid, interval]


# --- watch (line output; a plug-in may register a live view instead) ---------------

def cmd_watch(v, args):
    v.echo_statustext = False
    start = time.monotonic()
    end = start + args.seconds if args.seconds else math.inf
    counts = {}
    try:
        while True:
            now = time.monotonic()
            if now >= end:
                break
            msg = v.recv(args.wanted, min(0.5, end - now))
            if msg is not None:
                if args.rates:
                    counts[msg.get_type()] = counts.get(msg.get_type(), 0) + 1
                else:
                    print(msg, flush=True)
    except KeyboardInterrupt:
        pass
    if args.rates:
        print_rates(counts, time.monotonic() - start)


def print_rates(counts, seconds):
    print("%-28s %8s %8s" % ("MESSAGE", "COUNT", "HZ"))
    for name in sorted(counts):
        print("%-28s %8d %8.2f" % (name, counts[name], counts[name] / max(seconds, 1e-3)))
    sys.stdout.flush()


def check_watch(args):
    args.wanted = {message_name(message_id(m)) for m in args.messages} or None


def cmd_ports(args):
    ports = mavctl_link.usb_serial_ports()
    for port in ports:
        print(port)
    if not ports:
        print("no USB serial device", file=sys.stderr)


def register(sub):
    register_params(sub)
    register_mission(sub)

    def add(name, help, **defaults):
        if taken(sub, name):
            return None
        p = sub.add_parser(name, help=help)
        p.set_defaults(**defaults)
        return p

    p = add("command", "send a COMMAND_LONG, print the COMMAND_ACK result", run=cmd_command,
            check=check_command)
    if p:
        p.add_argument("name", metavar="NAME_OR_ID", help="MAV_CMD name (NAV_TAKEOFF) or number")
        p.add_argument("params", nargs="*", metavar="P", help="param1 .. param7 (default 0; nan allowed)")
    for name in ("arm", "disarm"):
        p = add(name, "%s the vehicle" % name, run=cmd_arm)
        if p:
            p.add_argument("--force", action="store_true", help="override the vehicle's checks")
    p = add("mode", "MAV_CMD_DO_SET_MODE", run=cmd_mode, check=check_mode)
    if p:
        p.add_argument("base", metavar="BASE",
                       help="base mode: number, MAV_MODE name, or MAV_MODE_FLAG names joined by |")
        p.add_argument("custom", nargs="*", metavar="CUSTOM", help="custom mode [custom sub mode]")
    add("reboot", "reboot the vehicle's autopilot", run=cmd_reboot)
    p = add("watch", "print telemetry until Ctrl-C", run=cmd_watch, check=check_watch)
    if p:
        p.add_argument("messages", nargs="*", metavar="MSG", help="message names (default: all)")
        p.add_argument("--seconds", type=float, help="stop after this long")
        p.add_argument("--rates", action="store_true", help="a table of message rates instead of messages")
    p = add("stream", "MAV_CMD_SET_MESSAGE_INTERVAL: a message at HZ", run=cmd_stream, check=check_stream)
    if p:
        p.add_argument("message", metavar="MSG", help="message name or id")
        p.add_argument("hz", metavar="HZ", help="rate in Hz, 'default' or 'off'")
    add("ports", "list the USB serial devices auto-connect would consider", func=cmd_ports)
