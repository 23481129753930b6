"""The camera service: a camera component as ground stations and autopilots find and
drive it. It answers the discovery QGroundControl and ArduPilot perform
(REQUEST_MESSAGE, or the older REQUEST_CAMERA_INFORMATION / _SETTINGS, for
CAMERA_INFORMATION then CAMERA_SETTINGS), CAMERA_CAPTURE_STATUS and
STORAGE_INFORMATION (one storage, not supported), and takes images on
IMAGE_START_CAPTURE (one, a number, or until IMAGE_STOP_CAPTURE, at an interval): each
is the application's capture(index) -> True when taken, announced with
CAMERA_IMAGE_CAPTURED on every link after the command's ACK. Settings: CAMERA_VENDOR,
CAMERA_MODEL, CAMERA_RESOLUTION, CAMERA_FOCAL_MM, CAMERA_SENSOR_MM.
Reference: docs/services/peripheral.md#camera
"""
from struct import pack_into

from ..compat import const, ticks_diff, ticks_add
from ..kernels import copy, zero

NEEDS = ("commands",)

_MSG_CAMERA_INFORMATION = const(259)
_MSG_CAMERA_SETTINGS = const(260)
_MSG_STORAGE_INFORMATION = const(261)
_MSG_CAMERA_CAPTURE_STATUS = const(262)
_MSG_CAMERA_IMAGE_CAPTURED = const(263)
_CMD_REQUEST_CAMERA_INFORMATION = const(521)
_CMD_REQUEST_CAMERA_SETTINGS = const(522)
_CMD_REQUEST_STORAGE_INFORMATION = const(525)
_CMD_REQUEST_CAMERA_CAPTURE_STATUS = const(527)
_CMD_IMAGE_START_CAPTURE = const(2000)
_CMD_IMAGE_STOP_CAPTURE = const(2001)
_ACCEPTED = const(0)
_TEMPORARILY_REJECTED = const(1)
_DENIED = const(2)
_CAP_CAPTURE_IMAGE = const(2)  # CAMERA_CAP_FLAGS
_INFO_LEN = const(237)
_SETTINGS_LEN = const(14)
_STATUS_LEN = const(23)
_STORAGE_LEN = const(61)
_STORAGE_NOT_SUPPORTED = const(3)  # STORAGE_STATUS
_CAPTURED_LEN = const(255)


