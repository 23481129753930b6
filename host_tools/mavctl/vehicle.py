"""One vehicle on one pymavlink connection, as mavctl's subcommands get it: its ids
learnt from its first HEARTBEAT, our heartbeats sent while we wait for answers, the
messages it sends, commands; the parameter and mission protocols are its too
(param_protocol.py, mission_protocol.py). CPython with pymavlink, MAVLink 2."""
import sys
import time

from mavctl.errors import EXIT_NO_HEARTBEAT, Failure
from mavctl.mission_protocol import MissionProtocol
from mavctl.names import enum_name, mavlink
from mavctl.param_protocol import ParamProtocol

HEARTBEAT_PERIOD = 1.0
MAV_TYPE_GCS = 6


class Vehicle(ParamProtocol, MissionProtocol):
    """One vehicle on one connection; heartbeats go out while we wait for answers."""

    def __init__(self, conn, target_system=None, target_component=None, echo_statustext=True):
        self.conn = conn
        self.mav = conn.mav
        self.target_system = target_system
        self.target_component = target_component
        self.echo_statustext = echo_statustext
        self._next_heartbeat = 0.0
        self.heartbeat_msg = None  # the vehicle's first HEARTBEAT (type, autopilot)

    def heartbeat(self):
        now = time.monotonic()
        if now >= self._next_heartbeat:
            self._next_heartbeat = now + HEARTBEAT_PERIOD
            # MAV_TYPE_GCS, MAV_AUTOPILOT_INVALID, MAV_STATE_ACTIVE
            self.mav.heartbeat_send(MAV_TYPE_GCS, 8, 0, 0, 4)

    def connect(self, timeout):
        """Wait for the vehicle's HEARTBEAT (or its answer to our PING); learn its ids
        if not given."""
        deadline = time.monotonic() + timeout
        asked = False
        while time.monotonic() < deadline:
            self.heartbeat()
            msg = self.conn.recv_match(blocking=True, timeout=0.2)
            if msg is None:
                continue
            kind = msg.get_type()
            if kind == "PING":
                if (msg.target_system, msg.target_component) != (self.mav.srcSystem, self.mav.srcComponent):
                    continue
            elif kind != "HEARTBEAT" or msg.type == MAV_TYPE_GCS:
                if not asked:
                    # Rather than wait up to a second for the next beat, ask: PING to
                    # all (0/0) and a HEARTBEAT by REQUEST_MESSAGE. Sent once the link
                    # carries traffic (udpin learns its peer from it).
                    self.mav.ping_send(int(time.time() * 1e6), 0, 0, 0)
                    self.mav.command_long_send(0, 0, mavlink.MAV_CMD_REQUEST_MESSAGE, 0,
                                               mavlink.MAVLINK_MSG_ID_HEARTBEAT, 0, 0, 0, 0, 0, 0)
                    asked = True
                continue
            if self.target_system not in (None, msg.get_srcSystem()):
                continue
            if self.target_component not in (None, msg.get_srcComponent()):
                continue
            self.target_system = msg.get_srcSystem()
            self.target_component = msg.get_srcComponent()
            if kind == "HEARTBEAT":
                self.heartbeat_msg = msg
            return msg
        raise Failure("no HEARTBEAT from a vehicle within %g s: is it powered, on this link, "
                      "at this baud?" % timeout, EXIT_NO_HEARTBEAT)

    def recv(self, types, timeout, cond=None):
        """Next message from the vehicle whose type is in types (None: any) and that
        satisfies cond, or None after timeout seconds."""
        deadline = time.monotonic() + timeout
        while True:
            self.heartbeat()
            left = deadline - time.monotonic()
            if left <= 0:
                return None
            msg = self.conn.recv_match(blocking=True, timeout=min(left, 0.2))
            if msg is None or msg.get_srcSystem() != self.target_system:
                continue
            kind = msg.get_type()
            if kind == "STATUSTEXT" and self.echo_statustext and msg.severity <= 4:
                print("vehicle: %s: %s" % (enum_name("MAV_SEVERITY", msg.severity)[13:], msg.text),
                      file=sys.stderr)
            if (types is None or kind in types) and (cond is None or cond(msg)):
                return msg

    def for_me(self, msg):
        """A reply addressed to this ground station (0: broadcast)."""
        ts = getattr(msg, "target_system", 0)
        tc = getattr(msg, "target_component", 0)
        return ts in (0, self.mav.srcSystem) and tc in (0, self.mav.srcComponent)

    # --- commands

    def command(self, command, params=(), tries=3, timeout=1.5):
        """COMMAND_LONG until its final COMMAND_ACK -> the ack message."""
        p = (list(params) + [0.0] * 7)[:7]
        for confirmation in range(tries):
            self.mav.command_long_send(self.target_system, self.target_component, command,
                                       confirmation, *p)
            wait = timeout
            while True:
                ack = self.recv(("COMMAND_ACK",), wait,
                                lambda m: m.command == command and self.for_me(m))
                if ack is None or ack.result != mavlink.MAV_RESULT_IN_PROGRESS:
                    break
                print("%s: in progress %d%%" % (enum_name("MAV_CMD", command), ack.progress),
                      file=sys.stderr)
                wait = 30.0  # a long-running command reports progress, then its result
            if ack is not None:
                return ack
        raise Failure("no COMMAND_ACK for %s" % enum_name("MAV_CMD", command))
