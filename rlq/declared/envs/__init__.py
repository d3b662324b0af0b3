"""What each env declares of its keys: a frozen dataclass per env (type, default, allowed values and meaning of each
key), the one home of an ``env.`` key. The envs read them (rlq.envs), rlq/config registers each in Hydra's
ConfigStore as the schema of ``env=<name>`` (rlq/config/store.py), and conf/env/<name>.yaml names that schema. No
JAX or MuJoCo here: composing a config imports none."""

from rlq.declared.envs import brittle_star, cartpole, humanoid, lunar

#: each env's declaration by its name (``env=<name>``), as rlq.envs.ENVS names the envs
ENV_CONFIGS: dict[str, type] = {
    "cartpole": cartpole.Config,
    "lunar": lunar.Config,
    "lunar_box2d": lunar.Box2DConfig,
    "humanoid": humanoid.Config,
    "brittle_star": brittle_star.Config,
    "brittle_star_undirected": brittle_star.UndirectedConfig,
}
