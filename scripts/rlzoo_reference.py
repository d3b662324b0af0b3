"""The reference side of scripts/bench_rlzoo.py: Stable-Baselines3 DQN or PPO on Gymnasium's LunarLander-v3
with rl-baselines3-zoo's tuned hyperparameters, trained or scored in one process.

Runs under a Python with torch, stable-baselines3 and gymnasium[box2d] (its own venv: rlq never imports it,
and rlq's environment never installs torch). The hyperparameters are rl-zoo's LunarLander-v3 entries of
hyperparams/dqn.yml and hyperparams/ppo.yml (rl-baselines3-zoo at 22e3ff2, 2026-04-23), given to SB3 as the
zoo gives them (a DummyVecEnv of Monitor-wrapped envs, the rest SB3's defaults); the zoo's periodic evaluation
callback is left out, so the timed training is ``model.learn`` alone.

    python scripts/rlzoo_reference.py train --algo dqn --seed 101 --model dqn.zip [--steps N] [--threads T]
    python scripts/rlzoo_reference.py eval --algo dqn --model dqn.zip --episodes 100 --first-seed 10000

Each prints one JSON line: ``train`` its wall time (model built and trained) and env steps, ``eval`` the
deterministic policy's return per episode, episode i reset with seed ``first-seed + i``.
"""

from __future__ import annotations

import argparse
import json
import time

ENV_ID = "LunarLander-v3"

# hyperparams/dqn.yml, LunarLander-v3
RLZOO_DQN = {
    "n_timesteps": 100_000,
    "learning_rate": 6.3e-4,
    "batch_size": 128,
    "buffer_size": 50_000,
    "learning_starts": 0,
    "gamma": 0.99,
    "target_update_interval": 250,
    "train_freq": 4,
    "gradient_steps": -1,
    "exploration_fraction": 0.12,
    "exploration_final_eps": 0.1,
    "policy_kwargs": {"net_arch": [256, 256]},
}

# hyperparams/ppo.yml, LunarLander-v3 (policy: SB3's MlpPolicy default, 64-64 tanh)
RLZOO_PPO = {
    "n_envs": 16,
    "n_timesteps": 1_000_000,
    "n_steps": 1024,
    "batch_size": 64,
    "gae_lambda": 0.98,
    "gamma": 0.999,
    "n_epochs": 4,
    "ent_coef": 0.01,
}

RECIPES = {"dqn": RLZOO_DQN, "ppo": RLZOO_PPO}


def train(algo: str, seed: int, model_path: str, steps: int | None) -> dict:
    import torch
    from stable_baselines3 import DQN, PPO
    from stable_baselines3.common.env_util import make_vec_env

    kwargs = dict(RECIPES[algo])
    total = steps or kwargs.pop("n_timesteps")
    kwargs.pop("n_timesteps", None)
    n_envs = kwargs.pop("n_envs", 1)
    start = time.perf_counter()
    env = make_vec_env(ENV_ID, n_envs=n_envs, seed=seed)
    cls = {"dqn": DQN, "ppo": PPO}[algo]
    model = cls("MlpPolicy", env, seed=seed, device="cpu", verbose=0, **kwargs)
    model.learn(total_timesteps=total)
    train_s = time.perf_counter() - start
    model.save(model_path)
    return {
        "train_wall_s": round(train_s, 2),
        "env_steps": int(model.num_timesteps),
        "n_envs": n_envs,
        "torch_threads": torch.get_num_threads(),
    }


def evaluate(algo: str, model_path: str, episodes: int, first_seed: int) -> dict:
    import gymnasium as gym
    from stable_baselines3 import DQN, PPO

    model = {"dqn": DQN, "ppo": PPO}[algo].load(model_path, device="cpu")
    env = gym.make(ENV_ID)
    returns = []
    for i in range(episodes):
        obs, _ = env.reset(seed=first_seed + i)
        total, done = 0.0, False
        while not done:
            action, _ = model.predict(obs, deterministic=True)
            obs, reward, terminated, truncated, _ = env.step(action)
            total += float(reward)
            done = terminated or truncated
        returns.append(round(total, 3))
    return {"episode_returns": returns}


def versions() -> dict:
    import gymnasium
    import stable_baselines3
    import torch

    return {
        "torch": torch.__version__,
        "stable_baselines3": stable_baselines3.__version__,
        "gymnasium": gymnasium.__version__,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("mode", choices=["train", "eval", "versions"])
    parser.add_argument("--algo", choices=sorted(RECIPES), default="dqn")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--model", default="model.zip")
    parser.add_argument("--steps", type=int, default=None, help="env steps (default: the recipe's n_timesteps)")
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--first-seed", type=int, default=10_000)
    parser.add_argument("--threads", type=int, default=None, help="torch's intra-op threads (default: torch's own)")
    args = parser.parse_args()
    if args.threads:
        import torch

        torch.set_num_threads(args.threads)
    if args.mode == "train":
        out = train(args.algo, args.seed, args.model, args.steps)
    elif args.mode == "eval":
        out = evaluate(args.algo, args.model, args.episodes, args.first_seed)
    else:
        out = versions()
    print(json.dumps(out), flush=True)


if __name__ == "__main__":
    main()
