"""Simulators that produce calidar inputs with a known truth."""
