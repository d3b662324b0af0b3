"""``controller=cpg``'s keys: the central pattern generator of the brittle star (env=brittle_star or
brittle_star_undirected). The agent's action modulates 10 oscillators (IP_k at 2k, OOP_k at 2k+1;
parametric_segment: one per joint); their outputs are the joint targets (rlq/controllers/cpg.py)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from rlq.lib.settings import COUNT, FINITE, NON_NEGATIVE, POSITIVE, setting


@dataclass(frozen=True)
class Config:
    """``controller=cpg``'s keys: type, default, allowed values and meaning. Choices and rules across keys and the
    env: ``rlq.controllers.cpg.check``."""

    name: str = setting("cpg")
    #: leading_arm: Discrete(5), T0's leading-arm pattern | parametric: Box(5A+1) = Box(26), T2's genotype |
    #: parametric_segment: Box(4AS+2A+1) = Box(71) for 5 x 3: R, X per joint, omega, IP->OOP bias and
    #: segment-to-segment lag per arm | parametric_symmetric: Box(5), 5 arms: leading arm, rower amplitude, leader
    #: lift, omega, rower IP->OOP bias | decentralised: one role per arm (0 leader, 1 left rower, 2 right rower,
    #: 3 idle), T0's pattern built arm by arm (rlq/controllers/roles.py; with env.observation=arm_sectors)
    mode: str = setting("leading_arm")
    #: every_step | at_reset: latch the episode's first action (open loop, MAP-Elites)
    modulate: str = setting("every_step")
    #: euler | rk4 (dt = the env's control timestep, one CPG step per control step)
    integrator: str = setting("euler")
    #: ring: IP<->OOP per arm + neighbouring arms (T0) | arm: IP<->OOP only (T2) | none (parametric_segment: arm =
    #: IP<->OOP per segment + consecutive segments; ring adds the first segments of neighbouring arms)
    coupling: str = setting("ring")
    coupling_weight: float = setting(5.0, NON_NEGATIVE)
    #: a
    amplitude_gain: float = setting(20.0, POSITIVE)
    #: b
    offset_gain: float = setting(20.0, POSITIVE)
    #: initial phases uniform in +-phase_noise
    phase_noise: float = setting(0.01, NON_NEGATIVE)
    #: J = leading_amplitude x the joint's action bound (leading_arm, decentralised)
    leading_amplitude: float = setting(0.5, NON_NEGATIVE)
    #: omega of leading_arm and decentralised
    leading_omega: float = setting(math.pi, FINITE)
    #: an arm index fixes the leading arm (the action is then ignored); below env.num_arms: check
    leading_arm: int | None = setting(None, COUNT)
    #: parametric* bounds: R (parametric_symmetric: rower amplitude) in [0, max_amplitude]
    max_amplitude: float = setting(1.0, POSITIVE)
    #: X (parametric_symmetric: leader lift) in [-max_offset, max_offset]
    max_offset: float = setting(1.0, NON_NEGATIVE)
    #: omega in [0, max_omega] (3 pi); phase biases and lags in [-pi, pi]
    max_omega: float = setting(3 * math.pi, POSITIVE)
