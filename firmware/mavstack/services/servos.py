"""Relays and servos: the seed's DO_SET_RELAY / DO_REPEAT_RELAY / DO_SET_SERVO /
DO_REPEAT_SERVO (181-184) drive a board's relay and servo table (board settings RELAYS,
SERVO_CHANNELS, SERVO_NOMINAL, SERVO_RANGE; the profile's set_relay / set_servo for the
hardware). Repeats run in tick(), one relay and one servo repeat at a time; mission
items of these commands come through do_item(item). The sender must be in control. Where streams run,
the relays go out as NAMED_VALUE_INT "RELAYS" and the table in SERVO_OUTPUT_RAW.
Reference (the commands' parameters, settings, telemetry): docs/services/seed.md.
"""
from ..compat import const, ticks_diff
from ..fields import fix, i32
from ..kernels import copy
from .commands import Command
from ..statustext import WARNING

NEEDS = ("commands",)  # its commands
AFTER = ("streams",)  # SERVO_OUTPUT_RAW: the table goes over the telemetry slot

_CMD_DO_SET_RELAY = const(181)
_CMD_DO_REPEAT_RELAY = const(182)
_CMD_DO_SET_SERVO = const(183)
_CMD_DO_REPEAT_SERVO = const(184)
_ACCEPTED = const(0)
_DENIED = const(2)
_MSG_SERVO_OUTPUT_RAW = const(36)
_MSG_NAMED_VALUE_INT = const(252)
_RELAYS_NAME = b"RELAYS"


