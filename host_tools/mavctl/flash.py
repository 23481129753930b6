"""`mavctl flash ...`: put mavstack on a board; the options and the work are
flash_build.py's (`mavctl flash -h` lists them), so both spellings stay one tool."""
import argparse


def run_flash(args):
    from mavctl import flash_build  # loaded only when flashing: other subcommands start without it

    return flash_build.main(args.flash_args)


def register(sub):
    # '+' as the prefix: every word after `flash`, options included, goes to flash_build.py.
    p = sub.add_parser("flash", prefix_chars="+", add_help=False,
                       help="compile mavstack for a board and copy it over (see mavctl flash -h)")
    p.add_argument("flash_args", nargs=argparse.REMAINDER)
    p.set_defaults(func=run_flash)