class Camera:
    NAME = "camera"

    def __init__(self, vendor="mavstack", model="camera", resolution=(1920, 1080), focal_mm=4.0,
                 sensor_mm=(6.2, 4.6)):
        self.capture = None  # the application's capture(index) -> True when the image was taken
        self.images = 0  # images taken (image_index of the next is this)
        self.interval_ms = 0  # capturing at an interval, 0: not
        self.left = 0  # images still to take at the interval, -1: until stopped
        self._next = 0
        self._announce = 0  # CAMERA_IMAGE_CAPTURED owed (the last image's) after the ACK
        self._interval = bytearray(4)  # the interval's float32, as IMAGE_START_CAPTURE sent it
        self._info = bytearray(_INFO_LEN)
        pack_into("<IIfffIHHH", self._info, 0, 0, 0, focal_mm, sensor_mm[0], sensor_mm[1],
                  _CAP_CAPTURE_IMAGE, resolution[0], resolution[1], 0)
        _text(self._info, 30, vendor, 32)
        _text(self._info, 62, model, 32)
        self._settings = bytearray(_SETTINGS_LEN)
        pack_into("<IBff", self._settings, 0, 0, 0, -1.0, -1.0)  # image mode; zoom, focus unknown
        self._captured = bytearray(_CAPTURED_LEN)
        pack_into("<f", self._captured, 28, 1.0)  # q = (1, 0, 0, 0): not known
        self._captured[48] = 1  # camera_id (deprecated; 1 as the first camera)

    def attach(self, ep):
        self.ep = ep
        for msgid, send in ((_MSG_CAMERA_INFORMATION, self.send_information),
                            (_MSG_CAMERA_SETTINGS, self.send_settings),
                            (_MSG_CAMERA_CAPTURE_STATUS, self.send_capture_status),
                            (_MSG_STORAGE_INFORMATION, self.send_storage),
                            (_MSG_CAMERA_IMAGE_CAPTURED, self.send_captured)):
            if ep.has(msgid):
                ep.producers[msgid] = send
        commands = ep.commands
        commands[_CMD_IMAGE_START_CAPTURE] = self._start
        commands[_CMD_IMAGE_STOP_CAPTURE] = self._stop
        commands[_CMD_REQUEST_CAMERA_INFORMATION] = self._request_information
        commands[_CMD_REQUEST_CAMERA_SETTINGS] = self._request_settings
        commands[_CMD_REQUEST_CAMERA_CAPTURE_STATUS] = self._request_status
        commands[_CMD_REQUEST_STORAGE_INFORMATION] = self._request_storage

    # --- commands -------------------------------------------------------------------------
    def _request_information(self, cmd):
        return self._reply(cmd, _MSG_CAMERA_INFORMATION)

    def _request_settings(self, cmd):
        return self._reply(cmd, _MSG_CAMERA_SETTINGS)

    def _request_status(self, cmd):
        return self._reply(cmd, _MSG_CAMERA_CAPTURE_STATUS)

    def _request_storage(self, cmd):
        return self._reply(cmd, _MSG_STORAGE_INFORMATION)

    def _reply(self, cmd, msgid):
        # param1: 0 no action, 1 send it
        if cmd.finite(1) and cmd.int(1) == 0:
            return _ACCEPTED
        if msgid not in self.ep.producers:
            return _DENIED
        cmd.reply = msgid
        return _ACCEPTED

    def _start(self, cmd):
        # param2: interval (s), param3: total images (0: until stopped), param4: sequence.
        # Read without floats (a float is a heap object on MicroPython).
        o = cmd._offset(2)
        p = cmd.payload
        ms = _ms(p, o) if cmd.finite(2) else 0
        total = cmd.int(3) if cmd.finite(3) else 1
        if p[o + 3] & 0x80 and ms or total < 0 or (total != 1 and ms <= 0):
            return _DENIED
        if self.interval_ms:
            return _TEMPORARILY_REJECTED  # capturing already: stop first
        if not self._shoot():
            return _TEMPORARILY_REJECTED
        if total != 1:
            self.interval_ms = ms
            copy(self._interval, p, o << 10, 4)  # for CAMERA_CAPTURE_STATUS, as sent
            self.left = total - 1 if total else -1
            self._next = ticks_add(self.ep.now, ms)
        return _ACCEPTED

    def _stop(self, cmd):
        self.interval_ms = 0
        self.left = 0
        zero(self._interval, 0, 4)
        return _ACCEPTED

    def _shoot(self):
        """Take image number self.images -> taken; announced on the next tick (after the ACK)."""
        taken = self.capture(self.images) if self.capture is not None else True
        self._captured[49] = 1 if taken else 0  # capture_result
        pack_into("<i", self._captured, 44, self.images)
        if taken:
            self.images += 1
        self._announce = 1
        return taken

    # --- periodic work -------------------------------------------------------------------
    def tick(self, now):
        if self._announce:
            self._announce = 0
            self._all(_MSG_CAMERA_IMAGE_CAPTURED)
        if self.interval_ms and ticks_diff(now, self._next) >= 0:
            self._next = ticks_add(self._next, self.interval_ms)
            self._shoot()
            if self.left > 0:
                self.left -= 1
                if self.left == 0:
                    self.interval_ms = 0

    def _all(self, msgid):
        send = self.ep.producers.get(msgid)
        links = self.ep.links
        i = 0  # by index: see docs/design.md
        while send is not None and i < len(links):
            send(links[i])
            i += 1

    # --- producers: send(link) -> bool ----------------------------------------------------
    def send_information(self, link):
        self.ep.clock.stamp_ms(self._info, 0)
        return link.send_payload(_MSG_CAMERA_INFORMATION, self._info, _INFO_LEN)

    def send_settings(self, link):
        self.ep.clock.stamp_ms(self._settings, 0)
        return link.send_payload(_MSG_CAMERA_SETTINGS, self._settings, _SETTINGS_LEN)

    def send_capture_status(self, link):
        off = link.tx.clear(_STATUS_LEN)
        buf = link.txbuf
        self.ep.clock.stamp_ms(buf, off)
        copy(buf, self._interval, off + 4, 4)  # (from 0)  # image_interval
        buf[off + 16] = 3 if self.interval_ms else 0  # image_status: interval capturing, or idle
        pack_into("<i", buf, off + 18, self.images)
        return link.send(_MSG_CAMERA_CAPTURE_STATUS)

    def send_storage(self, link):
        # One storage, "not supported": where the images go is the application's business.
        off = link.tx.clear(_STORAGE_LEN)
        buf = link.txbuf
        self.ep.clock.stamp_ms(buf, off)
        buf[off + 24] = 1  # storage_id
        buf[off + 25] = 1  # storage_count
        buf[off + 26] = _STORAGE_NOT_SUPPORTED
        return link.send(_MSG_STORAGE_INFORMATION)

    def send_captured(self, link):
        p = self._captured
        self.ep.clock.stamp_unix(p, 0)
        self.ep.clock.stamp_ms(p, 8)
        return link.send_payload(_MSG_CAMERA_IMAGE_CAPTURED, p, _CAPTURED_LEN)


def _ms(p, o):
    """The float32 of seconds at p[o] -> whole ms (its sign ignored; rounded, at most
    1000 s), in small ints: 16 bits of mantissa, times 1000, shifted."""
    e = (p[o + 3] & 0x7F) << 1 | p[o + 2] >> 7
    if e == 0:
        return 0
    v = (((p[o + 2] & 0x7F) | 0x80) << 8 | p[o + 1]) * 1000  # mantissa * 2^15, below 2^26
    s = e - 142  # value = mantissa * 2^(e - 127 - 15)
    if s > 4:
        return 1000000
    v = v << s if s >= 0 else ((v + (1 << (-s - 1))) >> -s if s > -31 else 0)  # rounded
    return v if v < 1000000 else 1000000


def _text(buf, off, s, n):
    raw = s.encode() if isinstance(s, str) else bytes(s)
    raw = raw[:n]
    buf[off:off + len(raw)] = raw


def create(ep):
    return ep.add(Camera(ep.setting("CAMERA_VENDOR", "mavstack"), ep.setting("CAMERA_MODEL", "camera"),
                         ep.setting("CAMERA_RESOLUTION", (1920, 1080)), ep.setting("CAMERA_FOCAL_MM", 4.0),
                         ep.setting("CAMERA_SENSOR_MM", (6.2, 4.6))))
