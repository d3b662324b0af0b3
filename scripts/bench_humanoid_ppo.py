"""Benchmark rlq's PPO against brax's PPO on the MJX humanoid, same settings, one process.

Both learners get the MJX tutorial's settings (conf/experiment/humanoid_ppo.yaml), the same env
(brax's humanoid, MJX backend), the same number of PPO updates and evaluations at the same step
counts (greedy policy, ``--eval-episodes`` episodes each). brax's trainer calls
``jax.device_put_replicated`` (removed in jax 0.11): a one-function shim restores it.

Reported per learner: wall time of the whole ``train`` call (env construction, compilation,
training, evaluations; rlq also writes its final checkpoint), compile time (jax's own trace +
lowering + compile events, every program and recompilation included) and the number of
compilations over 1 s, steady env steps/s (training only: rlq's mean over its chunks; brax: its
fastest epoch after the first), and the greedy eval return at each evaluation. ``after_first``
gives both learners' fastest and mean epoch (brax) or chunk (rlq) after the first, and
``vs_brax`` sets these like against like.

    python scripts/bench_humanoid_ppo.py --out bench_humanoid.json                        # GPU
    python scripts/bench_humanoid_ppo.py --env-only --out bench_humanoid_env.json         # env steps/s only
    python scripts/bench_humanoid_ppo.py --env-only --trace-steps 4 --out env_trace.json  # + GPU kernels per step
    python scripts/bench_humanoid_ppo.py --env-only --env-groups 2 --out env_groups.json  # 2 batches per step
    python scripts/bench_humanoid_ppo.py --rlq-mjx-impl jax warp --out bench_humanoid.json  # rlq on MJX-JAX and Warp
    python scripts/bench_humanoid_ppo.py --trace-update --out update_trace.json         # GPU kernels of one PPO update
    python scripts/bench_humanoid_ppo.py --steps 4000 --num-envs 4 --batch-size 4 \\
        --num-minibatches 2 --unroll 5 --epochs 1 --episode-length 20 --eval-every 2000 \\
        --eval-episodes 2 --out /tmp/bench_cpu.json                                       # CPU smoke
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import itertools
import json
import math
import tempfile
import time
from pathlib import Path

import jax
import jax.numpy as jnp
from bench_common import device_trace_summary, parse_xla_options, run_header

TUTORIAL = {"gamma": 0.97, "lr": 3e-4, "ent_coef": 1e-3, "reward_scaling": 0.1, "clip_eps": 0.3, "gae_lambda": 0.95}
RANDOMIZE = {"friction": [0.6, 1.4], "gain_delta": [-5.0, 5.0]}


class CompileTimer:
    """Seconds jax spends tracing, lowering and compiling (all programs), from jax's own events."""

    EVENTS = (
        "/jax/core/compile/jaxpr_trace_duration",
        "/jax/core/compile/jaxpr_to_mlir_module_duration",
        "/jax/core/compile/backend_compile_duration",
    )

    def __init__(self) -> None:
        self.seconds, self.big_compiles = 0.0, 0

    def __call__(self, event: str, duration: float, **_) -> None:
        if event in self.EVENTS:
            self.seconds += duration
            self.big_compiles += int(event == self.EVENTS[2] and duration > 1.0)

    def __enter__(self) -> CompileTimer:
        jax.monitoring.register_event_duration_secs_listener(self)
        return self

    def __exit__(self, *exc) -> None:
        jax.monitoring.unregister_event_duration_listener(self)

    def figures(self) -> dict:
        return {"compile_s": round(self.seconds, 2), "compiles_over_1s": self.big_compiles}


def plan(args) -> dict:
    """brax's schedule: (evals - 1) epochs of equal numbers of updates, at least ``--steps`` in all."""
    steps_per_update = args.batch_size * args.num_minibatches * args.unroll
    epochs = max(1, math.ceil(args.steps / args.eval_every))
    updates_per_epoch = math.ceil(args.steps / (epochs * steps_per_update))
    return {
        "steps_per_update": steps_per_update,
        "epochs": epochs,
        "updates": epochs * updates_per_epoch,
        "steps_per_epoch": updates_per_epoch * steps_per_update,
        "env_steps": epochs * updates_per_epoch * steps_per_update,
    }


