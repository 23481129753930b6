"""The unix vehicle's services in-process on CPython, on an in-memory link, for the fuzzer:
its board profile (boards/unix.py) with signing added and the simulator as application,
storing under a directory, driven poll by poll on a simulated clock. `whole=True` builds
every service of the `make run` board (and the seed's extras of its application) in either
dialect, at a UDP link's budget: the vehicle the MicroPython engine fuzzes (live.py), in
process, for the list of what it handles and for the corpus' replay (replay.py).

Between fuzzed batches a ground station runs real exchanges that must still succeed
(`param_exchange`, `mission_exchange`, `command_exchange`); they sign their frames with
the vehicle's key when the fuzz turned signing on, as a ground station that holds the
key would.
"""
import math
import os
import random
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
for _p in (os.path.join(ROOT, "firmware"), os.path.join(ROOT, "boards"), os.path.join(ROOT, "tests", "mpy")):
    if _p not in sys.path:
        sys.path.insert(0, _p)

from harness import Bench  # noqa: E402
from mavstack.compat import ticks_add  # noqa: E402
from mavstack.endpoint import Reboot, Shutdown  # noqa: E402
from mavstack.services import compose  # noqa: E402
from pymavlink.dialects.v20 import common as mavlink2  # noqa: E402

from fuzz import frames  # noqa: E402

SERVICES = ("signing", "status", "params", "commands", "missions", "streams")
GCS = frames.EXCHANGE_GCS  # the well-behaved ground station of the exchanges
LINK_BYTES_PER_S = 5760  # a 57600 baud radio


class ExchangeFailed(AssertionError):
    """A real protocol exchange did not succeed between fuzzed batches."""


class Refused(Exception):
    """The vehicle refused an upload cleanly (it may be tried again)."""


def _board():
    import unix

    return unix


def _simulator(ep):
    from sim import Simulator

    return Simulator(ep)


