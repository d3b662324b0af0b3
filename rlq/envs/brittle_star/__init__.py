"""rlq.envs.brittle_star.env."""
