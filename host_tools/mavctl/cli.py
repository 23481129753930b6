"""mavctl's command line: global options, the subcommands gathered from plug-in modules
(PLUGINS, each with register(sub)), and the run that turns every Failure into one line
and an exit status. The plug-in convention: docs/mavctl.md.
"""
import argparse
import importlib
import os
import sys

from mavctl import link as mavctl_link
from mavctl.args import group, taken  # noqa: F401  (plug-ins have them from here too)
from mavctl.errors import EXIT_OK, EXIT_STATUS_HELP, EXIT_USAGE, Failure

PLUGINS = ("mavctl.watch", "mavctl.plot", "mavctl.sim", "mavctl.signing", "mavctl.flash",
           "mavctl.params", "mavctl.mission", "mavctl.commands")


def load_plugins(sub, names=None):
    for name in PLUGINS if names is None else names:
        try:
            module = importlib.import_module(name)
        except ModuleNotFoundError as e:
            if e.name == name:
                continue
            print("mavctl: %s unavailable: %s" % (name, e), file=sys.stderr)
            continue
        except Exception as e:  # a broken plug-in must not take the other subcommands down
            print("mavctl: %s unavailable: %s: %s" % (name, type(e).__name__, e), file=sys.stderr)
            continue
        module.register(sub)


def parser():
    ap = argparse.ArgumentParser(
        prog="mavctl",
        description="Drive a MAVLink vehicle: parameters, missions, commands, telemetry, flashing.",
        epilog=EXIT_STATUS_HELP)
    mavctl_link.add_arguments(ap)
    sub = ap.add_subparsers(dest="subcommand", required=True, metavar="SUBCOMMAND")
    load_plugins(sub)
    return ap


def main(argv=None):
    args = parser().parse_args(argv)
    try:
        check = getattr(args, "check", None)
        if check is not None:
            check(args)
        if getattr(args, "run", None) is not None:
            with mavctl_link.vehicle(args) as v:
                status = args.run(v, args)
        else:
            status = args.func(args)
        return EXIT_OK if status is None else status
    except Failure as e:
        print("mavctl: %s" % e, file=sys.stderr)
        return e.status
    except KeyboardInterrupt:
        print("mavctl: interrupted", file=sys.stderr)
        return EXIT_USAGE
    except BrokenPipeError:
        # The reader went away (`mavctl ... | head`): done, and nothing left to flush at exit.
        try:
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        except (OSError, ValueError):
            pass
        return EXIT_OK


def entry():
    """The installed `mavctl` command."""
    sys.exit(main())
