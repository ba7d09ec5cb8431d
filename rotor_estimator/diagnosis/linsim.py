# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Exact-discretization simulation of linear rotor models (the diagnosis's re-simulation engine).

The diagnosis re-simulates the nominal model and its augmentations many times, so it
uses a different and cheaper scheme than the RK4 data simulator: for a first-order
model ``dq/dt = A(Omega) q + B u`` (Miller & Howard, Eq. 2 in first-order form, possibly
augmented with pedestal or modal states) each sample period is advanced exactly,

    q[k+1] = Phi q[k] + Gamma1 (u_s[k] + u_z[k]) + Gamma2 (u_s[k+1] - u_s[k]),

with ``Phi = expm(A h)`` and the first-order-hold input matrices from the block
exponential ``expm([[A h, B h, 0], [0, 0, I], [0, 0, 0]]) = [[Phi, Gamma1, Gamma2], ...]``.
Smooth forcing ``u_s`` (imbalance, harmonic forces) is interpolated linearly between
samples; step forcing ``u_z`` (impact, zero-order hold per :mod:`rotor_estimator.core.recording`)
is held. ``A`` may change with speed: it is rebuilt per block of samples (piecewise
constant speed), cached by speed.

The initial state is the periodic steady state of the smooth forcing at the first
block's speed (harmonics fitted over the first revolutions), so a recording that
starts in steady running needs no transient fit.
"""
from __future__ import annotations

import threading
from dataclasses import dataclass
from typing import Callable

import numpy as np
from scipy.linalg import expm

from rotor_estimator.core.jit import njit

#: Samples per block over which the speed (and so A) is held constant.
BLOCK_SAMPLES = 256


@njit(cache=True)
def _project_outputs(states, c_out, out):
    """``out[k] = C q[k]`` for every sample (the same loop for the linear and the cubic recursion)."""
    for k in range(states.shape[0]):
        for r in range(c_out.shape[0]):
            acc = 0.0
            for j in range(states.shape[1]):
                acc += c_out[r, j] * states[k, j]
            out[k, r] = acc


@njit(cache=True)
def _transposed(phi, g1, g2):
    """``Phi^T``, ``Gamma1^T``, ``Gamma2^T`` per block, so that the recursions' inner loops run along contiguous
    memory over the state index: each state's sum keeps its order (bit for bit the same), and the
    independent sums of the states proceed side by side (1.75x for 28 states, where each waited on its own)."""
    n_blocks, n, m = g1.shape
    phi_t = np.empty((n_blocks, n, n))
    g1_t = np.empty((n_blocks, m, n))
    g2_t = np.empty((n_blocks, m, n))
    for b in range(n_blocks):
        for i in range(n):
            for j in range(n):
                phi_t[b, j, i] = phi[b, i, j]
            for j in range(m):
                g1_t[b, j, i] = g1[b, i, j]
                g2_t[b, j, i] = g2[b, i, j]
    return phi_t, g1_t, g2_t


@njit(cache=True)
def _propagate(phi, g1, g2, block, us, uz, q0, c_out):
    """Run the FOH/ZOH recursion; returns outputs (N, p) = C q and the states (N, n)."""
    n_samples = us.shape[0]
    n = q0.shape[0]
    m = us.shape[1]
    p = c_out.shape[0]
    phi_t, g1_t, g2_t = _transposed(phi, g1, g2)
    states = np.empty((n_samples, n))
    out = np.empty((n_samples, p))
    acc = np.empty(n)
    for i in range(n):
        states[0, i] = q0[i]
    for k in range(n_samples - 1):
        b = block[k]
        for i in range(n):
            acc[i] = 0.0
        for j in range(n):
            s = states[k, j]
            for i in range(n):
                acc[i] += phi_t[b, j, i] * s
        for j in range(m):
            v = us[k, j] + uz[k, j]
            d = us[k + 1, j] - us[k, j]
            for i in range(n):
                acc[i] += g1_t[b, j, i] * v + g2_t[b, j, i] * d
        for i in range(n):
            states[k + 1, i] = acc[i]
    _project_outputs(states, c_out, out)
    return out, states


def discretize(a: np.ndarray, b: np.ndarray, h_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``Phi, Gamma1, Gamma2`` of the first-order-hold discretization over ``h_s`` seconds."""
    n, m = b.shape
    big = np.zeros((n + 2 * m, n + 2 * m))
    big[:n, :n] = a * h_s
    big[:n, n:n + m] = b * h_s
    big[n:n + m, n + m:] = np.eye(m)
    e = expm(big)
    return e[:n, :n], e[:n, n:n + m], e[:n, n + m:]


