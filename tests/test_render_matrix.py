"""docs/matrix.md's generated table agrees with its result files (scripts/render_matrix.py), every env × algo pair
has a row, and the cells hold what the files say: seeds over threshold / N, median, IQM [95 % CI], times."""

from __future__ import annotations

import json
import re

import pytest

from tests.helpers import script_module

SCORES = [250.0 + i for i in range(15)] + [112.0]


@pytest.fixture(scope="module")
def render():
    with script_module("render_matrix") as module:
        yield module


def result_file(folder, scores=SCORES, pair="lunar:dqn", **extra) -> None:
    """A result file as scripts/run_matrix.py writes it: one N-seed record and one single-seed record."""
    env, algo = pair.split(":")
    base = {"pair": pair, "env": env, "algo": algo, "base_seed": 5000, "machine": "h200", "date": "2026-12-02"}
    threshold = {"metric": "box2d", "value": 200.0, "why": "Box2D"}
    seeds = {**base, "kind": "seeds", "num_seeds": len(scores), "rc": 0, "process_wall_s": 61.25}
    seeds.update({"per_seed": scores, "threshold": threshold, **extra})
    single = {**base, "kind": "single_seed", "num_seeds": 1, "rc": 0, "process_wall_s": 47.4, "per_seed": [260.0]}
    single.update({"threshold": threshold, "over_threshold": 1})
    report = {"written_by": "scripts/run_matrix.py", "machine": "h200", "results": [seeds, single]}
    (folder / "matrix_h200_2026_12_02.json").write_text(json.dumps(report))


def table_rows(section: str) -> list[list[str]]:
    return [[c.strip() for c in line.strip("|").split("|")] for line in section.splitlines() if line.startswith("| ")]


def lunar_dqn_row(render, folder) -> list[str]:
    """The lunar:dqn row of the table generated from ``folder``'s result files."""
    return next(r for r in table_rows(render.section(render.result_files(folder))) if r[:2] == ["lunar", "dqn"])


@pytest.fixture(scope="module")
def section(render) -> str:
    """The generated section of the repository's result files, made once: each section bootstraps every
    pair's interval (rliable: about a minute on 2 busy cores)."""
    return render.section(render.result_files())


@pytest.mark.slow  # the section bootstraps every row's interval: 40 s of the quick tier's 2 cores
def test_the_page_agrees_with_its_result_files(render, section) -> None:
    """render.render(page, files) == page: the page's span from BEGIN to END is the generated section."""
    page = render.PAGE.read_text()
    start, stop = page.find(render.BEGIN), page.find(render.END)
    assert 0 <= start <= stop, "docs/matrix.md has no generated section"
    assert page[start : stop + len(render.END)] == section, "run: python scripts/render_matrix.py"


@pytest.mark.slow  # the same section
def test_every_pair_has_a_row_and_no_cell_is_over_120_characters(render, section) -> None:
    rows = table_rows(section)[1:]
    pairs = {(row[0], row[1]) for row in rows}
    assert pairs == {(env, algo) for env in render.ENVS for algo in render.ALGOS}
    assert all(len(cell) <= 120 for row in rows for cell in row), [c for r in rows for c in r if len(c) > 120]


def test_a_measured_row_shows_the_files_figures(render, tmp_path) -> None:
    result_file(tmp_path)
    files = render.result_files(tmp_path)
    row = next(r for r in table_rows(render.section(files)) if r[:2] == ["lunar", "dqn"])
    stats = render.seed_stats(SCORES, 200.0)
    assert row[3] == "15/16 ≥ 200 (h200)"
    assert row[4] == "256.5" and float(row[4]) == stats.median
    iqm, low, high = (float(x) for x in re.findall(r"[0-9.]+", row[5]))
    assert iqm == pytest.approx(stats.iqm, abs=0.05) and low <= iqm <= high
    assert row[6:9] == ["61.2 s", "47.4 s, 1/1", "met"] and row[9].endswith("matrix_h200_2026_12_02.json`")
    older = next(r for r in table_rows(render.section(files)) if r[:2] == ["lunar", "ppo"])
    assert older[3].startswith("older: ")


