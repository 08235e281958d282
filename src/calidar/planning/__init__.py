"""Calibration flight planning (``calidar plan``): predicted σ of a planned flight before it is
flown."""
