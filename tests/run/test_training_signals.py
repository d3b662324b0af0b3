"""Training signals of the loop: the return window of every seed."""

import json

import numpy as np

from tests.conftest import train_run


def test_train_rows_carry_the_return_window(tmp_path):
    train_run(
        tmp_path,
        "budget.env_steps=4096",
        "log_every_steps=1024",
        "num_seeds=2",
        "eval.every_steps=0",
        "video.at_end=false",
        "return_window=10",
    )
    rows = [json.loads(line) for line in (tmp_path / "metrics.jsonl").read_text().splitlines()]
    train = [r for r in rows if r["kind"] == "train"]
    assert len(train) == 12 and all("return_window" in r for r in train)
    windows = [r["return_window"] for r in train if r["seed"] != "mean"]
    assert all(w is not None and 5 < w < 500 for w in windows)  # CartPole episodes of an untrained policy
    means = [r for r in train if r["seed"] == "mean"]
    per_seed = {(r["env_steps"], r["seed"]): r["return_window"] for r in train if r["seed"] != "mean"}
    for row in means:
        assert np.isclose(row["return_window"], np.mean([per_seed[(row["env_steps"], s)] for s in (0, 1)]))
