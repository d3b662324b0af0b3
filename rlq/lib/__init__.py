"""rlq.lib."""
