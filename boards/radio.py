"""Settings shared by the boards that fly on a 57600 baud telemetry radio (pico, esp32,
pyboard): the application's parameters and the streams sent without being asked."""
from mavstack.services.params import UINT8, INT32, REAL32, READ_ONLY

PARAMS = (
    ("MAV_SYS_ID", UINT8, 1, 1, 255, READ_ONLY),
    ("WP_ACCEPT_RAD", REAL32, 2.0, 0.1, 100.0),
    ("WP_SPEED", REAL32, 2.0, 0.1, 20.0),
    ("BATT_CAPACITY", INT32, 2200, 0, 1000000),
    ("BATT_LOW_VOLT", REAL32, 10.5, 0.0, 60.0),
    ("FS_GCS_ENABLE", UINT8, 1, 0, 5),
    ("FS_GCS_TIMEOUT", REAL32, 5.0, 1.0, 120.0),
)
PARAM_ENCODING = "bytewise"
PARAM_AUTOSAVE_MS = 2000  # flash: save shortly after the last change
PARAM_SYSID = "MAV_SYS_ID"


# streams
# (message id, Hz) sent without being asked, sized for a 57600 baud radio (5760 B/s);
# ground stations change them with SET_MESSAGE_INTERVAL or REQUEST_DATA_STREAM.
DEFAULT_STREAMS = (
    (1, 1),  # SYS_STATUS
    (42, 1),  # MISSION_CURRENT
    (24, 1),  # GPS_RAW_INT
    (30, 4),  # ATTITUDE
    (33, 2),  # GLOBAL_POSITION_INT
    (74, 2),  # VFR_HUD
    (147, 0.5),  # BATTERY_STATUS
    (245, 0.5),  # EXTENDED_SYS_STATE
    (242, 0.2),  # HOME_POSITION
)
