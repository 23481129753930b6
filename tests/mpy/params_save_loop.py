"""Saves parameter set after parameter set until killed (the kill -9 test).

    params_save_loop.py STORAGE_DIR

Set k: BRD_SERIAL_NUM = k, SIM_SPEED = 0.5 + (k % 290) / 10, SYSID_MYGCS = k % 255 + 1,
so a file holding two sets' values shows. Starts from the set it finds (k + 1), prints
`start k` and `saved k` after each save.
"""
import sys

from harness import Bench, Board
from unix_params import PARAMS


class ParamsBoard(Board):
    PARAMS = PARAMS


def main():
    b = Bench(services=("params",), board=ParamsBoard, storage=sys.argv[1])
    p = b.ep.services["params"]
    k = p.get("BRD_SERIAL_NUM")
    print("start", k)
    while True:
        k += 1
        p.set("BRD_SERIAL_NUM", k)
        p.set("SIM_SPEED", 0.5 + (k % 290) / 10)
        p.set("SYSID_MYGCS", k % 255 + 1)
        if not p.save():
            print("failed", k)
        print("saved", k)


main()
