"""Bit-accurate models of the measurement stage (:mod:`hdl.measurement`)."""
