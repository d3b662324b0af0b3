"""`python -m rlq.cli` = `rlq`."""

from rlq.cli.main import main

main()
