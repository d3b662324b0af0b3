"""Compose a run config from conf/ with Hydra's compose API and validate it, before anything runs."""

from __future__ import annotations

import copy
import difflib
import re

from omegaconf import DictConfig, OmegaConf, open_dict

from rlq.errors import ConfigError, UsageError
from rlq.run.conf_dir import CONF_DIR
from rlq.run.tuned import check_supported
from rlq.run.validate import check_output_dir, check_run_config, check_types, integral_floats

#: overrides that leave the pair's tuned settings out: a component's own defaults (conf/tuned/ is for `rlq train`)
WITHOUT_TUNED = ["~tuned", "~tuned/controller", "~tuned/machine"]
#: config groups whose keys are free (XLA's option names, the env's options): ``+`` adds to them
FREE_KEYS = ("compiler_options", "eval.env", "sweep")


def _closest(word: str, choices: list[str]) -> str | None:
    """The choice ``word`` was most likely meant to be (a typo's correction), if any is close."""
    close = difflib.get_close_matches(word, choices, n=1, cutoff=0.6)
    return close[0] if close else None


def _unknown_key_hint(key: str, overrides: list[str]) -> str:
    """' (did you mean algo.lr?)' for a misspelt ``key``, from the keys of its parent in the composed config."""
    if not overrides and "." not in key:
        return ""
    parent, _, leaf = key.rpartition(".")
    try:
        cfg = compose([o for o in overrides if _group_override(o)])
    except Exception:
        return ""
    node = OmegaConf.select(cfg, parent, default=None) if parent else cfg
    if not isinstance(node, DictConfig):
        return ""
    match = _closest(leaf, [str(k) for k in node])
    return f" (did you mean {parent + '.' if parent else ''}{match}?)" if match else ""


def explain_hydra_error(err: Exception, overrides: list[str] | None = None) -> str:
    """One line for an error of Hydra's composition (``overrides``: the command's, for a did-you-mean hint)."""
    text = str(err)
    missing = re.search(r"Could not find '([\w/]+)/(\w+)'", text)
    if missing:
        group, option = missing.groups()
        options = sorted(p.stem for p in (CONF_DIR / group).glob("*.yaml"))
        match = _closest(option, options)
        hint = f"did you mean {group}={match}?" if match else f"e.g. {group}={options[0]}"
        return f"unknown {group} '{option}'; choose one of: {', '.join(options)} ({hint})"
    ambiguous = re.search(r"Ambiguous value for argument '([^']+)'", text)
    if ambiguous:
        return (
            f"{ambiguous.group(1)} gives several values, which is a sweep: add -m "
            f"(rlq train -m {ambiguous.group(1)}), or give one value"
        )
    unknown_key = re.search(r"Key '([\w.]+)' is not in struct", text) or re.search(
        r"Could not override '([\w.]+)'", text
    )
    if unknown_key:
        key = unknown_key.group(1)
        append = re.search(r"To append to your config use (\S+)", text)
        if key in FREE_KEYS and append:
            return f"{key} is a group of free keys, which an override adds to with a leading +: {append.group(1)}"
        free = next((f for f in FREE_KEYS if key.startswith(f + ".")), None)
        hint = f" (a new key of {free} is added with {append.group(1)})" if free and append else ""
        hint = hint or _unknown_key_hint(key, overrides or [])
        return f"unknown config key '{key}'; `rlq train --cfg job` lists the keys{hint}"
    first = next((line for line in text.splitlines() if line.strip()), type(err).__name__).strip()
    override = getattr(err, "override", None)  # Hydra's OverrideParseException names the override it could not read
    if isinstance(override, str):
        return (
            f"cannot read the override '{override}' ({first}); check its brackets and braces, and quote a "
            "value that holds '=', '<' or '>' so that the quotes reach rlq: in a shell, 'key=\"a>=b\"'"
        )
    return first


def compose(overrides: list[str], with_hydra: bool = False) -> DictConfig:
    """Compose the run config as Hydra will, without making a run directory (``with_hydra``:
    keep Hydra's own node, e.g. ``hydra.run.dir``)."""
    from hydra import compose as hydra_compose
    from hydra import initialize_config_dir
    from hydra.core.global_hydra import GlobalHydra

    GlobalHydra.instance().clear()
    try:
        with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
            return hydra_compose(config_name="config", overrides=overrides, return_hydra_config=with_hydra)
    finally:
        GlobalHydra.instance().clear()


