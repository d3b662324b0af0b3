"""`rlq eval run=<dir>`: greedy evaluation of a finished run's checkpoint.

The policy is rebuilt from the run's own config (`.hydra/config.yaml`) and checkpoint; the
evaluation env defaults to the training env and can be swapped (`env=lunar_box2d`) for a
reference simulator with the same spaces. JAX envs run all episodes in one compiled program;
host simulators (HostEnv) run on the host with a jitted policy.
"""

from __future__ import annotations

import copy
import sys
from pathlib import Path
from typing import Any, cast

import jax
import jax.numpy as jnp
import numpy as np
from omegaconf import DictConfig, OmegaConf

from rlq.config.compose import WITHOUT_TUNED, compose
from rlq.config.conf_dir import CONF_DIR
from rlq.errors import ConfigError, RunDirError
from rlq.lib.batch import seed_entry
from rlq.lib.env_api import Env, HostEnv
from rlq.lib.rollout import PolicyFn, evaluate
from rlq.lib.spaces import AgentsDiscrete, Discrete, Space
from rlq.run.checks.memory import check_evaluation_size, free_bytes
from rlq.run.checks.validate import check_run_config, check_time_limit
from rlq.run.programs import members
from rlq.run.programs.build import Programs, build
from rlq.run.programs.env_stack import checked_env, evaluation_config
from rlq.store import checkpoint
from rlq.store.lock import remove_leftovers
from rlq.tools.env_overrides import with_env_overrides

#: top-level keys every run config has; one without them was truncated
RUN_KEYS = ("seed", "num_seeds", "budget", "env", "controller", "algo", "logger", "eval", "checkpoint")


#: the config groups a run chose; everything else at the top level is a run-level option
COMPONENT_KEYS = ("env", "controller", "algo", "logger")


#: the config groups whose options added since a run was written come in at their defaults: those
#: whose configs name themselves (``name:``), so the run's choice can be read back (not the logger's)
OPTION_GROUPS = ("env", "algo", "controller")


def _over_defaults(defaults: DictConfig, cfg: DictConfig) -> DictConfig:
    """``cfg`` merged over a plain (unstructured, unflagged) copy of ``defaults``: ``cfg`` wins."""
    return cast(DictConfig, OmegaConf.merge(OmegaConf.create(OmegaConf.to_container(defaults)), cfg))


def with_current_run_defaults(cfg: DictConfig) -> DictConfig:
    """``cfg`` with the options added since it was written, at their defaults: run-level ones (e.g.
    ``program_cache`` for a run trained before it existed) and those of the env, algo and
    controller it chose (e.g. ``env.solver.sweep_layout``). The run's own choices and values win."""
    defaults = compose(WITHOUT_TUNED)
    run_level = OmegaConf.masked_copy(defaults, [str(k) for k in defaults if k not in COMPONENT_KEYS])
    merged = _over_defaults(run_level, cfg)
    chosen = {
        group: name
        for group in OPTION_GROUPS
        if isinstance(cfg.get(group), DictConfig)
        and isinstance(name := cfg[group].get("name"), str)
        and (CONF_DIR / group / f"{name}.yaml").exists()
    }
    if chosen:
        current = compose([*(f"{group}={name}" for group, name in chosen.items()), *WITHOUT_TUNED])
        for group in chosen:
            merged[group] = _over_defaults(current[group], merged[group])
    return merged


def load_run_config(run_dir: Path) -> DictConfig:
    """A run's ``.hydra/config.yaml``, checked as `rlq train` checks a new one (nothing compiled)."""
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
    try:
        cfg = OmegaConf.load(path)
    except Exception as err:
        raise RunDirError(f"{path} is unreadable (truncated or corrupt): {str(err).splitlines()[0]}") from None
    missing = [k for k in RUN_KEYS if not isinstance(cfg, DictConfig) or k not in cfg]
    if missing:
        raise RunDirError(f"{path} is truncated or corrupt: no {', '.join(missing)}")
    cfg = with_current_run_defaults(cast(DictConfig, cfg))
    checked = cast(DictConfig, cfg.copy())
    if "devices" in checked:  # the devices it trained on may not be here; eval, render, resume choose theirs
        checked.devices = 1 if jax.process_count() == 1 else None  # over several processes: all of theirs
    if "distributed" in checked:  # so may its processes: `rlq resume` joins those srun started (rlq/cli/resume.py)
        checked.distributed = {"enabled": False}
    try:
        check_run_config(checked, memory=False)
    except ConfigError as err:
        raise RunDirError(f"{path} does not describe a run rlq can rebuild: {err}") from None
    except Exception as err:  # a key deeper down that was cut off
        raise RunDirError(f"{path} is truncated or corrupt: {type(err).__name__}: {str(err).splitlines()[0]}") from None
    return cast(DictConfig, cfg)


