"""Decentralised CPG modulation: each arm picks its own role, and the roles make one modulation.

Roles (the action of one arm in ``controller.mode=decentralised``): ``LEADER`` lifts (X[OOP] = J,
no oscillation), ``LEFT`` and ``RIGHT`` row (R[IP] = R[OOP] = J, IP/OOP bias pi/2 as T0's left and
right rowers), ``IDLE`` rests (R = X = 0). Phase biases between neighbouring arms a, b = a + 1
(mod A) follow T0's pattern edge by edge: a leader at either end gives (IP_a, IP_b, pi/4) and
(OOP_b, OOP_a, pi/4) (T0's first rowers), a left and a right rower give (IP_left, IP_right, pi)
(T0's second rowers), anything else 0. So the roles of T0's leading arm L (L leader, L-1 and L-2
left, L+1 and L+2 right) give exactly ``oscillators.leading_arm_modulation(L)``.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from rlq.controllers.oscillators import IP, OOP, Modulation

LEADER, LEFT, RIGHT, IDLE = 0, 1, 2, 3
NUM_ROLES = 4


def leading_arm_roles(arm: int, num_arms: int) -> np.ndarray:
    """T0's pattern as roles: the leader, its two left (L-1, L-2) and two right (L+1, L+2) rowers."""
    roles = np.full(num_arms, IDLE)
    roles[arm] = LEADER
    for offset in (1, 2):
        roles[(arm - offset) % num_arms] = LEFT
        roles[(arm + offset) % num_arms] = RIGHT
    return roles


def _set_pair(rho: jax.Array, o1: int, o2: int, bias: jax.Array) -> jax.Array:
    return rho.at[o1, o2].set(bias).at[o2, o1].set(-bias)


def role_modulation(roles: jax.Array, amplitude: jax.Array, omega: float) -> Modulation:
    """The modulation of one role per arm (``roles``: A ints in 0..3); ``amplitude`` holds J per
    oscillator (2A), the leader lifts by its OOP oscillator's J."""
    roles = jnp.clip(jnp.asarray(roles, jnp.int32), 0, NUM_ROLES - 1)
    num_arms = roles.shape[0]
    n = 2 * num_arms
    rowing = jnp.repeat((roles == LEFT) | (roles == RIGHT), 2)
    R = jnp.where(rowing, amplitude, 0.0)
    oop = np.arange(num_arms) * 2 + OOP
    X = jnp.zeros(n).at[oop].set(jnp.where(roles == LEADER, amplitude[oop], 0.0))
    rho = jnp.zeros((n, n))
    half_pi = jnp.pi / 2
    for k in range(num_arms):
        rower_bias = jnp.where(roles[k] == LEFT, half_pi, jnp.where(roles[k] == RIGHT, -half_pi, 0.0))
        rho = _set_pair(rho, 2 * k + IP, 2 * k + OOP, rower_bias)
    for a in range(num_arms):
        b = (a + 1) % num_arms
        led = (roles[a] == LEADER) | (roles[b] == LEADER)
        left_right = (roles[a] == LEFT) & (roles[b] == RIGHT)
        right_left = (roles[a] == RIGHT) & (roles[b] == LEFT)
        ip_bias = jnp.where(led, jnp.pi / 4, jnp.where(left_right, jnp.pi, jnp.where(right_left, -jnp.pi, 0.0)))
        rho = _set_pair(rho, 2 * a + IP, 2 * b + IP, ip_bias)
        rho = _set_pair(rho, 2 * b + OOP, 2 * a + OOP, jnp.where(led, jnp.pi / 4, 0.0))
    return Modulation(R=R, X=X, omega=jnp.full(n, omega), rho=rho)
