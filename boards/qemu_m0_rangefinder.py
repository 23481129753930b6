"""The emulated Cortex-M0 (qemu_m0's machine and firmware build) as a distance-sensor
peripheral: boards/peripheral.py's settings and rangefinder application, its one UART
the REPL until the vehicle starts and MAVLink after, parameters in a RAM region, the
heap locked once it is up. Built and run by mcu/firmware.py; tests/test_mcu_peripheral.py.
"""
NAME = "qemu_m0_rangefinder"
BOARD_MODULES = ("peripheral",)  # frozen with the profile (firmware/manifest.py)
STORAGE = "ram"
STORAGE_REGION = (0x2002C000, 0x10000)  # as qemu_m0
MPY_ARCH = "armv6m"
MACHINE = "nRF51"
BAUD = 115200
HEAP_LOCK = True
PARAM_AUTOSAVE_MS = 0  # RAM storage: saved on PREFLIGHT_STORAGE only
RAM_BUDGET = 34 * 1024  # measured (make bench): 28 KB held, a 32 KB heap its smallest (the whole vehicle: 56 KB)

from peripheral import *  # noqa: E402,F401,F403


def storage():
    import sys
    from mavstack.storage_ram import RamStorage

    if sys.platform != "qemu":
        return RamStorage(bytearray(STORAGE_REGION[1]))
    import uctypes

    return RamStorage(uctypes.bytearray_at(*STORAGE_REGION))


def transports():
    from mavstack.qemu import UartTransport

    return [UartTransport(BAUD)]
