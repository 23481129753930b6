"""Gives key after key through SETUP_SIGNING, with timestamp saves in between, until killed
(the kill -9 test).

    signing_save_loop.py STORAGE_DIR

Key k holds k + 1 in its first 4 bytes (little-endian) and k in every other byte, so a
file mixing two writes shows. Prints `start k`, `key k` once key k is saved and
`ts T` after each timestamp save (T the timestamp saved).
"""
import struct
import sys

from harness import Bench


def key_payload(k):
    # SETUP_SIGNING: initial_timestamp (u64), target_system, target_component, secret_key[32]
    p = bytearray(42)
    struct.pack_into("<Q", p, 0, 1000 * k)
    p[8] = 1
    p[9] = 1
    for i in range(32):
        p[10 + i] = k & 0xFF
    struct.pack_into("<I", p, 10, k + 1)
    return p


def main():
    b = Bench(services=("signing",), storage=sys.argv[1], options={"signing_save_ms": "1"})
    sg = b.ep.services["signing"]
    k = struct.unpack_from("<I", sg.key, 0)[0] if sg.enabled else 0
    print("start", k)
    link = b.ep.links[0]
    while True:
        k += 1
        sg._on_setup(link, key_payload(k))  # as the frame arrives: key and timestamp saved
        print("key", k)
        for _ in range(3):
            b.run(1, 1000)  # a second on: the clock moves, the timestamp is saved
            print("ts", struct.unpack("<Q", bytes(sg.ts) + b"\0\0")[0])


main()
