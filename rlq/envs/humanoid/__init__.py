"""rlq.envs.humanoid.env."""
