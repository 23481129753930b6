"""Command protocol: COMMAND_LONG and COMMAND_INT through one dispatch table.

Handlers live in endpoint.commands {MAV_CMD id: handler(cmd) -> MAV_RESULT}; any
service or the application adds entries, by id or by seed name (handle()). Every
command addressed to us gets exactly one final COMMAND_ACK, sent to its sender in the
same poll, or held back by the link's budget and sent by a later tick, in order; a
handler that needs time returns IN_PROGRESS and finishes through cmd.defer(). A retry
(confirmation one higher, within 3 s, or while its ACK is held back) gets its ACK without
a second run. A handler may set cmd.reply: that message follows the ACK. Built in here:
MAV_CMD_REQUEST_MESSAGE (512) for every producer.
Reference (the Command API, retries, held-back ACKs, the built-ins): docs/services/commands.md.
"""
from ...compat import const, ticks_diff, to_grid
from ...fields import u16
from ...faults import COMMAND
from ...kernels import crc16, copy
from ...link import RANK_BULK, RANK_FILL, RANK_AUTO
from .command import Command, Pending  # noqa: F401  (Pending: handlers' cmd.defer())

_MSG_COMMAND_INT = const(75)
_MSG_COMMAND_LONG = const(76)
_MSG_COMMAND_ACK = const(77)
_CMD_REQUEST_MESSAGE = const(512)

MAV_RESULT_ACCEPTED = const(0)
MAV_RESULT_TEMPORARILY_REJECTED = const(1)
MAV_RESULT_DENIED = const(2)
MAV_RESULT_UNSUPPORTED = const(3)
MAV_RESULT_FAILED = const(4)
MAV_RESULT_IN_PROGRESS = const(5)

_RETRY_WINDOW_MS = const(3000)  # a retry later than this after the ACK runs again

# Held-back ACKs: _HELD entries of _ENTRY bytes in one bytearray, oldest first: the ACK's
# payload as ack() packs it (the target at 8, 9 even where the dialect's ACK has none), the
# link's index, flags, the command's key (16 bits) and the message to follow (24 bits).
_HELD = const(8)
_ENTRY = const(17)
_ACK_LEN = const(10)
_AT_LINK = const(10)
_AT_FLAGS = const(11)
_AT_KEY = const(12)
_AT_REPLY = const(14)
_KEPT = const(1)  # flags: for a sender whose share its link keeps (link.sender_kept())
_REPLY = const(2)
_REPLY_ALL = const(4)
_ACK_FRAME = const(22)  # bytes of a MAVLink 2 COMMAND_ACK (unsigned), asked of the budget ...
_REPLY_ROOM = const(64)  # ... with room for the message that follows it, if any


