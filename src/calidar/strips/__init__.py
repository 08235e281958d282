"""Strip adjustment: overlaps, correspondences (tie planes, VGICP), calibration, quality."""
