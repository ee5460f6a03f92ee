"""Running the HDL in a simulator: the cocotb runner (Verilator or Icarus), pin and
stream drivers, payload packing, bus access, and the co-simulation bench that
``rowtrack run`` uses. Product code: the tests import it, never the reverse."""
