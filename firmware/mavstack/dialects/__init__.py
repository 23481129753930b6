"""Generated MAVLink dialects: one module per XML dialect."""
