"""Tests of the front end: unit tests here, the cocotb bench in ``camera/``."""