#: --reset-cache -> rlq's env.reset_cache value(s)
RESET_CACHE = {"true": [True], "false": [False], "both": [True, False]}


@dataclasses.dataclass(frozen=True)
class RlqVariant:
    """One rlq configuration the bench runs: env.reset_cache, env.mjx_impl, env.unroll_physics."""

    reset_cache: bool
    mjx_impl: str
    unroll: str

    @property
    def name(self) -> str:
        """e.g. rlq, rlq_warp_fresh_reset, rlq_unroll_all"""
        parts = ["rlq"] + ([self.mjx_impl] if self.mjx_impl != "jax" else [])
        parts += [] if self.reset_cache else ["fresh_reset"]
        parts += [f"unroll_{self.unroll}"] if self.unroll else []
        return "_".join(parts)

    def overrides(self) -> list[str]:
        out = [f"env.reset_cache={str(self.reset_cache).lower()}", f"env.mjx_impl={self.mjx_impl}"]
        return out + ([f"env.unroll_physics={self.unroll}"] if self.unroll else [])


def rlq_variants(args) -> list[RlqVariant]:
    """Each rlq variant asked for (--reset-cache x --rlq-mjx-impl x --rlq-unroll)."""
    return [
        RlqVariant(*axes)
        for axes in itertools.product(RESET_CACHE[args.reset_cache], args.rlq_mjx_impl, args.rlq_unroll or [""])
    ]


def run_rlq(args, schedule: dict, variant: RlqVariant, run_dir: Path) -> dict:
    from rlq.config.compose import compose
    from rlq.run.checks.validate import check_run_config
    from rlq.run.train import train

    hidden = ",".join(str(h) for h in args.policy_hidden)
    overrides = [
        "experiment=humanoid_ppo",
        "logger=quiet",
        "video.at_end=false",
        f"seed={args.seed}",
        f"budget.env_steps={schedule['env_steps']}",
        f"log_every_steps={schedule['steps_per_epoch']}",  # one compiled chunk per brax epoch
        f"eval.every_steps={schedule['steps_per_epoch']}",
        f"eval.episodes={args.eval_episodes}",
        f"algo.num_envs={args.num_envs}",
        f"algo.batch_size={args.batch_size}",
        f"algo.num_minibatches={args.num_minibatches}",
        f"algo.num_steps={args.unroll}",
        f"algo.update_epochs={args.epochs}",
        f"algo.policy_hidden=[{hidden}]",
        f"env.episode_length={args.episode_length}",
        *variant.overrides(),
    ]
    if args.randomize:
        overrides.append("env.randomize={friction:[0.6,1.4],gain_delta:[-5,5]}")
    overrides += xla_override(args) + args.rlq_override
    run_dir.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    with CompileTimer() as compiles:
        cfg = compose(overrides)
        check_run_config(cfg)
        result = train(cfg, run_dir)
    wall = time.perf_counter() - start
    evals = [
        {"env_steps": row["env_steps"], "return": row["return"]}
        for row in map(json.loads, (run_dir / "metrics.jsonl").read_text().splitlines())
        if row["kind"] == "eval" and row["seed"] == "mean"
    ]
    return {
        "command": "rlq train " + " ".join(overrides),
        "wall_s": round(wall, 2),
        **compiles.figures(),
        "rlq_init_and_chunk_compile_s": round(result.compile_s, 2),
        "steady_env_steps_per_s": round(result.steady_steps_per_s, 1),
        "chunk_s": [round(t, 2) for t in result.chunk_s],
        "after_first": after_first(result.env_steps / max(len(result.chunk_s), 1), result.chunk_s),
        "env_steps": result.env_steps,
        "evals": evals,
        "final_eval_return": evals[-1]["return"] if evals else None,
    }


