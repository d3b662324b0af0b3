import jax
import numpy as np
import pytest

from rlq.algos import algo_settings, pqn
from rlq.lib.spaces import Box
from rlq.run.programs.env_stack import make_env
from tests.fakes import SpacesOnly
from tests.helpers import compose_config, run_cli_in_process, train_run


def _small_algo(*overrides):
    cfg = compose_config("algo=pqn", "algo.num_envs=4", "algo.num_steps=8", "algo.num_minibatches=2", *overrides)
    return pqn.make(algo_settings(cfg.algo), make_env(cfg), budget_env_steps=64)


@pytest.mark.slow
def test_update_counts_steps_and_learns_on_every_minibatch():
    algo = _small_algo()
    state = jax.jit(lambda k: algo.init(k, algo.hyperparams))(jax.random.PRNGKey(0))
    new, metrics = jax.jit(lambda s: algo.update(s, algo.hyperparams))(state)
    assert int(metrics["env_steps"]) == algo.steps_per_update == 32
    assert algo.num_updates == 2
    assert np.isfinite(float(metrics["loss"])) and float(metrics["epsilon"]) == 1.0  # epsilon starts at 1
    pairs = zip(jax.tree.leaves(new.params), jax.tree.leaves(state.params), strict=True)
    assert all(not np.allclose(a, b) for a, b in pairs)


def test_q_network_has_layer_norm_by_default():
    normed, plain_algo = _small_algo(), _small_algo("algo.layer_norm=false")
    state = jax.jit(lambda k: normed.init(k, normed.hyperparams))(jax.random.PRNGKey(0))
    assert any("LayerNorm" in name for name in state.params["params"])
    plain = jax.jit(lambda k: plain_algo.init(k, plain_algo.hyperparams))(jax.random.PRNGKey(0))
    assert not any("LayerNorm" in name for name in plain.params["params"])


def test_check_rejects_continuous_actions_and_ragged_minibatches():
    cfg = compose_config("algo=pqn")
    message = pqn.check(algo_settings(cfg.algo), SpacesOnly(Box.uniform(-1, 1, 3), Box.uniform(-1, 1, 2)))
    assert "algo=pqn needs a discrete action space" in message
    cfg = compose_config("algo=pqn", "algo.num_minibatches=3")
    assert "algo.num_minibatches=3 must divide" in pqn.check(algo_settings(cfg.algo), make_env(cfg))


@pytest.mark.slow
def test_bad_lambda_through_the_cli(workdir):
    proc = run_cli_in_process("train", "algo=pqn", "algo.lam=1.5", "logger=quiet", cwd=workdir)
    assert proc.returncode == 2
    assert proc.stderr.strip().count("\n") == 0 and "algo.lam" in proc.stderr
    assert not (workdir / "outputs").exists()


@pytest.mark.slow
def test_pqn_solves_cartpole(tmp_path):
    result = train_run(tmp_path, "experiment=cartpole_pqn", "num_seeds=3", "video.at_end=false")
    assert result.env_steps <= 500_000
    assert np.all(result.eval_return >= 475), result.eval_return
