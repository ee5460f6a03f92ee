"""Tests of the domain-transform filter and solver; cocotb bench in ``dt_filter/``."""
