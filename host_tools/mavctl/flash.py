"""`mavctl flash ...`: put mavstack on a board; the options and the work are flash.py's
(`mavctl flash -h` lists them), so both spellings stay one tool."""
import argparse


def run_flash(args):
    from mavctl import flash_build as flash  # builds with mpy-cross, copies with mpremote: loaded only when flashing
    return flash.main(args.flash_args)


def register(sub):
    # '+' as the prefix: every word after `flash`, options included, goes to flash.py.
    p = sub.add_parser("flash", prefix_chars="+", add_help=False,
                       help="compile mavstack for a board and copy it over (see mavctl flash -h)")
    p.add_argument("flash_args", nargs=argparse.REMAINDER)
    p.set_defaults(func=run_flash)
