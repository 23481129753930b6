"""The simulated vehicle: MicroPython's unix port, UDP (or pty) links, files on disk.

    .venv/bin/micropython firmware/main.py --board unix --link udpout:127.0.0.1:14550
"""
NAME = "unix"
DIALECT = "common"
SYSID = 1
COMPID = 1
MAV_TYPE = 2  # MAV_TYPE_QUADROTOR
MAV_AUTOPILOT = 0  # MAV_AUTOPILOT_GENERIC
SERVICES = ("status", "params", "commands", "missions", "inputs", "seed_telemetry", "streams", "ftp",
            "geography", "servos", "debug", "auth", "calibration", "seed_commands")  # inputs before streams: its slots stream by default
STORAGE = __file__.rsplit("/", 2)[0] + "/storage"
# Several links (here, `--link` repeated, or `--set links=SPEC,SPEC`) are routed between
# (docs/routing.md): a ground station, a companion on a pty, a camera behind the vehicle.
LINKS = ("udpout:127.0.0.1:14550",)
ROUTES = 16  # the route table's size
ROUTE_TIMEOUT_MS = 10000  # a route not heard from this long is forgotten
PRIVATE_LINKS = ""  # link indexes nothing is forwarded to or from, "1,2"
UDP_BYTES_PER_S = 200000
MISSION_CAPACITY = 500
FENCE_CAPACITY = 100
RALLY_CAPACITY = 20
OPERATOR_PASSKEY = None  # a string makes CHANGE_OPERATOR_CONTROL required to take control
GCS_TIMEOUT_MS = 5000
# Modes (mavstack/services/status/modes.py): what the simulator flies, one row a mode:
# (number, name, MAV_MODE_FLAG bits, PX4 main mode, PX4 sub mode, MAV_STANDARD_MODE).
# Ground stations that assume ArduPilot (MAVProxy's `mode GUIDED`) read and set the
# number, ArduCopter's; MAVSDK reads and sets PX4's main/sub mode; modern ones may use
# the standard mode (MAV_CMD_DO_SET_STANDARD_MODE). ArduCopter takes off and follows
# setpoints in GUIDED, so TAKEOFF and OFFBOARD show as GUIDED (4) to the former.
FLIGHT_MODES = (
    (0, "STABILIZE", 64 | 16, 7, 0, 0),  # manual: MANUAL_CONTROL / RC sticks fly it (PX4: Stabilized; Manual is taken for it)
    (2, "ALT_HOLD", 64 | 16, 2, 0, 4),  # manual, altitude held (PX4: Altitude; standard ALTITUDE_HOLD)
    (16, "POSITION", 64 | 16, 3, 0, 1),  # manual, position held (ArduCopter POSHOLD; PX4 Position; POSITION_HOLD)
    (3, "AUTO", 16 | 4, 4, 4, 6),  # flies the mission (PX4 Mission; standard MISSION)
    (5, "LOITER", 16 | 4, 4, 3, 0),  # holds where it is (PX4 Hold: PX4's AUTO.LOITER asks for it)
    (4, "GUIDED", 16 | 8, 4, 3, 0),  # goes to a commanded point and holds (PX4 shows it as Hold)
    (6, "RTL", 16 | 4, 4, 5, 5),  # home at the return altitude, lands (standard SAFE_RECOVERY)
    (9, "LAND", 16 | 4, 4, 6, 7),  # lands here, disarms (standard LAND)
    (4, "TAKEOFF", 16 | 8 | 4, 4, 2, 8),  # climbs to the takeoff altitude, then LOITER (standard TAKEOFF)
    (4, "OFFBOARD", 16 | 8, 6, 0, 0),  # follows an offboard computer's setpoints
)
MODE_NUMBERING = "auto"  # per link, as its ground station reads modes (modes.py), or "ardupilot" / "px4"
# inputs (mavstack/services/inputs/)
INPUT_TIMEOUT_MS = 1000  # an input that stops this long is lost: on_input_lost (the simulator's failsafe)
RC_OVERRIDE_TIMEOUT_MS = 3000  # an RC override channel not set again this long goes back to the radio
RAM_BUDGET = 432 * 1024  # heap the vehicle may hold after start-up (main.py reports it): every service and the simulator (its flight modes, commands and failsafes ~40 KB), routing, 64-bit pointers
WATCHDOG_MS = 2000  # under host_tools/watchdog.py: it restarts the vehicle when the loop stops this long


def transports():
    from mavstack.transport import open_transport

    return [open_transport(spec, UDP_BYTES_PER_S) for spec in LINKS]


def watchdog(ms):
    """The unix port's watchdog is a process, host_tools/watchdog.py, which runs this
    vehicle and starts it again when it stops feeding; None without it (`make run`)."""
    from mavstack.compat import getenv

    port = getenv("MAVSTACK_WATCHDOG_PORT")
    if not port:
        return None
    from unix_watchdog import ProcessWatchdog  # only then (RAM)

    return ProcessWatchdog(int(port), ms)


def application(endpoint):
    from sim import Simulator
    from sim import seed as sim_seed

    sim = Simulator(endpoint)
    sim_seed.compose(endpoint, sim)  # calibration, video, debug values, state corrections
    return sim


# relays and servos (mavstack/services/servos.py): the motors are outputs 1-4, the
# servo table 5-16 (SERVO_OUTPUT_RAW shows both)
RELAYS = 4
SERVO_CHANNELS = (5, 16)
AUTH_KEY = None  # this vehicle's AUTH_KEY (services/auth.py; --set auth_key=...), sent only when signed


# params
from unix_params import PARAMS  # noqa: E402  (the table: boards/unix_params.py)

PARAM_ENCODING = "auto"  # integers in param_value: "auto" (each link as its ground station assumes), "bytewise" or "c_cast"
PARAM_AUTOSAVE_MS = 2000  # save this long after the last change (0: on PREFLIGHT_STORAGE only)
PARAM_SYSID = "MAV_SYS_ID"  # the read-only parameter that shows the system id


# streams
# (message id, Hz) sent on every link without being asked: QGroundControl and MAVSDK
# never send REQUEST_DATA_STREAM to a generic autopilot. Ground stations change them
# with MAV_CMD_SET_MESSAGE_INTERVAL or REQUEST_DATA_STREAM (mavstack/services/streams/).
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
    (83, 4),  # ATTITUDE_TARGET            (sent once a setpoint was taken)
    (85, 4),  # POSITION_TARGET_LOCAL_NED
    (87, 4),  # POSITION_TARGET_GLOBAL_INT
    (91, 10),  # HIL_CONTROLS              (while in HIL)
)


# missions (capacities above; mavstack/services/missions/)
MISSION_FRAMES = (0, 2, 3, 5, 6)  # MAV_FRAMEs the simulator flies: global, mission, relative alt
MISSION_COMMANDS = ()  # MAV_CMDs the application flies beyond the seed's NAV/CONDITION/DO set
MISSION_RETRY_MS = 250  # re-request a missing item after this until the round trip is measured
MISSION_RETRIES = 5  # re-request time doublings without progress (--set mission_retries=N)
MISSION_TIMEOUT_MS = 5000  # give up (MISSION_ACK OPERATION_CANCELLED) after this without a new item
MISSION_JUMP_SLOTS = 16  # DO_JUMP items a mission may hold (one repeat counter each)
