"""What plug-in modules share to build mavctl's command line: a subcommand's actions
made on first use (group) and the check for a subcommand name already taken (taken).
The plug-in convention: docs/mavctl.md."""


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
