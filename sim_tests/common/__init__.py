"""Tests of what every stage shares: fixed point, parameter checks, the dependency rule,
the block catalog, Verilog output, results docs, progress and the CLI."""
