"""The one adjustment engine shared by every calibration (docs/architecture.md).

>>> from calidar.adjust import Parameter, ParameterSet, solve
"""

from calidar.adjust.parameters import Parameter, ParameterSet
from calidar.adjust.solution import Solution
from calidar.adjust.solver import solve

__all__ = ["Parameter", "ParameterSet", "Solution", "solve"]
