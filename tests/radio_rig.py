"""A telemetry radio between the unix vehicle and a ground station, for radio flow control
(link.py, docs/routing.md): what the test and the benchmark of it share.

RadioBuffer models a SiK radio on the vehicle's side: the vehicle writes to it at its
serial rate (the vehicle's link budget, 57600 baud: 5760 B/s); its transmit buffer
(BUFFER bytes) empties over the air at AIR_BYTES_PER_S, less than the serial port can
feed it (the air also carries the radio's framing and the other way's slots); a frame
that does not fit in the buffer is lost (overflow). Once a second it sends the vehicle a
RADIO_STATUS (system 51, component 68) with txbuf, the buffer's free space in percent.
Frames from the ground station pass at once.

session(vehicle, seconds, flow) runs a ground station through it: the default streams,
then, over and over until `seconds` have passed, a full parameter download and a
100-item mission download -> the figures (overflow frames, downloads done, LINK_FLOW seen).
"""
import time

from pymavlink import mavutil
from pymavlink.dialects.v20 import common as mav2

from mission_gcs import MissionClient, plan
from relay import TO_GCS, Relay

SERIAL_BYTES_PER_S = 5760  # 57600 baud, 8N1
AIR_BYTES_PER_S = 3500
BUFFER = 2048


class RadioBuffer(Relay):
    def __init__(self, vehicle_port, air=AIR_BYTES_PER_S, buffer=BUFFER):
        self.air = float(air)
        self.buffer = buffer
        self.free_at = 0.0  # when the air has sent all that is in the buffer
        self.frames = 0
        self.overflow = 0
        self.lowest_txbuf = 100
        self.status = mav2.MAVLink(None, srcSystem=51, srcComponent=68)
        self._next_status = time.time() + 1.0
        Relay.__init__(self, vehicle_port)

    def backlog(self, now):
        return max(0.0, self.free_at - now) * self.air

    def forward(self, way, sock, data, addr):
        if way != TO_GCS:
            self.send(sock, data, addr)
            return
        now = time.time()
        self.frames += 1
        if self.backlog(now) + len(data) > self.buffer:
            self.overflow += 1
            return
        self.free_at = max(now, self.free_at) + len(data) / self.air
        self.deliver(self.free_at, sock, data, addr)

    def txbuf(self, now):
        return int(100 * (self.buffer - self.backlog(now)) / self.buffer)

    def tick(self, now):
        if now < self._next_status:
            return
        self._next_status += 1.0
        txbuf = self.txbuf(now)
        self.lowest_txbuf = min(self.lowest_txbuf, txbuf)
        msg = mav2.MAVLink_radio_status_message(180, 170, txbuf, 40, 45, 0, 0)
        self.send(self.veh_sock, bytes(msg.pack(self.status)), self.vehicle)


def params(m, timeout=20.0):
    """A full parameter download as ground stations do it: the list, then the missing
    ones by index -> parameters received (None if it did not complete)."""
    m.mav.param_request_list_send(1, 1)
    got, count = set(), None
    deadline = time.time() + timeout
    quiet = time.time()
    while time.time() < deadline:
        msg = m.recv_match(type="PARAM_VALUE", blocking=True, timeout=0.2)
        if msg is not None:
            count = msg.param_count
            got.add(msg.param_index)
            quiet = time.time()
            if len(got) == count:
                return count
        elif count is not None and time.time() - quiet > 1.0:
            for i in sorted(set(range(count)) - got)[:20]:
                m.mav.param_request_read_send(1, 1, b"", i)
            quiet = time.time()
    return None


def session(vehicle, seconds, items=100):
    vport = vehicle.port
    radio = RadioBuffer(vport)
    m = None
    try:
        m = mavutil.mavlink_connection("udpout:127.0.0.1:%d" % radio.port, source_system=255,
                                       source_component=190, dialect="common")
        deadline = time.time() + 20
        while m.recv_match(type="HEARTBEAT", blocking=True, timeout=0.5) is None:
            m.mav.heartbeat_send(6, 8, 0, 0, 0)
            assert time.time() < deadline, "no HEARTBEAT through the radio"
        c = MissionClient(m, timeout=1.5, retries=20)
        assert c.upload(plan(items)) == 0, "mission upload"
        flows = []
        # The flow the vehicle reports (LINK_FLOW), seen among what the downloads read.
        def watch(msg):
            if msg.get_type() == "NAMED_VALUE_INT" and msg.name == "LINK_FLOW":
                flows.append(msg.value)
        m.message_hooks.append(lambda _m, msg: watch(msg))
        start_frames, start_overflow = radio.frames, radio.overflow
        downloads = {"params": 0, "missions": 0, "failed": 0}
        end = time.time() + seconds
        while time.time() < end:
            m.mav.heartbeat_send(6, 8, 0, 0, 0)
            if params(m):
                downloads["params"] += 1
            else:
                downloads["failed"] += 1
            m.mav.heartbeat_send(6, 8, 0, 0, 0)
            got = c.download()
            if got is not None and len(got) == items:
                downloads["missions"] += 1
            else:
                downloads["failed"] += 1
        vehicle.check_alive()
        return dict(downloads, frames=radio.frames - start_frames, overflow=radio.overflow - start_overflow,
                    lowest_txbuf=radio.lowest_txbuf, flow_min=min(flows) if flows else 100,
                    flow_reports=len(flows))
    finally:
        if m is not None:
            m.close()
        radio.close()
