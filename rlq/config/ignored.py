"""Keys a chosen variant never reads, refused when the command line sets them: ``algo.variant=ars algo.sigma=0.3``
would run ARS as if ``algo.sigma`` were not there. One table (``IGNORED``): each entry names the component, the
setting that makes it ignore keys, and the keys. Only keys the user set are refused: a preset, a tuned file or the
yaml defaults carry the keys of every variant."""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

from omegaconf import DictConfig, ListConfig, OmegaConf

from rlq.config.compose import group_override
from rlq.errors import ConfigError

#: the section-relative settings (``["variant=ars"]``) under which an entry's keys are not read, or None where they are
Choice = Callable[[DictConfig], list[str] | None]


@dataclass(frozen=True)
class Ignored:
    """``keys`` of ``section`` (``algo``, ``env``) are not read by its components ``names`` when ``choice`` of the
    section's composed config names the settings that make it so; ``reads``: the setting that would read them."""

    section: str
    names: tuple[str, ...]
    choice: Choice
    keys: tuple[str, ...]
    reads: str


def _text(value: Any) -> str:
    if value is None:
        return "null"
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, ListConfig | list):
        return "[" + ",".join(_text(v) for v in value) + "]"
    return str(value)


def _is(key: str, *values: Any) -> Choice:
    """The setting ``key=value`` where the section's ``key`` is one of ``values``."""

    def choice(node: DictConfig) -> list[str] | None:
        value = OmegaConf.select(node, key, default=None)
        return [f"{key}={_text(value)}"] if value in values else None

    return choice


def _is_not(key: str, *values: Any) -> Choice:
    """The setting ``key=value`` where the section's ``key`` is none of ``values``."""

    def choice(node: DictConfig) -> list[str] | None:
        value = OmegaConf.select(node, key, default=None)
        return [f"{key}={_text(value)}"] if value not in values else None

    return choice


def _all(*choices: Choice) -> Choice:
    """The settings of every choice, where each names some."""

    def choice(node: DictConfig) -> list[str] | None:
        named = [c(node) for c in choices]
        return [s for n in named for s in n or []] if all(named) else None

    return choice


def _linear(node: DictConfig) -> list[str] | None:
    return ["genotype=policy", "hidden=[]"] if node.get("genotype") == "policy" and not node.get("hidden") else None


def _mlp(node: DictConfig) -> list[str] | None:
    hidden = node.get("hidden")
    return ["genotype=policy", f"hidden={_text(hidden)}"] if node.get("genotype") == "policy" and hidden else None


def _no_iso_line(node: DictConfig) -> list[str] | None:
    """MAP-Elites' uniform elites are varied by ``algo.emitter`` where it names a variation, else by
    ``algo.variation``: iso_line's keys are read by iso_line only."""
    emitter, variation = node.get("emitter"), node.get("variation")
    if emitter == variation:  # the default: algo.emitter follows algo.variation
        return None if variation == "iso_line" else [f"variation={variation}"]
    if emitter in ("gaussian", "iso_line"):
        return None if emitter == "iso_line" else [f"emitter={emitter}"]
    return None if variation == "iso_line" else [f"variation={variation}", f"emitter={emitter}"]


_SEARCHES = ("random_search", "es", "map_elites")
_EPSILON_GREEDY = ("dqn", "pqn", "qlearning")
_CMA = ("cma_emitters", "cma_sigma")
_CVT = ("archive.cells", "archive.cvt_samples", "archive.cvt_seed")