#: what ``OmegaConf.select`` returns for a key the config has not
_ABSENT = object()


def check_composes(overrides: list[str]) -> None:
    """The overrides compose (known groups, options and keys; readable syntax): what `rlq train
    --cfg job` needs before Hydra prints the config."""
    check_group_values(overrides)
    try:
        compose(overrides)
    except Exception as err:
        raise ConfigError(explain_hydra_error(err, overrides)) from None


def check_package(overrides: list[str], printed: str, package: str) -> None:
    """``package`` names a node of the config `rlq train --cfg <printed>` prints (``job``: the run's
    config, ``hydra``: Hydra's node, ``all``: both), as ``--package`` asks; Hydra would print a line
    without rlq's prefix and exit 1."""
    if package == "_global_":
        return
    cfg = compose(overrides, with_hydra=printed != "job")
    if printed == "hydra":
        cfg = OmegaConf.create({"hydra": cfg.hydra})
    if OmegaConf.select(cfg, package, default=_ABSENT, throw_on_missing=False) is not _ABSENT:
        return
    parent, node = "", cfg  # the deepest node of the path that exists, whose keys the line lists
    for part in package.split("."):
        child = node.get(part) if isinstance(node, DictConfig) else None
        if not isinstance(child, DictConfig):
            break
        parent, node = f"{parent}.{part}".lstrip("."), child
    where = f"{parent} has" if parent else "its top-level keys are"
    keys = ", ".join(str(k) for k in node)
    raise ConfigError(f"--package {package}: --cfg {printed} prints no such key; {where}: {keys}")


def _group_override(item: str) -> bool:
    key = item.split("=", 1)[0].lstrip("+~")
    return key.split("/")[0] in ("env", "controller", "algo", "machine", "tuned", "logger", "experiment", "hydra")


#: the config groups an override chooses an option of (``algo=ppo``); hydra/launcher etc. are Hydra's
GROUPS = ("env", "controller", "algo", "machine", "tuned", "logger", "experiment")


def check_group_values(overrides: list[str]) -> None:
    """A group takes the name of one option (``algo=ppo``), not a dict or list (``algo={}``, ``algo=[ppo]``):
    Hydra would take ``algo={}`` as the config itself and fail while the job runs."""
    for item in overrides:
        key, _, value = item.partition("=")
        group = key.lstrip("+~")
        if group.split("/")[0] in GROUPS and "." not in group and value.strip().startswith(("{", "[")):
            options = sorted(p.stem for p in (CONF_DIR / group).glob("*.yaml"))
            raise UsageError(
                f"{group}={value}: {group} takes the name of one option ({', '.join(options)}); "
                f"set its keys one by one, e.g. {group}.<key>=<value>"
            )


def check_added_keys(defaults: DictConfig, overrides: list[str]) -> None:
    """Keys added with ``+``/``++`` (which Hydra accepts anywhere) exist in the config or belong to
    a group of free keys: a misspelt ``+algo.lrr=1e-3`` would otherwise be ignored without a word."""
    for item in overrides:
        if not item.startswith("+") or _group_override(item):
            continue
        key = item.split("=", 1)[0].lstrip("+")
        if key.startswith("hydra.") or any(key == f or key.startswith(f + ".") for f in FREE_KEYS):
            continue
        if OmegaConf.select(defaults, key, default=_ABSENT) is _ABSENT:
            raise ConfigError(
                f"unknown config key '{key}' (in {item}); a leading + adds keys only to {' and '.join(FREE_KEYS)}: "
                "`rlq train --cfg job` lists the keys"
            )


def check_interpolations(cfg: DictConfig) -> None:
    """Every ``${...}`` of the run's config (Hydra's own node aside) resolves: one line, not OmegaConf's traceback."""
    from omegaconf.errors import OmegaConfBaseException

    for key in (str(k) for k in cfg):
        if key == "hydra":
            continue
        try:
            node = cfg[key]
            if isinstance(node, DictConfig):
                OmegaConf.to_container(node, resolve=True)
        except OmegaConfBaseException as err:
            where = getattr(err, "full_key", None) or key
            first = str(err).splitlines()[0] if str(err) else type(err).__name__
            raise ConfigError(
                f"{where}: {first}; a ${{...}} names another key of the config (`rlq train --cfg job` lists them)"
            ) from None


