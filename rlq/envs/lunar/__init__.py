"""rlq.envs.lunar.env."""