#: every key a chosen variant does not read
IGNORED: tuple[Ignored, ...] = (
    Ignored("algo", ("random_search",), _is("variant", "hill_climb"), ("ars",), "algo.variant=ars"),
    Ignored(
        "algo",
        ("random_search",),
        _is("variant", "ars"),
        ("population", "sampling", "low", "high", "sigma"),
        "algo.variant=hill_climb",
    ),
    Ignored(
        "algo",
        ("random_search",),
        _all(_is("variant", "hill_climb"), _is("sampling", "uniform")),
        ("sigma",),
        "algo.sampling=gaussian",
    ),
    Ignored(
        "algo",
        _SEARCHES,
        _is("genotype", "action"),
        ("hidden", "bias", "activation", "low", "high"),
        "algo.genotype=policy",
    ),
    Ignored("algo", _SEARCHES, _linear, ("activation",), "an MLP (algo.hidden=[16])"),
    Ignored("algo", _SEARCHES, _mlp, ("bias",), "a linear policy (algo.hidden=[])"),
    Ignored("algo", ("es",), _is_not("strategy", "open_es"), ("lr",), "algo.strategy=open_es"),
    Ignored("algo", ("es",), _is("keep", "candidate"), ("mean_episodes",), "algo.keep=mean"),
    Ignored("algo", ("map_elites",), _no_iso_line, ("iso_sigma", "line_sigma"), "algo.variation=iso_line"),
    Ignored(
        "algo", ("map_elites",), _is_not("emitter", "improvement", "mixed"), _CMA, "algo.emitter=improvement or mixed"
    ),
    Ignored("algo", ("map_elites",), _is_not("emitter", "mixed"), ("improvement_fraction",), "algo.emitter=mixed"),
    Ignored("algo", ("map_elites",), _is_not("emitter", "rotation"), ("rotation_fraction",), "algo.emitter=rotation"),
    Ignored(
        "algo",
        ("map_elites",),
        _is("es_fraction", 0, 0.0),
        ("es_objective", "es_sigma", "es_lr"),
        "algo.es_fraction above 0",
    ),
    Ignored(
        "algo",
        ("map_elites",),
        _is("champion.candidates", 0),
        ("champion.episodes",),
        "algo.champion.candidates above 0",
    ),
    Ignored("algo", ("map_elites",), _is("archive.kind", "grid"), _CVT, "algo.archive.kind=cvt"),
    Ignored("algo", ("map_elites",), _is("archive.kind", "cvt"), ("archive.shape",), "algo.archive.kind=grid"),
    Ignored(
        "algo",
        _EPSILON_GREEDY,
        _is("epsilon.schedule", "linear"),
        ("epsilon.decay",),
        "algo.epsilon.schedule=exponential",
    ),
    Ignored(
        "algo",
        _EPSILON_GREEDY,
        _is("epsilon.schedule", "exponential"),
        ("epsilon.duration",),
        "algo.epsilon.schedule=linear",
    ),
    Ignored("algo", ("reinforce",), _is_not("baseline", "value"), ("vf_coef",), "algo.baseline=value"),
    Ignored(
        "algo", ("qlearning",), _is("replay_size", 0), ("replay_batch", "replay_updates"), "algo.replay_size above 0"
    ),
    Ignored(
        "env",
        ("lunar", "lunar_box2d"),
        _is("enable_wind", False),
        ("wind_power", "turbulence_power"),
        "env.enable_wind=true",
    ),
)


def _covers(key: str, ignored: str) -> bool:
    """Whether the user's ``key`` (section-relative) is ``ignored`` or below it (``ars.top`` under ``ars``)."""
    return key == ignored or key.startswith(ignored + ".")


def check_ignored(cfg: DictConfig, user_keys: Iterable[str], table: Iterable[Ignored] = IGNORED) -> None:
    """Raises ConfigError naming the first key of ``user_keys`` (the command line's, e.g. ``algo.sigma``) that the
    composed ``cfg``'s chosen variant does not read."""
    for given in user_keys:
        section, _, rest = given.partition(".")
        node = cfg.get(section)
        if not rest or not isinstance(node, DictConfig):
            continue
        for entry in table:
            if entry.section != section or node.get("name") not in entry.names:
                continue
            if not any(_covers(rest, ignored) for ignored in entry.keys):
                continue
            settings = entry.choice(node)
            if settings:
                chosen = " ".join(f"{section}.{setting}" for setting in settings)
                raise ConfigError(
                    f"{given} is not read with {section}={node.get('name')} {chosen}: drop {given}, or set "
                    f"{entry.reads}, which reads it"
                )


def given_keys(overrides: Iterable[str]) -> list[str]:
    """The keys the command line sets a value of (``algo.sigma=0.3``, ``+sweep.algo.lr=[...]``): not its group
    choices (``algo=ppo``) or deletions (``~tuned``)."""
    return [o.split("=", 1)[0].lstrip("+") for o in overrides if not group_override(o) and not o.startswith("~")]
