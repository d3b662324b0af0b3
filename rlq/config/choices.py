"""Group choices that contradict each other, which Hydra would settle without a word: a group given twice (it takes
the last), or a group choice against the one a preset (``experiment=``) makes (the preset's run name on another
run)."""

from __future__ import annotations

import yaml

from rlq.config.conf_dir import CONF_DIR
from rlq.errors import UsageError

#: the config groups (and their subgroups, e.g. env/physics) an override chooses an option of (``algo=ppo``);
#: hydra/launcher etc. are Hydra's
GROUPS = ("env", "controller", "algo", "machine", "tuned", "logger", "experiment")


def group_options(group: str) -> list[str]:
    """The options of config group ``group`` (a subgroup too: ``env/physics``): its YAML files under conf/."""
    return sorted(p.stem for p in (CONF_DIR / group).glob("*.yaml"))


def preset_choices(name: str) -> dict[str, str]:
    """The group choices preset ``name`` makes (``override /algo: dqn`` in conf/experiment/<name>.yaml)."""
    path = CONF_DIR / "experiment" / f"{name}.yaml"
    if not path.is_file():
        return {}  # Hydra's error names the unknown preset
    defaults = (yaml.safe_load(path.read_text()) or {}).get("defaults", [])
    return {
        key.removeprefix("override /"): str(value)
        for entry in defaults
        if isinstance(entry, dict)
        for key, value in entry.items()
        if key.startswith("override /")
    }


def check_choices(overrides: list[str]) -> None:
    """Each group is chosen once, and not against the preset's choice; raises UsageError naming the fix."""
    given: dict[str, str] = {}
    for item in overrides:
        key, _, value = item.partition("=")
        group = key.lstrip("+")
        if key.startswith("~") or "." in group or group.split("/")[0] not in GROUPS:
            continue
        if group in given:
            raise UsageError(
                f"{group} is given twice ({group}={given[group]} and {group}={value}), and only the last would count: "
                f"give {group} once"
            )
        given[group] = value
    preset = given.get("experiment")
    for group, value in preset_choices(preset).items() if preset else ():
        if group in given and given[group] != value:
            raise UsageError(
                f"experiment={preset} sets {group}={value}, which {group}={given[group]} contradicts: drop "
                f"{group}={given[group]} to run the preset, or drop experiment={preset} to choose the groups yourself"
            )
