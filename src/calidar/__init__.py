"""calidar — open geometric calibration of laser scanning systems.

Units are SI and radians inside the library; degrees appear only at the user's edge
(CLI, files, report). Times are GPS seconds. See docs/conventions.md.
"""

__version__ = "0.1.0"
