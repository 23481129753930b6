"""Routing driver for instruction counts (bench_route.py runs this under callgrind).

    mpy_route.py STREAM MODE

An endpoint (system 1) with three links over null transports (they take every write,
budgeted at 200,000 B/s as UDP links are) and no services; the stream is fed to link 0's
parser in 4 KiB views, the clock 50 ms on for each. MODE 0 feeds nothing, 1 feeds it with no router, 2 with a router
(16 routes, link 1 having heard the frames' target): the difference between 2 and 1 is
what routing costs. Prints the kernels in use, the frames parsed, the frames forwarded
(one a link written to), and the heap a 16-route table holds (gc.mem_alloc).
"""
import gc
import sys

from mavstack import kernels
from mavstack.dialects import common
from mavstack.endpoint import Endpoint
from mavstack.router import Router

CHUNK = 4096


class Null:
    bytes_per_s = 200000
    name = "null"

    def readinto(self, buf):
        return 0

    def write(self, buf, n):
        return n

    def close(self):
        pass


def main(argv):
    with open(argv[0], "rb") as f:
        data = f.read()
    mv = memoryview(data)
    views = [mv[i:i + CHUNK] for i in range(0, len(data), CHUNK)]
    sizes = [len(v) for v in views]
    ep = Endpoint(common, 1, 1)
    for _ in range(3):
        ep.add_link(Null())
    gc.collect()
    before = gc.mem_alloc()
    router = Router(16, 10000, 0)
    gc.collect()
    table = gc.mem_alloc() - before
    if argv[1] == "2":
        ep.add(router)
        router.learn(255, 190, 1)  # the station the targeted frames go to, heard on link 1
    rx = ep.links[0].rx
    if argv[1] != "0":
        for i in range(len(views)):
            ep.now += 50  # (a simulated clock: the budget refills, as 4 KiB a poll would)
            rx.feed(views[i], sizes[i])
    print(kernels.IMPL, rx.frames, router.forwarded, table)


main(sys.argv[1:])
