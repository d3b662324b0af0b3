"""A run's expected time, said before it compiles (conf/expected.yaml, rlq.run.checks.expected)."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from omegaconf import OmegaConf

from rlq.config.conf_dir import CONF_DIR
from rlq.run.checks.expected import expected, expected_line, shortfall_line
from tests.helpers import compose_config, run_cli_in_process, script_module

REPO = Path(__file__).resolve().parents[2]


def expected_table() -> dict:
    """conf/expected.yaml as plain data."""
    return OmegaConf.to_container(OmegaConf.load(CONF_DIR / "expected.yaml"))


def results_file(source: str) -> dict:
    """The results file a figure names (a path from the repository's root)."""
    return json.loads((REPO / source).read_text())


def test_every_figure_is_a_tuned_pairs_and_names_a_results_file():
    table = expected_table()
    for pair, machines in table["pairs"].items():
        assert (CONF_DIR / "tuned" / f"{pair}.yaml").is_file(), pair
        for machine in ("cpu", "gpu"):
            if machine in machines:
                assert (REPO / expected(pair, machine).source).is_file(), (pair, machine)
        if "alternative" in machines:
            assert (CONF_DIR / "tuned" / f"{'_'.join(machines['alternative'])}.yaml").is_file(), pair
    for source, device in table.get("devices", {}).items():  # a card named for a source the table has
        assert source in table["sources"] and device.startswith("one "), source


def test_each_gpu_figure_names_the_card_its_results_file_records():
    """devices: is copied by hand; the card it names (one H200 where it names none) is the file's own."""
    table = expected_table()
    for pair, machines in table["pairs"].items():
        if "gpu" in machines:
            found = expected(pair, "gpu")
            card = found.device.removeprefix("one ")
            assert card in results_file(found.source)["device"], (pair, card, found.source)


def numbers(tree: object):
    if isinstance(tree, dict):
        tree = list(tree.values())
    if isinstance(tree, list):
        for item in tree:
            yield from numbers(item)
    elif isinstance(tree, int | float) and not isinstance(tree, bool):
        yield float(tree)


def test_every_figure_is_copied_from_its_results_file():
    """The figures are copied by hand from result files: each must be one of its file's numbers, to 0.1 s."""
    table = expected_table()
    for pair, machines in table["pairs"].items():
        for machine in ("cpu", "gpu"):
            if machine in machines:
                figure = expected(pair, machine)
                found = numbers(results_file(figure.source))
                assert any(abs(value - figure.seconds) <= 0.05 + 1e-9 for value in found), (pair, machine)


def test_a_long_cpu_run_says_so_with_the_quick_alternatives():
    reinforce = compose_config("env=lunar", "algo=reinforce")
    line = expected_line(reinforce, {"env": "lunar", "algo": "reinforce", "machine": "cpu"})
    assert line.startswith("rlq: expected time: about 27 min on 2 idle CPU cores")
    assert "a GPU (52 s on one H200)" in line and "`rlq train algo=ppo env=lunar` (73 s here)" in line
    mapping = compose_config("env=lunar", "algo=map_elites")
    line = expected_line(mapping, {"env": "lunar", "algo": "map_elites", "machine": "cpu"})
    assert line.startswith("rlq: expected time: about 20 min on 2 idle CPU cores")
    assert "a GPU (56 s on one H200)" in line and "`rlq train algo=ppo env=lunar` (73 s here)" in line


def test_short_and_unmeasured_runs_and_other_budgets():
    cartpole = expected_line(compose_config(), {"env": "cartpole", "algo": "ppo", "machine": "cpu"})
    assert cartpole.startswith("rlq: expected time: about 13 s") and "quicker" not in cartpole
    dqn = expected_line(compose_config("env=lunar", "algo=dqn"), {"env": "lunar", "algo": "dqn", "machine": "cpu"})
    assert dqn.startswith("rlq: expected time: about 4 min on 2 idle CPU cores") and "quicker" not in dqn
    gpu = compose_config("env=lunar", "algo=dqn", "machine=gpu")  # its GPU budget: the figure's
    assert "about 43 s on one H200" in expected_line(gpu, {"env": "lunar", "algo": "dqn", "machine": "gpu"})
    es = expected_line(compose_config("env=lunar", "algo=es"), {"env": "lunar", "algo": "es", "machine": "cpu"})
    assert es.startswith("rlq: expected time: about 5 min on 2 idle CPU cores") and "quicker" not in es
    es_gpu = compose_config("env=lunar", "algo=es", "machine=gpu")  # its own recipe and figure on a GPU
    assert "about 41 s on one H200" in expected_line(es_gpu, {"env": "lunar", "algo": "es", "machine": "gpu"})
    pqn = expected_line(compose_config("env=lunar", "algo=pqn"), {"env": "lunar", "algo": "pqn", "machine": "cpu"})
    assert pqn.startswith("rlq: expected time: about 5 min on 2 idle CPU cores") and "quicker" not in pqn
    star = compose_config("env=brittle_star", "algo=dqn")  # MJX pairs: measured on a GPU only
    assert "not measured for this recipe (one H200: 120 s" in expected_line(
        star, {"env": "brittle_star", "algo": "dqn", "machine": "cpu"}
    )
    star_qd = compose_config("env=brittle_star", "algo=map_elites", "machine=gpu")  # measured on an H100: said so
    assert "about 2 min on one H100" in expected_line(
        star_qd, {"env": "brittle_star", "algo": "map_elites", "machine": "gpu"}
    )
    longer = compose_config("env=lunar", "algo=dqn", "budget.env_steps=1e6")  # never scaled: not said
    assert expected_line(longer, {"env": "lunar", "algo": "dqn", "machine": "cpu"}) is None
    assert expected_line(compose_config("num_seeds=3"), {"env": "cartpole", "algo": "ppo", "machine": "cpu"}) is None


def test_a_recipe_short_of_the_matrix_goal_says_what_it_reached_and_which_recipe_reaches_it(tmp_path):
    humanoid_es = {"env": "humanoid", "algo": "es", "machine": "gpu"}
    line = shortfall_line(compose_config("env=humanoid", "algo=es", "machine=gpu"), humanoid_es)
    assert line == (
        "rlq: this recipe falls short of the matrix's goal: greedy returns of 481-563 on 9 held-out seeds, against "
        "the threshold of 6000 (docs/matrix.md); `rlq train algo=ppo env=humanoid` reaches it"
    )
    longer = compose_config("env=humanoid", "algo=es", "machine=gpu", "budget.env_steps=6e8")  # not what was measured
    assert shortfall_line(longer, humanoid_es) is None
    walks = {"env": "humanoid", "algo": "ppo", "machine": "gpu"}
    assert shortfall_line(compose_config("env=humanoid", "algo=ppo", "machine=gpu"), walks) is None
    printed = run_cli_in_process("train", "algo=es", "env=humanoid", "machine=gpu", "--cfg", "job", cwd=tmp_path)
    assert printed.returncode == 0, printed.stderr
    assert "\n# this recipe falls short of the matrix's goal: greedy returns of 481-563" in printed.stdout


@pytest.mark.slow  # the matrix's section bootstraps every row's interval
def test_the_recipes_said_to_fall_short_are_those_the_matrix_lists_with_its_figures():
    """conf/expected.yaml's `short` is written by hand: its pairs are the ones whose seeds miss the matrix's goal, and
    its figures are those of the pair's GPU rows pooled as the matrix pools them (the range of the scores, or the
    seeds over the threshold, of all their seeds)."""
    with script_module("render_matrix") as render:
        files = render.result_files()
        _, _, goals = render.rows(files)
    seeds_short = ("on GPUs", "on 2 CPU cores")  # not the time goal: a slow recipe still reaches its threshold
    listed = {pair.replace(":", "_") for pair, why in goals.items() if any(w.endswith(seeds_short) for w in why)}
    said = {pair: entry["short"] for pair, entry in expected_table()["pairs"].items() if "short" in entry}
    assert set(said) == listed
    for pair, text in said.items():
        name, records = pair.replace("_", ":", 1), []
        for _, report in files:
            if report["machine"] in render.GPU_MACHINES:
                picked = render.pick(report["results"], name, "seeds") or render.pick(
                    report["results"], name, "single_seed"
                )
                records += [picked] if picked else []
        scores = [score for record in records for score in record["per_seed"]]
        over = sum(score >= record["threshold"]["value"] for record in records for score in record["per_seed"])
        figures = (f"{min(scores):.0f}-{max(scores):.0f} on {len(scores)} held-out seeds", f"{over} of {len(scores)}")
        assert any(figure in text for figure in figures), (pair, text, figures)


def test_the_cards_command_on_a_cpu_says_its_time_in_its_first_lines_and_stops_at_once(tmp_path):
    env = {**os.environ, "JAX_PLATFORMS": "cpu", "WANDB_MODE": "disabled"}
    cmd = [sys.executable, "-m", "rlq.cli", "train", "algo=dqn", "env=lunar"]
    proc = subprocess.Popen(cmd, cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    first: list[str] = []
    while len(first) < 5 and not any(line.startswith("rlq: expected time") for line in first):
        first.append(proc.stdout.readline())
    assert first[-1].startswith("rlq: expected time: about 4 min"), first
    deadline = time.monotonic() + 300  # metrics.jsonl: the signal handlers are in place, the programs compiling
    while not list(tmp_path.glob("outputs/*/*/metrics.jsonl")) and time.monotonic() < deadline:
        time.sleep(0.05)
    proc.send_signal(signal.SIGTERM)  # while it compiles: nothing to save, it ends at once
    rest, _ = proc.communicate(timeout=120)
    assert proc.returncode == 128 + signal.SIGTERM, "".join(first) + rest
    assert "rlq: stopped by SIGTERM before training began: nothing to save" in rest
