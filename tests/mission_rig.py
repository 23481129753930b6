"""The missions service in-process (CPython) on the bench's in-memory link, with pymavlink
encoding what the ground stations send and decoding what the vehicle answers.

    r = Rig(tmp_path, services=("commands", "missions"), board=..., options=...)
    r.send("mission_count", 1, 1, 3, 0, sysid=255, v1=False)   any pymavlink *_encode
    r.run(ms)           advance the simulated clock, polling every ms
    r.take("MISSION_ACK") -> messages of that type the vehicle sent since the last take
    r.upload(items), r.download() -> items (MISSION_ITEM_INT form)
"""
import os
import sys

from conftest import ROOT
from mission_gcs import Item

sys.path.insert(0, os.path.join(ROOT, "tests", "mpy"))
from harness import Bench, Board  # noqa: E402
from pymavlink.dialects.v10 import common as mavlink1  # noqa: E402
from pymavlink.dialects.v20 import common as mavlink2  # noqa: E402


class MissionBoard(Board):
    MISSION_CAPACITY = 500
    FENCE_CAPACITY = 100
    RALLY_CAPACITY = 20


class Rig:
    def __init__(self, tmp_path, services=("commands", "missions"), board=MissionBoard, options=None,
                 dialect=None, name="st"):
        self.storage = str(tmp_path / name)
        self.b = Bench(services=services, board=board, options=options, storage=self.storage,
                       dialect=dialect)
        self.ep = self.b.ep
        self.missions = self.ep.services.get("missions")
        self.dec = mavlink2.MAVLink(None)
        self.dec.robust_parsing = True
        self.got = []
        self._gcs = {}
        self._buf = bytearray(2048)
        self.b.drain = self._drain  # the vehicle's bytes go to pymavlink as well

    def _drain(self):
        b = self.b
        while True:
            n = b.gcs_end.readinto(self._buf)
            if not n:
                return
            b.rx.feed(self._buf, n)
            data = bytes(self._buf[:n])
            for msg in self.dec.parse_buffer(data) or ():
                msg._raw = msg.get_msgbuf()
                self.got.append(msg)

    def mav(self, sysid=255, compid=190, v1=False):
        """A pymavlink encoder for one ground station; v1: a MAVLink 1 one, which knows
        no extension fields (mission_type arguments are dropped)."""
        key = (sysid, compid, v1)
        if key not in self._gcs:
            module = mavlink1 if v1 else mavlink2
            self._gcs[key] = module.MAVLink(None, srcSystem=sysid, srcComponent=compid)
        return self._gcs[key]

    def send(self, name, *args, sysid=255, compid=190, v1=False, run=2):
        mav = self.mav(sysid, compid, v1)
        encode = getattr(mav, name + "_encode")
        if v1:
            args = args[:encode.__code__.co_argcount - 1]
        msg = encode(*args)
        data = msg.pack(mav)
        assert self.b.send_raw(bytearray(data)) == len(data)
        self.run(run)

    def run(self, ms=1):
        self.b.run(ms)

    def take(self, type=None):
        if type is None:
            out, self.got = self.got, []
            return out
        types = type if isinstance(type, (list, tuple)) else [type]
        out = [m for m in self.got if m.get_type() in types]
        self.got = [m for m in self.got if m.get_type() not in types]
        return out

    def last(self, type):
        got = self.take(type)
        return got[-1] if got else None

    def item_args(self, seq, item, mission_type=0, target=(1, 1)):
        return (target[0], target[1], seq, item.frame, item.command, item.current, item.autocontinue,
                item.p1, item.p2, item.p3, item.p4, item.x, item.y, item.z, mission_type)

    def upload(self, items, mission_type=0, sysid=255, v1=False, as_int=True):
        """Answer every request as it comes -> the MISSION_ACK type (None: none came)."""
        self.take()
        self.send("mission_count", 1, 1, len(items), mission_type, sysid=sysid, v1=v1)
        name = "mission_item_int" if as_int else "mission_item"
        for _ in range(4 * len(items) + 1):
            got = self.take(["MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK"])
            acks = [g for g in got if g.get_type() == "MISSION_ACK" and g.target_system == sysid]
            if acks:
                return acks[-1].type
            reqs = [g for g in got if g.get_type() != "MISSION_ACK" and g.target_system == sysid]
            if not reqs:
                return None
            for req in reqs:
                item = items[req.seq]
                if not as_int and isinstance(item.x, int):
                    item = item._replace(x=item.x / 1e7, y=item.y / 1e7)
                self.send(name, *self.item_args(req.seq, item, mission_type), sysid=sysid, v1=v1, run=0)
            self.run(2)
        return None

    def download(self, mission_type=0, sysid=255, v1=False, as_int=True):
        self.take()
        self.send("mission_request_list", 1, 1, mission_type, sysid=sysid, v1=v1)
        counts = self.take("MISSION_COUNT")
        if not counts:
            return None
        items = []
        for seq in range(counts[-1].count):
            if as_int:
                self.send("mission_request_int", 1, 1, seq, mission_type, sysid=sysid, v1=v1)
                got = self.take("MISSION_ITEM_INT")
            else:
                self.send("mission_request", 1, 1, seq, mission_type, sysid=sysid, v1=v1)
                got = self.take("MISSION_ITEM")
            if not got or got[-1].seq != seq:
                return None
            g = got[-1]
            items.append(Item(g.frame, g.command, g.current, g.autocontinue, g.param1, g.param2, g.param3,
                              g.param4, g.x, g.y, g.z))
        self.send("mission_ack", 1, 1, 0, mission_type, sysid=sysid, v1=v1)
        return items
