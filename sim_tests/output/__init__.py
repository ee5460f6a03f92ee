"""Tests of packets, the pose output, the UART and the host tool; cocotb bench in
``uart/``."""
