"""Trajectory reconstruction from delivered points (``calidar trajectory``, issue #30).

The sensor's path and attitude of each flight line from the points alone: the returns of one pulse
lie on one ray from the sensor (Gatziolis & McGaughey 2019, Remote Sensing 11:2258), and the
scan-angle field is the beam's angle about the along-track axis, so each scan line is a planar fan
of rays from the sensor. ``lines`` splits flight lines, ``pulses`` keeps what the fit needs from
streamed chunks, ``scanlines`` gives the starting values, ``spline`` the time basis, ``fit`` the
robust least squares (``mounting``: the scanner's encoder and scan-plane terms; ``quantised``: scan
angles stored in whole degrees), ``result`` the trajectory and its σ.
"""
