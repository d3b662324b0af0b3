"""Checks of a run's config before anything is compiled: key ranges, sizes in memory, expected times."""