class Commands:
    NAME = "commands"
    WAKE_ALL = True  # a command is other services' work: its frames wake every tick

    def __init__(self):
        self.cmd = Command(self)
        self._last_key = -1  # crc of the last command's sender + payload, if it ran
        self._pending_key = -1  # ... of the deferred command still IN_PROGRESS
        self._last_ms = 0
        self._last_result = 0
        self._last_param2 = 0
        self._last_reply = -1
        self._last_reply_all = False
        self.received = 0
        self.failed = 0  # handlers that raised
        self._held = bytearray(_HELD * _ENTRY)  # held-back ACKs (layout above)
        self._held_n = 0
        self._new = -1  # the entry the last ack() held back, -1: sent or dropped
        self.acks_held = 0  # ACKs the budget held back (then sent by a tick)
        self.acks_dropped = 0  # held-back ACKs dropped: no room left
        self.ack_broadcast = True  # ACK_UNSUPPORTED_BROADCAST: UNSUPPORTED for component 0 too

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
        if cmd.confirmation > 0 and self._find(_tag(cmd), cmd.key) >= 0:
            return  # its ACK is held back, on its way: no second run
        if self._is_retry(cmd):
            # The ACK did not get through: the answer again, not a second run (and the
            # requested message: it may be what got lost).
            self._last_ms = self.ep.now
            cmd.result_param2 = self._last_param2
            cmd.reply = self._last_reply
            cmd.reply_all = self._last_reply_all
            self._answer(cmd, self._last_result)
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
            if cmd.payload[31] == 0 and not self.ack_broadcast:
                return  # a peripheral keeps out of what other components answer
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
        self._answer(cmd, result)

    def _answer(self, cmd, result):
        """The ACK, then the message asked for (cmd.reply): now, or after the held-back ACK."""
        if self.ack(cmd, result, 0, cmd.result_param2):
            self._send_reply(cmd.link, cmd.reply, cmd.reply_all)
        elif self._new >= 0 and cmd.reply >= 0:
            e = self._new * _ENTRY
            self._held[e + _AT_FLAGS] |= _REPLY | (_REPLY_ALL if cmd.reply_all else 0)
            _put(self._held, e + _AT_REPLY, cmd.reply, 3)

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
        """COMMAND_ACK to the sender of `to` (the Command being handled, or a Pending),
        field by field: packed whole, its values would make a large frame (docs/design.md)
        -> True if sent now, False if held back (a later tick sends it) or dropped."""
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
        return self._sent(to)

    def holding(self):
        """ACKs held back, not sent yet (a reboot waits for them: status)."""
        return self._held_n

    # --- held-back ACKs (layout at the top; small frames: docs/design.md) -----------------
    def _sent(self, to):
        """Send the ACK packed in to.link.txbuf -> True; held back -> False. One for a
        sender with an ACK still held back waits behind it (its ACKs stay in order)."""
        i = self._find(_tag(to), -1)
        if i < 0 and to.link.send(_MSG_COMMAND_ACK):
            return True
        kept = to.link.sender_kept() if i < 0 else self._held[i * _ENTRY + _AT_FLAGS] & _KEPT
        self._new = self._room(kept)
        if self._new >= 0:
            _entry(self._held, self._new * _ENTRY, to, kept)
            self.acks_held += 1
        return False

    def _room(self, kept):
        """An entry for one more held-back ACK -> its index, or -1. When all are taken
        the oldest goes, a kept sender's only for a kept sender's (counted: dropped)."""
        if self._held_n == _HELD:
            self.acks_dropped += 1
            e = 0  # the oldest not kept, if any
            while e < _HELD * _ENTRY and self._held[e + _AT_FLAGS] & _KEPT:
                e += _ENTRY
            if e == _HELD * _ENTRY and not kept:
                return -1
            self._remove(e // _ENTRY if e < _HELD * _ENTRY else 0)
        self._held_n += 1
        return self._held_n - 1

    def _find(self, tag, key):
        """The oldest ACK held back for sender and link `tag` (_tag) and, if key >= 0, the
        command of that key -> its index, or -1."""
        held = self._held
        e = 0
        while e < self._held_n * _ENTRY:
            if _get(held, e + 8, 3) == tag and (key < 0 or _get(held, e + _AT_KEY, 2) == key & 0xFFFF):
                return e // _ENTRY
            e += _ENTRY
        return -1

    def _remove(self, i):
        n = self._held_n - 1
        if i < n:
            copy(self._held, self._held, (i + 1) * _ENTRY << 10 | i * _ENTRY, (n - i) * _ENTRY)
        self._held_n = n

    def tick(self, now):
        """Held-back ACKs, oldest first, while the budget pays: a kept sender's at RANK_BULK,
        others' at RANK_FILL; one that must wait holds its queue (link, kept) in order."""
        waiting = 0  # bit 2 * link index + kept: that queue waits
        i = 0
        while i < self._held_n:
            q = 1 << (2 * self._held[i * _ENTRY + _AT_LINK] + (self._held[i * _ENTRY + _AT_FLAGS] & _KEPT))
            if not waiting & q and self._send_held(i * _ENTRY):
                self._remove(i)
            else:
                waiting |= q
                i += 1
        return 1 if self._held_n else to_grid(now, 1000)

    def _send_held(self, e):
        held = self._held
        link = self.ep.links[held[e + _AT_LINK]]
        link.rank = RANK_BULK if held[e + _AT_FLAGS] & _KEPT else RANK_FILL
        room = _ACK_FRAME + (_REPLY_ROOM if held[e + _AT_FLAGS] & _REPLY else 0)
        sent = link.can_send(room, link.rank) and _load(link, held, e) and link.send(_MSG_COMMAND_ACK)
        if sent:
            self._reply_held(link, e)
        link.rank = RANK_AUTO
        return sent

    def _reply_held(self, link, e):
        flags = self._held[e + _AT_FLAGS]
        if flags & _REPLY:
            self._send_reply(link, _get(self._held, e + _AT_REPLY, 3), flags & _REPLY_ALL)


# Held-back entries, field by field (few locals each: docs/design.md).
def _tag(to):
    """Who an ACK is for: its sender and link, as an entry keeps them at 8, 9, 10."""
    return to.sysid | to.compid << 8 | to.link.index << 16


def _get(b, o, n):
    """The n-byte little-endian int at b[o]."""
    v = 0
    while n:
        n -= 1
        v = v << 8 | b[o + n]
    return v


def _put(b, o, v, n):
    while n:
        b[o] = v & 0xFF
        v >>= 8
        o += 1
        n -= 1


def _entry(held, e, to, kept):
    """Entry e from the ACK packed in to.link.txbuf, for `to`."""
    copy(held, to.link.txbuf, to.link.begin() << 10 | e, _ACK_LEN)
    _put(held, e + 8, _tag(to), 3)
    held[e + _AT_FLAGS] = _KEPT if kept else 0
    _put(held, e + _AT_KEY, to.key, 2)


def _load(link, held, e):
    """The held-back ACK of entry e into link.txbuf -> True."""
    copy(link.txbuf, held, e << 10 | link.begin(), _ACK_LEN)
    return True


def command_id(name):
    """MAV_CMD id for a name such as 'NAV_TAKEOFF' or 'MAV_CMD_NAV_TAKEOFF' (names.py)."""
    from . import names  # loaded on first use, for RAM: a board that registers by id never loads it
    return names.command_id(name)


def create(ep):
    commands = Commands()
    commands.ack_broadcast = ep.setting("ACK_UNSUPPORTED_BROADCAST", True)
    return ep.add(commands)
