"""Tests of the row-descriptor lanes and the golden descriptor; cocotb benches in
``row_descriptor/``."""