def test_seeds_pooled_from_several_programs_show_each_programs_time(render, tmp_path) -> None:
    parts = [{"base_seed": 5000, "num_seeds": 8, "process_wall_s": 96.61}, {"base_seed": 5008, "num_seeds": 8}]
    parts[1]["process_wall_s"] = 107.3
    result_file(tmp_path, parts=parts)
    row = lunar_dqn_row(render, tmp_path)
    assert row[3] == "15/16 ≥ 200 (h200)" and row[6] == "8 + 8 seeds: 96.6 s, 107 s"


def test_a_changed_score_changes_the_table(render, tmp_path) -> None:
    result_file(tmp_path)
    before = render.section(render.result_files(tmp_path))
    result_file(tmp_path, scores=[*SCORES[:-1], 201.0])
    after = render.section(render.result_files(tmp_path))
    assert before != after and "16/16 ≥ 200 (h200)" in after


def test_refused_and_failed_pairs_say_why(render, tmp_path) -> None:
    result_file(tmp_path, pair="cartpole:ppo", scores=[], failed="cut off after 600 s")
    report = json.loads((tmp_path / "matrix_h200_2026_12_02.json").read_text())
    del report["results"][0]["per_seed"]
    (tmp_path / "matrix_h200_2026_12_02.json").write_text(json.dumps(report))
    section = render.section(render.result_files(tmp_path))
    row = next(r for r in table_rows(section) if r[:2] == ["cartpole", "ppo"])
    assert row[3] == "failed (h200, below)"
    assert "- `cartpole:ppo` (h200): cut off after 600 s" in section
    assert "- `humanoid:dqn` refused: DQN chooses among discrete actions" in section


def test_other_matrix_files_are_not_read_and_a_page_without_markers_is_refused(render, tmp_path) -> None:
    (tmp_path / "matrix_plain_commands_h200.json").write_text(json.dumps({"runs": []}))
    assert render.result_files(tmp_path) == []
    with pytest.raises(render.RenderError, match="no generated section"):
        render.render("# a page\n", [])


def test_a_pair_with_only_a_single_seed_shows_it_once(render, tmp_path) -> None:
    """A pair measured only by one cold seed: that seed is its row, its time under the single seed's column alone."""
    result_file(tmp_path)
    report = json.loads((tmp_path / "matrix_h200_2026_12_02.json").read_text())
    report["results"] = [r for r in report["results"] if r["kind"] == "single_seed"]
    (tmp_path / "matrix_h200_2026_12_02.json").write_text(json.dumps(report))
    row = lunar_dqn_row(render, tmp_path)
    assert row[3] == "1/1 ≥ 200 (h200)" and row[4] == "260"
    assert row[6:8] == ["—", "47.4 s, 1/1"]


def goal_of(render, folder, **kwargs) -> str:
    result_file(folder, **kwargs)
    return lunar_dqn_row(render, folder)[8]


def test_the_goal_column_names_each_goal_a_row_misses_with_its_figure(render, tmp_path) -> None:
    """15 of 16 seeds over the threshold and, on a GPU, one cold seed within the pair's time (60 s for
    LunarLander DQN): "met", or each shortfall with the measured figure."""
    assert goal_of(render, tmp_path) == "met"
    assert goal_of(render, tmp_path, scores=[*SCORES[:-2], 150.0, 112.0]) == "14/16 under 15/16"
    assert goal_of(render, tmp_path, scores=SCORES[:8]) == "8 seeds of 16"
    report = json.loads((tmp_path / "matrix_h200_2026_12_02.json").read_text())
    report["results"][1]["process_wall_s"] = 71.6
    (tmp_path / "matrix_h200_2026_12_02.json").write_text(json.dumps(report))
    row = lunar_dqn_row(render, tmp_path)
    assert row[8] == "8 seeds of 16; 1 seed 71.6 s over 60.0 s"
    report["results"] = report["results"][:1]
    (tmp_path / "matrix_h200_2026_12_02.json").write_text(json.dumps(report))
    row = lunar_dqn_row(render, tmp_path)
    assert row[8] == "8 seeds of 16; 1 seed not timed"


