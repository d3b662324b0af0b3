"""Calibrate env=lunar (JAX) against Gymnasium's Box2D LunarLander-v3 with the heuristic controller.

Both simulators run the same seeds with the same random draws (terrain, initial push, engine
dispersion, read from Box2D's generator); the JAX side runs all seeds vmapped with the jnp port
of Gymnasium's heuristic. Prints per-simulator summaries and the mean return difference.

    python scripts/calibrate_lunar.py --seeds 500 --json calib.json
"""

from __future__ import annotations

import argparse
import json
import time

import jax
import jax.numpy as jnp
import numpy as np
from gymnasium.envs.box2d.lunar_lander import heuristic as gym_heuristic

from rlq.envs.lunar import consts as C
from rlq.envs.lunar.box2d_reference import LunarBox2D
from rlq.envs.lunar.env import LunarLander
from rlq.envs.lunar.heuristic import heuristic_episodes
from rlq.envs.lunar.physics.step import SolverConfig

MAX_STEPS = 1000
VY_SCALE = C.FPS / (C.H / 2)  # observation vy -> m/s


class _Unwrapped:
    """What Gymnasium's ``heuristic(env, s)`` reads from ``env``."""

    def __init__(self, continuous: bool):
        self.continuous = continuous
        self.unwrapped = self


def run_box2d(seeds: list[int], continuous: bool, wind: bool) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """Heuristic episodes on Box2D; also returns every seed's random draws."""
    env = LunarBox2D(continuous=continuous, enable_wind=wind, max_episode_steps=MAX_STEPS)
    fake = _Unwrapped(continuous)
    rows, draws = [], []
    for seed in seeds:
        draws.append(env.draws(seed, MAX_STEPS))
        obs, _ = env.reset(seed)
        ret, t, first, vy_before = 0.0, 0, -1, np.nan
        while True:
            prev = obs
            obs, reward, terminated, truncated, _ = env.step(gym_heuristic(fake, obs))
            ret += reward
            t += 1
            if first < 0 and (obs[6] or obs[7]):
                first, vy_before = t, float(prev[3]) * VY_SCALE
            if terminated or truncated:
                break
        landed = terminated and reward == 100
        rows.append((ret, t, landed, terminated and not landed, first, vy_before))
    env.close()
    stacked = {k: np.asarray([d[k] for d in draws]) for k in ("terrain", "init_force", "wind_idx", "dispersion")}
    return _columns(rows), stacked


def run_jax(
    draws: dict[str, np.ndarray], continuous: bool, wind: bool, solver: SolverConfig, batch: int
) -> dict[str, np.ndarray]:
    """The same episodes on env=lunar, all seeds vmapped (in batches of ``batch``)."""
    env = LunarLander(continuous=continuous, enable_wind=wind, max_episode_steps=MAX_STEPS, solver=solver)

    def episode_batch(terrain, force, wind_idx, dispersion):
        keys = jax.random.split(jax.random.PRNGKey(0), terrain.shape[0])
        state = jax.vmap(env.reset_with)(keys, terrain, force, wind_idx, dispersion)
        return heuristic_episodes(env, state, MAX_STEPS)

    run = jax.jit(episode_batch)
    parts = []
    n = draws["terrain"].shape[0]
    for i in range(0, n, batch):
        sl = slice(i, min(i + batch, n))
        res = run(
            *(jnp.asarray(draws[k][sl], jnp.float32) for k in ("terrain", "init_force", "wind_idx", "dispersion"))
        )
        parts.append(jax.device_get(res))
    res = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
    rows = zip(res["ret"], res["length"], res["landed"], res["crashed"], res["first"], res["vy"], strict=True)
    return _columns(list(rows))


def _columns(rows: list[tuple]) -> dict[str, np.ndarray]:
    cols = list(zip(*rows, strict=True))
    names = ("return", "length", "landed", "crashed", "first_contact", "touchdown_vy")
    return {name: np.asarray(col, float) for name, col in zip(names, cols, strict=True)}


def summarise(r: dict[str, np.ndarray]) -> dict[str, float]:
    landed = r["landed"] > 0
    contact_to_rest = (r["length"] - r["first_contact"])[landed & (r["first_contact"] > 0)]
    return {
        "mean_return": float(r["return"].mean()),
        "landing_rate": float(landed.mean()),
        "crash_rate": float((r["crashed"] > 0).mean()),
        "truncation_rate": float(((r["landed"] == 0) & (r["crashed"] == 0)).mean()),
        "mean_length": float(r["length"].mean()),
        "touchdown_speed": float(np.nanmean(-r["touchdown_vy"])),
        "contact_to_rest_steps": float(contact_to_rest.mean()) if contact_to_rest.size else float("nan"),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=500, help="seeds 0 .. N-1 (after --first-seed)")
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--variants", default="discrete,continuous")
    parser.add_argument("--velocity-iterations", type=int, default=SolverConfig.velocity_iterations)
    parser.add_argument("--position-iterations", type=int, default=SolverConfig.position_iterations)
    parser.add_argument("--wind", action="store_true", help="enable_wind (default wind and turbulence power)")
    parser.add_argument("--batch", type=int, default=500, help="seeds per vmapped JAX batch")
    parser.add_argument("--per-seed", action="store_true", help="print every seed's returns")
    parser.add_argument("--json", help="write the summaries (and per-seed returns) here")
    args = parser.parse_args()

    seeds = list(range(args.first_seed, args.first_seed + args.seeds))
    solver = SolverConfig(velocity_iterations=args.velocity_iterations, position_iterations=args.position_iterations)
    report: dict = {"seeds": [seeds[0], seeds[-1]], "wind": args.wind, "solver": solver.__dict__, "variants": {}}
    for variant in args.variants.split(","):
        continuous = variant == "continuous"
        t0 = time.time()
        box2d, draws = run_box2d(seeds, continuous, args.wind)
        t1 = time.time()
        jx = run_jax(draws, continuous, args.wind, solver, args.batch)
        t2 = time.time()
        sb, sj = summarise(box2d), summarise(jx)
        if args.per_seed:
            for i, seed in enumerate(seeds):
                print(f"{variant} seed {seed}: box2d {box2d['return'][i]:8.2f} jax {jx['return'][i]:8.2f}")
        print(f"\n== {variant} ({len(seeds)} seeds; box2d {t1 - t0:.0f} s, jax {t2 - t1:.0f} s)")
        print(f"{'':24s}{'box2d':>10s}{'jax':>10s}")
        for key in sb:
            print(f"{key:24s}{sb[key]:10.3f}{sj[key]:10.3f}")
        diff = float(jx["return"].mean() - box2d["return"].mean())
        print(f"{'mean return difference':24s}{diff:10.3f}   (jax - box2d)")
        report["variants"][variant] = {
            "box2d": sb,
            "jax": sj,
            "mean_return_difference": diff,
            "landing_rate_difference": sj["landing_rate"] - sb["landing_rate"],
            "per_seed_return": {"box2d": box2d["return"].tolist(), "jax": jx["return"].tolist()},
        }
    if args.json:
        with open(args.json, "w") as f:
            json.dump(report, f, indent=2)


if __name__ == "__main__":
    main()
