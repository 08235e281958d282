"""The one adjustment engine shared by every calibration (docs/architecture.md).

A problem implements :class:`ResidualProblem` (its parameters, row σ, residuals and Jacobian);
:func:`solve` takes it and the :class:`SolverOptions`:

>>> import numpy as np
>>> from calidar.adjust import FunctionProblem, Parameter, ParameterSet, SolverOptions, solve
>>> x = np.arange(5.0)
>>> ab = ParameterSet([Parameter("a", 0.0, "m"), Parameter("b", 0.0, "1")])
>>> line = FunctionProblem(lambda v: v["a"] + v["b"] * x - (1.0 + 2.0 * x), ab, sigma=0.1)
>>> sol = solve(line, SolverOptions(robust=None))
>>> round(sol.values["a"], 6), round(sol.values["b"], 6)
(1.0, 2.0)
"""

from calidar.adjust.parameters import Parameter, ParameterSet
from calidar.adjust.residuals import (Block, FunctionProblem, ResidualProblem, SolverOptions,
                                      Values, prior_groups)
from calidar.adjust.solution import Solution
from calidar.adjust.solver import estimate, solve

__all__ = ["Block", "FunctionProblem", "Parameter", "ParameterSet", "ResidualProblem", "Solution",
           "SolverOptions", "Values", "estimate", "prior_groups", "solve"]
