"""mavstack as a distance-sensor peripheral on MicroPython's unix port (the settings and
the rangefinder application: boards/peripheral.py), on a pty or UDP link:

    .venv/bin/micropython firmware/main.py --board unix_peripheral --link serial:/dev/pts/N:115200
"""
NAME = "unix_peripheral"
BOARD_MODULES = ("peripheral",)
STORAGE = __file__.rsplit("/", 2)[0] + "/storage"
LINKS = ("udpout:127.0.0.1:14550",)
UDP_BYTES_PER_S = 200000
PARAM_AUTOSAVE_MS = 2000
RAM_BUDGET = 160 * 1024  # 64-bit pointers; measured in tests/test_boards.py
WATCHDOG_MS = 0

from peripheral import *  # noqa: E402,F401,F403


def transports():
    from mavstack.transport import open_transport

    return [open_transport(spec, UDP_BYTES_PER_S) for spec in LINKS]
