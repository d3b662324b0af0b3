"""`rlq eval run=<dir>`: greedy evaluation of a finished run's checkpoint.

The policy is rebuilt from the run's own config (`.hydra/config.yaml`) and checkpoint; the
evaluation env defaults to the training env and can be swapped (`env=lunar_box2d`) for a
reference simulator with the same spaces. JAX envs run all episodes in one compiled program;
host simulators (HostEnv) run on the host with a jitted policy.
"""

from __future__ import annotations

import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from rlq.config.recorded import env_choice, recorded_spec
from rlq.config.spec import RunSpec, as_spec, with_values
from rlq.errors import ConfigError, RunDirError
from rlq.lib.batch import seed_entry
from rlq.lib.env_api import Env, HostEnv
from rlq.lib.rollout import PolicyFn, evaluate
from rlq.lib.spaces import AgentsDiscrete, Discrete, Space
from rlq.run.checks.memory import check_evaluation_size, free_bytes
from rlq.run.checks.validate import check_run_config, check_time_limit
from rlq.run.programs import members
from rlq.run.programs.build import Programs, build
from rlq.run.programs.env_stack import checked_env
from rlq.store import checkpoint
from rlq.store.lock import remove_leftovers
from rlq.tools.env_overrides import with_env_overrides


def load_run_config(run_dir: Path) -> RunSpec:
    """A run's ``.hydra/config.yaml`` as a RunSpec, checked as `rlq train` checks a new one (nothing compiled)."""
    run_dir = Path(run_dir)
    if not run_dir.is_dir():
        raise RunDirError(f"run={run_dir} is not a directory; give a run directory written by `rlq train`")
    path = run_dir / ".hydra" / "config.yaml"
    if not path.exists():
        raise RunDirError(f"{run_dir} is not an rlq run directory (no .hydra/config.yaml)")
    removed = remove_leftovers(run_dir)
    if removed:
        names = ", ".join(str(p.relative_to(run_dir)) for p in removed)
        print(f"rlq: note: removed what a stopped write left in {run_dir}: {names}", file=sys.stderr, flush=True)
    spec = recorded_spec(path)
    # the devices it trained on may not be here (eval, render, resume choose theirs: over several processes all of
    # theirs); nor may its processes (`rlq resume` joins those srun started: rlq/cli/resume.py)
    checked = with_values(
        spec,
        {
            "devices": 1 if jax.process_count() == 1 else None,
            "distributed": {"enabled": False, "coordinator_address": None, "num_processes": None, "process_id": None},
        },
    )
    try:
        check_run_config(checked, memory=False)
    except ConfigError as err:
        raise RunDirError(f"{path} does not describe a run rlq can rebuild: {err}") from None
    except Exception as err:  # a key deeper down that was cut off
        raise RunDirError(f"{path} is truncated or corrupt: {type(err).__name__}: {str(err).splitlines()[0]}") from None
    return spec


def eval_env_config(run: RunSpec | Mapping[str, Any], env_name: str | None, env_overrides: list[str]) -> RunSpec:
    """``spec`` with the env `rlq eval`/`rlq render` step: the run's evaluation env (``eval.env`` over its
    env), or ``env_name`` with its defaults, and the ``env.<key>=<value>`` overrides checked as `rlq train`
    checks them (rlq.tools.env_overrides.with_env_overrides)."""
    return with_env_overrides(env_choice(as_spec(run), env_name), env_overrides)


def _spaces_text(env: Env | HostEnv) -> str:
    """``observations of shape (4,) and actions Discrete(2)``."""

    def text(space: Space) -> str:
        if isinstance(space, AgentsDiscrete):
            return f"Discrete({space.n}) for each of {space.agents} agents"
        return f"Discrete({space.n})" if isinstance(space, Discrete) else f"of shape {space.shape}"

    return f"observations {text(env.observation_space)} and actions {text(env.action_space)}"


def _space_kind(space: Space) -> tuple[str, object]:
    """What a policy's input or output depends on: Discrete's size (and agents), a Box's shape (not its bounds)."""
    if isinstance(space, AgentsDiscrete):
        return ("agents", (space.n, space.agents))
    return ("discrete", space.n) if isinstance(space, Discrete) else ("box", space.shape)


def check_policy_fits(run_spec: RunSpec, eval_spec: RunSpec, env: Env | HostEnv, env_overrides: list[str]) -> None:
    """``env`` (built from ``eval_spec``: another env, or ``env_overrides``) has the observation and action
    spaces of the env the run trained on, so its policy can act in it; raises ConfigError naming both."""
    run_env, eval_env = run_spec.env["name"], eval_spec.env["name"]
    trained = checked_env(run_spec, f"env={run_env}")
    if all(
        _space_kind(a) == _space_kind(b)
        for a, b in ((env.observation_space, trained.observation_space), (env.action_space, trained.action_space))
    ):
        return
    label = " ".join([f"env={eval_env}", *env_overrides])
    same_env = eval_env == run_env
    fix = (
        "drop the env overrides that change them"
        if same_env
        else f"choose an env with them (or leave env={eval_env} out)"
    )
    raise ConfigError(
        f"{label} gives {_spaces_text(env)}; this run's policy was trained on env={run_env}: "
        f"{_spaces_text(trained)}; {fix}"
    )


