"""The one place that knows Hydra: compose a command's overrides from conf/ and resolve them into a RunSpec.

It imports no JAX and builds no env (import-linter's layers, pyproject.toml): what a run needs of the machine
(keeping JAX off the GPU, starting the distributed runtime) and the checks that build an env are the CLI's.
"""

from rlq.config.resolve import resolve
from rlq.config.spec import RunSpec

__all__ = ["RunSpec", "resolve"]