def test_a_cpu_row_has_no_time_goal_and_a_row_without_threshold_says_so(render, tmp_path) -> None:
    result_file(tmp_path)
    report = json.loads((tmp_path / "matrix_h200_2026_12_02.json").read_text())
    report["machine"] = "cpu"
    for record in report["results"]:
        record["machine"], record["process_wall_s"] = "cpu", 900.0
    (tmp_path / "matrix_cpu_2026_12_02.json").write_text(json.dumps(report))
    (tmp_path / "matrix_h200_2026_12_02.json").unlink()
    row = lunar_dqn_row(render, tmp_path)
    assert row[8] == "met"
    for record in report["results"]:
        record["threshold"]["value"] = None
    (tmp_path / "matrix_cpu_2026_12_02.json").write_text(json.dumps(report))
    row = lunar_dqn_row(render, tmp_path)
    assert row[8] == "no threshold"


def goals_summary_of(render, folder) -> list[str]:
    """The generated lines that read the pairs against the goals, all rows of a pair together."""
    lines = render.section(render.result_files(folder)).splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith("Pairs against the goals"))
    stop = next(i for i in range(start + 1, len(lines)) if lines[i].startswith("Refused pairs"))
    return [line for line in lines[start:stop] if line]


def test_a_pair_is_read_against_the_goals_over_all_its_rows(render, tmp_path) -> None:
    """The seeds of a pair's GPU rows are pooled: 15/16 on one GPU and 1/1 on another meet the seeds goal together,
    where the one-seed row alone says "1 seed of 16"; every cold seed must be within the time, the slowest named."""
    result_file(tmp_path)
    report = json.loads((tmp_path / "matrix_h200_2026_12_02.json").read_text())
    single = {**report["results"][1], "machine": "h100", "process_wall_s": 55.0}
    h100 = {"written_by": "scripts/run_matrix.py", "machine": "h100", "results": [single]}
    (tmp_path / "matrix_h100_2026_12_05.json").write_text(json.dumps(h100))
    assert goals_summary_of(render, tmp_path)[0].endswith("1 of the 1 measured pairs with a threshold meet them.")
    rows = [r for r in table_rows(render.section(render.result_files(tmp_path))) if r[:2] == ["lunar", "dqn"]]
    assert [(r[3], r[8]) for r in rows] == [("1/1 ≥ 200 (h100)", "1 seed of 16"), ("15/16 ≥ 200 (h200)", "met")]
    single["process_wall_s"], single["per_seed"], single["over_threshold"] = 64.0, [150.0], 0
    (tmp_path / "matrix_h100_2026_12_05.json").write_text(json.dumps(h100))
    assert goals_summary_of(render, tmp_path)[1:] == [
        "- `lunar:dqn`: 15/17 under 15/16 on GPUs; 1 seed 64.0 s over 60.0 s (h100)"
    ]


def test_cartpole_pairs_must_meet_the_seeds_goal_on_2_cpu_cores_too(render, tmp_path) -> None:
    result_file(tmp_path, pair="cartpole:ppo", scores=[500.0] * 16)
    assert goals_summary_of(render, tmp_path)[1:] == ["- `cartpole:ppo`: not measured on 2 CPU cores"]
    report = json.loads((tmp_path / "matrix_h200_2026_12_02.json").read_text())
    report["machine"] = "cpu"
    for record in report["results"]:
        record["machine"] = "cpu"
        record["per_seed"] = [500.0] * 13 + [100.0] * 3 if record["kind"] == "seeds" else [500.0]
    (tmp_path / "matrix_cpu_2026_12_02.json").write_text(json.dumps(report))
    assert goals_summary_of(render, tmp_path)[1:] == ["- `cartpole:ppo`: 13/16 under 15/16 on 2 CPU cores"]
