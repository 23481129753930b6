"""The simulated vehicle behind boards/unix.py: a simple kinematic model that flies
the mission in AUTO mode and feeds telemetry, so a ground station sees a live vehicle.

It is an application like any other: it reads and writes the endpoint's services
and allocates freely (it stands in for real sensors and control code).
"""
import math

from mavstack.compat import ticks_diff

HOME_LAT = 47.397742  # a field where ground stations' maps have tiles
HOME_LON = 8.545594
HOME_ALT = 488.0
EARTH_RADIUS = 6378137.0


class Simulator:
    def __init__(self, endpoint):
        self.ep = endpoint
        self.lat = HOME_LAT
        self.lon = HOME_LON
        self.alt = HOME_ALT  # metres above mean sea level
        self.vn = 0.0  # north, east, down speeds (m/s)
        self.ve = 0.0
        self.vd = 0.0
        self.heading = 0.0  # radians
        self.roll = 0.0
        self.pitch = 0.0
        self.throttle = 0.0  # 0..1
        self.battery_v = 12.6
        self.battery_remaining = 100.0  # percent
        self._last = None

    def tick(self, now):
        if self._last is None:
            self._last = now
            return
        dt = ticks_diff(now, self._last) / 1000.0
        if dt < 0.02:
            return
        self._last = now
        self.fly(dt)
        self.publish(now)

    def fly(self, dt):
        """Advance the model: in AUTO and armed, fly toward the current mission item."""

    def publish(self, now):
        """Write the model's state into the telemetry slots."""

    def move(self, dn, de, dd):
        """Move by metres north, east and down."""
        self.lat += math.degrees(dn / EARTH_RADIUS)
        self.lon += math.degrees(de / (EARTH_RADIUS * math.cos(math.radians(self.lat))))
        self.alt -= dd
