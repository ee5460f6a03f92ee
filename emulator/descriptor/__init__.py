"""Bit-accurate models of the row-descriptor lanes' parts (:mod:`hdl.descriptor`); the
lane models are :mod:`emulator.row_descriptor`."""
