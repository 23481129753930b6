"""Ground-station moves shared by the end-to-end tests (pymavlink against the unix vehicle)."""
import time

from conftest import recv

MAV_RESULT_ACCEPTED = 0
MAV_RESULT_TEMPORARILY_REJECTED = 1
MAV_RESULT_DENIED = 2
MAV_RESULT_UNSUPPORTED = 3
MAV_RESULT_FAILED = 4


def start(vehicle, *args, **kw):
    """A unix vehicle with extra main.py arguments (e.g. "--set", "arm_veto=1")."""
    return vehicle(args=list(args), **kw)


def command(m, cmd, *params, target=None, confirmation=0):
    """COMMAND_LONG with params 1..7 (missing ones 0) to target (system, component)."""
    ts, tc = target if target is not None else (m.target_system, m.target_component)
    p = list(params) + [0.0] * (7 - len(params))
    m.mav.command_long_send(ts, tc, cmd, confirmation, *p)


def ack(m, cmd, timeout=5.0):
    return recv(m, "COMMAND_ACK", timeout, lambda a: a.command == cmd)


def run(m, cmd, *params, **kw):
    """Send a command and return its COMMAND_ACK's result (None: no ACK)."""
    timeout = kw.pop("timeout", 5.0)
    command(m, cmd, *params, **kw)
    a = ack(m, cmd, timeout)
    return None if a is None else a.result


def listen(m, type, timeout=5.0, cond=None, beat=0.5):
    """recv() that keeps sending GCS heartbeats, so the vehicle keeps hearing us."""
    deadline = time.time() + timeout
    while time.time() < deadline:
        m.mav.heartbeat_send(6, 8, 0, 0, 0)
        msg = recv(m, type, min(beat, max(0.01, deadline - time.time())), cond)
        if msg is not None:
            return msg
    return None


def vehicle_heartbeat(m, cond=None, timeout=5.0):
    return listen(m, "HEARTBEAT", timeout,
                  lambda h: h.get_srcSystem() == m.target_system and h.get_srcComponent() == 1
                  and (cond is None or cond(h)))


def request(m, msgid, timeout=5.0):
    """REQUEST_MESSAGE msgid -> (ack result, the message or None)."""
    from pymavlink.dialects.v20 import common

    name = common.mavlink_map[msgid].msgname
    command(m, 512, msgid)
    a = ack(m, 512, timeout)
    msg = recv(m, name, timeout) if a is not None and a.result == MAV_RESULT_ACCEPTED else None
    return (None if a is None else a.result), msg


def statustext(m, contains, timeout=5.0):
    return listen(m, "STATUSTEXT", timeout, lambda s: contains in s.text)
