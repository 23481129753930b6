"""A ground station that keeps at it over a bad link, for the fault-injection tests: every
request is sent again on silence, a mission upload answers whatever the vehicle asks
for, and each exchange says what it believes happened, so the test can hold the
vehicle's stored state against it (correct, or cleanly cancelled, never corrupt).

    g = Gcs(connection)                 a pymavlink connection, heartbeat not needed
    g = Gcs(connection, clock=fn)       ... on another clock (seconds): lossy_world.py's
    g.param_list() -> {name: value} or None
    g.upload(items) -> "accepted" | "refused" | "unsure"
    g.download() -> [item tuples] or None
    g.command(cmd, *params) -> MAV_RESULT or None (no ACK after every try)
Items are (frame, command, p1, p2, p3, p4, x, y, z) in MISSION_ITEM_INT form.
"""
import time

MISSION_ACK_ACCEPTED = 0


class Gcs:
    def __init__(self, m, tries=8, wait=0.6, clock=time.time):
        self.m = m
        self.clock = clock
        self.tries = tries
        self.wait = wait

    def recv(self, types, cond=None, timeout=1.0):
        deadline = self.clock() + timeout
        while True:
            left = deadline - self.clock()
            if left <= 0:
                return None
            msg = self.m.recv_match(type=list(types), blocking=True, timeout=min(left, 0.2))
            if msg is not None and (cond is None or cond(msg)):
                return msg

    def ask(self, send, types, cond=None):
        for _ in range(self.tries):
            send()
            got = self.recv(types, cond, self.wait)
            if got is not None:
                return got
        return None

    def drain(self, seconds=0.2):
        """Drop what is queued (announcements, late answers) so the next answer is fresh."""
        self.recv((), None, seconds)

    def param(self, name):
        """A parameter's PARAM_VALUE, read now."""
        self.drain()
        return self.ask(lambda: self.m.mav.param_request_read_send(1, 1, name.encode(), -1), ("PARAM_VALUE",),
                        lambda m: m.param_id == name)

    def param_list(self):
        mav = self.m.mav
        values = {}
        count = None
        for attempt in range(self.tries):
            if count is None:
                mav.param_request_list_send(1, 1)
            else:
                for i in range(count):
                    if i not in values:
                        mav.param_request_read_send(1, 1, b"", i)
            while True:
                msg = self.recv(("PARAM_VALUE",), timeout=0.8)
                if msg is None:
                    break
                count = msg.param_count
                values[msg.param_index] = (msg.param_id, msg.param_value)
                if len(values) == count:
                    return {name: value for name, value in values.values()}
        return None

    def upload(self, items, mission_type=0):
        """-> "accepted" (the vehicle said so), "refused" (it said no before taking any item:
        the old plan stands), or "unsure" (items went and the last word was lost or was a
        NACK that may answer a stray copy of an item after the end: old or new, never a
        mix)."""
        mav = self.m.mav
        kinds = ("MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK")
        # MISSION_ACK names no upload: a late or duplicated ACK of the previous one would
        # pass for this one's. Let the link go quiet first, as command() does.
        self.drain(0.3)
        got = self.ask(lambda: mav.mission_count_send(1, 1, len(items), mission_type), kinds)
        last_sent = None
        silent = 0
        while True:
            if got is None:
                silent += 1
                if last_sent is None:
                    return "refused"
                if silent > 4:
                    return "unsure"
                self._item(last_sent, items[last_sent], mission_type)  # the answer may be lost
                got = self.recv(kinds, timeout=self.wait)
                continue
            silent = 0
            if got.get_type() == "MISSION_ACK":
                if getattr(got, "mission_type", 0) != mission_type:
                    got = self.recv(kinds, timeout=self.wait)
                    continue
                if got.type == MISSION_ACK_ACCEPTED:
                    return "accepted"
                return "refused" if last_sent is None else "unsure"
            if got.seq >= len(items):
                return "unsure"
            self._item(got.seq, items[got.seq], mission_type)
            last_sent = got.seq
            got = self.recv(kinds, timeout=self.wait * 2)

    def _item(self, seq, item, mission_type):
        frame, command, p1, p2, p3, p4, x, y, z = item
        self.m.mav.mission_item_int_send(1, 1, seq, frame, command, 0, 1, p1, p2, p3, p4, x, y, z, mission_type)

    def download(self, mission_type=0):
        mav = self.m.mav
        count = self.ask(lambda: mav.mission_request_list_send(1, 1, mission_type), ("MISSION_COUNT",),
                         lambda m: getattr(m, "mission_type", 0) == mission_type)
        if count is None:
            return None
        items = []
        for seq in range(count.count):
            got = self.ask(lambda: mav.mission_request_int_send(1, 1, seq, mission_type), ("MISSION_ITEM_INT",),
                           lambda m: m.seq == seq)
            if got is None:
                return None
            items.append((got.frame, got.command, got.param1, got.param2, got.param3, got.param4,
                          got.x, got.y, got.z))
        mav.mission_ack_send(1, 1, 0, mission_type)
        return items

    def command(self, command, *params):
        p = list(params) + [0.0] * (7 - len(params))
        # COMMAND_ACK names no request: a late or duplicated ACK of the previous command
        # would pass for this one's. Let the link go quiet first.
        self.drain(0.3)
        for confirmation in range(self.tries):
            self.m.mav.command_long_send(1, 1, command, confirmation, *p)
            ack = self.recv(("COMMAND_ACK",), lambda a: a.command == command, self.wait)
            if ack is not None:
                return ack.result
        return None
