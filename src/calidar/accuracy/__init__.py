"""Absolute accuracy against surveyed checkpoints: the ground TIN at each checkpoint and the
ASPRS statistics."""
