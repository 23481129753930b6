"""Emulated Cortex-M3 board: MicroPython's qemu port on QEMU's MPS2-AN385 (native
emitter, so the viper kernels), 4 MB of RAM. REPL on UART 0, MAVLink on UART 1 (QEMU's
second -serial). Built and run by mcu/firmware.py; settings shared with qemu_m0 in
boards/qemu.py."""
NAME = "qemu_m3"
BOARD_MODULES = ("qemu", "qemu_params_block")  # frozen with the profile (firmware/manifest.py)
STORAGE = "ram"
STORAGE_REGION = (0x00200000, 0x80000)  # 512 KB of RAM above the firmware's, below the stack
# The filesystem of the firmware `mavctl flash` writes to (mcu/boot_fs.py mounts it at /flash)
FS_REGION = (0x00280000, 0x100000)  # 1 MB above the storage region
# A RAM word kept through a reset: set while the watchdog runs, it makes the firmware
# start main.py again after the reset (mcu/firmware.py builds that in).
RESTART_WORD = 0x00380000  # above the filesystem's region
WATCHDOG_MS = 2000  # the CMSDK watchdog resets the board when the loop stops this long
MPY_ARCH = "armv7m"  # mpy-cross -march for this CPU (mavctl flash)
MACHINE = "Cortex-M3"  # in the firmware's sys.implementation._machine: flash refuses other boards
RAM_BUDGET = 60 * 1024  # measured (make bench): 56.6 KB held; the board tests run in a 60 KB heap

from qemu import *  # noqa: E402,F401,F403


def storage():
    import qemu

    return qemu.storage(*STORAGE_REGION)


def watchdog(ms):
    """The CMSDK APB watchdog (mavstack/qemu.py), or None where there is none: on the
    unix port, or when its reset is latched (docs/reliability.md)."""
    import sys

    if sys.platform != "qemu":
        return None
    from mavstack.qemu import Watchdog, latched

    if latched():
        print("mavstack: the watchdog's reset is latched (an idle REPL): no watchdog until a reset")
        return None
    return Watchdog(ms, RESTART_WORD)
