# The test firmware: the board's frozen vehicle (firmware/manifest.py) with every
# service, not only the board's (the scripts try them all), plus the libraries the
# MicroPython-side test scripts import (tests/mpy/harness.py, wire_kinds.py); the
# scripts themselves are sent over the raw REPL (tests/mcu_rig.py).
include("../../firmware/manifest.py", services="all")
module("harness.py", base_path="../mpy")
module("wire_kinds.py", base_path="../mpy")
# The unix vehicle's table of rows, which params_steady.py declares (the boards freeze
# their parameters as a block, qemu_params_block.py).
module("unix_params.py", base_path="../../boards")
