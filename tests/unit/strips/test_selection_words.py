"""The excluded LAS classes are written once (strips.selection.EXCLUDED_GROUPS): the tuple the masks
use, the words of the report, the option's help and the error all come from it."""

from __future__ import annotations

import re

import numpy as np

from calidar.strips import selection
from calidar.strips.selection import EXCLUDED_CLASSES, EXCLUDED_GROUPS, excluded, excluded_words


def _numbers(text: str) -> set[int]:
    """Every class a text names: '3–5' counts 3, 4 and 5."""
    out: set[int] = set()
    for a, b in re.findall(r"(\d+)(?:–(\d+))?", text):
        out.update(range(int(a), int(b or a) + 1))
    return out


def test_the_words_name_exactly_the_excluded_classes():
    assert excluded_words() == "vegetation (3–5), noise (7, 18) and water (9)"
    assert _numbers(excluded_words()) == set(EXCLUDED_CLASSES)
    assert excluded_words(False) == "vegetation, noise and water"
    assert np.array_equal(excluded(np.arange(20)), np.isin(np.arange(20), [3, 4, 5, 7, 9, 18]))


def test_a_new_group_changes_words_and_mask_together(monkeypatch):
    groups = (*EXCLUDED_GROUPS, ("overlap", (12,)))
    monkeypatch.setattr(selection, "EXCLUDED_GROUPS", groups)
    words = selection.excluded_words()
    assert words.endswith("water (9) and overlap (12)") and _numbers(words) == {3, 4, 5, 7, 9, 12, 18}
