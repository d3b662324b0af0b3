"""The shape of the package, as issue 75 set it: no folder of rlq/ holds more than 15 modules (its
``__init__.py`` counted), and no function of the runner (rlq/run/) is over 80 lines, from its ``def`` to its
last line, so a newcomer reads the training loop step by step (prepare, loop, finish); omegaconf is read in at
most 10 modules, all of rlq/config/ and rlq/cli/ (the runner takes a RunSpec), and no config is read with a
default of the code's own (``cfg.get(key, default)``) outside rlq/config/. ast only: no import."""

import ast
import re
from pathlib import Path

RLQ = Path(__file__).resolve().parents[1] / "rlq"
MAX_MODULES = 15
MAX_LINES = 80
MAX_OMEGACONF = 10
#: the receivers of ``.get(key, default)`` that are configs (not CLI options, checkpoint sidecars or summaries)
CONFIG_NAMES = re.compile(r"\b(cfg|config|spec|node|hydra\w*|settings|section|algo|env|controller)\b")


def crowded_folders(root: Path, base: Path) -> dict[str, int]:
    """The folders under ``root`` (itself included) holding more than ``MAX_MODULES`` modules, named from
    ``base``, with their count."""
    folders = [root, *(path for path in root.rglob("*") if path.is_dir() and path.name != "__pycache__")]
    counts = {str(folder.relative_to(base)): len(list(folder.glob("*.py"))) for folder in folders}
    return {folder: count for folder, count in sorted(counts.items()) if count > MAX_MODULES}


def long_functions(root: Path, base: Path) -> dict[str, int]:
    """The functions and methods of the modules under ``root`` over ``MAX_LINES`` lines, named from ``base``,
    with their length."""
    long = {}
    for path in sorted(root.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                lines = (node.end_lineno or node.lineno) - node.lineno + 1
                if lines > MAX_LINES:
                    long[f"{path.relative_to(base)}::{node.name} (line {node.lineno})"] = lines
    return long


def omegaconf_modules(root: Path, base: Path) -> list[str]:
    """The modules under ``root`` that import omegaconf, named from ``base``."""
    found = []
    for path in sorted(root.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else []
            if isinstance(node, ast.ImportFrom) and node.module:
                names = [node.module]
            if any(name.split(".")[0] == "omegaconf" for name in names):
                found.append(str(path.relative_to(base)))
                break
    return found


def config_defaults(root: Path, base: Path) -> list[str]:
    """The ``<config>.get(key, default)`` calls under ``root``, as ``path:line: call``."""
    found = []
    for path in sorted(root.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if (
                isinstance(node, ast.Call)
                and isinstance(node.func, ast.Attribute)
                and node.func.attr == "get"
                and len(node.args) == 2
                and CONFIG_NAMES.search(ast.unparse(node.func.value))
            ):
                found.append(f"{path.relative_to(base)}:{node.lineno}: {ast.unparse(node)}")
    return found


def test_omegaconf_is_read_in_rlq_config_and_rlq_cli_only():
    found = omegaconf_modules(RLQ, RLQ.parent)
    outside = [name for name in found if not name.startswith(("rlq/config/", "rlq/cli/"))]
    assert not outside, f"modules outside rlq/config and rlq/cli that import omegaconf: {outside}"
    assert len(found) <= MAX_OMEGACONF, f"{len(found)} modules import omegaconf (at most {MAX_OMEGACONF}): {found}"


def test_no_config_key_gets_a_default_outside_rlq_config():
    found = [call for call in config_defaults(RLQ, RLQ.parent) if not call.startswith("rlq/config/")]
    assert not found, f"config keys read with a default of the code's own (the yaml holds them): {found}"


def test_no_folder_of_rlq_holds_more_than_15_modules():
    crowded = crowded_folders(RLQ, RLQ.parent)
    assert not crowded, f"folders over {MAX_MODULES} modules (__init__.py counted): {crowded}"


def test_no_function_of_the_runner_is_over_80_lines():
    long = long_functions(RLQ / "run", RLQ.parent)
    assert not long, f"functions over {MAX_LINES} lines (def to last line): {long}"


def test_the_limits_name_the_offenders(tmp_path):
    """A folder of 16 modules and a function of 81 lines are named, with their count."""
    package = tmp_path / "pkg"
    package.mkdir()
    for index in range(15):
        (package / f"m{index}.py").write_text("")
    (package / "__init__.py").write_text("def long():\n" + "    x = 1\n" * 80)
    assert crowded_folders(package, tmp_path) == {"pkg": 16}
    assert long_functions(package, tmp_path) == {"pkg/__init__.py::long (line 1)": 81}
