# MicroPython freezing manifest: mavstack, the program and one board profile, compiled
# into the firmware image, so their code runs from flash and leaves the heap to data.
#
#   MAVSTACK_BOARD=pico make -C ports/rp2 BOARD=RPI_PICO FROZEN_MANIFEST=$PWD/firmware/manifest.py
#
# or from a manifest of your own: include("/path/to/mavstack/firmware/manifest.py", board="pico").
# Options (include() keywords, or MAVSTACK_BOARD / MAVSTACK_NATIVE in the environment):
#   board   the profile in boards/ to freeze; it is importable as `board`, and main.py
#           (frozen as `main`) runs it at boot on ports that run main.py
#   native  0 leaves out the viper kernels, for ports built without the native emitter
#           (their code would not run there); the portable kernels are then used
# Reference: docs/core.md.
import os
import tempfile

options.defaults(board=os.environ.get("MAVSTACK_BOARD"), native=os.environ.get("MAVSTACK_NATIVE", "1") != "0")
if not options.board:
    raise ValueError("say which board profile to freeze: MAVSTACK_BOARD=NAME (see boards/)")

_root = os.path.dirname(os.path.abspath("manifest.py"))  # include() runs us from firmware/
_boards = os.path.join(_root, "..", "boards")

for _dir, _subdirs, _files in os.walk(os.path.join(_root, "mavstack")):
    _subdirs.sort()
    for _name in sorted(_files):
        if not _name.endswith(".py") or (_name.endswith("_viper.py") and not options.native):
            continue
        module(os.path.relpath(os.path.join(_dir, _name), _root), base_path=_root)
module("main.py", base_path=_root)

# The profile and the board modules it imports (boards/NAME.py says which, in BOARD_MODULES).
_profile = os.path.join(_boards, options.board + ".py")
if not os.path.exists(_profile):
    raise ValueError("no board profile " + _profile)
module(options.board + ".py", base_path=_boards)
with open(_profile) as _f:
    for _line in _f:
        if _line.startswith("BOARD_MODULES"):
            for _mod in eval(_line.split("=", 1)[1]):
                module(_mod + ".py", base_path=_boards)

# `import board` finds the profile, as on a board where flash copies it as board.py.
_alias = tempfile.mkdtemp(prefix="mavstack-board-")
with open(os.path.join(_alias, "board.py"), "w") as _f:
    _f.write("from %s import *  # noqa: F401,F403 (frozen by firmware/manifest.py)\n" % options.board)
module("board.py", base_path=_alias)
