"""solution.json holds whatever a method puts in it: numpy scalars, infinite σ, NaN (issue 26: two of
thirty 2-CCR passes ended in "internal error" on a numpy bool and an inf)."""

from __future__ import annotations

import json

import numpy as np

from calidar.adjust import Parameter, ParameterSet, solve
from calidar.adjust.solution import json_ready
from calidar.io.json_file import write_json


def _strict(text: str):
    def refuse(token):
        raise AssertionError(f"{token} is not JSON")

    return json.loads(text, parse_constant=refuse)


def test_json_ready_makes_numpy_and_non_finite_values_plain():
    doc = json_ready({"a": np.bool_(True), "b": np.float64(np.inf), "c": [np.int64(3), float("nan"), -np.inf],
                      "d": np.arange(2.0), np.str_("k"): (1, np.float32(0.5)), "e": None, "f": "text"})
    assert doc == {"a": True, "b": None, "c": [3, None, None], "d": [0.0, 1.0], "k": [1, 0.5], "e": None,
                   "f": "text"}
    assert type(doc["a"]) is bool and type(doc["c"][0]) is int
    _strict(json.dumps(doc, allow_nan=False))


def test_solution_json_with_numpy_extras_and_infinities_is_written(tmp_path):
    params = ParameterSet([Parameter("a", 0.0, "m"), Parameter("b", 0.0, "m")])
    sol = solve(lambda v: np.array([v["a"] - 1.0, v["a"] + 1.0 - 2.0]), params)  # b unobservable: σ inf
    sol.extra.update({"open_low": np.bool_(False), "sigma": {"b": float("inf")}, "z": np.float64(-1.5),
                      "interval": np.array([8.75, np.nan])})
    doc = _strict(write_json(tmp_path / "solution.json", sol.to_dict()).read_text())
    assert doc["open_low"] is False and doc["sigma"] == {"b": None} and doc["z"] == -1.5
    assert doc["interval"] == [8.75, None] and doc["parameters"]["b"]["sigma"] is None
