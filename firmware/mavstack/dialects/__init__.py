"""Generated MAVLink dialects: per XML dialect a runtime module (CRC_LEN, FMT: what the
stack needs on a board) and a *_meta module (message and enum names, for host tools
and applications); layout.py derives field layouts from the two."""

