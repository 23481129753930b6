"""Emulated Cortex-M0 board (the RP2040's core family): MicroPython's qemu port on
QEMU's micro:bit with flash raised to 1 MB and RAM to 256 KB; no native emitter, so
the portable kernels. One UART: the REPL until the vehicle starts, MAVLink after.
Built and run by mcu/firmware.py; settings shared with qemu_m3 in boards/qemu.py."""
NAME = "qemu_m0"
BOARD_MODULES = ("qemu", "qemu_params_block")  # frozen with the profile (firmware/manifest.py)
STORAGE = "ram"
STORAGE_REGION = (0x2002C000, 0x10000)  # 64 KB between the firmware's RAM and the stack
MPY_ARCH = "armv6m"  # mpy-cross -march for this CPU (mavctl flash)
MACHINE = "nRF51"  # in the firmware's sys.implementation._machine: flash refuses other boards
RAM_BUDGET = 60 * 1024  # measured (make bench): 56.2 KB held; the board tests run in a 60 KB heap

from qemu import *  # noqa: E402,F401,F403


def storage():
    import qemu

    return qemu.storage(*STORAGE_REGION)
