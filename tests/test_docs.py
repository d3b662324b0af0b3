"""The docs' references hold: every file a current page names exists, and docs/results/ keeps only the files
that docs/results.md (the table of current figures) cites; other evidence lives in docs/history/results/."""

from __future__ import annotations

import re

from tests.helpers import REPO

PAGES = [
    REPO / "README.md",
    *sorted((REPO / "docs").glob("*.md")),
    REPO / "docs" / "results" / "README.md",
    REPO / "scripts" / "README.md",
]
PATH = re.compile(
    r"(?<![\w/.-])((?:docs|scripts|conf|tests)/[\w./-]+\.(?:md|jsonl|json|py|yaml|png|sbatch|sh))(?![\w])"
)


def cited_paths() -> dict[str, list[str]]:
    """Repository paths named in the current pages, each with the pages that name it."""
    cited: dict[str, list[str]] = {}
    for page in PAGES:
        if page.exists():
            for match in PATH.finditer(page.read_text()):
                cited.setdefault(match.group(1).rstrip("."), []).append(page.relative_to(REPO).as_posix())
    return cited


def test_every_path_a_page_names_exists() -> None:
    missing = {path: pages for path, pages in cited_paths().items() if not (REPO / path).exists()}
    assert not missing, missing


def test_results_folder_holds_only_what_results_md_cites() -> None:
    table = (REPO / "docs" / "results.md").read_text()
    kept = [p for p in (REPO / "docs" / "results").iterdir() if p.name != "README.md"]
    stray = [p.name for p in kept if p.name not in table]
    assert not stray, f"docs/results/ files docs/results.md does not cite (move them to docs/history/results/): {stray}"
    index = (REPO / "docs" / "results" / "README.md").read_text()
    assert all(p.name in index for p in kept), "docs/results/README.md indexes every file"


def table_cells(text: str) -> list[str]:
    """The cells of the Markdown tables in ``text`` (code blocks left out)."""
    cells, fenced = [], False
    for line in text.splitlines():
        if line.startswith("```"):
            fenced = not fenced
        elif not fenced and line.lstrip().startswith("|"):
            cells += [cell.strip() for cell in re.split(r"(?<!\\)\|", line.strip().strip("|"))]
    return cells


def test_the_readme_fits_a_newcomer_and_tables_hold_short_cells() -> None:
    """README ≤ 150 lines; no table cell over 120 characters in README.md or docs/*.md (prose goes under a table)."""
    assert len((REPO / "README.md").read_text().splitlines()) <= 150
    pages = [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]
    long = {page.name: [c[:60] for c in table_cells(page.read_text()) if len(c) > 120] for page in pages}
    assert not {name: cells for name, cells in long.items() if cells}, long