def eval_env_config(cfg: DictConfig, env_name: str | None, env_overrides: list[str]) -> DictConfig:
    """``cfg`` with the env `rlq eval`/`rlq render` step: the run's evaluation env (``eval.env`` over its
    env), or ``env_name`` with its defaults, and the ``env.<key>=<value>`` overrides checked as `rlq train`
    checks them (rlq.tools.env_overrides.with_env_overrides)."""
    env_cfg = copy.deepcopy(evaluation_config(cfg).env)  # the run's evaluation env (eval.env), changed below
    if env_name:
        path = CONF_DIR / "env" / f"{env_name}.yaml"
        if not path.exists():
            options = sorted(p.stem for p in (CONF_DIR / "env").glob("*.yaml"))
            raise ConfigError(f"unknown env '{env_name}'; choose one of: {', '.join(options)}")
        env_cfg = compose([f"env={env_name}", *WITHOUT_TUNED]).env  # with its own defaults (env/physics)
    out = cfg.copy()
    out.env = env_cfg
    return with_env_overrides(out, env_overrides)


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


def check_policy_fits(run_cfg: DictConfig, eval_cfg: DictConfig, env: Env | HostEnv, env_overrides: list[str]) -> None:
    """``env`` (built from ``eval_cfg``: another env, or ``env_overrides``) has the observation and action
    spaces of the env the run trained on, so its policy can act in it; raises ConfigError naming both."""
    trained = checked_env(run_cfg, f"env={run_cfg.env.name}")
    if all(
        _space_kind(a) == _space_kind(b)
        for a, b in ((env.observation_space, trained.observation_space), (env.action_space, trained.action_space))
    ):
        return
    label = " ".join([f"env={eval_cfg.env.name}", *env_overrides])
    same_env = eval_cfg.env.name == run_cfg.env.name
    fix = (
        "drop the env overrides that change them"
        if same_env
        else f"choose an env with them (or leave env={eval_cfg.env.name} out)"
    )
    raise ConfigError(
        f"{label} gives {_spaces_text(env)}; this run's policy was trained on env={run_cfg.env.name}: "
        f"{_spaces_text(trained)}; {fix}"
    )


def evaluation_target(
    run_cfg: DictConfig, env_name: str | None, env_overrides: list[str], autoreset: bool = True
) -> tuple[DictConfig, Env]:
    """The config and env `rlq eval` and `rlq render` step (``eval_env_config``), built with the env's
    own checks; another env (``env_name``) or ``env_overrides`` must fit the run's policy."""
    eval_cfg = eval_env_config(run_cfg, env_name, env_overrides)
    env = checked_env(eval_cfg, f"env={eval_cfg.env.name}", autoreset=autoreset)
    if env_name or env_overrides:
        check_policy_fits(run_cfg, eval_cfg, env, env_overrides)
    return eval_cfg, env


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
    run_dir: Path, ckpt: str | None = None, cfg: DictConfig | None = None, skipped: list[str] | None = None
) -> tuple[DictConfig, Programs, Any, Path]:
    """A run's config, its rebuilt programs and its restored (all-seed) state; ``ckpt`` names the
    checkpoint as ``checkpoint.resolve`` reads it (default: the newest intact one, falling back past
    truncated or corrupt ones, whose notes go into ``skipped``). The config and checkpoint are checked
    before anything is compiled."""
    cfg = load_run_config(run_dir) if cfg is None else cfg
    cfg.devices = 1  # evaluation and video take one seed at a time, whatever devices trained the run
    path, notes = checkpoint.resolve_noting(run_dir, ckpt, cfg)
    if skipped is not None:
        skipped.extend(notes)
    checkpoint.verify(path)
    programs = build(members.program_config(cfg))
    template = jax.eval_shape(programs.init, members.init_inputs(members.program_config(cfg)))
    return cfg, programs, jax.device_put(checkpoint.load(path, template)), path


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
    run_cfg = load_run_config(run_dir)
    eval_cfg, env = evaluation_target(run_cfg, env_name, env_overrides or [])
    check_time_limit(env, f"env={eval_cfg.env.name}")
    if not isinstance(env, HostEnv):
        check_evaluation_size(env, episodes, free_bytes())
    skipped: list[str] = []
    cfg, programs, state, path = restore_run(run_dir, ckpt, run_cfg, skipped)
    key = jax.random.PRNGKey(seed)
    per_seed = []
    for i in range(int(cfg.num_seeds)):
        policy = programs.algo.policy(seed_entry(state, i, int(cfg.num_seeds)))
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
        "env": eval_cfg.env.name,
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
