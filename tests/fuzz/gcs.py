"""The well-behaved ground station of the MicroPython engine (live.py), over the vehicle's
udpin link from a port of its own and as frames.EXCHANGE_GCS, which fuzz frames never
forge: the real exchanges that must succeed between fuzzed batches (set and read a
parameter, commands, a mission upload and its download, signing off), and the reads
the invariants need (every parameter in force, each plan's count and id, SYS_STATUS).
It signs with the key in force when the fuzz turned signing on, as a station that
holds the key would. Every wait gives up after a while: ExchangeFailed.
"""
import math
import time
from collections import deque

from fuzz import frames, wire

_MAV_RESULT_ACCEPTED = 0
_PARAM_REAL32 = 9


class ExchangeFailed(AssertionError):
    """A real protocol exchange did not succeed between fuzzed batches."""


class Refused(Exception):
    """The vehicle refused an upload cleanly, for a reason the fuzz may have made (DENIED,
    cancelled, outside the allowed area): it may be tried again. args[0]: MISSION_ACK's type."""


class Gcs:
    def __init__(self, port, dialect, signing, on_frame=None):
        self.port = wire.Port(port)
        self.dialect = dialect
        self.table = frames.layouts(dialect)
        self.ids = wire.ids(self.table)
        self.signing = signing
        self.speaker = wire.Speaker(frames.EXCHANGE_GCS, self.table, signing)
        self.on_frame = on_frame  # called with every frame the vehicle sends (the engine's watch)
        self.backlog = deque()
        self.common = "MISSION_ITEM_INT" in self.ids  # the seed's dialect has neither it nor plan types

    # --- sending and waiting ------------------------------------------------------------
    def send(self, name, **fields):
        fields.setdefault("target_system", 1)
        fields.setdefault("target_component", 1)
        self.port.send(self.speaker.frame(name, **fields))

    def to_me(self, m):
        """Is this answer addressed to this station (where the message says)?"""
        return (m.get("target_system", self.speaker.sysid) == self.speaker.sysid
                and m.get("target_component", self.speaker.compid) in (self.speaker.compid, 0))

    def heartbeat(self):
        self.port.send(self.speaker.frame("HEARTBEAT", type=6, autopilot=8, mavlink_version=3))

    def frames(self, seconds):
        """(msgid, payload) of what the vehicle sends, for up to `seconds` (the caller stops
        when it has what it waits for; what it did not look at stays for the next wait)."""
        deadline = time.time() + seconds
        while True:
            while self.backlog:
                yield self.backlog.popleft()
            left = deadline - time.time()
            if left <= 0:
                return
            for dgram in self.port.received(min(left, 0.05)):
                for mid, _sys, _comp, payload, f in wire.scan(dgram):
                    self.signing.saw(f)
                    if self.on_frame is not None:
                        self.on_frame(mid, payload)
                    self.backlog.append((mid, payload))

    def wait(self, name, cond=None, seconds=0.3):
        """The first message called name (and matching cond(fields)) -> its fields, else None."""
        got = self.wait_any((name,), cond, seconds)
        return got[1] if got is not None else None

    def wait_any(self, names, cond=None, seconds=0.3):
        """The first message of any of these names (matching cond) -> (name, fields), else None."""
        wanted = {self.ids[k]: k for k in names if k in self.ids}
        for mid, payload in self.frames(seconds):
            if mid in wanted:
                fields = wire.decode(self.table, mid, payload)
                fields["_payload"] = payload
                if cond is None or cond(fields):
                    return wanted[mid], fields
        return None

    def ask(self, name, fields, answer, cond=None, tries=6, seconds=0.3):
        """Send a request until its answer comes (a reply the link's budget could not carry
        is dropped; a ground station asks again) -> the answer's fields or None."""
        for _ in range(tries):
            self.send(name, **fields)
            got = self.wait(answer, cond, seconds)
            if got is not None:
                return got
        return None

    # --- the exchanges --------------------------------------------------------------------
    def param_exchange(self, rng):
        name = b"SIM_SPEED"
        value = round(rng.uniform(1.0, 25.0), 2)
        got = self.ask("PARAM_SET", dict(param_id=name, param_value=value, param_type=_PARAM_REAL32),
                       "PARAM_VALUE", lambda m: m["param_id"] == name and abs(m["param_value"] - value) < 1e-4)
        if got is None:
            raise ExchangeFailed("PARAM_SET SIM_SPEED=%s not answered with the value" % value)
        got = self.ask("PARAM_REQUEST_READ", dict(param_id=name, param_index=-1), "PARAM_VALUE",
                       lambda m: m["param_id"] == name)
        if got is None or abs(got["param_value"] - value) > 1e-4:
            raise ExchangeFailed("PARAM_REQUEST_READ SIM_SPEED answered %s (set %s)" % (got, value))

    def command(self, command, *params, result=_MAV_RESULT_ACCEPTED):
        """COMMAND_LONG until its COMMAND_ACK (the confirmation counts the tries)."""
        fields = {"command": command}
        for i, p in enumerate(params):
            fields["param%d" % (i + 1)] = p
        for confirmation in range(6):
            fields["confirmation"] = confirmation
            ack = self.ask("COMMAND_LONG", fields, "COMMAND_ACK", lambda m: m["command"] == command and self.to_me(m),
                           tries=1)
            if ack is not None:
                break
        if ack is None or ack["result"] != result:
            raise ExchangeFailed("command %d answered %s" % (command, ack))

    def command_exchange(self):
        """Parameters saved (PREFLIGHT_STORAGE), and in the common dialect a REQUEST_MESSAGE
        for AUTOPILOT_VERSION (which also tells the parameter service that this station
        reads integers bytewise)."""
        if self.common:
            self.command(512, 148.0)
        self.command(245, 1.0)

    def signing_off(self):
        """SETUP_SIGNING with a zero key, signed with the key in force: signing off."""
        self.send("SETUP_SIGNING", secret_key=bytes(32), initial_timestamp=0)

    def mission_exchange(self, rng, n=3, attempts=6):
        """A small upload and its download. A DENIED or cancelled upload (a transfer the fuzz
        left open) is tried again after a pause, as a ground station would."""
        for attempt in range(attempts):
            try:
                return self._mission_exchange(rng, n)
            except Refused as e:
                if attempt == attempts - 1:
                    raise ExchangeFailed("mission upload refused %d times: MISSION_ACK %s" % (attempts, e))
                if e.args[0] in (14, 15):  # a transfer the fuzz left open: a pause
                    time.sleep(0.5)

    def _mission_exchange(self, rng, n):
        base = rng.randrange(1000)
        items = [dict(seq=i, frame=3, command=16, current=0, autocontinue=1, param1=0.0, param2=2.0, param3=0.0,
                      param4=float(base), x=473977420 + i * 1000 + base, y=85455940, z=20.0 + i)
                 for i in range(n)]
        if not self.common:  # the seed's MISSION_ITEM: degrees as float32
            for it in items:
                it["x"] /= 1e7
                it["y"] /= 1e7
        self.upload(items)
        count = self.plan_count(0)
        if count is None or count[0] != n:
            raise ExchangeFailed("mission download: count %s, uploaded %d" % (count, n))
        request, item = ("MISSION_REQUEST_INT", "MISSION_ITEM_INT") if self.common else ("MISSION_REQUEST", "MISSION_ITEM")
        for seq in range(n):
            got = self.ask(request, dict(seq=seq, mission_type=0), item, lambda m: m["seq"] == seq and self.to_me(m))
            want = items[seq]
            if got is None or not math.isclose(got["x"], want["x"], rel_tol=1e-6) \
                    or not math.isclose(got["param4"], want["param4"]):
                raise ExchangeFailed("mission download: item %d is %s, uploaded %s" % (seq, got, want))
        self.send("MISSION_ACK", type=0, mission_type=0)

    def upload(self, items, mission_type=0):
        kinds = ("MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK")
        got = self._ask_any("MISSION_COUNT", dict(count=len(items), mission_type=mission_type), kinds)
        item = "MISSION_ITEM_INT" if self.common else "MISSION_ITEM"
        for _ in range(4 * len(items) + 8):
            if got is None:
                raise ExchangeFailed("mission upload: the vehicle went silent")
            name, m = got
            if name == "MISSION_ACK":
                if m["type"] in (14, 15):  # MAV_MISSION_DENIED, OPERATION_CANCELLED
                    raise Refused(m["type"])
                if m["type"] in (10, 11, 12):  # INVALID_PARAM5_X .. 7: outside the allowed area
                    self.send("SAFETY_SET_ALLOWED_AREA", frame=0)  # all zeros: no area (the fuzz set it)
                    raise Refused(m["type"])
                if m["type"] != 0:
                    raise ExchangeFailed("mission upload: MISSION_ACK %d" % m["type"])
                return
            if m.get("mission_type", 0) == mission_type and 0 <= m["seq"] < len(items):
                self.send(item, mission_type=mission_type, **items[m["seq"]])
            got = self.wait_any(kinds, self.to_me, 3.0)
        raise ExchangeFailed("mission upload: no MISSION_ACK")

    def _ask_any(self, name, fields, kinds, tries=6):
        for _ in range(tries):
            self.send(name, **fields)
            got = self.wait_any(kinds, self.to_me, 0.4)
            if got is not None:
                return got
        return None

    # --- reads for the invariants -----------------------------------------------------------
    def plan_count(self, mission_type):
        """-> (count, opaque_id or None) of a plan in force."""
        got = self.ask("MISSION_REQUEST_LIST", dict(mission_type=mission_type), "MISSION_COUNT",
                       lambda m: m.get("mission_type", 0) == mission_type and self.to_me(m))
        if got is None:
            return None
        return got["count"], got.get("opaque_id")

    def params(self, count):
        """Every parameter in force -> {index: (name, 4 value bytes, type)}: the list, then
        what it missed read by index."""
        out = {}

        def keep(m):
            i = m["param_index"]
            if 0 <= i < count:
                out[i] = (m["param_id"], bytes(m["_payload"][0:4]).ljust(4, b"\0"), m["param_type"])
            return len(out) == count

        self.send("PARAM_REQUEST_LIST")
        self.wait("PARAM_VALUE", keep, 1.0 + count * 0.005)
        for i in range(count):
            if i not in out:
                got = self.ask("PARAM_REQUEST_READ", dict(param_id=b"", param_index=i), "PARAM_VALUE",
                               lambda m: m["param_index"] == i)
                if got is None:
                    raise ExchangeFailed("PARAM_REQUEST_READ of index %d not answered" % i)
                keep(got)
        return out

    def sys_status(self):
        """A SYS_STATUS asked for now -> its fields."""
        if self.common:
            for _ in range(4):
                self.send("COMMAND_LONG", command=512, param1=1.0)
                got = self.wait("SYS_STATUS", None, 0.4)
                if got is not None:
                    return got
        else:  # the seed has no REQUEST_MESSAGE: its extended status stream, on
            got = self.ask("REQUEST_DATA_STREAM", dict(req_stream_id=2, req_message_rate=4, start_stop=1),
                           "SYS_STATUS", None, tries=4, seconds=0.6)
            if got is not None:
                return got
        raise ExchangeFailed("no SYS_STATUS")
