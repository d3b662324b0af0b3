"""Central pattern generator of the brittle star tutorials: coupled amplitude-controlled phase
oscillators, two per arm (in-plane IP at index 2k, out-of-plane OOP at 2k+1), or two per segment
in the per-segment layout (``segment_osc``: arm-major, then segment, then IP/OOP).

    dphi_i = omega_i + sum_j w_ij r_j sin(phi_j - phi_i - rho_ij)
    ddr_i  = a (a/4 (R_i - r_i) - dr_i)
    ddx_i  = b (b/4 (X_i - x_i) - dx_i)
    output_i = x_i + r_i cos(phi_i)

``rho_ij`` is the phase of j relative to i at the coupled equilibrium (phi_j - phi_i -> rho_ij).
Pure functions only; the controller wrapper lives in rlq/controllers/cpg.py.
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

IP, OOP = 0, 1


class CPGState(struct.PyTreeNode):
    phase: jax.Array
    amplitude: jax.Array
    amplitude_rate: jax.Array
    offset: jax.Array
    offset_rate: jax.Array


class Modulation(struct.PyTreeNode):
    """Targets the oscillators converge to: amplitudes R, offsets X, frequencies omega (rad/s),
    phase biases rho (n x n, antisymmetric)."""

    R: jax.Array
    X: jax.Array
    omega: jax.Array
    rho: jax.Array


def osc(arm: int, kind: int) -> int:
    """Oscillator index of an arm's in-plane (kind 0) or out-of-plane (kind 1) joint."""
    return 2 * arm + kind


def segment_osc(arm: Any, segment: Any, kind: Any, num_segments: int) -> Any:
    """Oscillator index of one joint in the per-segment layout (ints or integer arrays)."""
    return 2 * (arm * num_segments + segment) + kind


def init_state(key: jax.Array, num_oscillators: int, phase_noise: float = 0.01) -> CPGState:
    """Phases uniform in +-phase_noise, everything else zero."""
    zeros = jnp.zeros(num_oscillators)
    phase = jax.random.uniform(key, (num_oscillators,), minval=-phase_noise, maxval=phase_noise)
    return CPGState(phase=phase, amplitude=zeros, amplitude_rate=zeros, offset=zeros, offset_rate=zeros)


def coupling_weights(num_arms: int, topology: str, weight: float, num_segments: int = 1) -> np.ndarray:
    """Symmetric weights over ``segment_osc`` indices (``osc`` for one segment per arm).

    ``arm`` couples IP and OOP of each segment (T2) and, along each arm, IP_s-IP_s+1 and
    OOP_s-OOP_s+1; ``ring`` adds IP_k-IP_k+1 and OOP_k-OOP_k+1 around the disk at the arms' first
    segments (T0); ``none``: free oscillators.
    """
    if topology not in ("ring", "arm", "none"):
        raise ValueError(f"controller.coupling must be ring, arm or none, got {topology!r}")
    n = 2 * num_arms * num_segments
    adjacency = np.zeros((n, n))
    if topology == "none":
        return adjacency
    for k in range(num_arms):
        for s in range(num_segments):
            adjacency[segment_osc(k, s, IP, num_segments), segment_osc(k, s, OOP, num_segments)] = 1
            for kind in (IP, OOP):
                if s + 1 < num_segments:
                    adjacency[segment_osc(k, s, kind, num_segments), segment_osc(k, s + 1, kind, num_segments)] = 1
        if topology == "ring" and num_arms > 1:
            nxt = (k + 1) % num_arms
            for kind in (IP, OOP):
                adjacency[segment_osc(k, 0, kind, num_segments), segment_osc(nxt, 0, kind, num_segments)] = 1
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


def require_five_arms(num_arms: int, what: str) -> None:
    if num_arms != 5:
        raise ValueError(f"{what} needs 5 arms, got {num_arms}")


