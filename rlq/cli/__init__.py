"""The `rlq` command line: one module per subcommand; the only code that prints errors and exits."""

from rlq.cli.main import main

__all__ = ["main"]