def check_overrides(overrides: list[str], multirun: bool = False) -> list[str]:
    """Compose and validate the overrides of `rlq train` (one job); raises ConfigError or UsageError.

    Returns the overrides with integer keys written in float notation (``budget.env_steps=1e6``)
    rewritten as integers. The output directory (``hydra.run.dir``, with ``multirun``
    ``hydra.sweep.dir``) must be creatable.
    """
    return checked_run(overrides, multirun)[0]


def checked_run(overrides: list[str], multirun: bool = False) -> tuple[list[str], DictConfig | None]:
    """``check_overrides``, and the config it composed with Hydra's node, the one Hydra would compose
    for the returned overrides: None where an override was rewritten (Hydra's own record of the
    overrides, ``hydra.overrides.task``, would still hold the float), and with ``multirun``."""
    for item in overrides:
        if "=" not in item:
            raise UsageError(f"'{item}' is not an override; write key=value (e.g. algo=ppo)")
    overrides = [f"+{o}" if o.startswith("sweep.") else o for o in overrides]  # its keys are added (rlq/run/members.py)
    check_group_values(overrides)
    try:
        cfg = compose([*overrides, "hydra.mode=MULTIRUN" if multirun else "hydra.mode=RUN"], with_hydra=True)
        defaults = compose([o for o in overrides if _group_override(o)])
    except Exception as err:
        raise ConfigError(explain_hydra_error(err, overrides)) from None
    check_interpolations(cfg)
    out_key = "hydra.sweep.dir" if multirun else "hydra.run.dir"
    try:
        out_dir = OmegaConf.select(cfg, out_key)
    except Exception as err:  # an interpolation in the directory's name that does not resolve
        raise ConfigError(f"{out_key}: {str(err).splitlines()[0]}") from None
    value_keys = [o.split("=", 1)[0].lstrip("+") for o in overrides if not _group_override(o)]
    value_keys = [k for k in value_keys if not k.startswith("~")]
    fixed = integral_floats(defaults, cfg, value_keys)
    for key, value in fixed.items():
        OmegaConf.update(cfg, key, value)
    overrides = [
        f"{o.split('=', 1)[0]}={fixed[o.split('=', 1)[0].lstrip('+')]}"
        if o.split("=", 1)[0].lstrip("+") in fixed
        else o
        for o in overrides
    ]
    check_types(defaults, cfg, value_keys)
    check_added_keys(defaults, overrides)
    check_output_dir("" if out_dir is None else out_dir, out_key)
    composed = None if fixed or multirun else copy.deepcopy(cfg)
    with open_dict(cfg):
        del cfg["hydra"]
    if cfg.get("platform") == "cpu":
        from rlq.run.devices import keep_to_the_cpu

        keep_to_the_cpu()
    from rlq.run.distributed import settings, start

    if multirun and settings(cfg).enabled:
        raise ConfigError("distributed: a sweep's jobs run in one process each; set distributed.enabled=false")
    if not multirun:
        start(cfg)  # before anything starts JAX's backends (check_run_config lays out the devices)
    check_supported(cfg)
    check_run_config(cfg)
    return overrides, composed


def _interval_ends(item: str) -> str:
    """An ``interval(a,b)`` sweep (Optuna's, any tag) as the choice of its two ends, the values to check; others as given."""
    from hydra.core.override_parser.overrides_parser import OverridesParser
    from hydra.core.override_parser.types import IntervalSweep

    try:
        (override,) = OverridesParser.create().parse_overrides([item])
    except Exception:
        return item  # sweep_jobs reports it
    value = override.value()
    if not isinstance(value, IntervalSweep):
        return item
    return f"{override.get_key_element()}={value.start!r},{value.end!r}"


