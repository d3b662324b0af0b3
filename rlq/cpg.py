"""Central pattern generator of the brittle star tutorials: coupled amplitude-controlled phase
oscillators, two per arm (in-plane IP at index 2k, out-of-plane OOP at 2k+1).

    dphi_i = omega_i + sum_j w_ij r_j sin(phi_j - phi_i - rho_ij)
    ddr_i  = a (a/4 (R_i - r_i) - dr_i)
    ddx_i  = b (b/4 (X_i - x_i) - dx_i)
    output_i = x_i + r_i cos(phi_i)

``rho_ij`` is the phase of j relative to i at the coupled equilibrium (phi_j - phi_i -> rho_ij).
Pure functions only; the controller wrapper lives in rlq/controllers/cpg.py.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

IP, OOP = 0, 1


@struct.dataclass
class CPGState:
    phase: jax.Array
    amplitude: jax.Array
    amplitude_rate: jax.Array
    offset: jax.Array
    offset_rate: jax.Array


@struct.dataclass
class Modulation:
    """Targets the oscillators converge to: amplitudes R, offsets X, frequencies omega (rad/s),
    phase biases rho (n x n, antisymmetric)."""

    R: jax.Array
    X: jax.Array
    omega: jax.Array
    rho: jax.Array


def osc(arm: int, kind: int) -> int:
    """Oscillator index of an arm's in-plane (kind 0) or out-of-plane (kind 1) joint."""
    return 2 * arm + kind


def init_state(key: jax.Array, num_oscillators: int, phase_noise: float = 0.01) -> CPGState:
    """Phases uniform in +-phase_noise, everything else zero."""
    zeros = jnp.zeros(num_oscillators)
    phase = jax.random.uniform(key, (num_oscillators,), minval=-phase_noise, maxval=phase_noise)
    return CPGState(phase=phase, amplitude=zeros, amplitude_rate=zeros, offset=zeros, offset_rate=zeros)


def coupling_weights(num_arms: int, topology: str, weight: float) -> np.ndarray:
    """Symmetric weights: ``arm`` couples IP_k and OOP_k (T2); ``ring`` adds IP_k-IP_k+1 and
    OOP_k-OOP_k+1 around the disk (T0). ``none``: free oscillators."""
    if topology not in ("ring", "arm", "none"):
        raise ValueError(f"controller.coupling must be ring, arm or none, got {topology!r}")
    adjacency = np.zeros((2 * num_arms, 2 * num_arms))
    if topology == "none":
        return adjacency
    for k in range(num_arms):
        adjacency[osc(k, IP), osc(k, OOP)] = 1
        if topology == "ring" and num_arms > 1:
            nxt = (k + 1) % num_arms
            adjacency[osc(k, IP), osc(nxt, IP)] = 1
            adjacency[osc(k, OOP), osc(nxt, OOP)] = 1
    adjacency = np.maximum(adjacency, adjacency.T)
    return weight * adjacency


def derivatives(state: CPGState, mod: Modulation, weights: jax.Array, a: float, b: float) -> CPGState:
    diff = state.phase[None, :] - state.phase[:, None] - mod.rho  # [i, j] = phi_j - phi_i - rho_ij
    dphase = mod.omega + jnp.sum(weights * state.amplitude[None, :] * jnp.sin(diff), axis=1)
    ddr = a * (a / 4 * (mod.R - state.amplitude) - state.amplitude_rate)
    ddx = b * (b / 4 * (mod.X - state.offset) - state.offset_rate)
    return CPGState(
        phase=dphase, amplitude=state.amplitude_rate, amplitude_rate=ddr, offset=state.offset_rate, offset_rate=ddx
    )


def _axpy(state: CPGState, deriv: CPGState, h: float) -> CPGState:
    return jax.tree.map(lambda s, d: s + h * d, state, deriv)


