"""rlq: a config-driven runner for RL and quality-diversity experiments in JAX."""

__version__ = "0.1.0"


def __getattr__(name: str):
    """``rlq.make_train`` without importing JAX when the package is imported (the CLI starts faster)."""
    if name == "make_train":
        from rlq.run.make_train import make_train

        return make_train
    raise AttributeError(f"module 'rlq' has no attribute {name!r}")