def after_first(steps: float, seconds: list[float] | tuple[float, ...]) -> dict[str, float | None]:
    """Env steps/s of the fastest and of the mean epoch (brax) or chunk (rlq) after the first
    (brax's first epoch holds its compile; later ones can still recompile, so brax's steady figure
    has always been its fastest)."""
    later = seconds[1:]
    if not later:
        return {"fastest": None, "mean": None}
    return {"fastest": round(steps / min(later), 1), "mean": round(steps * len(later) / sum(later), 1)}


def same_statistic_ratios(rlq: dict, brax: dict) -> dict[str, float]:
    """``rlq_steady_over_brax_steady`` sets rlq's mean over all chunks against brax's fastest epoch;
    these set like against like after the first epoch or chunk: fastest and mean."""
    return {
        f"rlq_{stat}_over_brax_{stat}": round(rlq["after_first"][stat] / brax["after_first"][stat], 3)
        for stat in ("fastest", "mean")
        if rlq["after_first"][stat] and brax["after_first"][stat]
    }


def xla_override(args) -> list[str]:
    """The rlq override that adds --xla-option's pairs to the preset's ``compiler_options``."""
    options = parse_xla_options(args.xla_option)
    values = {k: f"'{v}'" if isinstance(v, str) else json.dumps(v) for k, v in options.items()}
    return ["++compiler_options={" + ",".join(f"{k}:{v}" for k, v in values.items()) + "}"] if options else []


def shim_device_put_replicated() -> None:
    """brax's trainer replicates its state with this (removed from jax 0.11). An identity ``pmap``
    over brax's axis name returns arrays placed like the training epoch's outputs."""

    def device_put_replicated(x, devices):
        stacked = jax.tree.map(lambda a: jnp.stack([jnp.asarray(a)] * len(devices)), x)
        return jax.pmap(lambda tree: tree, axis_name="i", devices=devices)(stacked)

    jax.device_put_replicated = device_put_replicated


def brax_randomization(sys, rng):
    """The tutorial's ``domain_randomize`` (rlq's sampler, so both learners draw the same way)."""
    from rlq.envs.humanoid import randomize

    ranges = randomize.parse(RANDOMIZE)
    overrides = jax.vmap(lambda key: randomize.sample(key, sys, ranges))(rng)
    in_axes = jax.tree.map(lambda _: None, sys).tree_replace({k: 0 for k in overrides})
    return sys.tree_replace(overrides), in_axes


def run_brax(args, schedule: dict) -> dict:
    from brax import envs
    from brax.training.agents.ppo import networks as ppo_networks
    from brax.training.agents.ppo import train as ppo

    shim_device_put_replicated()
    records: list[tuple[float, int, dict]] = []

    def progress(step, metrics):
        records.append((time.perf_counter(), int(step), {k: float(v) for k, v in metrics.items()}))

    start = time.perf_counter()
    with CompileTimer() as timer:
        env = envs.get_environment("humanoid", backend="mjx")
        network = functools.partial(ppo_networks.make_ppo_networks, policy_hidden_layer_sizes=tuple(args.policy_hidden))
        ppo.train(
            environment=env,
            num_timesteps=schedule["env_steps"],
            num_evals=schedule["epochs"] + 1,
            episode_length=args.episode_length,
            action_repeat=1,
            num_envs=args.num_envs,
            batch_size=args.batch_size,
            num_minibatches=args.num_minibatches,
            unroll_length=args.unroll,
            num_updates_per_batch=args.epochs,
            discounting=TUTORIAL["gamma"],
            learning_rate=TUTORIAL["lr"],
            entropy_cost=TUTORIAL["ent_coef"],
            reward_scaling=TUTORIAL["reward_scaling"],
            clipping_epsilon=TUTORIAL["clip_eps"],
            gae_lambda=TUTORIAL["gae_lambda"],
            normalize_observations=True,
            network_factory=network,
            randomization_fn=brax_randomization if args.randomize else None,
            num_eval_envs=args.eval_episodes,
            deterministic_eval=True,
            seed=args.seed,
            progress_fn=progress,
        )
    wall = time.perf_counter() - start
    walltimes = [m["training/walltime"] for _, step, m in records if step > 0 and "training/walltime" in m]
    epoch_s = [b - a for a, b in zip([0.0, *walltimes[:-1]], walltimes, strict=True)]
    later_epochs = after_first(schedule["steps_per_epoch"], epoch_s)
    return {
        "wall_s": round(wall, 2),
        **timer.figures(),
        "epoch_s": [round(t, 2) for t in epoch_s],
        "steady_env_steps_per_s": later_epochs["fastest"],
        "after_first": later_epochs,
        "env_steps": records[-1][1] if records else None,
        "evals": [{"env_steps": step, "return": m["eval/episode_reward"]} for _, step, m in records],
        "final_eval_return": records[-1][2]["eval/episode_reward"] if records else None,
    }


