"""``stop.when``: a condition on a logged metric that ends a run early ("solved"), e.g.
``eval/return>=200``: the mean over seeds of an evaluation's (``eval/``) or a chunk's training
(``train/``) metric, compared with a threshold by ``>=``, ``>``, ``<=`` or ``<``."""

from __future__ import annotations

import math
import operator
import re
from collections.abc import Callable
from dataclasses import dataclass

from rlq.errors import ConfigError

#: the comparisons ``stop.when`` accepts (two-character ones first, so ``>=`` is not read as ``>``)
OPERATORS: dict[str, Callable[[float, float], bool]] = {
    ">=": operator.ge,
    "<=": operator.le,
    ">": operator.gt,
    "<": operator.lt,
}
KINDS = ("eval", "train")
_PATTERN = re.compile(r"^\s*(\w+)/([\w\-.]+)\s*(>=|<=|>|<)\s*(\S+)\s*$")


@dataclass(frozen=True)
class StopRule:
    kind: str  # "eval" or "train": the rows the metric is read from
    metric: str
    op: str
    threshold: float

    def met(self, value: float) -> bool:
        return not math.isnan(value) and OPERATORS[self.op](value, self.threshold)

    def __str__(self) -> str:
        return f"{self.kind}/{self.metric}{self.op}{self.threshold:g}"


def parse_stop(text: str) -> StopRule:
    """``"eval/return>=200"`` as a StopRule; a ConfigError names what is wrong."""
    example = """e.g. 'stop.when="eval/return>=200"' in a shell"""
    match = _PATTERN.match(str(text))
    if match is None:
        raise ConfigError(
            f"stop.when={text!r} is not <eval|train>/<metric><op><number> with op one of "
            f"{', '.join(OPERATORS)} ({example})"
        )
    kind, metric, op, number = match.groups()
    if kind not in KINDS:
        raise ConfigError(f"stop.when={text!r}: the metric must start with eval/ or train/, not {kind}/ ({example})")
    try:
        threshold = float(number)
    except ValueError:
        raise ConfigError(f"stop.when={text!r}: the threshold {number!r} is not a number ({example})") from None
    if math.isnan(threshold):
        raise ConfigError(f"stop.when={text!r}: the threshold must be a number, not nan")
    return StopRule(kind, metric, op, threshold)
