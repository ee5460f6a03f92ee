"""Tests of the measurement engine and router; cocotb benches in ``measurement_engine/``
and ``measurement_router/``."""
