"""Raspberry Pi Pico (RP2040): telemetry radio on UART0 (GP0 TX, GP1 RX), files on littlefs."""
NAME = "pico"
DIALECT = "common"
SYSID = 1
COMPID = 1
MAV_TYPE = 10  # MAV_TYPE_GROUND_ROVER
MAV_AUTOPILOT = 0
SERVICES = ("status", "params", "commands", "missions", "streams")
STORAGE = "/data"
UART_ID = 0
UART_TX = 0
UART_RX = 1
BAUD = 57600
MISSION_CAPACITY = 200
FENCE_CAPACITY = 50
RALLY_CAPACITY = 10
OPERATOR_PASSKEY = None
GCS_TIMEOUT_MS = 5000
WATCHDOG_MS = 2000  # machine.WDT: at most 8388 ms on the RP2040
RAM_BUDGET = 128 * 1024  # of the ~190 KB heap MicroPython leaves on the RP2040


def transports():
    from machine import UART, Pin
    from mavstack.transport.serial import UartTransport

    uart = UART(UART_ID, BAUD, tx=Pin(UART_TX), rx=Pin(UART_RX), txbuf=1024, rxbuf=1024, timeout=0)
    return [UartTransport(uart, BAUD, "uart0")]


def reset():
    import machine

    machine.reset()


def watchdog(ms):
    """machine.WDT, fed by the poll loop; once started it cannot be stopped. None on a
    port without it (the unix port, where tests/test_boards.py tries every profile)."""
    try:
        from machine import WDT
    except ImportError:
        return None
    return WDT(timeout=ms)


# parameters and default streams for a 57600 baud radio
BOARD_MODULES = ("radio",)  # frozen with the profile (firmware/manifest.py)
from radio import PARAMS, PARAM_ENCODING, PARAM_AUTOSAVE_MS, PARAM_SYSID, DEFAULT_STREAMS  # noqa: E402,F401