def env_throughput(args) -> dict:
    """Env-only steps/s (uniform random actions) of rlq's wrapped humanoid (each ``--reset-cache``
    and ``--rlq-mjx-impl`` variant), and of brax's training wrappers (Vmap/Episode/AutoReset) around the same env."""
    from brax import envs
    from brax.envs.wrappers import training as brax_wrappers

    from rlq.config.compose import compose
    from rlq.run.programs.env_stack import make_env

    keys = jax.random.split(jax.random.PRNGKey(args.seed), args.num_envs)
    variants = {}
    for variant in rlq_variants(args):
        overrides = ["experiment=humanoid_ppo", *variant.overrides()]
        overrides += [f"env.episode_length={args.episode_length}"]
        overrides += ["env.randomize={friction:[0.6,1.4],gain_delta:[-5,5]}"] if args.randomize else []
        env = make_env(compose(overrides + [o for o in args.rlq_override if o.startswith("env.")]))
        variants[variant.name] = (jax.vmap(env.reset), jax.vmap(env.step))
    brax_env = brax_wrappers.wrap(
        envs.get_environment("humanoid", backend="mjx"),
        episode_length=args.episode_length,
        randomization_fn=(lambda sys: brax_randomization(sys, keys)) if args.randomize else None,
    )
    if not args.skip_brax:
        variants["brax"] = (brax_env.reset, brax_env.step)
    options = parse_xla_options(args.xla_option) or None
    groups, per_group = args.env_groups, args.num_envs // args.env_groups
    out = {}
    for name, (reset, step) in variants.items():

        def run(states, key, num_steps, step=step):
            """Steps ``groups`` independent batches per scan step (one batch unless ``--env-groups``)."""

            def one(states, k):
                actions = [
                    jax.random.uniform(kk, (per_group, 17), minval=-1, maxval=1) for kk in jax.random.split(k, groups)
                ]
                return tuple(step(s, a) for s, a in zip(states, actions, strict=True)), None

            return jax.lax.scan(one, states, jax.random.split(key, num_steps))[0]

        start = time.perf_counter()
        state = tuple(jax.jit(reset)(part) for part in jnp.split(keys, groups))
        program = jax.jit(run, static_argnums=2).lower(state, keys[0], args.env_steps).compile(options)
        compile_s = time.perf_counter() - start
        jax.block_until_ready(program(state, keys[1]))
        start = time.perf_counter()
        jax.block_until_ready(program(state, keys[2]))
        seconds = time.perf_counter() - start
        out[name] = {
            "env_groups": groups,
            "compile_s": round(compile_s, 2),
            "env_steps_per_s": round(args.num_envs * args.env_steps / seconds, 1),
        }
        if args.trace_steps:
            traced = jax.jit(run, static_argnums=2).lower(state, keys[0], args.trace_steps).compile(options)
            jax.block_until_ready(traced(state, keys[1]))
            out[name][f"trace_{args.trace_steps}_steps"] = device_trace_summary(
                functools.partial(traced, state, keys[3])
            )
        print(name, json.dumps(out[name]), flush=True)
    return out


