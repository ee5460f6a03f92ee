"""Tests of the register map and register file; cocotb bench in ``regs/``."""