def step(
    state: CPGState,
    mod: Modulation,
    weights: jax.Array,
    dt: float,
    a: float = 20.0,
    b: float = 20.0,
    method: str = "euler",
) -> CPGState:
    """One integration step of length ``dt`` with the modulation held constant."""
    f = lambda s: derivatives(s, mod, weights, a, b)  # noqa: E731
    if method == "euler":
        return _axpy(state, f(state), dt)
    if method == "rk4":
        k1 = f(state)
        k2 = f(_axpy(state, k1, dt / 2))
        k3 = f(_axpy(state, k2, dt / 2))
        k4 = f(_axpy(state, k3, dt))
        return jax.tree.map(lambda s, d1, d2, d3, d4: s + dt / 6 * (d1 + 2 * d2 + 2 * d3 + d4), state, k1, k2, k3, k4)
    raise ValueError(f"controller.integrator must be euler or rk4, got {method!r}")


def output(state: CPGState) -> jax.Array:
    return state.offset + state.amplitude * jnp.cos(state.phase)


def leading_arm_modulation(arm: jax.Array, amplitude: jax.Array, omega: float = float(np.pi)) -> Modulation:
    """T0's leading-arm pattern for 5 arms; ``amplitude`` (J) holds one value per oscillator.

    The leading arm L lifts (X[OOP_L] = J, no oscillation); its neighbours L-1, L-2 (left) and
    L+1, L+2 (right) row with R = J and phase biases that make the stroke push away from L.
    """
    n = amplitude.shape[0]
    num_arms = n // 2
    arm = jnp.asarray(arm, jnp.int32)
    left1, left2 = (arm - 1) % num_arms, (arm - 2) % num_arms
    right1, right2 = (arm + 1) % num_arms, (arm + 2) % num_arms
    R = jnp.zeros(n)
    for rower in (left1, left2, right1, right2):
        R = R.at[2 * rower + IP].set(amplitude[2 * rower + IP]).at[2 * rower + OOP].set(amplitude[2 * rower + OOP])
    X = jnp.zeros(n).at[2 * arm + OOP].set(amplitude[2 * arm + OOP])
    pairs = [
        (2 * left1 + IP, 2 * left1 + OOP, np.pi / 2),
        (2 * left2 + IP, 2 * left2 + OOP, np.pi / 2),
        (2 * right1 + OOP, 2 * right1 + IP, np.pi / 2),
        (2 * right2 + OOP, 2 * right2 + IP, np.pi / 2),
        (2 * left1 + IP, 2 * arm + IP, np.pi / 4),
        (2 * arm + OOP, 2 * left1 + OOP, np.pi / 4),
        (2 * arm + IP, 2 * right1 + IP, np.pi / 4),
        (2 * right1 + OOP, 2 * arm + OOP, np.pi / 4),
        (2 * left2 + IP, 2 * right2 + IP, np.pi),
    ]
    rho = jnp.zeros((n, n))
    for o1, o2, bias in pairs:
        rho = rho.at[o1, o2].set(bias).at[o2, o1].set(-bias)
    return Modulation(R=R, X=X, omega=jnp.full(n, omega), rho=rho)


def parametric_size(num_arms: int) -> int:
    """R (2A) + X (2A) + omega (1) + one IP->OOP phase bias per arm (A): 26 for 5 arms."""
    return 5 * num_arms + 1


def parametric_bounds(
    num_arms: int, max_amplitude: float, max_offset: float, max_omega: float
) -> tuple[np.ndarray, np.ndarray]:
    """T2's genotype bounds: R in [0, 1], X in [-1, 1], omega in [0, 3pi], biases in [-pi, pi]."""
    n = 2 * num_arms
    low = np.concatenate([np.zeros(n), -max_offset * np.ones(n), [0.0], -np.pi * np.ones(num_arms)])
    high = np.concatenate([max_amplitude * np.ones(n), max_offset * np.ones(n), [max_omega], np.pi * np.ones(num_arms)])
    return low, high


def parametric_modulation(params: jax.Array, num_arms: int) -> Modulation:
    """Genotype [R (2A), X (2A), omega, bias_k (A)] -> modulation; bias_k = rho[IP_k, OOP_k]."""
    n = 2 * num_arms
    R, X, omega, bias = params[:n], params[n : 2 * n], params[2 * n], params[2 * n + 1 :]
    ip = np.arange(num_arms) * 2 + IP
    rho = jnp.zeros((n, n)).at[ip, ip + 1].set(bias).at[ip + 1, ip].set(-bias)
    return Modulation(R=R, X=X, omega=jnp.full(n, omega), rho=rho)
