"""Commits plan after plan into a mission store until killed (the atomic-commit test).

    missions_commit_loop.py STORAGE_DIR

Plan k has 5 + (37 * k) % 150 items; item i carries k in param1 and i in param2, so a
plan made of two commits' records shows. Starts from the plan it finds (k + 1), and
prints `committed k` after each commit.
"""
import struct
import sys

from mavstack.services.missions.store import MissionStore, RECORD_SIZE
from mavstack.storage import Storage


def size(k):
    return 5 + (37 * k) % 150


def main():
    store = MissionStore(Storage(sys.argv[1]), "mission", 0, 500)
    rec = bytearray(RECORD_SIZE)
    k = 0
    if store.count and store.read(0, rec):
        k = int(struct.unpack_from("<f", rec, 0)[0]) + 1
    print("start", k, store.count)
    while True:
        n = size(k)
        store.begin()
        for i in range(n):
            struct.pack_into("<ffffiifHBB", rec, 0, k, i, 0, 0, 473977420 + i, 85455940, 10.0, 16, 3, 1)
            store.put(i, rec)
        store.seal(n)
        store.commit()
        print("committed", k)
        k += 1


main()
