"""The runner: the training loop (train.py, in three steps: prepare.py, loop.py, finish.py), its hooks and results.
Its programs are built in rlq.run.programs, its config checked in rlq.run.checks, and what ends a run early is in
rlq.run.stops."""
