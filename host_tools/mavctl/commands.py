"""mavctl's own one-shot subcommands: command, arm/disarm, mode, reboot, stream and ports.
Registered like any plug-in (cli.PLUGINS); `params` and `mission` are params.py and
mission.py, `watch` is watch.py."""
import math
import sys

from mavctl import link as mavctl_link
from mavctl.args import taken
from mavctl.errors import EXIT_OK, EXIT_REFUSED, Failure, usage
from mavctl.names import enum_name, enum_value, mavlink, message_id, message_name

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


def cmd_ports(args):
    ports = mavctl_link.usb_serial_ports()
    for port in ports:
        print(port)
    if not ports:
        print("no USB serial device", file=sys.stderr)


def register(sub):
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
    p = add("stream", "MAV_CMD_SET_MESSAGE_INTERVAL: a message at HZ", run=cmd_stream, check=check_stream)
    if p:
        p.add_argument("message", metavar="MSG", help="message name or id")
        p.add_argument("hz", metavar="HZ", help="rate in Hz, 'default' or 'off'")
    add("ports", "list the USB serial devices auto-connect would consider", func=cmd_ports)
