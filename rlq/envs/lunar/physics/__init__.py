"""rlq.envs.lunar.env.physics."""
