"""The env stack a run builds; the evaluation program's env (``eval.env``)."""

import jax
import numpy as np
import pytest

from rlq.run.programs.build import build
from rlq.run.programs.env_stack import evaluation_env, evaluation_metrics, make_env
from rlq.run.programs.keys import seed_keys
from rlq.run.result import eval_summary
from tests.helpers import compose_config


def test_the_evaluation_env_is_the_run_s_own_unless_eval_env_says_otherwise():
    cfg = compose_config()
    env = make_env(cfg)
    assert evaluation_env(cfg, env) is env
    limited = compose_config("+eval.env.max_episode_steps=7")
    assert evaluation_env(limited, make_env(limited)).max_episode_steps == 7


def test_evaluations_step_the_eval_env():
    """A greedy CartPole policy's evaluation under a 7-step time limit: every episode lasts 7 steps."""
    cfg = compose_config("+eval.env.max_episode_steps=7", "eval.episodes=4")
    programs = build(cfg)
    keys = seed_keys(cfg.seed, cfg.num_seeds)
    record = programs.evaluate(programs.init(keys, programs.hyper), keys)
    np.testing.assert_array_equal(np.asarray(record["episode_length"]), 7)
    assert programs.env.max_episode_steps == 500


@pytest.mark.parametrize(
    "overrides",
    [
        ("algo=ppo",),
        ("algo=map_elites", "algo.batch_size=4"),
        ("algo=random_search", "algo.population=4"),
        ("algo=random_search", "algo.population=4", "algo.descriptor=last_obs", "algo.descriptor_dims=[0,2]")
        + ("algo.archive={shape:[4,4],low:[-1,-1],high:[1,1]}",),
    ],
)
def test_evaluation_metrics_are_the_names_of_an_evaluation_row(overrides):
    """What `stop.when` is checked against before anything compiles is what an evaluation logs."""
    cfg = compose_config("eval.episodes=2", *overrides)
    programs = build(cfg)
    keys = seed_keys(cfg.seed, cfg.num_seeds)
    row = eval_summary(programs.evaluate(programs.init(keys, programs.hyper), keys))
    assert evaluation_metrics(cfg, programs.env) == sorted(row)


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore::UserWarning")
def test_the_humanoid_s_evaluation_steps_the_physics_of_the_eval_env(monkeypatch):
    """The evaluation env is built while the evaluation program is traced (its MJX model uploaded
    eagerly inside that trace), and the program steps its physics, not the training env's."""
    cfg = compose_config(
        "env=humanoid", "env.unroll_physics=linesearch", "++eval.env.unroll_physics=none", "eval.episodes=2"
    )
    programs = build(cfg)
    trained = programs.env.unwrapped
    stepped = []
    brax_class = type(trained.brax_env)
    original = brax_class.step
    monkeypatch.setattr(brax_class, "step", lambda self, *args: stepped.append(self) or original(self, *args))
    keys = seed_keys(cfg.seed, cfg.num_seeds)
    programs.evaluate.lower(jax.eval_shape(programs.init, keys, programs.hyper_shape), keys)
    evaluated = evaluation_env(cfg, programs.env).unwrapped
    assert (trained.unroll_physics, evaluated.unroll_physics) == ("linesearch", "none")
    assert stepped == [evaluated.brax_env]


def test_the_programs_carry_their_names_into_jax_s_logs_and_profiles():
    programs = build(compose_config())
    keys = seed_keys(0, 1)
    assert "module @jit_init" in programs.init.lower(keys, programs.hyper_shape).as_text()
    assert (
        "module @jit_chunk"
        in programs.chunk.lower(
            jax.eval_shape(programs.init, keys, programs.hyper_shape), programs.hyper_shape
        ).as_text()
    )


@pytest.mark.slow  # traces the GPU recipes' programs (8 s each on a CPU)
@pytest.mark.parametrize("algo", ["ppo", "pqn", "dqn"])
def test_lunar_gpu_recipes_programs_step_the_world_once_each(algo, monkeypatch):
    """What the programs of `rlq train algo=<algo> env=lunar machine=gpu` trace of LunarLander's physics: the chunk
    one world step (the env's step; cached starts put no reset in it), init one (the reset's, without contacts)
    and the evaluation two (its episodes' reset's, then its step's, with no reset inside). Another rollout or an
    evaluation inside the update, or a reset inside the step, would add some, and as much again to compile."""
    from rlq.envs.lunar.physics import step as physics

    cfg = compose_config(f"algo={algo}", "env=lunar", "machine=gpu")
    programs = build(cfg)
    stepped: list[str] = []
    original = physics.step

    def step(*args, **kwargs):
        contacts = args[6] if len(args) > 6 else kwargs.get("contacts", True)
        stepped.append("step" if contacts else "reset")
        return original(*args, **kwargs)

    monkeypatch.setattr(physics, "step", step)
    keys = seed_keys(cfg.seed, cfg.num_seeds)
    traced = {}
    with jax.default_device(jax.devices("cpu")[0]):  # one solver form traced, as a run traces for its device
        stepped.clear()
        init = programs.init.trace(keys, programs.hyper_shape)
        traced["init"] = list(stepped)
        stepped.clear()
        programs.chunk.trace(init.out_info, programs.hyper_shape)
        traced["chunk"] = list(stepped)
        stepped.clear()
        programs.evaluate.trace(init.out_info, keys)
        traced["evaluate"] = list(stepped)
    assert traced == {"init": ["reset"], "chunk": ["step"], "evaluate": ["reset", "step"]}
    assert programs.rest is None  # the chunks divide into whole blocks: no second chunk program
