"""ESP32 DevKit: telemetry radio on UART2 (GPIO17 TX, GPIO16 RX), files on littlefs."""
NAME = "esp32"
DIALECT = "common"
SYSID = 1
COMPID = 1
MAV_TYPE = 11  # MAV_TYPE_SURFACE_BOAT
MAV_AUTOPILOT = 0
SERVICES = ("status", "params", "commands", "missions", "streams")
STORAGE = "/data"
UART_ID = 2
UART_TX = 17
UART_RX = 16
BAUD = 57600
MISSION_CAPACITY = 300
FENCE_CAPACITY = 50
RALLY_CAPACITY = 10
OPERATOR_PASSKEY = None
GCS_TIMEOUT_MS = 5000
RAM_BUDGET = 96 * 1024


def transports():
    from machine import UART
    from mavstack.transport import UartTransport

    uart = UART(UART_ID, BAUD, tx=UART_TX, rx=UART_RX, txbuf=1024, rxbuf=1024, timeout=0)
    return [UartTransport(uart, BAUD, "uart2")]


def reset():
    import machine

    machine.reset()


# params
from mavstack.services.params import UINT8, UINT16, INT32, REAL32, READ_ONLY  # noqa: E402

PARAMS = (
    ("MAV_SYS_ID", UINT8, 1, 1, 255, READ_ONLY),
    ("WP_ACCEPT_RAD", REAL32, 2.0, 0.1, 100.0),
    ("WP_SPEED", REAL32, 2.0, 0.1, 20.0),
    ("BATT_CAPACITY", INT32, 2200, 0, 1000000),
    ("BATT_LOW_VOLT", REAL32, 10.5, 0.0, 60.0),
    ("FS_GCS_ENABLE", UINT8, 1, 0, 5),
    ("FS_GCS_TIMEOUT", REAL32, 5.0, 1.0, 120.0),
    ("SR0_POSITION", UINT16, 2, 0, 20),
    ("SR0_EXT_STAT", UINT16, 1, 0, 20),
)
PARAM_ENCODING = "bytewise"
PARAM_AUTOSAVE_MS = 2000  # flash: save shortly after the last change
PARAM_SYSID = "MAV_SYS_ID"


# streams
# (message id, Hz) sent without being asked, sized for a 57600 baud radio (5760 B/s);
# ground stations change them with SET_MESSAGE_INTERVAL or REQUEST_DATA_STREAM.
DEFAULT_STREAMS = (
    (1, 1),  # SYS_STATUS
    (24, 1),  # GPS_RAW_INT
    (30, 4),  # ATTITUDE
    (33, 2),  # GLOBAL_POSITION_INT
    (74, 2),  # VFR_HUD
    (147, 0.5),  # BATTERY_STATUS
    (245, 0.5),  # EXTENDED_SYS_STATE
    (242, 0.2),  # HOME_POSITION
)
