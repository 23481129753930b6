"""mavstack as a camera component on MicroPython's unix port: component 100
(MAV_COMP_ID_CAMERA), MAV_TYPE_CAMERA, the system id followed from the autopilot's
HEARTBEAT, found by the discovery ground stations and autopilots perform, taking (here:
counting) images on IMAGE_START_CAPTURE (mavstack/services/camera.py).

    .venv/bin/micropython firmware/main.py --board unix_camera --link serial:/dev/pts/N:115200
"""
from mavstack.services.params import REAL32

NAME = "unix_camera"
DIALECT = "common"
SYSID = "follow"
SYSID_WAIT_MS = 10000
SYSID_FALLBACK = 1
COMPID = 100  # MAV_COMP_ID_CAMERA
MAV_TYPE = 30  # MAV_TYPE_CAMERA
SERVICES = ("peripheral", "params", "commands", "camera")
ACK_UNSUPPORTED_BROADCAST = False
STORAGE = __file__.rsplit("/", 2)[0] + "/storage"
LINKS = ("udpout:127.0.0.1:14550",)
UDP_BYTES_PER_S = 200000
PARAM_ENCODING = "bytewise"
PARAM_AUTOSAVE_MS = 2000
PARAMS = (  # REAL32: the same under either integer encoding (docs/services/peripheral.md)
    ("CAM_QUALITY", REAL32, 90.0, 1.0, 100.0),  # JPEG quality, stored and served
    ("CAM_FAIL_EVERY", REAL32, 0.0, 0.0, 1000.0),  # every Nth capture fails (0: none), for testing
)
CAMERA_VENDOR = "mavstack"
CAMERA_MODEL = "unix camera"
CAMERA_RESOLUTION = (1920, 1080)
RAM_BUDGET = 180 * 1024
WATCHDOG_MS = 0


def transports():
    from mavstack.transport import open_transport

    return [open_transport(spec, UDP_BYTES_PER_S) for spec in LINKS]


class Shutter:
    """Takes no picture: counts them, and fails every CAM_FAIL_EVERY-th."""

    def __init__(self, ep):
        self.params = ep.services["params"]
        self.every = int(self.params.get("CAM_FAIL_EVERY"))  # read once, and on a change
        self.params.on_change = self._changed
        ep.services["camera"].capture = self.capture

    def _changed(self, name, value):
        if name == "CAM_FAIL_EVERY":
            self.every = int(value)

    def capture(self, index):
        return not (self.every and (index + 1) % self.every == 0)

    def tick(self, now):
        pass


def application(ep):
    return Shutter(ep)