class Servos:
    NAME = "servos"

    def __init__(self, relays=0, channels=None, nominal=1500, limits=(800, 2200), board=None):
        self.relay_count = relays
        self.first, self.last = channels or (1, 0)
        self.nominal = nominal
        self.low, self.high = limits
        self.relays = 0
        self._servos = bytearray(2 * max(0, self.last - self.first + 1))  # us, u16 each
        self._set_relay = getattr(board, "set_relay", None)
        self._set_servo = getattr(board, "set_servo", None)
        # The repeats: output, half-cycles left, half a cycle (ms), when the next is due;
        # the servo's width
        self.relay_repeat = [-1, 0, 0, 0]
        self.servo_repeat = [-1, 0, 0, 0, 0]
        self.tm = None
        self._write_servo = None
        self._scratch = bytearray(4)

    def attach(self, ep):
        self.ep = ep
        self._item_cmd = Command()  # do_item's: a mission item's params read as a command's
        self._by_id = {_CMD_DO_SET_RELAY: self._cmd_set_relay, _CMD_DO_REPEAT_RELAY: self._cmd_repeat_relay,
                       _CMD_DO_SET_SERVO: self._cmd_set_servo, _CMD_DO_REPEAT_SERVO: self._cmd_repeat_servo}
        for cmd in self._by_id:
            ep.commands[cmd] = self._by_id[cmd]
        tm = getattr(ep, "telemetry", None)
        if tm is not None and _MSG_SERVO_OUTPUT_RAW in tm.slots:
            # Whatever the application writes to SERVO_OUTPUT_RAW, the table goes over it.
            self.tm = tm
            self._write_servo = tm.servo_output
            tm.servo_output = self._servo_output
        for i in range(self.first, self.last + 1):
            self._put(i, self.nominal)

    # --- the table ---------------------------------------------------------------------
    def servo(self, n):
        """The pulse width (us) of servo output n, None outside the table."""
        if n < self.first or n > self.last:
            return None
        o = (n - self.first) * 2
        return self._servos[o] | self._servos[o + 1] << 8

    def set_relay(self, n, on):
        if on:
            self.relays |= 1 << n
        else:
            self.relays &= ~(1 << n)
        if self._set_relay is not None:
            self._set_relay(n, on)
        if self.tm is not None and _MSG_NAMED_VALUE_INT in self.tm.slots:
            self.tm.named_value_int(_RELAYS_NAME, self.relays)

    def set_servo(self, n, us):
        self._put(n, us)
        if self._set_servo is not None:
            self._set_servo(n, us)
        self._overlay()

    def _put(self, n, us):
        o = (n - self.first) * 2
        self._servos[o] = us & 0xFF
        self._servos[o + 1] = us >> 8

    def _servo_output(self, outputs, port=0):
        self._write_servo(outputs, port)
        self._overlay()

    def _overlay(self):
        # Outputs 1-8 at payload offset 4, 9-16 (extensions) at 21, u16 each.
        if self.tm is None:
            return
        s = self.tm.slots[_MSG_SERVO_OUTPUT_RAW]
        n = self.first
        while n <= self.last:
            if n <= 8:
                self._copy_to(s.buf, 4 + (n - 1) * 2, n)
            elif n <= 16 and s.ext is not None:
                self._copy_to(s.buf, 21 + (n - 9) * 2, n)
            n += 1
        if not s.written:
            self.tm.clock.stamp_us32(s.buf, 0)
            s.written = True

    def _copy_to(self, buf, o, n):
        i = (n - self.first) * 2
        buf[o] = self._servos[i]
        buf[o + 1] = self._servos[i + 1]

    # --- commands ----------------------------------------------------------------------
    def do_item(self, item):
        """A mission's DO_SET_RELAY / DO_REPEAT_RELAY / DO_SET_SERVO / DO_REPEAT_SERVO
        (services/missions/runner.py's Item; its record holds param1-4 where COMMAND_LONG
        does) carried out as the command would be -> MAV_RESULT, None for another item.
        The application calls it as the runner makes such an item current."""
        handler = self._by_id.get(item.command)
        if handler is None:
            return None
        cmd = self._item_cmd
        cmd.payload = item.rec
        return handler(cmd)

    def _allowed(self, cmd):
        if cmd.link is None:  # a mission item: its plan was uploaded by a station in control
            return True
        if self.ep.allows(cmd.link):
            return True
        self.ep.statustext(WARNING, b"Servo/relay: GCS not in control")
        return False

    def _refuse(self, text):
        self.ep.statustext(WARNING, text)
        return _DENIED

    def _relay_of(self, cmd):
        if not cmd.finite(1) or not 0 <= cmd.int(1) < self.relay_count:
            return -1
        return cmd.int(1)

    def _servo_of(self, cmd):
        if not cmd.finite(1) or not self.first <= cmd.int(1) <= self.last:
            return -1
        if not cmd.finite(2) or not self.low <= cmd.int(2) <= self.high:
            return -2
        return cmd.int(1)

    def _cmd_set_relay(self, cmd):
        n = self._relay_of(cmd)
        if n < 0 or not cmd.finite(2) or cmd.int(2) not in (0, 1):
            return self._refuse(b"Relay: no such relay or setting")
        if not self._allowed(cmd):
            return _DENIED
        if self.relay_repeat[0] == n:
            self.relay_repeat[0] = -1
        self.set_relay(n, cmd.int(2) == 1)
        return _ACCEPTED

    def _cmd_repeat_relay(self, cmd):
        n = self._relay_of(cmd)
        if n < 0:
            return self._refuse(b"Relay: no such relay")
        half = _half_cycle_ms(cmd, 2, 3, self._scratch)
        if half <= 0:
            return self._refuse(b"Relay repeat: bad cycle count or time")
        if not self._allowed(cmd):
            return _DENIED
        r = self.relay_repeat
        r[0] = n
        r[1] = cmd.int(2) * 2
        r[2] = half
        r[3] = self.ep.now
        self._relay_step()
        return _ACCEPTED

    def _cmd_set_servo(self, cmd):
        n = self._servo_of(cmd)
        if n < 0:
            return self._refuse(b"Servo: no such output or width out of range")
        if not self._allowed(cmd):
            return _DENIED
        if self.servo_repeat[0] == n:
            self.servo_repeat[0] = -1
        self.set_servo(n, cmd.int(2))
        return _ACCEPTED

    def _cmd_repeat_servo(self, cmd):
        n = self._servo_of(cmd)
        if n < 0:
            return self._refuse(b"Servo: no such output or width out of range")
        half = _half_cycle_ms(cmd, 3, 4, self._scratch)
        if half <= 0:
            return self._refuse(b"Servo repeat: bad cycle count or time")
        if not self._allowed(cmd):
            return _DENIED
        r = self.servo_repeat
        r[0] = n
        r[1] = cmd.int(3) * 2
        r[2] = half
        r[3] = self.ep.now
        r[4] = cmd.int(2)
        self._servo_step()
        return _ACCEPTED

    # --- repeats -----------------------------------------------------------------------
    def tick(self, now):
        r = self.relay_repeat
        if r[0] >= 0 and ticks_diff(now, r[3]) >= 0:
            self._relay_step()
        r = self.servo_repeat
        if r[0] >= 0 and ticks_diff(now, r[3]) >= 0:
            self._servo_step()

    def _relay_step(self):
        r = self.relay_repeat
        self.set_relay(r[0], not self.relays & (1 << r[0]))
        r[1] -= 1
        r[3] += r[2]
        if r[1] <= 0:
            r[0] = -1

    def _servo_step(self):
        r = self.servo_repeat
        r[1] -= 1
        # Odd half-cycles left: at the commanded width; even: back at nominal.
        self.set_servo(r[0], r[4] if r[1] & 1 else self.nominal)
        r[3] += r[2]
        if r[1] <= 0:
            r[0] = -1


def _half_cycle_ms(cmd, count, time, scratch):
    """Half a cycle in ms from the cycle count and cycle time (s) parameters; 0 if bad.
    The seconds go through their float32 bits (units.fix: * 1e4, exact), not a float:
    on MicroPython a float is a heap object."""
    if not cmd.finite(count) or not cmd.finite(time) or not 1 <= cmd.int(count) <= 10000:
        return 0
    copy(scratch, cmd.payload, (time - 1) * 4 << 10, 4)
    if not fix(scratch, 0, True):
        return 0
    ms = i32(scratch, 0) // 20  # seconds * 1e4 -> half a cycle in ms
    return ms if 0 < ms <= 3600000 else 0


def create(ep):
    board = getattr(ep, "board", None)
    return ep.add(Servos(ep.setting("RELAYS", 0), getattr(board, "SERVO_CHANNELS", None),
                         ep.setting("SERVO_NOMINAL", 1500),
                         getattr(board, "SERVO_RANGE", (800, 2200)), board))
