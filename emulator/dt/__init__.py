"""Bit-accurate model of the domain-transform filter (:mod:`hdl.dt`)."""
