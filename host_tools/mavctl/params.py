"""`mavctl params`: list, get and set parameters; save them to, load them from and compare
them with QGroundControl .params and MAVProxy .parm files (param_file.py) or the board's
defaults; keep or reload the vehicle's own storage."""
import fnmatch
import os
import sys

from mavctl import ROOT
from mavctl.args import group
from mavctl.commands import result_status
from mavctl.errors import EXIT_OK, EXIT_REFUSED, Failure, usage
from mavctl.progress import progress
from mavctl.names import mavlink
from mavctl.param_file import read_params, write_params


def params_list(v, args):
    for p in all_params(v):
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
    root = ROOT
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


def register(sub):
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
