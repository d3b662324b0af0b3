"""The one optimiser builder: Adam with an optional linear decay to 0 and optional global-norm clipping."""

from __future__ import annotations

import optax


def adam(
    lr: float, anneal_steps: int | None, max_grad_norm: float | None, eps: float = 1e-8
) -> optax.GradientTransformation:
    """Adam at ``lr`` (decayed linearly to 0 over ``anneal_steps`` optimiser steps when given), after
    clipping the gradients' global norm to ``max_grad_norm`` (None or 0: no clipping)."""
    schedule = optax.linear_schedule(lr, 0.0, anneal_steps) if anneal_steps else lr
    clip = [optax.clip_by_global_norm(max_grad_norm)] if max_grad_norm else []
    return optax.chain(*clip, optax.adam(schedule, eps=eps))
