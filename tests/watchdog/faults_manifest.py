# The firmware of tests/test_mcu_watchdog.py: the emulated M3's (firmware/manifest.py,
# which it follows), with tests/watchdog/board.py as the profile frozen as `board` and
# faults.py beside it. Not named manifest.py: mcu/firmware.py builds a manifest in a
# build directory named after it, and tests/mcu/manifest.py's would be this one's, where
# its own board.mpy (the frozen profile) could pass for this one's.
package("mavstack", base_path="../../firmware")
module("main.py", base_path="../../firmware")
for _name in ("qemu_m3.py", "qemu.py", "qemu_params_block.py"):
    module(_name, base_path="../../boards")
module("board.py")
module("faults.py")
module("faulty_params_block.py")  # (its readable table, faulty_params.py, stays on the host)
