"""tests/helpers.py's quick_sample: which cases of a long table the quick tier runs, and that the full suite runs
every one of them unchanged."""

from __future__ import annotations

import pytest

from tests.helpers import quick_sample


def slow(case) -> bool:
    return any(mark.name == "slow" for mark in getattr(case, "marks", ()))


def values(case) -> tuple:
    return tuple(case.values) if hasattr(case, "values") else case


def test_every_nth_case_stays_quick_and_the_others_keep_their_values_marked_slow():
    cases = [("a", 1), ("b", 2), ("c", 3), ("d", 4), ("e", 5)]
    sampled = quick_sample(cases, 2)
    assert [slow(case) for case in sampled] == [False, True, False, True, False]
    assert [values(case) for case in sampled] == cases


def test_a_case_with_its_own_marks_and_id_keeps_them():
    cases = ["x", pytest.param("y", marks=pytest.mark.skip, id="why")]
    _, second = quick_sample(cases, 2)
    assert second.id == "why" and {mark.name for mark in second.marks} == {"skip", "slow"}


def test_a_tuple_is_one_value_for_a_test_of_one_argument():
    cases = [("p", "q"), ("r", "s")]
    _, second = quick_sample(cases, 2, single=True)
    assert second.values == (("r", "s"),)
    _, second = quick_sample(cases, 2)
    assert second.values == ("r", "s")


def test_every_must_be_at_least_one():
    with pytest.raises(ValueError, match="every must be >= 1"):
        quick_sample([1, 2], 0)