def update_trace(args) -> dict:
    """PPO updates of each rlq variant (the preset with --rlq-override/--xla-option), timed per
    update in chunks of about --trace-updates updates, and profiled: the GPU kernels of one call of
    the chunk program (``traced_updates`` updates) by busy time, per device stream."""
    from rlq.algos import ppo
    from rlq.config.compose import compose
    from rlq.run.programs.build import build, call_chunk, with_hyper
    from rlq.run.programs.compiler import options_from_config
    from rlq.run.programs.compiling import compile_pipelined
    from rlq.run.programs.keys import seed_keys

    out = {}
    for variant in rlq_variants(args):
        overrides = ["experiment=humanoid_ppo", *variant.overrides()]
        cfg = compose(overrides + xla_override(args) + args.rlq_override)
        cfg.log_every_steps = args.trace_updates * ppo.steps_per_update(cfg.algo)
        programs = build(cfg)  # close to --trace-updates updates per chunk (chunk_plan picks the exact count)
        keys = seed_keys(cfg.seed, 1)
        start = time.perf_counter()
        init = programs.init.trace(keys, programs.hyper_shape)
        lowerings = {
            "chunk": functools.partial(programs.chunk.lower, init.out_info, programs.hyper_shape),
            "init": init.lower,
        }
        compiled = compile_pipelined(lowerings, options_from_config(cfg))
        chunk, state = with_hyper(compiled["chunk"], programs.hyper), compiled["init"](keys, programs.hyper)
        compile_s = time.perf_counter() - start
        calls = programs.calls_per_chunk
        state = jax.block_until_ready(state)
        start = time.perf_counter()
        state = jax.block_until_ready(call_chunk(chunk, state, calls)[0])
        first_chunk_s = time.perf_counter() - start
        start = time.perf_counter()
        for _ in range(3):
            state = call_chunk(chunk, state, calls)[0]
        jax.block_until_ready(state)
        update_s = (time.perf_counter() - start) / (3 * programs.updates_per_chunk)
        name = variant.name + "".join(f"+{o}" for o in args.rlq_override)
        out[name] = {
            "updates_per_chunk": programs.updates_per_chunk,
            "compile_s": round(compile_s, 2),
            "update_s": round(update_s, 4),
            "env_steps_per_s": round(programs.algo.steps_per_update / update_s, 1),
            "first_chunk_s": round(first_chunk_s, 3),
            "later_chunk_s": round(update_s * programs.updates_per_chunk, 3),
        }
        if not args.no_profile:
            out[name]["trace_1_update"] = device_trace_summary(functools.partial(chunk, state), top=40)
            out[name]["traced_updates"] = programs.updates_per_chunk // calls
        print(name, json.dumps({k: v for k, v in out[name].items() if k != "trace_1_update"}), flush=True)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=30_000_000, help="env steps (rounded up to whole epochs)")
    parser.add_argument("--num-envs", type=int, default=4096)
    parser.add_argument("--batch-size", type=int, default=1024, help="brax's meaning: unrolls per minibatch")
    parser.add_argument("--num-minibatches", type=int, default=32)
    parser.add_argument("--unroll", type=int, default=10)
    parser.add_argument("--epochs", type=int, default=8, help="passes over each batch (brax: num_updates_per_batch)")
    parser.add_argument("--policy-hidden", type=int, nargs="+", default=[64, 64, 64, 64])
    parser.add_argument("--episode-length", type=int, default=1000)
    parser.add_argument("--eval-every", type=int, default=5_000_000)
    parser.add_argument("--eval-episodes", type=int, default=128)
    parser.add_argument("--randomize", action="store_true", help="the tutorial's domain randomisation in both")
    parser.add_argument("--reset-cache", choices=list(RESET_CACHE), default="true", help="rlq's AutoReset variant(s)")
    parser.add_argument(
        "--rlq-mjx-impl", nargs="+", choices=["jax", "warp"], default=["jax"], help="rlq's env.mjx_impl value(s)"
    )
    parser.add_argument(
        "--rlq-unroll",
        nargs="+",
        choices=["none", "linesearch", "all"],
        default=[],
        help="rlq's env.unroll_physics value(s) (default: the preset's)",
    )
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--rlq-override", action="append", default=[], help="extra rlq override, e.g. algo.recompute_gae=false"
    )
    parser.add_argument("--skip-brax", action="store_true")
    parser.add_argument("--brax-first", action="store_true", help="run brax's PPO before rlq's variants")
    parser.add_argument("--env-only", action="store_true", help="only env steps/s: rlq (cached/fresh reset) vs brax")
    parser.add_argument("--env-steps", type=int, default=1000, help="--env-only: steps per timed scan")
    parser.add_argument(
        "--trace-steps",
        type=int,
        default=0,
        help="--env-only: also profile a scan of this many steps (kernels per stream)",
    )
    parser.add_argument(
        "--env-groups",
        type=int,
        default=1,
        help="--env-only: split --num-envs into this many independently stepped batches",
    )
    parser.add_argument(
        "--xla-option",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="XLA compiler option for rlq's programs (and --env-only's), e.g. "
        "xla_gpu_command_buffer_scheduling_mode=CONCURRENT; brax's PPO keeps XLA's defaults",
    )
    parser.add_argument(
        "--trace-update",
        action="store_true",
        help="time and profile PPO updates of each rlq variant (see --trace-updates)",
    )
    parser.add_argument("--no-profile", action="store_true", help="--trace-update: time only, no profiler trace")
    parser.add_argument(
        "--trace-updates",
        type=int,
        default=1,
        help="--trace-update: updates per compiled chunk (as in a run; the figures are per update)",
    )
    parser.add_argument("--skip-rlq", action="store_true")
    parser.add_argument("--out", type=Path, default=Path("bench_humanoid_ppo.json"))
    args = parser.parse_args()
    if any("=" not in option for option in args.xla_option):
        parser.error("--xla-option takes KEY=VALUE")
    if args.env_groups < 1 or args.num_envs % args.env_groups:
        parser.error(f"--env-groups must divide --num-envs ({args.num_envs}), got {args.env_groups}")
    if args.env_groups > 1 and args.randomize:
        parser.error("--env-groups > 1 cannot be combined with --randomize (brax randomises one batch of --num-envs)")

    schedule = plan(args)
    report = {
        **run_header(),
        "settings": {**vars(args), "out": str(args.out), **TUTORIAL, "schedule": schedule},
        "runs": {},
    }

    def save() -> None:
        args.out.write_text(json.dumps(report, indent=2))

    if args.trace_update:
        report["update_trace"] = update_trace(args)
        save()
        print(f"wrote {args.out}")
        return
    if args.env_only:
        report["env_only"] = env_throughput(args)
        save()
        print(f"wrote {args.out}")
        return

    def record(name: str, run: dict) -> None:
        report["runs"][name] = run
        print(name, json.dumps({k: v for k, v in run.items() if k != "evals"}), flush=True)
        save()

    if args.brax_first and not args.skip_brax:
        record("brax", run_brax(args, schedule))
    with tempfile.TemporaryDirectory() as tmp:
        for variant in [] if args.skip_rlq else rlq_variants(args):
            record(variant.name, run_rlq(args, schedule, variant, Path(tmp) / variant.name))
    if not (args.brax_first or args.skip_brax):
        record("brax", run_brax(args, schedule))
    runs = report["runs"]
    brax = runs.get("brax")
    for name, run in runs.items() if brax else ():
        if name != "brax":
            report.setdefault("vs_brax", {})[name] = {
                "rlq_wall_over_brax_wall": round(run["wall_s"] / brax["wall_s"], 3),
                "rlq_steady_over_brax_steady": round(run["steady_env_steps_per_s"] / brax["steady_env_steps_per_s"], 3),
                **same_statistic_ratios(run, brax),
            }
    save()
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
