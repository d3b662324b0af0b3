"""rlq.run."""
