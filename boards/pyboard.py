"""STM32 pyboard (PYBv1.1): telemetry radio on UART(4) (X1 TX, X2 RX), files on internal flash."""
NAME = "pyboard"
DIALECT = "common"
SYSID = 1
COMPID = 1
MAV_TYPE = 7  # MAV_TYPE_AIRSHIP (balloon-class payloads)
MAV_AUTOPILOT = 0
SERVICES = ("status", "params", "commands", "missions", "streams")
STORAGE = "/flash/data"
UART_ID = 4
BAUD = 57600
MISSION_CAPACITY = 200
FENCE_CAPACITY = 50
RALLY_CAPACITY = 10
OPERATOR_PASSKEY = None
GCS_TIMEOUT_MS = 5000
WATCHDOG_MS = 2000  # machine.WDT resets the board when the loop stops this long
RAM_BUDGET = 96 * 1024  # of the ~100 KB heap on the STM32F405


def transports():
    from machine import UART
    from mavstack.transport.serial import UartTransport

    uart = UART(UART_ID, BAUD, txbuf=1024, rxbuf=1024, timeout=0)
    return [UartTransport(uart, BAUD, "uart4")]


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
