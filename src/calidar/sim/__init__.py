"""Simulators that write inputs with a known truth."""
