"""rlq: a config-driven runner for RL and quality-diversity experiments in JAX."""

__version__ = "0.1.0"
