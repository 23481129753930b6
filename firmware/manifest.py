# MicroPython freezing manifest: main.py, one board profile and the part of mavstack that
# board uses (its SERVICES, what they import, its dialect), compiled into the firmware
# image, so their code runs from flash and leaves the heap to data.
#
#   MAVSTACK_BOARD=pico make -C ports/rp2 BOARD=RPI_PICO FROZEN_MANIFEST=$PWD/firmware/manifest.py
#
# or from a manifest of your own: include("/path/to/mavstack/firmware/manifest.py", board="pico").
# Options (include() keywords, or MAVSTACK_<NAME> in the environment): board (the profile
# in boards/), services (instead of the profile's SERVICES: names, comma separated, or
# "all"), native (0: no viper kernels), meta (1: the dialect's names too), opt (mpy-cross -O).
# The list of modules: host_tools/stack_files.py. Reference: docs/core.md.
import os
import sys
import tempfile

_env = os.environ.get
options.defaults(board=_env("MAVSTACK_BOARD"), services=_env("MAVSTACK_SERVICES"),
                 native=_env("MAVSTACK_NATIVE", "1") != "0", meta=_env("MAVSTACK_META", "0") != "0",
                 opt=int(_env("MAVSTACK_OPT", "0")))
if not options.board:
    raise ValueError("say which board profile to freeze: MAVSTACK_BOARD=NAME (see boards/)")

_root = os.path.dirname(os.path.abspath("manifest.py"))  # include() runs us from firmware/
_boards = os.path.join(_root, "..", "boards")
sys.path.insert(0, os.path.join(_root, "..", "host_tools"))
import stack_files  # noqa: E402

_profile = os.path.join(_boards, options.board + ".py")
if not os.path.exists(_profile):
    raise ValueError("no board profile " + _profile)
_settings = stack_files.profile(options.board)
_services = options.services or _settings.get("SERVICES")
if _services is None:
    raise ValueError("boards/%s.py: no SERVICES this manifest can read (a tuple of names): "
                     "give services=" % options.board)
if _services == "all":
    _services = stack_files.service_names()
elif isinstance(_services, str):
    _services = [s.strip() for s in _services.split(",") if s.strip()]

# The profile and the board modules it imports (boards/NAME.py says which, in BOARD_MODULES).
_board_modules = [options.board] + list(_settings.get("BOARD_MODULES", ()))
for _mod in _board_modules:
    module(_mod + ".py", base_path=_boards, opt=options.opt)
module("main.py", base_path=_root, opt=options.opt)
_roots = [os.path.join(_root, "main.py")] + [os.path.join(_boards, m + ".py") for m in _board_modules]
for _rel in stack_files.stack_modules(_services, _settings.get("DIALECT", "common"), _roots,
                                      options.native, options.meta):
    module(_rel, base_path=_root, opt=options.opt)

# `import board` finds the profile, as on a board where flash copies it as board.py: the
# profile itself under that name too (not a module importing it: its globals, in the
# heap, would be there twice).
_alias = tempfile.mkdtemp(prefix="mavstack-board-")
with open(_profile) as _src, open(os.path.join(_alias, "board.py"), "w") as _f:
    _f.write(_src.read())
module("board.py", base_path=_alias)
