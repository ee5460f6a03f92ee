"""Tests of the golden models: simulator, tracker, temporal filter, metrics."""