def evaluation_target(
    run: RunSpec | Mapping[str, Any], env_name: str | None, env_overrides: list[str], autoreset: bool = True
) -> tuple[RunSpec, Env]:
    """The spec and env `rlq eval` and `rlq render` step (``eval_env_config``), built with the env's
    own checks; another env (``env_name``) or ``env_overrides`` must fit the run's policy."""
    run_spec = as_spec(run)
    eval_spec = eval_env_config(run_spec, env_name, env_overrides)
    env = checked_env(eval_spec, f"env={eval_spec.env['name']}", autoreset=autoreset)
    if env_name or env_overrides:
        check_policy_fits(run_spec, eval_spec, env, env_overrides)
    return eval_spec, env


def host_episodes(env: HostEnv, policy: PolicyFn, seeds: list[int], key: jax.Array) -> dict[str, np.ndarray]:
    """One episode per seed on a host simulator, all side by side (``env`` and ``env.fresh()`` copies): one
    policy call per step for every episode at once, the finished ones' actions unused. Episode ``i``'s step
    ``t`` draws with ``fold_in(fold_in(key, i), t)``. Returns returns and lengths."""
    count = len(seeds)
    envs = [env] + [env.fresh() for _ in seeds[1:]]
    act = jax.jit(jax.vmap(lambda obs, episode_key, t: policy(obs, jax.random.fold_in(episode_key, t))))
    episode_keys = jax.vmap(lambda i: jax.random.fold_in(key, i))(jnp.arange(count))
    obs = np.stack([np.asarray(sim.reset(seed=seed)[0], np.float32) for sim, seed in zip(envs, seeds, strict=True)])
    returns, lengths, live = np.zeros(count), np.zeros(count, np.int32), np.ones(count, bool)
    while live.any():
        actions = np.asarray(act(obs, episode_keys, lengths))
        for i in np.flatnonzero(live):
            next_obs, reward, terminated, truncated, _ = envs[i].step(actions[i])
            obs[i] = np.asarray(next_obs, np.float32)
            returns[i] += float(reward)
            lengths[i] += 1
            limit = env.max_episode_steps is not None and lengths[i] >= env.max_episode_steps
            live[i] = not (terminated or truncated or limit)
    for sim in envs[1:]:
        sim.close()
    return {"return": returns, "length": lengths}


def restore_run(
    run_dir: Path, ckpt: str | None = None, spec: RunSpec | None = None, skipped: list[str] | None = None
) -> tuple[RunSpec, Programs, Any, Path]:
    """A run's spec (on one device), its rebuilt programs and its restored (all-seed) state; ``ckpt`` names the
    checkpoint as ``checkpoint.resolve`` reads it (default: the newest intact one, falling back past
    truncated or corrupt ones, whose notes go into ``skipped``). The config and checkpoint are checked
    before anything is compiled."""
    # evaluation and video take one seed at a time, whatever devices trained the run
    spec = with_values(load_run_config(run_dir) if spec is None else spec, {"devices": 1})
    if members.sweeping(spec):  # its checkpoint holds every member's seeds, its config one member's
        first = Path(run_dir) / members.MEMBERS_DIR / members.member_dirname(members.members(spec)[0])
        raise ConfigError(f"{run_dir} is an in-program sweep's run: give one of its members' directories, e.g. {first}")
    path, notes = checkpoint.resolve_noting(run_dir, ckpt, spec.values)
    if skipped is not None:
        skipped.extend(notes)
    checkpoint.verify(path)
    program = members.program_config(spec)
    programs = build(program)
    template = jax.eval_shape(programs.init, members.init_keys(program), programs.hyper_shape)
    return spec, programs, jax.device_put(members.load_state(path, template, program)), path


def evaluate_run(
    run_dir: Path,
    env_name: str | None = None,
    episodes: int = 100,
    seed: int = 0,
    env_overrides: list[str] | None = None,
    ckpt: str | None = None,
) -> dict[str, Any]:
    """Evaluate every seed of a run; returns per-seed mean returns, the overall mean and every episode's
    return (``episode_returns``: one list per seed, for the spread)."""
    run_spec = load_run_config(run_dir)
    eval_spec, env = evaluation_target(run_spec, env_name, env_overrides or [])
    check_time_limit(env, f"env={eval_spec.env['name']}")
    if not isinstance(env, HostEnv):
        check_evaluation_size(env, episodes, free_bytes())
    skipped: list[str] = []
    spec, programs, state, path = restore_run(run_dir, ckpt, run_spec, skipped)
    key = jax.random.PRNGKey(seed)
    per_seed = []
    num_seeds = int(spec.seeds.count)
    for i in range(num_seeds):
        policy = programs.algo.policy(seed_entry(state, i, num_seeds))
        if isinstance(env, HostEnv):
            record = host_episodes(env, policy, [seed + e for e in range(episodes)], jax.random.fold_in(key, i))
        else:
            raw = jax.jit(lambda k, p=policy: evaluate(env, p, k, episodes))(jax.random.fold_in(key, i))
            record = {"return": np.asarray(raw["episode_return"]), "length": np.asarray(raw["episode_length"])}
        per_seed.append(record)
    returns = [float(np.mean(r["return"])) for r in per_seed]
    state_metrics = {}
    if programs.algo.state_metrics is not None:
        values = jax.device_get(jax.jit(jax.vmap(programs.algo.state_metrics))(state))
        state_metrics = {k: [float(x) for x in np.asarray(v)] for k, v in values.items()}
    return {
        "run": str(run_dir),
        "state_metrics": state_metrics,
        "env": eval_spec.env["name"],
        "env_overrides": list(env_overrides or []),
        "episodes": episodes,
        "seed": seed,
        "checkpoint": str(path),
        "skipped_checkpoints": skipped,
        "per_seed_return": returns,
        "episode_returns": [[float(x) for x in r["return"]] for r in per_seed],
        "mean_return": float(np.mean(returns)),
        "min_seed_return": float(np.min(returns)),
    }
