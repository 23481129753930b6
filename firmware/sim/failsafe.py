"""The simulated vehicle's failsafes: a lost pilot input (inputs.py reports it) or a lost
ground station (FS_GCS_ENABLE; a mission in AUTO flies on, as ArduPilot's "continue in
auto") puts the vehicle in LOITER at once and in RTL FS_HOLD_S seconds later, unless
the input comes back or a ground station picks another mode first. Reference:
docs/sim.md.
"""
from .commands import INFO, ON_GROUND, PILOT_MODES, WARNING


class Failsafe:
    """The hold before the return, for the flight pilot (pilot.py)."""

    def __init__(self, pilot):
        self.pilot = pilot
        self.left = None  # seconds of hold left before RTL (None: no return pending)
        self.reason = None
        self.mode = None  # the mode flown when the input was lost

    def trip(self, reason):
        """Hold at once, return FS_HOLD_S seconds later unless the input comes back."""
        pilot = self.pilot
        status = pilot.status
        if status is None or not status.armed or pilot.landed == ON_GROUND or pilot.mode in ("RTL", "LAND"):
            pilot.ep.statustext(WARNING, "Failsafe: " + reason)
            return
        hold = pilot.mission.setting(None, "FS_HOLD_S", 5.0)
        mode = pilot.mode
        pilot.set_mode("LOITER")
        self.left, self.reason, self.mode = hold, reason, mode
        pilot.ep.statustext(WARNING, "Failsafe: %s: holding, RTL in %.0f s" % (reason, hold))

    def clear(self, reason):
        """The lost input is back: no return after the hold."""
        if self.left is not None:
            self.left = None
            self.pilot.ep.statustext(INFO, "Failsafe: %s: holding here" % reason)

    def tick(self, dt):
        if self.left is None:
            return
        inputs = self.pilot.inputs
        if self.mode in PILOT_MODES and inputs is not None and inputs.demand(self.mode, 0.0) is not None:
            self.clear("input back")
            return
        self.left -= dt
        if self.left <= 0:
            self.left = None
            self.pilot.ep.statustext(WARNING, "Failsafe: %s: returning" % self.reason)
            self.pilot.set_mode("RTL")

    def gcs_lost(self, link):
        """status.on_gcs_lost: a failsafe once no ground station is left (FS_GCS_ENABLE)."""
        pilot = self.pilot
        pilot.ep.statustext(WARNING, "GCS lost on " + link.name)
        status = pilot.status
        for other in pilot.ep.links:
            if status.gcs_present(other):
                return  # another ground station is still there
        if pilot.mission.setting(None, "FS_GCS_ENABLE", 1.0) and pilot.mode != "AUTO":
            self.trip("GCS lost")

    def gcs_regained(self, link):
        self.pilot.ep.statustext(INFO, "GCS heard on " + link.name)
        if self.reason == "GCS lost":
            self.clear("GCS back")
