"""Read-only tables by message id kept as constants, in flash when frozen
(host_tools/mavgen.py): InfoTable, every dialect's CRC_LEN; IdTable, the FMT of a dialect
of 64 messages or more."""
from ..kernels import id_info


class IdTable:
    """A read-only table by message id, as two tuples of constants (the ids ascending, their
    values), which a frozen module keeps in flash: read like a dict (d[id], get, in, len,
    iteration, keys, items), found by bisection. The runtime modules' FMT, read at start-up."""

    def __init__(self, ids, values):
        self.ids = ids
        self.values = values

    def _at(self, msgid):
        ids = self.ids
        lo, hi = 0, len(ids)
        while lo < hi:
            mid = (lo + hi) >> 1
            if ids[mid] < msgid:
                lo = mid + 1
            else:
                hi = mid
        return lo if lo < len(ids) and ids[lo] == msgid else -1

    def get(self, msgid, default=None):
        i = self._at(msgid)
        return default if i < 0 else self.values[i]

    def __getitem__(self, msgid):
        i = self._at(msgid)
        if i < 0:
            raise KeyError(msgid)
        return self.values[i]

    def __contains__(self, msgid):
        return self._at(msgid) >= 0

    def __len__(self):
        return len(self.ids)

    def __iter__(self):
        return iter(self.ids)

    def keys(self):
        return self.ids

    def items(self):
        return zip(self.ids, self.values)


class InfoTable:
    """A dialect's CRC_LEN, id -> crc_extra | len1 << 8 | len2 << 16, as one constant
    block that the parser's and encoder's kernels read in place (kernels.id_info; its
    layout: docs/core.md). Read like a dict (d[id], get, in, len, iteration, keys, items)
    where a frame is not in hand: at start-up, by services, by tests."""

    def __init__(self, block):
        self.block = block

    def get(self, msgid, default=None):
        v = id_info(self.block, msgid)
        return v if v else default

    def __getitem__(self, msgid):
        v = id_info(self.block, msgid)
        if not v:
            raise KeyError(msgid)
        return v

    def __contains__(self, msgid):
        return id_info(self.block, msgid) != 0

    def keys(self):
        b = self.block
        ids = [i for i in range(256) if b[3 * i + 2]]  # (every message has a length)
        for j in range(770, 770 + 6 * (b[768] | b[769] << 8), 6):
            ids.append(b[j] | b[j + 1] << 8 | b[j + 2] << 16)
        return ids

    def __len__(self):
        return len(self.keys())

    def __iter__(self):
        return iter(self.keys())

    def items(self):
        return [(i, id_info(self.block, i)) for i in self.keys()]
