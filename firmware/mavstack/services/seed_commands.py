"""The seed's remaining MAV_CMDs, as immediate commands (COMMAND_LONG / COMMAND_INT).

OVERRIDE_GOTO (252) holds (LOITER) and continues (AUTO), a position inside the allowed
area going to the application's on_goto; NAV_ROI (80) is kept and handed to on_roi;
NAV_PATHPLANNING (81) and DO_CONTROL_VIDEO (200) go to the application (on_pathplanning,
on_video; UNSUPPORTED without). CONDITION_* (112-115) are mission items and the *_LAST
markers no commands: UNSUPPORTED, with a STATUSTEXT. Every command here that changes
the vehicle needs the sender in control. REASONS gives the coverage table's words for
the refused ones (host_tools/seed_coverage.py reads it).
Reference (each command's parameters): docs/services/seed.md.
"""
from ..compat import const
from ..kernels import copy
from ..statustext import WARNING

NEEDS = ("commands",)  # its commands
USES = ("status", "missions", "geography")

_ACCEPTED = const(0)
_DENIED = const(2)
_UNSUPPORTED = const(3)

_CMD_NAV_ROI = const(80)
_CMD_NAV_PATHPLANNING = const(81)
_CMD_NAV_LAST = const(95)
_CMD_CONDITION_LAST = const(159)
_CMD_DO_CONTROL_VIDEO = const(200)
_CMD_DO_LAST = const(240)
_CMD_OVERRIDE_GOTO = const(252)
_GOTO_DO_HOLD = const(0)
_GOTO_DO_CONTINUE = const(1)
_GOTO_HOLD_AT_CURRENT = const(2)
_GOTO_HOLD_AT_SPECIFIED = const(3)

MISSION_ONLY = (112, 113, 114, 115)
MARKERS = (_CMD_NAV_LAST, _CMD_CONDITION_LAST, _CMD_DO_LAST)
REASONS = {
    _CMD_NAV_LAST: "a marker (end of the NAV ids), not a command",
    _CMD_CONDITION_LAST: "a marker (end of the CONDITION ids), not a command",
    _CMD_DO_LAST: "a marker (end of the DO ids), not a command",
}
for _c in MISSION_ONLY:
    REASONS[_c] = "a mission item (the runner and the simulator carry it out); no mission step to hold as a command"


class SeedCommands:
    NAME = "seed_commands"
    CLOCK = False

    def __init__(self):
        self.on_goto = None
        self.on_roi = None
        self.on_pathplanning = None
        self.on_video = None
        self.roi = -1  # MAV_ROI of the last NAV_ROI, -1: none
        self.roi_params = bytearray(28)  # its param1-4, x, y, z as they came
        self.roi_int = False  # ... in COMMAND_INT's form (x, y int32)
        self.held = False

    def attach(self, ep):
        self.ep = ep
        # A service listed before this one that handles a command keeps it.
        for cmd, handler in ((_CMD_OVERRIDE_GOTO, self._goto), (_CMD_NAV_ROI, self._roi),
                             (_CMD_NAV_PATHPLANNING, self._pathplanning),
                             (_CMD_DO_CONTROL_VIDEO, self._video)):
            if cmd not in ep.commands:
                ep.commands[cmd] = handler
        for cmd in MISSION_ONLY:
            if cmd not in ep.commands:
                ep.commands[cmd] = self._mission_only
        for cmd in MARKERS:
            ep.commands[cmd] = self._marker

    def _allowed(self, cmd):
        if self.ep.allows(cmd.link):
            return True
        self.ep.statustext(WARNING, b"Command: GCS not in control")
        return False

    def _goto(self, cmd):
        if not cmd.finite(1) or cmd.int(1) not in (_GOTO_DO_HOLD, _GOTO_DO_CONTINUE):
            return _DENIED
        if not self._allowed(cmd):
            return _DENIED
        status = self.ep.services.get("status")
        if cmd.int(1) == _GOTO_DO_CONTINUE:
            self.held = False
            return self._mode(status, "AUTO", True)
        where = cmd.int(2) if cmd.finite(2) else _GOTO_HOLD_AT_CURRENT
        if where == _GOTO_HOLD_AT_SPECIFIED:
            if not self._inside(cmd):
                return _DENIED
            if self.on_goto is None:
                self.ep.statustext(WARNING, b"Goto: no guided flight to a position")
                return _UNSUPPORTED
            return self.on_goto(cmd)
        if where != _GOTO_HOLD_AT_CURRENT:
            return _DENIED
        self.held = True
        return self._mode(status, "LOITER", False)

    def _mode(self, status, name, run):
        # The board's mode for it, where it has one; else the mission runner alone.
        if status is not None and getattr(status, "modes", None) is not None and status.modes.by_name(name) >= 0:
            return status.set_flight_mode(name)
        missions = self.ep.services.get("missions")
        runner = getattr(missions, "runner", None)
        if runner is None:
            return _UNSUPPORTED
        if run:
            runner.run()
        else:
            runner.pause()
        return _ACCEPTED

    def _inside(self, cmd):
        geo = self.ep.services.get("geography")
        return geo is None or geo.allows_command(cmd, cmd.int(3) if cmd.finite(3) else 0)

    def _roi(self, cmd):
        if not cmd.finite(1) or not 0 <= cmd.int(1) <= 4:
            return _DENIED
        if not self._allowed(cmd):
            return _DENIED
        self.roi = cmd.int(1)
        self.roi_int = cmd.is_int
        copy(self.roi_params, cmd.payload, 0, 28)
        if self.on_roi is not None:
            return self.on_roi(cmd)
        return _ACCEPTED

    def _pathplanning(self, cmd):
        if not self._allowed(cmd):
            return _DENIED
        if self.on_pathplanning is None:
            self.ep.statustext(WARNING, b"Path planning: no planner on board")
            return _UNSUPPORTED
        return self.on_pathplanning(cmd)

    def _video(self, cmd):
        if not self._allowed(cmd):
            return _DENIED
        if self.on_video is None:
            self.ep.statustext(WARNING, b"Video: no camera on board")
            return _UNSUPPORTED
        return self.on_video(cmd)

    def _mission_only(self, cmd):
        self.ep.statustext(WARNING, b"CONDITION_*: a mission item, not a command")
        return _UNSUPPORTED

    def _marker(self, cmd):
        self.ep.statustext(WARNING, b"*_LAST: a marker, not a command")
        return _UNSUPPORTED


def create(ep):
    return ep.add(SeedCommands())