@dataclass(frozen=True)
class SpeedSchedule:
    """Blocks of piecewise-constant speed: ``block_of_sample`` (N,) index into ``speeds_rad_s``."""

    block_of_sample: np.ndarray
    speeds_rad_s: np.ndarray

    @classmethod
    def from_speed(cls, speed_rad_s: np.ndarray, *, block: int = BLOCK_SAMPLES,
                   tolerance_rad_s: float = 0.5) -> "SpeedSchedule":
        """Block means of ``speed_rad_s``, merged to one value when they differ by less than the tolerance."""
        speed = np.asarray(speed_rad_s, dtype=float)
        n = speed.size
        idx = np.arange(n) // block
        means = np.array([speed[idx == i].mean() for i in range(idx.max() + 1)])
        if np.ptp(means) < tolerance_rad_s:
            return cls(np.zeros(n, dtype=np.int64), np.array([float(np.mean(speed))]))
        return cls(idx.astype(np.int64), means)


def harmonic_phasors(u: np.ndarray, angle_rad: np.ndarray, n_harmonics: int = 4) -> np.ndarray:
    """Least-squares phasors ``U_h`` (h = 0..H) with ``u ~ Re(sum_h U_h exp(j h angle))``; shape (H+1, m)."""
    cols = [np.ones_like(angle_rad)]
    for h in range(1, n_harmonics + 1):
        cols += [np.cos(h * angle_rad), np.sin(h * angle_rad)]
    basis = np.column_stack(cols)
    coef, *_ = np.linalg.lstsq(basis, u, rcond=None)
    out = np.zeros((n_harmonics + 1, u.shape[1]), dtype=complex)
    out[0] = coef[0]
    for h in range(1, n_harmonics + 1):
        out[h] = coef[2 * h - 1] - 1j * coef[2 * h]
    return out


def harmonic_state_phasor(a: np.ndarray, b: np.ndarray, u_h: np.ndarray, harmonic: int,
                          speed_rad_s: float) -> np.ndarray:
    """The steady state's phasor ``(j h Omega I - A)^-1 B U_h`` of the input phasor ``U_h`` at harmonic ``h``."""
    return np.linalg.solve(1j * harmonic * speed_rad_s * np.eye(a.shape[0]) - a, b @ u_h)


def steady_state(a: np.ndarray, b: np.ndarray, phasors: np.ndarray, speed_rad_s: float,
                 angle0_rad: float) -> np.ndarray:
    """Periodic steady state at shaft angle ``angle0_rad``: ``sum_h Re((j h Omega I - A)^-1 B U_h e^{j h angle0})``."""
    q = np.zeros(a.shape[0])
    harmonics = [h for h, u_h in enumerate(phasors) if np.any(u_h)]
    if not harmonics:
        return q
    # the harmonics' resolvent solves in one stacked call (the same LAPACK solve each: bit for bit
    # :func:`harmonic_state_phasor`'s, at a third of the calls' overhead)
    eye = np.eye(a.shape[0])
    shifted = np.stack([1j * h * speed_rad_s * eye - a for h in harmonics])
    states = np.linalg.solve(shifted, np.stack([b @ phasors[h] for h in harmonics])[:, :, None])[:, :, 0]
    for h, x_h in zip(harmonics, states):
        q += np.real(x_h * np.exp(1j * h * angle0_rad))
    return q


