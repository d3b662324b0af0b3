"""scripts/run_matrix.py's checks and records (no training): bad input refused with one line before anything
runs, the plain commands it runs, each seed's score read from the threshold's metric, results merged per file."""

from __future__ import annotations

import json

import pytest

from tests.helpers import REPO, quick_sample, script_module


@pytest.fixture(scope="module")
def matrix():
    with script_module("run_matrix") as module:
        yield module


@pytest.fixture(scope="module")
def pairs():
    with script_module("matrix_pairs") as module:
        yield module


@pytest.mark.parametrize(
    "argv, said",
    [
        (["--pairs", "cartpole:nope"], "unknown algo 'nope'"),
        (["--pairs", "moon:ppo"], "unknown env 'moon'"),
        (["--pairs", "cartpole"], "is not env:algo"),
        (["--pairs", "cartpole:ppo", "cartpole:ppo"], "named twice"),
        (["--pairs", "cartpole:ppo", "--seeds", "0"], "--seeds 0: needs at least 1 seed"),
        (["--pairs", "cartpole:ppo", "--seeds", "two"], "invalid int value"),
        (["--pairs", "cartpole:ppo", "--threshold", "cartpole:ppo=inf"], "not a finite number"),
        (["--pairs", "cartpole:ppo", "--threshold", "cartpole:ppo=high"], "'high' is not a number"),
        (["--pairs", "cartpole:ppo", "--threshold", "lunar:ppo=10"], "names a pair not in --pairs"),
        (["--pairs", "lunar_box2d:ppo"], "unknown env 'lunar_box2d'"),
        (["--pairs", "cartpole:ppo", "--episodes", "0"], "--episodes 0: needs at least 1 episode"),
        (["--pairs", "cartpole:ppo", "--timeout", "0"], "--timeout 0: needs a positive number of seconds"),
        (["--pairs", "cartpole:ppo", "--deadline", "-5"], "--deadline -5: needs a positive number of seconds"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(matrix, capsys, tmp_path, argv, said) -> None:
    out = tmp_path / "m.json"
    with pytest.raises(SystemExit) as exit_:
        matrix.main([*argv, "--machine", "cpu", "--out", str(out)])
    err = capsys.readouterr().err
    assert exit_.value.code == 2
    assert said in err and len(err.strip().splitlines()) == 1, err
    assert not out.exists()


def test_an_out_file_in_no_folder_is_refused_before_anything_runs(matrix, capsys, tmp_path) -> None:
    with pytest.raises(SystemExit) as exit_:
        matrix.main(["--pairs", "cartpole:ppo", "--machine", "cpu", "--out", str(tmp_path / "nowhere" / "m.json")])
    assert exit_.value.code == 2 and "no folder" in capsys.readouterr().err


def test_a_result_file_of_another_machine_is_refused(matrix, capsys, tmp_path) -> None:
    out = tmp_path / "m.json"
    out.write_text(json.dumps({"machine": "h200", "results": []}))
    with pytest.raises(SystemExit) as exit_:
        matrix.main(["--pairs", "cartpole:ppo", "--machine", "cpu", "--out", str(out)])
    assert exit_.value.code == 2 and "machine 'h200'" in capsys.readouterr().err


def test_the_commands_are_the_plain_ones(matrix) -> None:
    assert matrix.command("lunar", "dqn", 16, 5000) == ["algo=dqn", "env=lunar", "num_seeds=16", "seed=5000"]
    assert matrix.command("lunar", "dqn", None, 5000) == ["algo=dqn", "env=lunar", "seed=5000"]
    args = matrix.parse_args(["--pairs", "cartpole:ppo", "--machine", "m", "--out", "x.json"])
    assert (args.seeds, args.base_seed) == (16, 5000)


def test_every_pair_has_one_threshold_and_the_documented_values(pairs) -> None:
    for env in pairs.ENVS:
        for algo in pairs.ALGOS:
            assert isinstance(pairs.threshold(env, algo), pairs.Threshold)
    assert pairs.threshold("cartpole", "ppo").value == 475.0
    assert pairs.threshold("cartpole", "qlearning").value == 195.0
    assert pairs.threshold("lunar", "map_elites") == pairs.Threshold("box2d", 200.0, pairs.BY_ENV["lunar"].why)
    assert pairs.threshold("humanoid", "es").value == 6000.0
    assert pairs.threshold("brittle_star", "ppo").metric == "distance_closed"
    assert pairs.threshold("humanoid", "map_elites").metric == "qd-score"  # a QD pair: its archive's score
    # the undirected MAP-Elites task's fitness is the energy spent: its fittest elite stands still
    assert pairs.threshold("brittle_star_undirected", "map_elites").metric == "furthest-distance-travelled"


def test_the_humanoid_map_elites_threshold_is_qdax_s_15_of_16_level(pairs) -> None:
    """The humanoid MAP-Elites threshold is what QDax's MAP-Elites held on 15 of its 16 seeds on the same evaluations:
    the second-lowest QD score of the runs its file records."""
    qdax = json.loads((REPO / "docs" / "results" / "humanoid_map_elites_qdax_16_seeds.json").read_text())
    scores = sorted(run["qd_score"] for run in qdax["runs"])
    assert len(scores) == 16 and sorted(run["seed"] for run in qdax["runs"]) == list(range(16))
    assert pairs.threshold("humanoid", "map_elites").value == scores[1] == qdax["level_held_on_15_of_16"]


def test_threshold_given_replaces_the_pairs_own_metric_kept(matrix) -> None:
    args = matrix.parse_args(
        ["--pairs", "lunar:dqn", "--threshold", "lunar:dqn=210", "--machine", "m", "--out", "x.json"]
    )
    got = args.thresholds[("lunar", "dqn")]
    assert (got.metric, got.value) == ("box2d", 210.0)


def test_scores_come_from_the_thresholds_metric(matrix, pairs, tmp_path) -> None:
    summary = {"eval_return": [500.0, 470.0], "final_eval": {"distance_closed": [0.2, 0.1], "qd-score": [9e4, 8e4]}}
    assert matrix.scores(tmp_path, summary, pairs.threshold("cartpole", "ppo"), 100)["per_seed"] == [500.0, 470.0]
    assert matrix.scores(tmp_path, summary, pairs.threshold("brittle_star", "ppo"), 100)["per_seed"] == [0.2, 0.1]
    assert matrix.scores(tmp_path, summary, pairs.threshold("humanoid", "map_elites"), 100)["per_seed"] == [9e4, 8e4]
    with pytest.raises(RuntimeError, match="distance_from_origin"):
        matrix.scores(tmp_path, summary, pairs.threshold("brittle_star_undirected", "es"), 100)


def test_the_refusal_line_is_kept(matrix) -> None:
    stderr = "some warning\nrlq: error: env=lunar algo=qlearning has no tuned settings\n\n"
    assert matrix.error_line(stderr) == "rlq: error: env=lunar algo=qlearning has no tuned settings"
    assert matrix.error_line("Traceback\nKeyError: 'x'\n") == "KeyError: 'x'"


def test_results_are_merged_per_pair_and_seed_count(matrix, tmp_path) -> None:
    out = tmp_path / "m.json"
    args = matrix.parse_args(["--pairs", "cartpole:ppo", "--machine", "m", "--out", str(out)])
    args.device = "cpu | cpu"
    old = {"pair": "cartpole:ppo", "kind": "seeds", "num_seeds": 16, "base_seed": 5000, "per_seed": [1.0]}
    other = {**old, "pair": "cartpole:dqn"}
    matrix.save(out, args, [old, other])
    new = {**old, "per_seed": [2.0]}
    matrix.save(out, args, matrix.merged(matrix.load(out, "m"), new))
    results = json.loads(out.read_text())["results"]
    assert [(r["pair"], r["per_seed"]) for r in results] == [("cartpole:dqn", [1.0]), ("cartpole:ppo", [2.0])]


def test_a_run_is_scored_after_it_ends_and_a_pending_one_says_so(matrix, pairs, tmp_path) -> None:
    (tmp_path / "summary.json").write_text(json.dumps({"eval_return": [500.0, 300.0], "final_eval": {}}))
    limit = pairs.threshold("cartpole", "ppo").as_dict()
    pending = {"pair": "cartpole:ppo", "run_dir": str(tmp_path), "threshold": limit, "failed": "not scored yet"}
    scored = matrix.score(pending, episodes=100)
    assert "failed" not in scored and (scored["per_seed"], scored["over_threshold"]) == ([500.0, 300.0], 1)
    missing = {**pending, "threshold": pairs.threshold("brittle_star", "ppo").as_dict()}
    assert matrix.score(missing, episodes=100)["failed"].startswith("scoring: ")


def runs_of(matrix, tmp_path, monkeypatch, flags: list[str]) -> list[tuple]:
    """(num_seeds or None, the time limit) of each process ``run_matrix.py --pairs cartpole:ppo <flags>`` starts, none
    of them run (each one's record says it failed, so nothing is scored)."""
    ran = []

    def run_pair(env, algo, seeds, args, work, timeout):
        ran.append((seeds, timeout))
        kind = "seeds" if seeds else "single_seed"
        return {"pair": f"{env}:{algo}", "kind": kind, "num_seeds": seeds or 1, "base_seed": 5000, "rc": 1}

    monkeypatch.setattr(matrix, "run_pair", run_pair)
    argv = ["--pairs", "cartpole:ppo", "--machine", "test", "--out", str(tmp_path / "m.json"), *flags]
    matrix.main([*argv, "--work", str(tmp_path)])
    return ran


@pytest.mark.parametrize(
    "flags, limit",
    quick_sample([([], None), (["--timeout", "580"], 580.0), (["--deadline", "10000"], "deadline")], 3),
)
def test_a_process_runs_without_a_time_limit_unless_given_one(matrix, tmp_path, monkeypatch, flags, limit) -> None:
    ((_, timeout),) = runs_of(matrix, tmp_path, monkeypatch, flags)
    if limit == "deadline":
        assert 9990 < timeout <= 10000  # what is left of the deadline
    else:
        assert timeout == limit


@pytest.mark.parametrize(
    "flags, kinds",
    quick_sample([([], [16]), (["--single-seed"], [16, None]), (["--single-seed-only"], [None])], 3),
)
def test_single_seed_flags_choose_the_runs(matrix, tmp_path, monkeypatch, flags, kinds) -> None:
    assert [seeds for seeds, _ in runs_of(matrix, tmp_path, monkeypatch, flags)] == kinds
