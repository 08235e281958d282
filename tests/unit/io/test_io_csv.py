import io

import numpy as np
import pytest

from calidar.io.csv import write_csv_rows


def test_matches_printf_formatting():
    rng = np.random.default_rng(0)
    cols = [rng.uniform(-1e6, 1e6, 5000), rng.normal(0, 1, 5000), rng.integers(-50, 50, 5000).astype(float)]
    cols[1][:4] = [-0.00004, 0.00004, -0.0, 0.99999]
    f = io.StringIO()
    write_csv_rows(f, cols, [6, 4, 0], block_rows=777)
    lines = f.getvalue().splitlines()
    assert len(lines) == 5000
    back = np.array([[float(x) for x in ln.split(",")] for ln in lines])
    for c, d in zip(range(3), (6, 4, 0)):
        assert np.max(np.abs(back[:, c] - cols[c])) <= 0.5 * 10.0**-d + 1e-9  # + the float spacing at 1e6
    assert [ln.split(",")[1] for ln in lines[:4]] == ["0.0000", "0.0000", "0.0000", "1.0000"]  # no "-0.0000"
    same = sum(ln == ",".join([f"{cols[0][i]:.6f}", f"{cols[1][i]:.4f}", f"{cols[2][i]:.0f}"]) for i, ln in enumerate(lines))
    assert same >= 4990  # only exact half-way cases may round differently from printf


def test_nan_and_too_large():
    f = io.StringIO()
    write_csv_rows(f, [np.array([np.nan, 1.5])], [2])
    assert f.getvalue() == "nan\n1.50\n"
    with pytest.raises(ValueError, match="too large"):
        write_csv_rows(io.StringIO(), [np.array([1e15])], [6])