def sweep_jobs(overrides: list[str]) -> list[list[str]]:
    """The override list of every job of a sweep (``algo=dqn,ppo seed=0,1``: 4 jobs), in
    Hydra's basic sweeper's order. An ``interval(a,b)`` of a sampling sweeper (Optuna) stands
    for jobs at both of its ends."""
    from hydra._internal.core_plugins.basic_sweeper import BasicSweeper
    from hydra.core.override_parser.overrides_parser import OverridesParser

    try:
        parsed = OverridesParser.create().parse_overrides([_interval_ends(o) for o in overrides])
    except Exception as err:
        raise ConfigError(explain_hydra_error(err)) from None
    (batch,) = BasicSweeper.split_arguments(parsed, max_batch_size=None)
    return [list(job) for job in batch]


def _unknown_env_key(cfg: DictConfig, key: str) -> str:
    """The line for an ``env.<key>`` the env has not, in the style of `rlq train`'s, with the keys it has."""
    parent = OmegaConf.select(cfg, key.rsplit(".", 1)[0], default=None)
    node = parent if isinstance(parent, DictConfig) else cfg.env
    keys = [str(k) for k in node if not (node is cfg.env and k == "name")]
    return f"unknown config key '{key}' of env={cfg.env.name}; its keys are {', '.join(keys)}"


def with_env_overrides(cfg: DictConfig, overrides: list[str]) -> DictConfig:
    """``cfg`` with the ``env.<key>=<value>`` overrides of `rlq eval` and `rlq render`, read and checked
    as `rlq train` reads and checks its own: the key must be one of ``cfg.env``'s, the value keeps its
    default's type and lies in its range (rlq.run.constraints). Raises ConfigError or UsageError."""
    from hydra.core.override_parser.overrides_parser import OverridesParser

    from rlq.run.constraints import problems

    parser = OverridesParser.create()
    out = copy.deepcopy(cfg)
    keys = []
    for item in overrides:
        try:
            (override,) = parser.parse_overrides([item])
        except Exception as err:
            raise ConfigError(explain_hydra_error(err)) from None
        key = override.key_or_group
        if override.is_sweep_override():
            raise UsageError(f"{item} gives several values; eval and render take one value per key")
        if key == "env.name":
            raise UsageError(f"{item}: choose the env with env=NAME")
        if OmegaConf.select(cfg, key, default=_ABSENT, throw_on_missing=False) is _ABSENT:
            raise ConfigError(_unknown_env_key(cfg, key))
        OmegaConf.update(out, key, override.value(), force_add=True)
        keys.append(key)
    for key, value in integral_floats(cfg, out, keys).items():
        OmegaConf.update(out, key, value)
    check_types(cfg, out, keys)
    problem = problems(out)
    if problem:
        raise ConfigError(problem)
    return out


def _swept_keys(overrides: list[str]) -> set[str]:
    """The keys a sweep varies (``seed=0,1``: seed), as Hydra's parser reads them (``sweep_jobs`` parsed them first)."""
    from hydra.core.override_parser.overrides_parser import OverridesParser

    parsed = OverridesParser.create().parse_overrides(overrides)
    return {o.key_or_group for o in parsed if o.is_sweep_override()}


def check_sweep(overrides: list[str]) -> None:
    """Validate every job of `rlq train -m` before the first starts; the error names the job."""
    for item in overrides:
        if "=" not in item:
            raise UsageError(f"'{item}' is not an override; write key=value (e.g. algo=ppo,dqn)")
    jobs = sweep_jobs(overrides)
    swept_keys = _swept_keys(overrides)

    def swept(job: list[str]) -> str:
        return " ".join(o for o in job if o.split("=", 1)[0].lstrip("+~") in swept_keys) or "no sweep"

    seen: dict[tuple[str, ...], int] = {}
    for number, job in enumerate(jobs):
        same = seen.setdefault(tuple(sorted(job)), number)
        if same != number:
            raise UsageError(
                f"jobs {same} and {number} of {len(jobs)} are the same run ({swept(job)}), which would share one "
                "directory: give each value once"
            )
    for number, job in enumerate(jobs):
        try:
            check_overrides(job, multirun=True)
        except (ConfigError, UsageError) as err:
            raise type(err)(f"job {number} of {len(jobs)} ({swept(job)}): {err}") from None
