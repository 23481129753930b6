"""The command a handler is given (Command: its parameters read from the payload on
demand) and a long-running one it keeps (Pending: progress, then the final result).
Reference (the Command API): docs/services/commands.md.
"""
import struct

from ...compat import const
from ...fields import i32, f32_is_nan, f32_to_int

_IN_PROGRESS = const(5)  # MAV_RESULT_IN_PROGRESS


class Command:
    """The command being handled (one instance, refilled per frame); its parameters are
    read from the payload on demand, int(i) and nan(i) allocating nothing."""

    def __init__(self, service=None):
        self._service = service  # the commands service (defer)
        self.link = None
        self.payload = None
        self.is_int = False
        self.command = 0
        self.sysid = 0  # sender
        self.compid = 0
        self.confirmation = 0
        self.frame = 0  # COMMAND_INT only
        self.result_param2 = 0  # set by a handler to explain a refusal
        self.reply = -1  # set by a handler: message id to produce after the ACK
        self.reply_all = False  # ... on every link instead of the sender's
        self.key = -1  # identifies re-sends of this command

    def _offset(self, i):
        if self.is_int and i == 5:
            return 16
        if self.is_int and i == 6:
            return 20
        return (i - 1) * 4

    def int(self, i):
        """Parameter i (1..7) rounded to an int; COMMAND_INT's x/y (5, 6) as sent."""
        o = self._offset(i)
        if self.is_int and (i == 5 or i == 6):
            return i32(self.payload, o)
        return f32_to_int(self.payload, o)

    def nan(self, i):
        """True when parameter i is NaN: 'use the default' by convention."""
        if self.is_int and (i == 5 or i == 6):
            return False
        return bool(f32_is_nan(self.payload, self._offset(i)))

    def finite(self, i):
        """True when parameter i is a number: not NaN, not an infinity."""
        if self.is_int and (i == 5 or i == 6):
            return True
        o = self._offset(i)
        return (self.payload[o + 3] & 0x7F) != 0x7F or (self.payload[o + 2] & 0x80) == 0

    def float(self, i):
        o = self._offset(i)
        if self.is_int and (i == 5 or i == 6):
            # Global frames carry degrees * 1e7, local frames metres * 1e4.
            scale = 1e4 if self.frame in (1, 4, 7, 8, 9, 20, 21) else 1e7
            return i32(self.payload, o) / scale
        return struct.unpack_from("<f", self.payload, o)[0]

    def defer(self):
        """Keep the command for a later progress()/done(); the handler returns IN_PROGRESS."""
        return Pending(self._service, self)


class Pending:
    """A long-running command: send IN_PROGRESS with progress, then the final result."""

    def __init__(self, service, cmd):
        self.service = service
        self.link = cmd.link
        self.command = cmd.command
        self.sysid = cmd.sysid
        self.compid = cmd.compid
        self.key = cmd.key
        self.percent = 0

    def progress(self, percent):
        self.percent = percent
        self.service.ack(self, _IN_PROGRESS, percent, 0)

    def done(self, result, result_param2=0):
        self.service.settle(self.key, result, result_param2)
        self.service.ack(self, result, 100, result_param2)
