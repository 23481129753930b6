"""The fuzzer of the parser and of the vehicle's frame handling, run in-process on CPython.

    frames.py      message layouts, a frame encoder (MAVLink 1 and 2, signed), structured
                   frames with random field values, the seed corpus (every message)
    rig.py         the unix vehicle's services on an in-memory link, and the ground-station
                   sequences that must still succeed between fuzzed batches
    invariants.py  the state checks run after every batch, and the storage snapshots
    engine.py      the loop: coverage-guided with atheris when installed, else a seeded
                   mutator over the same inputs (`python tests/fuzz/engine.py --seconds N`)
"""
