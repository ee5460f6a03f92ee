"""Bit-accurate packets and UART timing (:mod:`hdl.output`) and the host-side receiver."""
