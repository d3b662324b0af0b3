"""Work on run directories, above the runner: greedy evaluation of a checkpoint, comparing runs, sweep summaries
and warm starts (``init_from``)."""
