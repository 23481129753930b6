"""mavctl's command line: global options, the subcommands gathered from plug-in modules,
and the run that turns every Failure into one line and an exit status.

Plug-in convention. PLUGINS names modules (importable from host_tools/); each exposes

    def register(sub):      # sub: the argparse subparsers action of `mavctl`
        p = sub.add_parser("plot", help="...")
        p.add_argument(...)
        p.set_defaults(func=run_plot)            # run_plot(args) -> exit status
        p = group(sub, "mission").add_parser("show", help="...")   # `mavctl mission show`
        p.set_defaults(run=show_mission)         # show_mission(vehicle, args) -> exit status

- `set_defaults(run=f)`: mavctl opens the link (--connect or auto-connect), waits for the
  vehicle's HEARTBEAT, calls f(vehicle, args) with a mavctl_vehicle.Vehicle, closes the link.
- `set_defaults(func=f)`: mavctl calls f(args) and connects nothing; f may open the link
  itself with `with mavctl_link.vehicle(args) as v:` (for instance only for some options).
- `set_defaults(check=c)` (optional): c(args) runs before anything is opened, to refuse bad
  arguments or malformed files early (raise mavctl_errors.usage(...)).
- f returns an exit status (None counts as 0) or raises mavctl_errors.Failure(message,
  status); the statuses are listed in mavctl_errors. Ctrl-C ends the run quietly.
- `group(sub, "mission")` gives the subparsers of a subcommand that has actions (`params`,
  `mission`, `log`, `signing`...), creating it if no module did yet, so modules can add
  actions to each other's subcommands in any order.
- Modules are registered in PLUGINS order; a subcommand name already taken is kept by the
  earlier module (mavctl's own come last, so a plug-in may take over one of theirs). A module
  that is not there is skipped; one that fails to import is skipped with a warning.
- Progress bars: mavctl_progress.progress(total, what) (terminal only, quiet in pipes).
"""
import argparse
import importlib
import os
import sys

from mavctl import link as mavctl_link
from mavctl.errors import EXIT_OK, EXIT_STATUS_HELP, EXIT_USAGE, Failure

PLUGINS = ("mavctl.watch", "mavctl.plot", "mavctl.sim", "mavctl.signing", "mavctl.flash",
           "mavctl.params", "mavctl.mission", "mavctl.commands")


def group(sub, name, help=None):
    """The subparsers of subcommand `name` (`mavctl NAME ACTION ...`), made on first use."""
    groups = sub.__dict__.setdefault("mavctl_groups", {})
    if name not in groups:
        if name in sub.choices:
            raise RuntimeError("subcommand %s has no actions" % name)
        p = sub.add_parser(name, help=help)
        groups[name] = p.add_subparsers(dest="action", required=True, metavar="ACTION")
    elif help and not getattr(sub.choices[name], "_help_set", False):
        _set_help(sub, name, help)
    return groups[name]


def _set_help(sub, name, help):
    for action in sub._choices_actions:
        if action.dest == name:
            action.help = help
    sub.choices[name]._help_set = True


def taken(sub, name):
    """True if an earlier module registered subcommand `name` (then skip yours)."""
    return name in sub.choices


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
