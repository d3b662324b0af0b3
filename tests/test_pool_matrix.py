"""scripts/pool_matrix.py: one pair's results of several programs of consecutive seeds pooled into one row, and
what it refuses (one line, exit 2): gaps or overlaps between the parts, parts of other commits, unscored parts."""

from __future__ import annotations

import json

import pytest

from tests.helpers import script_module

THRESHOLD = {"metric": "box2d", "value": 200.0, "why": "Box2D"}


@pytest.fixture(scope="module")
def pool():
    with script_module("pool_matrix") as module:
        yield module


def record(base: int, scores: list[float], **extra) -> dict:
    """A scored N-seed record as scripts/run_matrix.py writes it."""
    return {
        "pair": "lunar:map_elites",
        "env": "lunar",
        "algo": "map_elites",
        "kind": "seeds",
        "num_seeds": len(scores),
        "base_seed": base,
        "command": f"rlq train algo=map_elites env=lunar num_seeds={len(scores)} seed={base}",
        "threshold": THRESHOLD,
        "rc": 0,
        "process_wall_s": 10.0 * len(scores),
        "compile_s": 5.0,
        "machine": "h200",
        "date": "2026-12-03",
        "rlq_commit": "abc1234",
        "per_seed": scores,
        "over_threshold": sum(s >= 200.0 for s in scores),
        **extra,
    }


def test_parts_pool_into_one_record_in_seed_order(pool) -> None:
    records = [record(104, [250.0, 150.0, 210.0, 220.0]), record(100, [201.0, 202.0, 203.0, 204.0])]
    pooled = pool.pooled(records, "lunar:map_elites", [104, 100])
    assert (pooled["num_seeds"], pooled["base_seed"], pooled["over_threshold"]) == (8, 100, 7)
    assert pooled["per_seed"] == [201.0, 202.0, 203.0, 204.0, 250.0, 150.0, 210.0, 220.0]
    assert [p["process_wall_s"] for p in pooled["parts"]] == [40.0, 40.0]


@pytest.mark.parametrize(
    "records, bases, said",
    [
        ([record(100, [1.0] * 4), record(108, [1.0] * 4)], [100, 108], "seeds 104 .. 107 are missing"),
        ([record(100, [1.0] * 4), record(102, [1.0] * 4)], [100, 102], "missing or run twice"),
        ([record(100, [1.0] * 4), record(104, [1.0] * 4, rlq_commit="def5678")], [100, 104], "differ in rlq_commit"),
        ([record(100, [1.0] * 4)], [100, 104], "no lunar:map_elites result from base seed 104"),
        ([record(100, [1.0] * 4), record(104, [1.0], rc="timeout")], [100, 104], "did not run to a score"),
        ([record(100, [1.0] * 4)], [100], "at least two base seeds"),
    ],
)
def test_bad_parts_are_refused(pool, records, bases, said) -> None:
    with pytest.raises(pool.BadPair, match=said):
        pool.pooled(records, "lunar:map_elites", bases)


def test_parts_of_two_commits_pool_only_with_the_reason_kept(pool) -> None:
    records = [record(100, [201.0] * 4), record(104, [202.0] * 4, rlq_commit="def5678")]
    pooled = pool.pooled(records, "lunar:map_elites", [100, 104], commits_differ_because="only es.py changed")
    assert pooled["commits_differ_because"] == "only es.py changed"
    assert pooled["rlq_commit"] == "def5678"
    assert [p["rlq_commit"] for p in pooled["parts"]] == ["abc1234", "def5678"]
    assert "commits_differ_because" not in pool.pooled(
        [record(100, [201.0] * 4), record(104, [202.0] * 4)], "lunar:map_elites", [100, 104], "unused"
    )


def test_the_file_gets_the_pooled_record_and_bad_input_is_one_line(pool, tmp_path, capsys) -> None:
    out = tmp_path / "matrix_h200.json"
    out.write_text(json.dumps({"machine": "h200", "results": [record(100, [201.0] * 4), record(104, [202.0] * 4)]}))
    pool.main(["--pair", "lunar:map_elites", "--bases", "100", "104", "--out", str(out)])
    results = json.loads(out.read_text())["results"]
    assert [r["num_seeds"] for r in results] == [4, 4, 8]
    pool.main(["--pair", "lunar:map_elites", "--bases", "100", "104", "--out", str(out)])  # replaced, not added
    assert len(json.loads(out.read_text())["results"]) == 3
    capsys.readouterr()
    with pytest.raises(SystemExit) as ended:
        pool.main(["--pair", "lunar:nope", "--bases", "100", "104", "--out", str(out)])
    assert ended.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("pool_matrix: error: ")
