"""Errors that reach the user as one clear line (the CLI prints them and exits non-zero)."""

from __future__ import annotations

from os import PathLike


class CalidarError(Exception):
    """Base class of every error calidar reports to a user."""


class InputError(CalidarError):
    """Bad input: names the file, the field and what was expected.

    >>> str(InputError("sbet.out", "size", "expected a multiple of 136 bytes, got 1000"))
    'sbet.out: size: expected a multiple of 136 bytes, got 1000'
    """

    def __init__(self, source: str | PathLike | None, field: str | None, problem: str):
        self.source = None if source is None else str(source)
        self.field = field
        self.problem = problem
        parts = [p for p in (self.source, field) if p]
        super().__init__(": ".join(parts + [problem]) if parts else problem)

    def __reduce__(self):  # rebuilt from its parts (errors raised in Dask tasks travel pickled)
        return type(self), (self.source, self.field, self.problem)


class OutputExistsError(CalidarError):
    """An output exists and --force was not given."""


class CalibrationError(CalidarError):
    """A calibration cannot proceed (no usable data, divergence, ...)."""


class OutputWriteError(CalidarError):
    """The results cannot be written (a full disk, a read-only or unwritable destination)."""