class FuzzVehicle:
    def __init__(self, storage, seed=1, dialect="common", whole=False):
        self.storage = str(storage)
        self.dialect = dialect
        self.whole = whole
        self.rng = random.Random(seed)
        self.reboots = 0
        self._seq = 0
        self._stamp = 0  # the exchanges' last signing timestamp
        self._buf = bytearray(4096)
        self.dec = mavlink2.MAVLink(None)
        self.dec.robust_parsing = True
        self.decoding = False
        self.got = []
        self.build()

    # --- the vehicle ------------------------------------------------------------------
    def build(self):
        # The services are added here rather than by Bench, after the link is given a
        # radio's budget: the streams then send what a radio would carry, not 200 KB/s.
        board = _board()
        table = __import__("mavstack.dialects." + self.dialect, None, None, ("CRC_LEN",))
        self.bench = Bench(services=(), board=board, storage=self.storage, ring=16384, dialect=table,
                           options={"dialect": self.dialect})
        self.bench.drain = self._drain
        self.ep = self.bench.ep
        link = self.ep.links[0]
        if not self.whole:
            link.bytes_per_s = link.transport.bytes_per_s = LINK_BYTES_PER_S
        if self.whole:
            why = compose(self.ep, ("signing",) + board.SERVICES)
            if why:
                raise ValueError(why)
        else:
            for name in SERVICES:
                __import__("mavstack.services." + name, None, None, ("create",)).create(self.ep)
        self.bench.app = board.application(self.ep) if self.whole else _simulator(self.ep)
        self.now = self.bench.now
        self.params = self.ep.services["params"]
        self.missions = self.ep.services["missions"]
        self.streams = self.ep.services["streams"]
        self.signing = self.ep.services["signing"]
        self.structured = frames.Structured(self.ep._handlers, self.ep.commands,
                                            [self.params.name(i) for i in range(self.params.count)],
                                            self.ep.sysid, self.ep.compid, frames.layouts(self.dialect))

    def reboot(self):
        """What main.py does on Reboot: let the old vehicle go, build it again."""
        self.ep.close()
        for store in self.missions.stores:
            if store is not None:
                store.close()
        self.reboots += 1
        self.build()

    def _drain(self):
        b = self.bench
        while True:
            n = b.gcs_end.readinto(self._buf)
            if not n:
                return
            if self.decoding:
                for msg in self.dec.parse_buffer(bytes(self._buf[:n])) or ():
                    self.got.append(msg)

    def poll(self, steps=1, step_ms=1):
        """steps rounds of the main loop; Reboot rebuilds the vehicle, Shutdown too (a
        board that powers down comes back on the same storage)."""
        for _ in range(steps):
            try:
                self.bench.run(1, step_ms)
            except (Reboot, Shutdown):
                self.reboot()

    def feed(self, data):
        """Bytes to the vehicle, polling whenever the link's buffer is full."""
        gcs = self.bench.gcs_end
        o = 0
        while o < len(data):
            n = min(len(data) - o, 2048)
            chunk = data[o:o + n]
            while gcs.write(chunk, n) != n:
                self.poll()
            o += n

    def settle(self):
        """Every byte fed so far handled: the link's buffer emptied, and a candidate frame
        the parser still waits on finished by 300 zero bytes (a longer frame than any),
        so that what the bytes held (a frame for us inside a spliced candidate, found
        when it is scanned again) takes effect now, not in the next batch."""
        self.feed(bytes(300))
        while self.bench.gcs_end.outbound.count:
            self.poll()
        self.poll()

    # --- a well-behaved ground station ------------------------------------------------
    def send(self, name, *args):
        msg = getattr(self.dec, name + "_encode")(*args)
        lay = frames.LAYOUTS[msg.id]
        payload = bytearray(lay.len2)
        for field, value in zip(msg.fieldnames, (getattr(msg, f) for f in msg.fieldnames)):
            _, ctype, n, _ = lay.fields[field]
            if n and ctype != "char":
                for k, v in enumerate(value):
                    frames.put(payload, lay, field, v, k)
            else:
                frames.put(payload, lay, field, value)
        key = None
        stamp = 0
        if self.signing.enabled:
            key = bytes(self.signing.key)
            stamp = self._stamp = max(self._stamp, int.from_bytes(bytes(self.signing.ts), "little")) + 1
        self._seq += 1
        self.feed(frames.encode(msg.id, payload, GCS[0], GCS[1], self._seq, 2, key, 0, stamp))

    def wait(self, types, cond=None, ms=1500):
        """Poll until a message of these types (matching cond) comes -> it, else None."""
        types = (types,) if isinstance(types, str) else types
        self.decoding = True
        try:
            for _ in range(ms // 5):
                for k, msg in enumerate(self.got):
                    if msg.get_type() in types and (cond is None or cond(msg)):
                        del self.got[:k + 1]
                        return msg
                del self.got[:]
                self.poll(1, 5)
        finally:
            self.decoding = False
        return None

    def quiesce(self, ms=6000):
        """Let time pass (abandoned transfers time out, saves fall due), output dropped."""
        self.poll(ms // 50, 50)

    def ask(self, name, args, types, cond=None, tries=5, ms=1000):
        """Send a request and wait for its answer, sending it again on silence as a ground
        station does (a reply the link's budget could not carry is dropped) -> it or None."""
        for _ in range(tries):
            self.send(name, *args)
            got = self.wait(types, cond, ms)
            if got is not None:
                return got
        return None

    def param_exchange(self):
        name = "SIM_SPEED"
        value = round(self.rng.uniform(1.0, 25.0), 2)
        got = self.ask("param_set", (1, 1, name.encode(), value, 9), "PARAM_VALUE",
                       lambda m: m.param_id == name and abs(m.param_value - value) < 1e-4)
        if got is None:
            raise ExchangeFailed("PARAM_SET %s=%s not answered with the value" % (name, value))
        got = self.ask("param_request_read", (1, 1, name.encode(), -1), "PARAM_VALUE",
                       lambda m: m.param_id == name)
        if got is None or abs(got.param_value - value) > 1e-4:
            raise ExchangeFailed("PARAM_REQUEST_READ %s answered %s (set %s)" % (name, got, value))
        return value

    def command_exchange(self):
        # REQUEST_MESSAGE AUTOPILOT_VERSION: an ACK, then the message. The confirmation
        # counts the tries, as the command protocol has it.
        for confirmation in range(5):
            self.send("command_long", 1, 1, 512, confirmation, 148, 0, 0, 0, 0, 0, 0)
            ack = self.wait("COMMAND_ACK", lambda m: m.command == 512)
            if ack is not None:
                break
        if ack is None or ack.result != 0:
            raise ExchangeFailed("REQUEST_MESSAGE answered %s" % ack)

    def signing_off(self):
        """SETUP_SIGNING with a zero key, signed with the key in force: signing off."""
        if not self.signing.enabled:
            return
        self.send("setup_signing", 1, 1, bytes(32), 0)
        self.poll(5)
        if self.signing.enabled:
            raise ExchangeFailed("SETUP_SIGNING with a zero key, signed, left signing on")

    def upload(self, items):
        """Items (seq, frame, command, current, autocontinue, p1..p4, x, y, z) as the vehicle
        asks for them; Refused on DENIED or cancelled, ExchangeFailed on anything else."""
        n = len(items)
        kinds = ("MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK")
        got = self.ask("mission_count", (1, 1, n, 0), kinds)
        for _ in range(4 * n + 8):
            if got is None:
                raise ExchangeFailed("mission upload: the vehicle went silent")
            if got.get_type() == "MISSION_ACK":
                if got.type in (14, 15):  # MAV_MISSION_DENIED, OPERATION_CANCELLED
                    raise Refused("MISSION_ACK %d" % got.type)
                if got.type != 0:
                    raise ExchangeFailed("mission upload: MISSION_ACK %d" % got.type)
                return
            seq, frame, cmd, cur, auto, p1, p2, p3, p4, x, y, z = items[got.seq]
            # The vehicle asks again for an item it did not get: no resend here.
            self.send("mission_item_int", 1, 1, seq, frame, cmd, cur, auto, p1, p2, p3, p4, x, y, z, 0)
            got = self.wait(kinds, ms=3000)
        raise ExchangeFailed("mission upload: no MISSION_ACK")

    def mission_exchange(self, n=3, attempts=3):
        """A small upload and its download. A DENIED or cancelled upload (a transfer the fuzz
        left open, a reply the budget dropped) is tried again after a pause, as a ground
        station would; failing every attempt is a failure."""
        for attempt in range(attempts):
            try:
                return self._mission_exchange(n)
            except Refused as e:
                if attempt == attempts - 1:
                    raise ExchangeFailed("mission upload refused %d times: %s" % (attempts, e))
                self.quiesce()

    def _mission_exchange(self, n):
        base = self.rng.randrange(1000)
        items = [(i, 3, 16, 0, 1, 0.0, 2.0, 0.0, float(base), 473977420 + i * 1000 + base, 85455940, 20.0 + i)
                 for i in range(n)]
        self.upload(items)
        count = self.ask("mission_request_list", (1, 1, 0), "MISSION_COUNT", lambda m: m.mission_type == 0)
        if count is None or count.count != n:
            raise ExchangeFailed("mission download: count %s, uploaded %d" % (count, n))
        for seq in range(n):
            item = self.ask("mission_request_int", (1, 1, seq, 0), "MISSION_ITEM_INT", lambda m: m.seq == seq)
            if item is None or item.x != items[seq][9] or not math.isclose(item.param4, float(base)):
                raise ExchangeFailed("mission download: item %d is %s" % (seq, item))
        self.send("mission_ack", 1, 1, 0, 0)
        self.poll(5)
