"""What ends a run early or at once, and how the loop sees it in time: signals, waits in slices, the chunk's
slices, the divergence guard and ``stop.when``."""