def _leading_arm_pattern(
    arm: jax.Array, rower_amplitude: jax.Array, lift: jax.Array, omega: jax.Array | float, rower_bias: jax.Array | float
) -> Modulation:
    """T0's leading-arm pattern for 5 arms (``rower_amplitude`` holds one R per oscillator).

    The leading arm L lifts (X[OOP_L] = lift, no oscillation); its neighbours L-1, L-2 (left) and
    L+1, L+2 (right) row with R = rower_amplitude, phase biases rower_bias between IP and OOP
    (mirrored for the right rowers) and T0's fixed biases between the arms, so the stroke pushes
    away from L.
    """
    n = rower_amplitude.shape[0]
    num_arms = n // 2
    require_five_arms(num_arms, "the leading-arm pattern")
    arm = jnp.asarray(arm, jnp.int32)
    left1, left2 = (arm - 1) % num_arms, (arm - 2) % num_arms
    right1, right2 = (arm + 1) % num_arms, (arm + 2) % num_arms
    R = jnp.zeros(n)
    for rower in (left1, left2, right1, right2):
        for kind in (IP, OOP):
            R = R.at[2 * rower + kind].set(rower_amplitude[2 * rower + kind])
    X = jnp.zeros(n).at[2 * arm + OOP].set(lift)
    pairs = [
        (2 * left1 + IP, 2 * left1 + OOP, rower_bias),
        (2 * left2 + IP, 2 * left2 + OOP, rower_bias),
        (2 * right1 + OOP, 2 * right1 + IP, rower_bias),
        (2 * right2 + OOP, 2 * right2 + IP, rower_bias),
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


def leading_arm_modulation(arm: jax.Array, amplitude: jax.Array, omega: float = float(np.pi)) -> Modulation:
    """T0's leading-arm pattern for 5 arms; ``amplitude`` (J) holds one value per oscillator.

    The leader lifts by its OOP oscillator's J; the rowers row with R = J and IP/OOP biases pi/2.
    """
    arm = jnp.asarray(arm, jnp.int32)
    return _leading_arm_pattern(arm, amplitude, amplitude[2 * arm + OOP], omega, np.pi / 2)


def _genotype_bounds(
    num_oscillators: int, num_angles: int, max_amplitude: float, max_offset: float, max_omega: float
) -> tuple[np.ndarray, np.ndarray]:
    """[R (n) in [0, max_amplitude], X (n) in +-max_offset, omega in [0, max_omega], angles in +-pi]."""
    n = num_oscillators
    low = np.concatenate([np.zeros(n), -max_offset * np.ones(n), [0.0], -np.pi * np.ones(num_angles)])
    high = np.concatenate(
        [max_amplitude * np.ones(n), max_offset * np.ones(n), [max_omega], np.pi * np.ones(num_angles)]
    )
    return low, high


def parametric_size(num_arms: int) -> int:
    """R (2A) + X (2A) + omega (1) + one IP->OOP phase bias per arm (A): 26 for 5 arms."""
    return 5 * num_arms + 1


def parametric_bounds(
    num_arms: int, max_amplitude: float, max_offset: float, max_omega: float
) -> tuple[np.ndarray, np.ndarray]:
    """T2's genotype bounds: R in [0, 1], X in [-1, 1], omega in [0, 3pi], biases in [-pi, pi]."""
    return _genotype_bounds(2 * num_arms, num_arms, max_amplitude, max_offset, max_omega)


def parametric_modulation(params: jax.Array, num_arms: int) -> Modulation:
    """Genotype [R (2A), X (2A), omega, bias_k (A)] -> modulation; bias_k = rho[IP_k, OOP_k]."""
    n = 2 * num_arms
    R, X, omega, bias = params[:n], params[n : 2 * n], params[2 * n], params[2 * n + 1 :]
    ip = np.arange(num_arms) * 2 + IP
    rho = jnp.zeros((n, n)).at[ip, ip + 1].set(bias).at[ip + 1, ip].set(-bias)
    return Modulation(R=R, X=X, omega=jnp.full(n, omega), rho=rho)


def arm_rotations(num_arms: int, blocks: tuple[tuple[int, bool], ...]) -> np.ndarray:
    """Index permutations ``(num_arms, dim)`` that turn a genotype by whole arms: row k gives arm a
    the numbers arm a - k had, so ``genotype[row k]`` drives the body as ``genotype`` did, turned by
    k arms. ``blocks`` lists the genotype's consecutive parts as ``(width, per_arm)``: a per-arm part
    holds ``width`` numbers for each arm, arm-major; a shared one (omega) ``width`` numbers."""
    rows = []
    for k in range(num_arms):
        parts, start = [], 0
        for width, per_arm in blocks:
            size = width * num_arms if per_arm else width
            index = np.arange(start, start + size)
            parts.append(np.roll(index.reshape(num_arms, width), k, axis=0).reshape(-1) if per_arm else index)
            start += size
        rows.append(np.concatenate(parts))
    return np.stack(rows)


def parametric_rotations(num_arms: int) -> np.ndarray:
    """``arm_rotations`` of T2's genotype [R (2A), X (2A), omega, bias_k (A)]."""
    return arm_rotations(num_arms, ((2, True), (2, True), (1, False), (1, True)))


def parametric_segment_rotations(num_arms: int, num_segments: int) -> np.ndarray:
    """``arm_rotations`` of [R (2AS), X (2AS), omega, bias_k (A), lag_k (A)] (``segment_osc`` is arm-major)."""
    per_arm = 2 * num_segments
    return arm_rotations(num_arms, ((per_arm, True), (per_arm, True), (1, False), (1, True), (1, True)))


def parametric_segment_size(num_arms: int, num_segments: int) -> int:
    """R (2AS) + X (2AS) + omega (1) + IP->OOP bias per arm (A) + segment lag per arm (A).

    4AS + 2A + 1: 71 for 5 arms x 3 segments (30 + 30 + 1 + 5 + 5).
    """
    return 4 * num_arms * num_segments + 2 * num_arms + 1


def parametric_segment_bounds(
    num_arms: int, num_segments: int, max_amplitude: float, max_offset: float, max_omega: float
) -> tuple[np.ndarray, np.ndarray]:
    """R in [0, max_amplitude], X in +-max_offset, omega in [0, max_omega], biases and lags in +-pi."""
    return _genotype_bounds(2 * num_arms * num_segments, 2 * num_arms, max_amplitude, max_offset, max_omega)


def parametric_segment_modulation(params: jax.Array, num_arms: int, num_segments: int) -> Modulation:
    """Genotype [R (2AS), X (2AS), omega, bias_k (A), lag_k (A)] -> modulation over ``segment_osc``.

    rho[IP_ks, OOP_ks] = bias_k in every segment of arm k; rho[IP_ks, IP_ks+1] = rho[OOP_ks, OOP_ks+1]
    = lag_k, so at equilibrium phi(segment s+1) - phi(segment s) = lag_k (a wave along the arm).
    """
    n = 2 * num_arms * num_segments
    R, X, omega = params[:n], params[n : 2 * n], params[2 * n]
    bias, lag = params[2 * n + 1 : 2 * n + 1 + num_arms], params[2 * n + 1 + num_arms :]
    arm = np.repeat(np.arange(num_arms), num_segments)
    segment = np.tile(np.arange(num_segments), num_arms)
    ip = segment_osc(arm, segment, IP, num_segments)
    rho = jnp.zeros((n, n)).at[ip, ip + OOP].set(bias[arm]).at[ip + OOP, ip].set(-bias[arm])
    inner = segment < num_segments - 1
    for kind in (IP, OOP):
        this, nxt = ip[inner] + kind, ip[inner] + 2 + kind
        rho = rho.at[this, nxt].set(lag[arm[inner]]).at[nxt, this].set(-lag[arm[inner]])
    return Modulation(R=R, X=X, omega=jnp.full(n, omega), rho=rho)


PARAMETRIC_SYMMETRIC_SIZE = 5


def parametric_symmetric_bounds(
    num_arms: int, max_amplitude: float, max_offset: float, max_omega: float
) -> tuple[np.ndarray, np.ndarray]:
    """[leading arm in [0, A], rower amplitude in [0, max_amplitude], lift in +-max_offset,
    omega in [0, max_omega], rower IP->OOP bias in +-pi]; 5 arms only."""
    require_five_arms(num_arms, "controller.mode=parametric_symmetric")
    low = np.array([0.0, 0.0, -max_offset, 0.0, -np.pi])
    high = np.array([float(num_arms), max_amplitude, max_offset, max_omega, np.pi])
    return low, high


def parametric_symmetric_modulation(params: jax.Array, num_arms: int) -> Modulation:
    """Genotype [leading arm, rower amplitude, lift, omega, rower bias] -> T0's leading-arm pattern.

    The leading arm is floored to an index (the bound A maps to A - 1); (L, J, J, omega, pi/2)
    gives ``leading_arm_modulation(L, J, omega)`` with one J for every oscillator.
    """
    arm = jnp.clip(jnp.floor(params[0]).astype(jnp.int32), 0, num_arms - 1)
    amplitude = jnp.full(2 * num_arms, params[1])
    return _leading_arm_pattern(arm, amplitude, params[2], params[3], params[4])
