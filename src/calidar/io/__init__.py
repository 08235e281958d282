"""Readers and writers of the files calidar meets: SBET and text trajectories, LAS/LAZ.

- :mod:`calidar.io.sbet`: Applanix SBET binary trajectories (read and write).
- :mod:`calidar.io.trajectory_text`: ASCII/CSV trajectories with named columns.
- :mod:`calidar.io.trajectory`: :func:`read_trajectory`, which picks one of the two.
- :mod:`calidar.io.las`: LAS/LAZ points with GPS time, scan angle, flight line, CRS.
"""

from calidar.io.las import LasPoints, iter_las_chunks, read_las, write_las
from calidar.io.sbet import read_sbet, write_sbet
from calidar.io.trajectory import read_trajectory
from calidar.io.trajectory_text import read_trajectory_text

__all__ = [
    "LasPoints", "iter_las_chunks", "read_las", "write_las", "read_sbet", "write_sbet",
    "read_trajectory", "read_trajectory_text",
]
