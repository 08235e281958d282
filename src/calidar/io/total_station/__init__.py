"""Total-station observations for the range calibration of a circular-scan lidar (CSV).

The file is CSV (UTF-8, comma-separated) in three parts: ``#!`` directive lines, one
header row, data rows. Lines starting with ``#`` (and not ``#!``) and blank lines are
comments; CSV readers with ``comment='#'`` read the table unchanged. Example::

    #! calidar-total-station 1
    #! scanner_sigma_mm: 2.0
    #! setup: TS1 angle_arcsec=1.0 distance_mm=1.0 distance_ppm=1.5
    setup,group,point,hz_gon,zd_gon,slope_m,scanner_m
    TS1,,P,12.34567,98.76543,4.5210,
    TS1,G1,A,35.10000,99.10000,7.8123,5.1803
    ...
    TS1,,E1,60.00000,97.50000,21.0331,18.2290

Directives (each required once, ``setup`` once per total-station setup):

- ``#! calidar-total-station 1``: the format and its version;
- ``#! scanner_sigma_mm: S``: 1σ noise of one scanner range (mm);
- ``#! setup: ID angle_arcsec=a distance_mm=b distance_ppm=c``: a total-station setup
  and its stated precision: σ of a direction / vertical angle (arc-seconds) and of a
  slope distance, b mm + c ppm of the distance.

Columns (all required, any order, no others):

- ``setup``: id of a declared setup the observation was made from;
- ``group``: id of the scan-circle group for the feature points A–D, empty otherwise;
- ``point``: ``P`` (the scanner's mirror centre; one per setup), ``A`` ``B`` (on the scan
  circle, level with P), ``C`` ``D`` (plumb above / below P), or ``E…`` (step 2: the
  stopped beam's spot on an arbitrary target);
- ``hz_<u>``: horizontal direction, 0 ≤ hz < 360 deg (400 gon);
- ``va_<u>`` (vertical angle, −90…90 deg) *or* ``zd_<u>`` (zenith distance, 0…180 deg, face I);
- ``slope_m``: slope distance from the total station (m, > 0);
- ``scanner_m``: the scanner's range (m, > 0) for A–D and E points; empty for P.

``<u>`` is ``deg`` or ``gon`` and declares the angle unit; both angle columns must use the
same unit. Each group needs exactly one A, B, C and D, all from one setup. Every error
names the file, the line and what was expected. Inside, angles are radians (vertical
angles, zenith distances converted), distances metres, σ SI.
"""

from calidar.io.total_station.observations import (  # noqa: F401 - the format's public face
    ANGLE_UNITS, ARCSEC, FEATURE_POINTS, FORMAT_LINE, FULL_CIRCLE, MAX_DISTANCE_M, MAX_FILE_BYTES,
    MAX_SETUPS, MAX_TARGETS, Setup, TotalStationObservations,
)
from calidar.io.total_station.read import read_observations  # noqa: F401
from calidar.io.total_station.write import format_observations, write_observations  # noqa: F401
