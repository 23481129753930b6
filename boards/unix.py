"""The simulated vehicle: MicroPython's unix port, UDP (or pty) links, files on disk.

    .venv/bin/micropython firmware/main.py --board unix --link udpout:127.0.0.1:14550
"""
NAME = "unix"
DIALECT = "common"
SYSID = 1
COMPID = 1
MAV_TYPE = 2  # MAV_TYPE_QUADROTOR
MAV_AUTOPILOT = 0  # MAV_AUTOPILOT_GENERIC
SERVICES = ("status", "params", "commands", "missions", "streams")
STORAGE = __file__.rsplit("/", 2)[0] + "/storage"
LINKS = ("udpout:127.0.0.1:14550",)
UDP_BYTES_PER_S = 200000
MISSION_CAPACITY = 500
FENCE_CAPACITY = 100
RALLY_CAPACITY = 20
OPERATOR_PASSKEY = None  # a string makes CHANGE_OPERATOR_CONTROL required to take control
GCS_TIMEOUT_MS = 5000
# Modes (mavstack/services/status.py): custom modes the simulator flies, each with the
# MAV_MODE_FLAG bits it sets, numbered as ground stations name them for a multicopter
# (MAVProxy's `mode AUTO`, `mode LOITER`). Any other custom mode is refused.
CUSTOM_MODES = (
    (3, "AUTO", 16 | 4),  # STABILIZE | AUTO: flies the mission while armed
    (5, "LOITER", 16),  # STABILIZE: holds where it is
)
RAM_BUDGET = 256 * 1024  # heap the vehicle may hold after start-up (main.py reports it)


def transports():
    from mavstack.transport import open_transport

    return [open_transport(spec, UDP_BYTES_PER_S) for spec in LINKS]


def application(endpoint):
    from simulator import Simulator

    return Simulator(endpoint)


# params
from unix_params import PARAMS  # noqa: E402  (the table: boards/unix_params.py)

PARAM_ENCODING = "auto"  # integers in param_value: "auto" (each link as its ground station assumes), "bytewise" or "c_cast"
PARAM_AUTOSAVE_MS = 2000  # save this long after the last change (0: on PREFLIGHT_STORAGE only)
PARAM_SYSID = "MAV_SYS_ID"  # the read-only parameter that shows the system id


# streams
# (message id, Hz) sent on every link without being asked: QGroundControl and MAVSDK
# never send REQUEST_DATA_STREAM to a generic autopilot. Ground stations change them
# with MAV_CMD_SET_MESSAGE_INTERVAL or REQUEST_DATA_STREAM (mavstack/services/streams.py).
# HEARTBEAT comes from the status service once a second.
DEFAULT_STREAMS = (
    (1, 1),  # SYS_STATUS
    (42, 1),  # MISSION_CURRENT
    (2, 1),  # SYSTEM_TIME
    (24, 2),  # GPS_RAW_INT
    (30, 10),  # ATTITUDE
    (31, 10),  # ATTITUDE_QUATERNION
    (33, 5),  # GLOBAL_POSITION_INT
    (32, 5),  # LOCAL_POSITION_NED
    (74, 4),  # VFR_HUD
    (62, 2),  # NAV_CONTROLLER_OUTPUT
    (65, 2),  # RC_CHANNELS
    (36, 2),  # SERVO_OUTPUT_RAW
    (147, 1),  # BATTERY_STATUS
    (245, 1),  # EXTENDED_SYS_STATE
    (242, 0.5),  # HOME_POSITION
)


# missions (capacities above; mavstack/services/missions.py, mission_runner.py)
MISSION_FRAMES = (0, 2, 3, 5, 6)  # MAV_FRAMEs the simulator flies: global, mission, relative alt
MISSION_COMMANDS = ()  # MAV_CMDs the application flies beyond the seed's NAV/CONDITION/DO set
MISSION_RETRY_MS = 250  # re-request a missing item after this until the round trip is measured
MISSION_RETRIES = 5  # re-request time doublings without progress (--set mission_retries=N)
MISSION_TIMEOUT_MS = 5000  # give up (MISSION_ACK OPERATION_CANCELLED) after this without a new item
MISSION_JUMP_SLOTS = 16  # DO_JUMP items a mission may hold (one repeat counter each)
