"""The fuzzer of the vehicle we ship (`make fuzz`, tests/test_fuzz.py, bench/bench_fuzz.py).

    engine.py      the command; also the second engine: the services in-process on CPython
    live.py        the MicroPython engine: batches, checkpoints, the report
    target.py      one MicroPython vehicle under fuzz: its batches confirmed, its corpus grown
    process.py     that vehicle as a process (the unix port, the make-run board with signing)
    wire.py        its udpin link from here: whole datagrams, the sentinel, signing stamps
    gcs.py         the well-behaved ground station: exchanges, and reads for the invariants
    frames.py      message layouts per dialect, an encoder, structured frames, seed frames
    invariants.py  what must hold, in process (rig.py) and for a vehicle in another process
    rig.py         the make-run board's services in-process, on a memory link
    corpus.py      the saved corpus (corpus/<dialect>.txt) and the features it is kept for
    replay.py      what the corpus reaches: replayed under coverage.py
Reference: docs/reliability.md.
"""
