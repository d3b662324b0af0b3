"""The budget arithmetic every algorithm shares (rlq/algos/base.py)."""

from rlq.algos.base import budget_note, rounded_note, updates_for_budget


def test_a_budget_takes_the_whole_updates_that_fit_and_at_least_one():
    assert updates_for_budget(2048, 512) == 4
    assert updates_for_budget(2047, 512) == 3
    assert updates_for_budget(100, 512) == 1


def test_a_budget_below_one_update_gets_a_note_saying_the_run_takes_one():
    assert budget_note(512, 512) is None
    assert budget_note(100, 512) == (
        "budget.env_steps=100 is below one update (512 env steps per seed): the run takes one update"
    )
    assert budget_note(2000, 64_000, iterations=True) == (
        "budget.env_steps=2000 is below one update (up to 64,000 env steps per seed): the run takes one update"
    )


def test_a_budget_rounded_down_to_whole_updates_gets_a_note():
    assert rounded_note(2048, 2048, 512) is None
    assert rounded_note(100, 512, 512) is None  # below one update: budget_note's
    assert rounded_note(2000, 1536, 512) == (
        "budget.env_steps=2,000 rounds down to 1,536 env steps per seed (3 whole updates of 512)"
    )
    assert rounded_note(2000, 1000, 500, iterations=True) is None
