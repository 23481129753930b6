"""IdTable: a read-only table by message id kept as two constant tuples, in flash when
frozen: the FMT of a dialect of 64 messages or more (host_tools/mavgen.py)."""


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