def _cached_steady_state(build_a, b, phasors, speed_rad_s, angle0_rad, cache: dict | None) -> np.ndarray:
    """:func:`steady_state` with the resolvents ``(j h Omega I - A)^-1 B`` kept in ``cache`` by speed."""
    if cache is None:
        return steady_state(build_a(speed_rad_s), b, phasors, speed_rad_s, angle0_rad)
    key = ("resolvents", round(float(speed_rad_s), 6), phasors.shape[0])
    if key not in cache:
        a = build_a(speed_rad_s)
        eye = np.eye(a.shape[0])
        cache[key] = [np.linalg.solve(1j * h * speed_rad_s * eye - a, b) for h in range(phasors.shape[0])]
    q = np.zeros(b.shape[0])
    for h, (res, u_h) in enumerate(zip(cache[key], phasors)):
        if np.any(u_h):
            q += np.real((res @ u_h) * np.exp(1j * h * angle0_rad))
    return q


def _discretized_blocks(build_a: Callable[[float], np.ndarray], b: np.ndarray, h_s: float,
                        schedule: SpeedSchedule, cache: dict | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``Phi, Gamma1, Gamma2`` per speed block, (blocks, n, n), (blocks, n, m) twice; cached by speed."""
    n_blocks = schedule.speeds_rad_s.size
    n, m = b.shape
    phi = np.empty((n_blocks, n, n))
    g1 = np.empty((n_blocks, n, m))
    g2 = np.empty((n_blocks, n, m))
    for i, w in enumerate(schedule.speeds_rad_s):
        key = round(float(w), 6)
        if cache is not None and key in cache:
            phi[i], g1[i], g2[i] = cache[key]
        else:
            phi[i], g1[i], g2[i] = discretize(build_a(float(w)), b, h_s)
            if cache is not None:
                cache[key] = (phi[i], g1[i], g2[i])
    return phi, g1, g2


#: Inputs whose first-revolution phasors :func:`_first_revolutions_phasors` keeps (the diagnosis re-simulates the
#: same few inputs, an effect's unit forces, at every trial coefficient set).
RECENT_PHASORS = 256
_recent_phasors: dict[bytes, np.ndarray] = {}
_recent_phasors_lock = threading.Lock()


def _first_revolutions_phasors(u_smooth: np.ndarray, angle_rad: np.ndarray, speed_rad_s: float,
                               h_s: float) -> np.ndarray:
    """:func:`harmonic_phasors` of ``u_smooth`` over its first two revolutions (at least 8 samples), kept for the
    last :data:`RECENT_PHASORS` inputs (keyed by the exact samples used: the same result as recomputing it)."""
    rev = min(max(8, int(round(2 * (2 * np.pi / max(speed_rad_s, 1e-6)) / h_s))), u_smooth.shape[0])
    u, angle = np.ascontiguousarray(u_smooth[:rev], dtype=float), np.ascontiguousarray(angle_rad[:rev], dtype=float)
    key = u.tobytes() + angle.tobytes() + np.array(u.shape).tobytes()
    with _recent_phasors_lock:  # a batch may diagnose in threads
        phasors = _recent_phasors.pop(key, None)
    if phasors is None:
        phasors = harmonic_phasors(u, angle)
    with _recent_phasors_lock:
        _recent_phasors.pop(key, None)
        if len(_recent_phasors) >= RECENT_PHASORS:
            _recent_phasors.pop(next(iter(_recent_phasors)))
        _recent_phasors[key] = phasors  # most recent last
    return phasors.copy()


#: Coefficients of the second, fourth and sixth central differences in :func:`foh_compensated`: the series of
#: ``1 / sinc^2(theta / 2) = arcsin(s)^2 / s^2`` in ``delta^2 = -4 s^2``, ``s = sin(theta / 2)`` (from
#: ``arcsin(z)^2 = z^2 + z^4 / 3 + 8 z^6 / 45 + 4 z^8 / 35 + ...``).
FOH_DIFFERENCE_SERIES = (-1.0 / 12.0, 1.0 / 90.0, -1.0 / 560.0)


def foh_compensated(u_smooth: np.ndarray) -> np.ndarray:
    """``u - delta^2 u / 12 + delta^4 u / 90 - delta^6 u / 560`` along the samples (axis 0; ``delta^2 u[k] =
    u[k+1] - 2 u[k] + u[k-1]``, the higher ones repeated; near the ends, where a difference runs off the record,
    it takes its nearest value): the smooth input the first-order hold should interpolate. Linear interpolation
    of a sampled sinusoid of ``theta`` rad per sample carries its fundamental at ``sinc^2(theta / 2)`` (a force at
    2X of 400 Hz sampled at 5 kHz: 0.92, so its fitted amplitude came out 9 % high); this pre-emphasis is that
    factor's inverse to its fourth term (:data:`FOH_DIFFERENCE_SERIES`), which leaves ``1 - O(s^8)``
    (``s = sin(theta / 2)``): 0.9997 there, 0.967 at 4X of 400 Hz at 5 kHz (theta = 2 rad), where the second
    difference alone (until the decimation by 4 came) left 0.990 and 0.875. Symmetric, so no phase shift. The
    first and last three samples keep less of the gain (0.65-0.96 of it at theta = 2): the diagnosis's fits
    leave the warm-up out, and a force error over a sample or two at the end moves the output little."""
    u = np.asarray(u_smooth, dtype=float)
    n = u.shape[0]
    out = np.array(u, dtype=float)
    d = u
    for coefficient in FOH_DIFFERENCE_SERIES:
        if d.shape[0] < 3:
            break
        d = d[2:] - 2.0 * d[1:-1] + d[:-2]  # valid on samples m .. n - 1 - m
        m = (n - d.shape[0]) // 2
        out[m:n - m] += coefficient * d
        out[:m] += coefficient * d[:1]
        out[n - m:] += coefficient * d[-1:]
    return np.ascontiguousarray(out)


def simulate_linear(build_a: Callable[[float], np.ndarray], b: np.ndarray, c: np.ndarray, h_s: float,
                    schedule: SpeedSchedule, angle_rad: np.ndarray, u_smooth: np.ndarray,
                    u_step: np.ndarray | None = None, *, steady_start: bool = True,
                    cache: dict | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Outputs ``C q`` (N, p) and states (N, n) of ``dq/dt = A(Omega) q + B u``.

    ``u_smooth`` (N, m) is first-order held, ``u_step`` (N, m) zero-order held. With
    ``steady_start`` the first state is the periodic steady state of ``u_smooth`` over
    the first revolutions (zero otherwise).
    """
    n = b.shape[0]
    phi, g1, g2 = _discretized_blocks(build_a, b, h_s, schedule, cache)
    u_smooth = np.ascontiguousarray(u_smooth, dtype=float)
    u_step = np.zeros_like(u_smooth) if u_step is None else np.ascontiguousarray(u_step, dtype=float)
    q0 = np.zeros(n)
    if steady_start and np.any(u_smooth):
        w0 = float(schedule.speeds_rad_s[0])
        ph = _first_revolutions_phasors(u_smooth, angle_rad, w0, h_s)
        q0 = _cached_steady_state(build_a, b, ph, w0, float(angle_rad[0]), cache)
    return _propagate(phi, g1, g2, np.ascontiguousarray(schedule.block_of_sample), foh_compensated(u_smooth), u_step,
                      q0, np.ascontiguousarray(c, dtype=float))


@njit(cache=True)
def _propagate_many(phi, g1, g2, block, us, q0, c_out):
    """:func:`_propagate` of K smooth inputs at once (no step input): ``us`` (N, m, K), ``q0`` (n, K); returns
    the outputs (N, p, K). The same sums in the same order, so each column equals its own run bit for bit;
    the K independent recursions interleave, where one alone waits on its own previous state."""
    n_samples = us.shape[0]
    n = q0.shape[0]
    m = us.shape[1]
    n_cols = us.shape[2]
    p = c_out.shape[0]
    s = q0.copy()
    nxt = np.empty((n, n_cols))
    out = np.empty((n_samples, p, n_cols))
    for k in range(n_samples):
        for r in range(p):
            for col in range(n_cols):
                out[k, r, col] = 0.0
            for j in range(n):
                cr = c_out[r, j]
                for col in range(n_cols):
                    out[k, r, col] += cr * s[j, col]
        if k == n_samples - 1:
            break
        b = block[k]
        for i in range(n):
            for col in range(n_cols):
                nxt[i, col] = 0.0
            for j in range(n):
                f = phi[b, i, j]
                for col in range(n_cols):
                    nxt[i, col] += f * s[j, col]
            for j in range(m):
                a1 = g1[b, i, j]
                a2 = g2[b, i, j]
                for col in range(n_cols):
                    nxt[i, col] += a1 * us[k, j, col] + a2 * (us[k + 1, j, col] - us[k, j, col])
        for i in range(n):
            for col in range(n_cols):
                s[i, col] = nxt[i, col]
    return out


def simulate_linear_many(build_a: Callable[[float], np.ndarray], b: np.ndarray, c: np.ndarray, h_s: float,
                         schedule: SpeedSchedule, angle_rad: np.ndarray, u_smooth: list[np.ndarray], *,
                         cache: dict | None = None) -> np.ndarray:
    """Outputs (N, p, K) of :func:`simulate_linear` (steady start, no step input) for each of the K smooth
    inputs ``u_smooth`` (each (N, m)), in one pass: each column equals its own :func:`simulate_linear` run."""
    n = b.shape[0]
    phi, g1, g2 = _discretized_blocks(build_a, b, h_s, schedule, cache)
    us = np.ascontiguousarray(np.stack([np.asarray(u, dtype=float) for u in u_smooth], axis=2))
    q0 = np.zeros((n, us.shape[2]))
    w0 = float(schedule.speeds_rad_s[0])
    for i in range(us.shape[2]):
        if np.any(us[:, :, i]):
            ph = _first_revolutions_phasors(us[:, :, i], angle_rad, w0, h_s)
            q0[:, i] = _cached_steady_state(build_a, b, ph, w0, float(angle_rad[0]), cache)
    return _propagate_many(phi, g1, g2, np.ascontiguousarray(schedule.block_of_sample), foh_compensated(us), q0,
                           np.ascontiguousarray(c, dtype=float))


#: Samples per chunk of :func:`_free_response`: within a chunk of one speed block the output is
#: ``C Phi^j`` (precomputed once per block, j < this) times the chunk's first state.
FREE_RESPONSE_CHUNK = 64


@njit(cache=True)
def _output_powers(phi_b, c_out, length):
    """``C Phi_b^j`` for ``j < length``, shape (length, p, n)."""
    p, n = c_out.shape
    m = np.empty((length, p, n))
    m[0] = c_out
    for j in range(1, length):
        for r in range(p):
            for i in range(n):
                m[j, r, i] = 0.0
            for h in range(n):
                v = m[j - 1, r, h]
                for i in range(n):
                    m[j, r, i] += v * phi_b[h, i]
    return m


@njit(cache=True)
def _free_response(phi, block, c_out, s0, n_samples, floor):
    """``out[k, :, i] = C Phi_k ... Phi_1 s0[:, i]``: the output of each initial state ``s0[:, i]`` (no input).

    Chunked: over a chunk of samples that share one speed block ``b``, ``out[k0 + j] = (C Phi_b^j) s[k0]``
    with ``C Phi_b^j`` computed once per block, and the state is carried to the next chunk by ``Phi_b^64``
    (:data:`FREE_RESPONSE_CHUNK` samples).
    Per sample this costs ``p n q`` products instead of ``(p + n) n q`` (3x for the rigid rotor's 8 states).
    Stops (zeros after) at a chunk whose first state is below ``floor`` times its start: a decayed transient.
    """
    n = phi.shape[1]
    q = s0.shape[1]
    p = c_out.shape[0]
    out = np.zeros((n_samples, p, q))
    powers = np.zeros((phi.shape[0], FREE_RESPONSE_CHUNK, p, n))
    chunk_step = np.zeros((phi.shape[0], n, n))  # Phi_b^FREE_RESPONSE_CHUNK
    have = np.zeros(phi.shape[0], dtype=np.bool_)
    s = s0.copy()
    nxt = np.empty((n, q))
    k = 0
    while k < n_samples:
        big = 0.0
        for i in range(n):
            for j in range(q):
                big = max(big, abs(s[i, j]))
        if big < floor:
            break
        b = block[k]
        end = k + 1
        while end < n_samples and end - k < FREE_RESPONSE_CHUNK and block[end] == b:
            end += 1
        if not have[b]:
            powers[b] = _output_powers(phi[b], c_out, FREE_RESPONSE_CHUNK)
            chunk_step[b] = np.linalg.matrix_power(np.ascontiguousarray(phi[b]), FREE_RESPONSE_CHUNK)
            have[b] = True
        for j in range(end - k):
            for r in range(p):
                for i in range(n):
                    v = powers[b, j, r, i]
                    for col in range(q):
                        out[k + j, r, col] += v * s[i, col]
        if end == n_samples:
            break
        # the state at the next chunk's first sample: one product by Phi_b^CHUNK for a whole chunk, else a step
        # per sample (a chunk cut short by a speed block's end)
        whole = end - k == FREE_RESPONSE_CHUNK
        for _ in range(1 if whole else end - k):
            for i in range(n):
                for col in range(q):
                    nxt[i, col] = 0.0
                for m in range(n):
                    f = chunk_step[b, i, m] if whole else phi[b, i, m]
                    for col in range(q):
                        nxt[i, col] += f * s[m, col]
            for i in range(n):
                for col in range(q):
                    s[i, col] = nxt[i, col]
        k = end
    return out


#: A start transient below this fraction of its initial state is taken as decayed (:func:`free_response`).
FREE_RESPONSE_FLOOR = 1e-9


def free_response(build_a: Callable[[float], np.ndarray], b: np.ndarray, c: np.ndarray, h_s: float,
                  schedule: SpeedSchedule, *, states: np.ndarray | None = None,
                  cache: dict | None = None) -> np.ndarray:
    """Output (N, p, q) of the unforced model from each unit initial state ``e_i`` (``i`` in ``states``, default
    all): the columns of a start transient ``C Phi^k dq0`` (output-error identification with an estimated
    initial state).

    A record that does not start in the periodic steady state the re-simulation assumes (a run from rest,
    a record cut just after a speed change) carries the free decay of the model's modes from an unknown
    state ``dq0``; it enters the output linearly, so each fit estimates it like the DC gap."""
    phi, _, _ = _discretized_blocks(build_a, b, h_s, schedule, cache)
    s0 = np.eye(b.shape[0])
    if states is not None:
        s0 = np.ascontiguousarray(s0[:, np.asarray(states, dtype=np.int64)])
    return _free_response(phi, np.ascontiguousarray(schedule.block_of_sample), np.ascontiguousarray(c, dtype=float),
                          s0, int(schedule.block_of_sample.size), FREE_RESPONSE_FLOOR)


@njit(cache=True)
def _contact_force(dx, dy, kc, clearance):
    """A radial contact spring beyond a clearance: ``-kc (|d| - c) d / |d|`` when ``|d| > c``, else nothing."""
    r = np.sqrt(dx * dx + dy * dy)
    if r <= clearance or r == 0.0:
        return 0.0, 0.0
    g = -kc * (r - clearance) / r
    return g * dx, g * dy


@njit(cache=True)
def _bearing_force(states, k, z0, k3, static, clearance, radial, out):
    """Nonlinear bearing force on ``z = states[k, z0:z0+m]`` (x1, y1, x2, y2) into ``out``.

    ``radial == 0``: ``f_j = -k3_j z_j^3`` per axis. ``radial == 1``: a radial cubic ``-k3 |d|^2 d`` on each
    bearing's displacement ``d = s + z`` from its centre (``s = static``: the static load point), less its
    value and tangent at ``s`` (``|s|^2 I + 2 s s^T``), which the linear coefficients already hold.
    ``radial == 2``: a radial contact spring of stiffness ``k3`` beyond the radial ``clearance`` (m,) on ``d``
    (:func:`_contact_force`), less its value and tangent at ``s`` (``(1 - c/|s|) I + (c/|s|) s s^T / |s|^2``
    times ``-k3`` when ``|s| > c``: a shaft resting on the contact has that stiffness in its coefficients).
    """
    m = out.shape[0]
    if radial == 0:
        for j in range(m):
            zj = states[k, z0 + j]
            out[j] = -k3[j] * zj * zj * zj
        return
    for j in range(0, m, 2):
        zx = states[k, z0 + j]
        zy = states[k, z0 + j + 1]
        sx = static[j]
        sy = static[j + 1]
        dx = sx + zx
        dy = sy + zy
        if radial == 2:
            kc, c = k3[j], clearance[j]
            fx, fy = _contact_force(dx, dy, kc, c)
            gx, gy = _contact_force(sx, sy, kc, c)
            rs = np.sqrt(sx * sx + sy * sy)
            tx, ty = 0.0, 0.0
            if rs > c and rs > 0.0:
                a, b = 1.0 - c / rs, c / (rs * rs * rs)
                tx = -kc * ((a + b * sx * sx) * zx + b * sx * sy * zy)
                ty = -kc * (b * sx * sy * zx + (a + b * sy * sy) * zy)
            out[j] = fx - gx - tx
            out[j + 1] = fy - gy - ty
            continue
        r2 = dx * dx + dy * dy
        s2 = sx * sx + sy * sy
        sd = sx * zx + sy * zy
        out[j] = -k3[j] * (r2 * dx - s2 * sx - s2 * zx - 2.0 * sx * sd)
        out[j + 1] = -k3[j + 1] * (r2 * dy - s2 * sy - s2 * zy - 2.0 * sy * sd)


@njit(cache=True)
def _held_input(us, k, i, substeps, j):
    """Channel ``j`` of the first-order-held input ``us`` (coarse samples) at substep ``i`` of sample ``k``: the
    straight line from ``us[k]`` to ``us[k + 1]`` (``i == substeps`` is the next sample's first substep), as
    a finer grid's samples would hold it; the last sample as it is."""
    if i == substeps:
        k += 1
        i = 0
    if i == 0 and substeps == 1 or k == us.shape[0] - 1:
        return us[k, j]
    f = i / substeps
    return us[k, j] * (1.0 - f) + us[k + 1, j] * f


@njit(cache=True)
def _propagate_cubic(phi, g1, g2, block, us, uz, q0, c_out, k3, z0, static, clearance, radial, substeps):
    """The FOH/ZOH recursion with a cubic generalized bearing force (:func:`_bearing_force`), ``z = q[z0:z0+m]``.

    The nonlinear force is first-order held too, its end value from a predictor step
    (Heun): ``q+ = Phi q + G1 (u + f(q)) + G2 du``, then ``q[k+1] = q+ + G2 (f(q+) - f(q))``.
    Each sample period is run in ``substeps`` equal steps (``Phi``, ``G1``, ``G2`` are the substep's), the smooth
    input on its straight line between samples (:func:`_held_input`), the step input and the speed block held; the
    outputs and states are kept at the samples only. Bit for bit the recursion over those inputs written out on
    the finer grid (test).
    """
    n_samples = us.shape[0]
    n = q0.shape[0]
    m = us.shape[1]
    p = c_out.shape[0]
    states = np.empty((n_samples, n))
    out = np.empty((n_samples, p))
    fk = np.empty(m)
    f1 = np.empty(m)
    pred = np.empty(n)
    cur = np.empty((1, n))
    for i in range(n):
        states[0, i] = q0[i]
        cur[0, i] = q0[i]
    phi_t, g1_t, g2_t = _transposed(phi, g1, g2)
    # The predictor below is _propagate's step with the held force added, written out again on purpose: one
    # shared compiled helper for both measured 1.35x slower at 8 states and changed the last bits at 28.
    for k in range(n_samples - 1):
        b = block[k]
        for sub in range(substeps):
            _bearing_force(cur, 0, z0, k3, static, clearance, radial, fk)
            for i in range(n):
                pred[i] = 0.0
            for j in range(n):
                s = cur[0, j]
                for i in range(n):
                    pred[i] += phi_t[b, j, i] * s
            for j in range(m):
                u0 = _held_input(us, k, sub, substeps, j)
                v = u0 + uz[k, j] + fk[j]
                d = _held_input(us, k, sub + 1, substeps, j) - u0
                for i in range(n):
                    pred[i] += g1_t[b, j, i] * v + g2_t[b, j, i] * d
            _bearing_force(pred.reshape(1, n), 0, z0, k3, static, clearance, radial, f1)
            for i in range(n):
                cur[0, i] = pred[i]
            for j in range(m):
                df = f1[j] - fk[j]
                for i in range(n):
                    cur[0, i] += g2_t[b, j, i] * df
        for i in range(n):
            states[k + 1, i] = cur[0, i]
    _project_outputs(states, c_out, out)
    return out, states


#: The longest step the nonlinear bearing force is first-order held over (:func:`simulate_cubic`): a record at a
#: coarser rate is simulated in substeps of at most this, its output kept at its own samples. Against the same
#: simulation at 20 kHz, a clearance contact (48 um orbit, 5 um clearance) held over 200 us (a record decimated
#: by 4) was 3.5 % of its peak off, over 100 us (decimated by 2, as the blind sets' contact and cubic records were
#: diagnosed until this) 0.5 %, over 50 us 0.04 %; a strong cubic (78 um orbit) diverged at 200 us, was 2.6 % off
#: at 100 us and 0.03 % at 50 us (test).
MAX_NONLINEAR_STEP_S = 5.0e-5


def simulate_cubic(build_a: Callable[[float], np.ndarray], b: np.ndarray, c: np.ndarray, h_s: float,
                   schedule: SpeedSchedule, angle_rad: np.ndarray, u_smooth: np.ndarray, u_step: np.ndarray,
                   k3: np.ndarray, z_index: int, *, preroll_s: float = 0.05, static_m: np.ndarray | None = None,
                   clearance_m: np.ndarray | None = None, cache: dict | None = None,
                   max_step_s: float | None = MAX_NONLINEAR_STEP_S) -> tuple[np.ndarray, np.ndarray]:
    """:func:`simulate_linear` plus the cubic force ``-k3 z^3`` on states ``z_index..z_index+m`` (per axis), or,
    with ``static_m`` (m,), the radial cubic about that static load point, or, with ``clearance_m`` (m,) too, a
    radial contact spring of stiffness ``k3`` beyond that clearance (:func:`_bearing_force`).

    The nonlinear periodic state is reached by a pre-roll of ``preroll_s`` seconds driven
    by the steady harmonic part of ``u_smooth`` (fitted over the first revolutions),
    started from the linear steady state; the pre-roll is dropped from the output. A sample period longer than
    ``max_step_s`` is run in equal substeps no longer than it (:data:`MAX_NONLINEAR_STEP_S`; ``None``: never).
    """
    n, m = b.shape
    substeps = 1 if max_step_s is None else max(1, int(np.ceil(h_s / max_step_s - 1e-9)))
    if substeps > 1 and cache is not None:
        cache = cache.setdefault(("substeps", substeps), {})  # the blocks of the finer step, apart
    phi, g1, g2 = _discretized_blocks(build_a, b, h_s / substeps, schedule, cache)
    w0 = float(schedule.speeds_rad_s[0])
    n_pre = int(round(preroll_s / h_s))
    ph = _first_revolutions_phasors(u_smooth, angle_rad, w0, h_s)
    ang_pre = angle_rad[0] - w0 * h_s * np.arange(n_pre, 0, -1)
    u_pre = np.zeros((n_pre, m))
    for hh in range(ph.shape[0]):
        u_pre += np.real(ph[hh][None, :] * np.exp(1j * hh * ang_pre)[:, None])
    q0 = steady_state(build_a(w0), b, ph, w0, float(ang_pre[0])) if n_pre else np.zeros(n)
    us = foh_compensated(np.ascontiguousarray(np.vstack([u_pre, u_smooth]), dtype=float))
    uz = np.ascontiguousarray(np.vstack([np.zeros((n_pre, m)), u_step]), dtype=float)
    block = np.ascontiguousarray(np.concatenate([np.zeros(n_pre, dtype=np.int64),
                                                 schedule.block_of_sample.astype(np.int64)]))
    if clearance_m is not None and static_m is None:
        raise ValueError("simulate_cubic: a contact's clearance_m needs its static_m")
    radial = 0 if static_m is None else (1 if clearance_m is None else 2)
    static = np.zeros(m) if static_m is None else np.ascontiguousarray(static_m, dtype=float)
    clearance = np.zeros(m) if clearance_m is None else np.ascontiguousarray(clearance_m, dtype=float)
    out, states = _propagate_cubic(phi, g1, g2, block, us, uz, q0, np.ascontiguousarray(c, dtype=float),
                                   np.ascontiguousarray(k3, dtype=float), z_index, static, clearance, radial, substeps)
    return out[n_pre:], states[n_pre:]
