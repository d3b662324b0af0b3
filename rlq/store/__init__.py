"""What a run leaves on disk, written and read back: whole files, the run lock and record, checkpoints and their
sidecars, metrics (JSONL, console, W&B), videos and the JSON readers. Below the runner: nothing here builds or
compiles a program."""
