"""The env × algo matrix's pairs and the one place their thresholds live (docs/matrix.md's "Thresholds"):
what a seed's final score is read from, and the value it must reach to count as a success."""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import asdict, dataclass
from pathlib import Path

#: the mark of run_matrix.py's result files among docs/results/matrix_*.json (render_matrix.py reads those only)
WRITTEN_BY = "scripts/run_matrix.py"

CONF = Path(__file__).resolve().parent.parent / "conf"

#: envs a pair may name: every env config but Gymnasium's host LunarLander (`rlq eval` only)
ENVS = tuple(sorted(p.stem for p in (CONF / "env").glob("*.yaml") if p.stem != "lunar_box2d"))
ALGOS = tuple(sorted(p.stem for p in (CONF / "algo").glob("*.yaml")))


class OneLineParser(argparse.ArgumentParser):
    """The matrix scripts' argument parser: a bad argument is one line, ``<script>: error: ...``, and exit 2."""

    def __init__(self, script: str, **kwargs) -> None:
        super().__init__(**kwargs)
        self.script = script

    def error(self, message: str) -> None:  # type: ignore[override]
        print(f"{self.script}: error: {message}", file=sys.stderr)
        raise SystemExit(2)


class BadPair(ValueError):
    """A pair name, seed count or threshold the matrix cannot run; its message is the one line to print."""


@dataclass(frozen=True)
class Threshold:
    """A seed succeeds when its ``metric`` reaches ``value`` (``None``: no threshold set, the score is reported)."""

    #: ``box2d`` (mean return over Gymnasium's Box2D episodes), ``eval_return`` (the run's final greedy
    #: evaluation) or a key of the run's ``final_eval`` (an env metric, e.g. ``distance_closed``)
    metric: str
    value: float | None
    #: where the value comes from, for the reader of a result file
    why: str

    def as_dict(self) -> dict:
        return asdict(self)


#: per env, then per (env, algo) where a pair differs from its env
BY_ENV = {
    "cartpole": Threshold("eval_return", 475.0, "CartPole greedy return"),
    "lunar": Threshold("box2d", 200.0, "mean return over 100 episodes of Gymnasium's Box2D LunarLander"),
    "humanoid": Threshold("eval_return", 6000.0, "humanoid greedy return"),
    "brittle_star": Threshold(
        "distance_closed", 0.16, "metres closed toward the 3 m target: the hand-made identity table's 0.16 m"
    ),
    "brittle_star_undirected": Threshold("distance_from_origin", None, "metres from the start; no threshold set"),
}
#: the undirected brittle star's MAP-Elites task (the tutorial's): the fitness is the energy spent, so the fittest
#: elite is the one that barely moves; the task's goals are the QD score and the furthest elite
FURTHEST_ELITE = Threshold(
    "furthest-distance-travelled",
    None,
    "metres from the start to where the archive's furthest elite ended (the task's goals: it and the QD score); "
    "no threshold set",
)
BY_PAIR = {
    ("brittle_star_undirected", "map_elites"): FURTHEST_ELITE,
    ("brittle_star_undirected", "random_search"): FURTHEST_ELITE,
    ("cartpole", "qlearning"): Threshold("eval_return", 195.0, "CartPole greedy return, tabular Q"),
    ("humanoid", "map_elites"): Threshold(
        "qd-score",
        546837.1,
        "the archive's QD score (the sum of its elites' returns, QDax's humanoid_uni fitness and offset 0) over "
        "feet-contact cells, at least what QDax 0.5.0's MAP-Elites holds on 15 of 16 seeds on the same evaluations "
        "(its second-lowest of seeds 0-15: docs/results/humanoid_map_elites_qdax_16_seeds.json)",
    ),
}


def threshold(env: str, algo: str) -> Threshold:
    return BY_PAIR.get((env, algo), BY_ENV[env])


#: the matrix's goals (issue "The matrix, second pass"), which the table reads each row against: at least 15 of
#: every 16 held-out seeds over the threshold, on 16 seeds or more; and, on one GPU, one cold seed's process (start to
#: exit) within a time per pair
SEEDS_GOAL = (15, 16)
GPU_MACHINES = ("h100", "h200")
#: one cold seed's seconds on a GPU, per env, then per (env, algo) where a pair differs (CartPole: none set)
SECONDS_BY_ENV = {"lunar": 60.0, "humanoid": 600.0, "brittle_star": 300.0, "brittle_star_undirected": 300.0}
SECONDS_BY_PAIR = {
    ("lunar", "reinforce"): 120.0,
    ("lunar", "random_search"): 120.0,
    ("humanoid", "ppo"): 60.0,
}


def seconds_goal(env: str, algo: str) -> float | None:
    """The goal for one cold seed's process on a GPU, in seconds (None: no time goal)."""
    return SECONDS_BY_PAIR.get((env, algo), SECONDS_BY_ENV.get(env))


def parse_pair(name: str) -> tuple[str, str]:
    """``env:algo`` as (env, algo); raises BadPair naming what is unknown."""
    env, sep, algo = name.partition(":")
    if not sep:
        raise BadPair(f"pair {name!r} is not env:algo (e.g. lunar:dqn)")
    if env not in ENVS:
        raise BadPair(f"pair {name!r}: unknown env {env!r} (one of {', '.join(ENVS)})")
    if algo not in ALGOS:
        raise BadPair(f"pair {name!r}: unknown algo {algo!r} (one of {', '.join(ALGOS)})")
    return env, algo


def parse_threshold(item: str, pairs: list[tuple[str, str]]) -> tuple[tuple[str, str], float]:
    """``env:algo=value``, a threshold in place of the pair's own, for a pair among ``pairs``."""
    name, sep, raw = item.partition("=")
    pair = parse_pair(name)
    if not sep:
        raise BadPair(f"threshold {item!r} is not env:algo=value")
    if pair not in pairs:
        raise BadPair(f"threshold {item!r} names a pair not in --pairs")
    try:
        value = float(raw)
    except ValueError:
        raise BadPair(f"threshold {item!r}: {raw!r} is not a number") from None
    if not math.isfinite(value):
        raise BadPair(f"threshold {item!r}: {raw!r} is not a finite number")
    return pair, value
