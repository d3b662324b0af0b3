"""CartPole-v1 from gymnax behind the rlq Env protocol."""

from __future__ import annotations

import importlib
import importlib.util
import sys
import types
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
from PIL import Image, ImageDraw

from rlq.declared.envs.cartpole import Config
from rlq.lib.env_api import Env, EnvState, initial_state
from rlq.lib.spaces import Box, Discrete


def _import_cartpole() -> types.ModuleType:
    import gymnax.environments.classic_control.cartpole as module

    return module


def gymnax_cartpole_module() -> types.ModuleType:
    """gymnax's CartPole module, loaded without running gymnax's package ``__init__`` files first.

    Those import every env gymnax ships, and its Pong and Catch import seaborn, scipy, pandas and
    matplotlib, which take longer on a small CPU than CartPole PPO's whole chunk compile. The
    CartPole module needs only ``gymnax.environments.environment`` and ``.spaces``. So the three
    packages above it go into ``sys.modules`` as ``lazy_package``s, whose ``__init__`` runs on the
    first attribute that is not yet there (``gymnax.make``, ``gymnax.environments.Catch``): a later
    ``import gymnax`` gets all of gymnax, with the very classes rlq uses (pickles of them resolve).
    Where gymnax is imported already, or its layout is not the one this expects, it is the ordinary
    import."""
    if "gymnax" in sys.modules:
        return _import_cartpole()
    spec = importlib.util.find_spec("gymnax")
    root = Path(next(iter(spec.submodule_search_locations or []), "")) if spec is not None else None
    packages = ("gymnax", "gymnax.environments", "gymnax.environments.classic_control")
    directories = [root.joinpath(*name.split(".")[1:]) for name in packages] if root is not None else []
    if not directories or not all((d / "__init__.py").is_file() for d in directories):
        return _import_cartpole()
    for name, directory in zip(packages, directories, strict=True):
        sys.modules[name] = lazy_package(name, directory)
    return _import_cartpole()


def lazy_package(name: str, directory: Path) -> types.ModuleType:
    """The package ``name`` in ``directory``, its ``__init__`` not yet run: a missing attribute that
    names a submodule imports that submodule, and any other missing attribute runs ``__init__`` once
    (PEP 562's module ``__getattr__``)."""
    spec = importlib.util.spec_from_file_location(
        name, directory / "__init__.py", submodule_search_locations=[str(directory)]
    )
    if spec is None or spec.loader is None:
        raise ImportError(f"no package {name} in {directory}")
    loader = spec.loader
    package = importlib.util.module_from_spec(spec)

    def run_init(attribute: str) -> object:
        if attribute.startswith("__"):
            raise AttributeError(f"module {name!r} has no attribute {attribute!r}")
        if (directory / f"{attribute}.py").is_file() or (directory / attribute / "__init__.py").is_file():
            return importlib.import_module(f"{name}.{attribute}")
        del package.__dict__["__getattr__"]
        loader.exec_module(package)
        return getattr(package, attribute)

    package.__dict__["__getattr__"] = run_init
    return package


class CartPole(Env):
    """gymnax's CartPole physics; termination from the pole/cart limits only.

    gymnax's own ``step`` auto-resets and folds the time limit in; rlq calls ``step_env`` and
    ``reset_env`` directly and leaves truncation to the TimeLimit wrapper.
    """

    max_episode_steps = 500
    render_fps = 50

    def __init__(self, max_episode_steps: int | None = 500):
        if max_episode_steps is None:  # gymnax's CartPole has no episode without a limit
            raise ValueError("env.max_episode_steps must be an integer >= 1 on CartPole (Gymnasium's is 500), got None")
        self._env = gymnax_cartpole_module().CartPole()
        self._params = self._env.default_params.replace(max_steps_in_episode=max_episode_steps)
        self.max_episode_steps = int(max_episode_steps)
        self.observation_space = observation_box(self._params)
        self.action_space = Discrete(2)

    def reset(self, key: jax.Array) -> EnvState:
        key, sub = jax.random.split(key)
        return self._start(sub, key)

    def step_and_reset(self, state: EnvState, action: jax.Array, key: jax.Array) -> tuple[EnvState, EnvState]:
        """The new episode is drawn from ``key`` itself: auto-reset keeps its obs and physics, not its
        key, so ``reset``'s split (a threefry hash per env and step) would be thrown away."""
        return self.step(state, action), self._start(key, key)

    def _start(self, draw: jax.Array, key: jax.Array) -> EnvState:
        """An episode's first state, its cart and pole drawn from ``draw``; ``key`` is the state's."""
        obs, inner = self._env.reset_env(draw, self._params)
        inner = jax.tree.map(jnp.asarray, inner)  # gymnax leaves time as a Python int
        return initial_state(obs.astype(jnp.float32), inner, key)

    def render(self, states: EnvState) -> np.ndarray:
        x, theta = np.atleast_1d(np.asarray(states.inner.x)), np.atleast_1d(np.asarray(states.inner.theta))
        return np.stack([_draw(float(a), float(b)) for a, b in zip(x, theta, strict=True)])

    def step(self, state: EnvState, action: jax.Array) -> EnvState:
        # CartPole's dynamics are deterministic: gymnax's step_env takes a key and does not use it,
        # so the state's key passes on unsplit
        obs, inner, reward, terminated, _ = self._env.step_env(state.key, state.inner, action, self._params)
        return state.replace(
            obs=obs.astype(jnp.float32),
            reward=jnp.asarray(reward, jnp.float32),
            terminated=jnp.asarray(terminated, bool),
            truncated=jnp.zeros((), bool),
            inner=inner,
        )


def observation_box(params) -> Box:
    """gymnax's CartPole observation bounds, from its params in numpy: its own ``observation_space``
    builds them with eager jnp operations, each a small compile before a run starts."""
    big = float(np.finfo(np.float32).max)
    high = (2 * float(params.x_threshold), big, 2 * float(params.theta_threshold_radians), big)
    return Box(tuple(-h for h in high), high)


def _draw(x: float, theta: float, width: int = 600, height: int = 400) -> np.ndarray:
    """One frame in the look of Gymnasium's CartPole renderer."""
    scale = width / 4.8
    cart_y, pole_len = height * 0.7, scale * 1.0
    img = Image.new("RGB", (width, height), (255, 255, 255))
    draw = ImageDraw.Draw(img)
    draw.line([(0, cart_y), (width, cart_y)], fill=(0, 0, 0))
    cx = width / 2 + x * scale
    draw.rectangle([cx - 25, cart_y - 15, cx + 25, cart_y + 15], fill=(0, 0, 0))
    tip = (cx + pole_len * np.sin(theta), cart_y - 15 - pole_len * np.cos(theta))
    draw.line([(cx, cart_y - 15), tip], fill=(202, 152, 101), width=10)
    draw.ellipse([cx - 5, cart_y - 20, cx + 5, cart_y - 10], fill=(129, 132, 203))
    return np.asarray(img)


def make(cfg: Config) -> Env:
    return CartPole(max_episode_steps=cfg.max_episode_steps)
