"""scripts/README.md names every script in scripts/ (and names none that is gone)."""

from __future__ import annotations

import re

from tests.helpers import REPO


def test_scripts_readme_indexes_every_script() -> None:
    scripts = REPO / "scripts"
    present = {
        p.relative_to(scripts).as_posix()
        for p in scripts.rglob("*")
        if p.is_file() and p.suffix in {".py", ".sh", ".sbatch"}
    }
    present = {p for p in present if "__pycache__" not in p}
    indexed = set(re.findall(r"^\| `([\w./-]+)` \|", (scripts / "README.md").read_text(), re.MULTILINE))
    assert present - indexed == set(), f"scripts missing from scripts/README.md: {sorted(present - indexed)}"
    assert indexed - present == set(), f"scripts/README.md names scripts that are gone: {sorted(indexed - present)}"
