"""rlq.envs.mujoco."""
