"""The runner: the training loop (train.py), its hooks and results. Its programs are built in rlq.run.programs,
its config checked in rlq.run.checks, and what ends a run early is in rlq.run.stops."""
