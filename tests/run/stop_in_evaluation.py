"""`python -m tests.run.stop_in_evaluation <rlq arguments>`: `rlq`, whose first evaluation sends its process
SIGTERM and then never ends on its own (as an evaluation that takes minutes), for tests/run/test_distributed.py."""

import os
import signal
import threading

from rlq.cli.main import main
from rlq.run.programs.compiling import CompiledPrograms


def evaluate(self, state, keys):
    os.kill(os.getpid(), signal.SIGTERM)
    threading.Event().wait()


CompiledPrograms.evaluate = evaluate
main()
