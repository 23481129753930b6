"""Command protocol: COMMAND_LONG and COMMAND_INT through one dispatch table.

Handlers live in endpoint.commands {MAV_CMD id: handler(cmd) -> MAV_RESULT}; any
service or the application adds entries, by id or by seed name (handle()). Every
command addressed to us gets exactly one final COMMAND_ACK, sent to its sender in the
same poll; a handler that needs time returns IN_PROGRESS and finishes through
cmd.defer(). A retry (confirmation one higher, within 3 s) gets its ACK again without a
second run. A handler may set cmd.reply: that message follows the ACK. Built in here:
MAV_CMD_REQUEST_MESSAGE (512) for every producer.
Reference (the Command API, retries, the built-in commands): docs/services/commands.md.
"""
import struct

from ..compat import const, ticks_diff
from ..fields import u16, i32, f32_is_nan, f32_to_int
from ..faults import COMMAND
from ..kernels import crc16

_MSG_COMMAND_INT = const(75)
_MSG_COMMAND_LONG = const(76)
_MSG_COMMAND_ACK = const(77)
_COMMAND_PAYLOAD = const(35)  # COMMAND_INT, the longer of the two
_CMD_REQUEST_MESSAGE = const(512)

MAV_RESULT_ACCEPTED = const(0)
MAV_RESULT_TEMPORARILY_REJECTED = const(1)
MAV_RESULT_DENIED = const(2)
MAV_RESULT_UNSUPPORTED = const(3)
MAV_RESULT_FAILED = const(4)
MAV_RESULT_IN_PROGRESS = const(5)

_RETRY_WINDOW_MS = const(3000)  # a retry later than this after the ACK runs again


class Command:
    """The command being handled (one instance, refilled per frame).

    Parameters are read from the payload on demand: int(i) and nan(i) allocate
    nothing; float(i) makes a float (fine for rare commands).
    """

    def __init__(self):
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
        self.service.ack(self, MAV_RESULT_IN_PROGRESS, percent, 0)

    def done(self, result, result_param2=0):
        self.service.settle(self.key, result, result_param2)
        self.service.ack(self, result, 100, result_param2)


class Commands:
    NAME = "commands"

    def __init__(self):
        self.cmd = Command()
        self.cmd._service = self
        self._last_key = -1  # crc of the last command's sender + payload, if it ran
        self._pending_key = -1  # ... of the deferred command still IN_PROGRESS
        self._last_ms = 0
        self._last_result = 0
        self._last_param2 = 0
        self._last_reply = -1
        self._last_reply_all = False
        self.received = 0
        self.failed = 0  # handlers that raised

    def attach(self, ep):
        self.ep = ep
        self.handlers = ep.commands
        self._ack_fmt = ep.fmt(_MSG_COMMAND_ACK)
        # The seed's COMMAND_ACK has only command and result.
        self._ack_short = len(self._ack_fmt) < 4
        ep.on(_MSG_COMMAND_LONG, self._on_long)
        if ep.on(_MSG_COMMAND_INT, self._on_int):
            ep.capabilities |= 1 << 3  # MAV_PROTOCOL_CAPABILITY_COMMAND_INT
        if _CMD_REQUEST_MESSAGE not in ep.commands:
            ep.commands[_CMD_REQUEST_MESSAGE] = self._request_message

    def handle(self, command, handler):
        """Register handler(cmd) -> MAV_RESULT for a MAV_CMD id or seed name ('NAV_TAKEOFF')."""
        if isinstance(command, str):
            command = command_id(command)
        self.handlers[command] = handler

    # The per-command path is in small functions with few locals (docs/design.md).
    def _on_long(self, link, p):
        self._run(link, p, False)

    def _on_int(self, link, p):
        self._run(link, p, True)

    def _run(self, link, p, is_int):
        # target_system and target_component are at 30, 31 in both messages.
        if not self.ep.for_us(p[30], p[31]):
            return
        self.received += 1
        cmd = self._fill(link, p, is_int)
        if cmd.key == self._pending_key:
            # The command still running, sent again: the same command, in progress.
            self.ack(cmd, MAV_RESULT_IN_PROGRESS, 0, 0)
            return
        if self._is_retry(cmd):
            # The ACK did not get through: the answer again, not a second run.
            self._last_ms = self.ep.now
            self.ack(cmd, self._last_result, 0, self._last_param2)
            # The requested message may be what got lost: send it again.
            self._send_reply(link, self._last_reply, self._last_reply_all)
            return
        self._execute(cmd)

    def _is_retry(self, cmd):
        return (cmd.confirmation > 0 and cmd.key == self._last_key
                and ticks_diff(self.ep.now, self._last_ms) < _RETRY_WINDOW_MS)

    def _fill(self, link, p, is_int):
        cmd = self.cmd
        cmd.link = link
        cmd.payload = p
        cmd.is_int = is_int
        cmd.command = u16(p, 28)
        cmd.sysid = link.rx.sysid
        cmd.compid = link.rx.compid
        cmd.confirmation = 0 if is_int else p[32]
        cmd.frame = p[32] if is_int else 0
        cmd.result_param2 = 0
        cmd.reply = -1
        cmd.reply_all = False
        # A retry is the same sender and the same bytes but for the confirmation count.
        cmd.key = crc16(p, 0, 30, cmd.sysid << 8 | cmd.compid)
        if is_int:
            cmd.key = crc16(p, 32, 33, cmd.key) | 0x10000  # the frame changes what x, y, z mean
        return cmd

    def _execute(self, cmd):
        handler = self.handlers.get(cmd.command)
        if handler is None:
            result = MAV_RESULT_UNSUPPORTED
        else:
            result = self.ep.faults.run(handler, cmd)
            if self.ep.faults.error is not None:
                result = self._failed(cmd)
        # Only a command that ran is remembered; a refused one may simply be tried again.
        ran = result == MAV_RESULT_ACCEPTED or result == MAV_RESULT_IN_PROGRESS
        self._last_key = cmd.key if ran else -1
        if result == MAV_RESULT_IN_PROGRESS:
            self._pending_key = cmd.key
        self._last_ms = self.ep.now
        self._last_result = result
        self._last_param2 = cmd.result_param2
        self._last_reply = cmd.reply
        self._last_reply_all = cmd.reply_all
        self.ack(cmd, result, 0, cmd.result_param2)
        self._send_reply(cmd.link, cmd.reply, cmd.reply_all)

    def _failed(self, cmd):
        """The handler raised: a fault (counted, reported), and the command FAILED."""
        self.ep.faults.count(COMMAND, cmd.command)
        self.failed += 1
        cmd.reply = -1
        return MAV_RESULT_FAILED

    def settle(self, key, result, result_param2):
        """A deferred command finished: a retry now gets its final result."""
        if key == self._pending_key:
            self._pending_key = -1
        if key == self._last_key:
            self._last_result = result
            self._last_param2 = result_param2

    def _send_reply(self, link, msgid, all_links):
        if msgid < 0:
            return
        producer = self.ep.producers.get(msgid)
        if producer is None:
            return
        if not all_links:
            producer(link)
            return
        i = 0  # (by index: see docs/design.md)
        while i < len(self.ep.links):
            producer(self.ep.links[i])
            i += 1

    def _request_message(self, cmd):
        # param1: message id; param7: 0 default / 1 requester / 2 broadcast.
        if not cmd.finite(1):
            return MAV_RESULT_DENIED
        msgid = cmd.int(1)
        if msgid not in self.ep.producers:
            return MAV_RESULT_DENIED  # supported command, message this vehicle cannot produce
        cmd.reply = msgid
        cmd.reply_all = cmd.int(7) == 2
        return MAV_RESULT_ACCEPTED

    def ack(self, to, result, progress, result_param2):
        """COMMAND_ACK to the sender of `to` (the Command being handled, or a Pending:
        its link, command, sysid and compid), field by field: packed whole, its values
        would make a large frame (docs/design.md)."""
        off = to.link.begin()
        buf = to.link.txbuf
        buf[off] = to.command & 0xFF
        buf[off + 1] = to.command >> 8
        buf[off + 2] = result
        if not self._ack_short:  # the seed's COMMAND_ACK has only command and result
            buf[off + 3] = progress
            buf[off + 4] = result_param2 & 0xFF  # int32, little-endian (>> keeps the sign)
            buf[off + 5] = (result_param2 >> 8) & 0xFF
            buf[off + 6] = (result_param2 >> 16) & 0xFF
            buf[off + 7] = (result_param2 >> 24) & 0xFF
            buf[off + 8] = to.sysid
            buf[off + 9] = to.compid
        to.link.send(_MSG_COMMAND_ACK)


def command_id(name):
    """MAV_CMD id for a name such as 'NAV_TAKEOFF' or 'MAV_CMD_NAV_TAKEOFF'.

    The names live in the dialects' *_meta modules, which are large: each is imported
    only for the look-up and dropped again. The seed's set first (it is the smaller),
    then today's. MicroPython keeps the interned names (about 11 KB for the seed's set,
    75 KB with today's on the 64-bit unix port): on a small board, register by id.
    """
    import gc
    import sys

    if not name.startswith("MAV_CMD_"):
        name = "MAV_CMD_" + name
    cid = None
    for meta in ("seed2012_meta", "common_meta"):
        module = "mavstack.dialects." + meta
        loaded = module in sys.modules
        try:
            cid = getattr(__import__(module, None, None, (name,)), name, None)
        except ImportError:  # not on this board
            continue
        finally:
            if not loaded and module in sys.modules:
                del sys.modules[module]
                package = sys.modules.get("mavstack.dialects")
                if package is not None and hasattr(package, meta):
                    delattr(package, meta)
                gc.collect()
        if cid is not None:
            return cid
    raise ValueError("unknown command " + name)


def create(ep):
    return ep.add(Commands())
