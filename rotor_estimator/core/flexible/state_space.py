# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Discrete state-space model of a (reduced) FE rotor with sensors and virtual stations.

State ``x = T^-1 [q_r, q_r']`` (Eq. 9 in modal coordinates, Appendix A), where the
diagonal scaling ``T`` gives the stationary covariance of the noise-driven rotor a unit
diagonal (only for conditioning; every output map includes ``T``). Input
``u = Omega^2 [cos theta, sin theta]`` carries the known unbalance forcing (Eq. 7), with
theta the shaft angle from the keyphasor. Unknown forcing is a white random force at
every shaft node (``process_noise_force_N_sqrt_s``), discretized exactly in the
eigenbasis of A (see :func:`_noise_covariances`).

Measurements (one row per channel, ``z = H x + D u + v``):

* probe: shaft displacement minus housing displacement at the station (m);
* accelerometer: absolute acceleration of the pedestal point or of the shaft (m/s^2),
  ``q_r'' = M_r^-1 (F_r - C_r q_r' - (K_r) q_r)`` so it depends on the state and on u.

The acceleration of a white-noise-driven model has no finite variance; as in the
paper the accelerometer is modelled through the state (its noise ``R`` absorbs the rest).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

from rotor_estimator.core.linear_filters import LinearGaussianModel, discretize
from rotor_estimator.core.flexible.description import RotorDescription
from rotor_estimator.core.flexible.fe_rotor import FERotor, assemble
from rotor_estimator.core.flexible.modal import ReducedModel, reduce, state_matrices

__all__ = ["FlexibleStateSpace", "build_state_space", "station_outputs", "unbalance_inputs",
           "periodic_steady_state", "simulate", "Simulation"]


@dataclass(frozen=True)
class FlexibleStateSpace:
    """Everything a filter needs. ``model``: the discrete :class:`LinearGaussianModel`
    (all sensor channels); ``A``, ``Bu`` continuous (scaled) matrices; ``P0``: the
    stationary covariance; ``channel_names``/``channel_units``/``channel_sensor``:
    per channel, with the sensor (station group) each channel belongs to."""

    rotor: RotorDescription
    fe: FERotor
    reduced: ReducedModel
    model: LinearGaussianModel
    A: np.ndarray
    Bu: np.ndarray
    T: np.ndarray
    P0: np.ndarray
    dt_s: float
    channel_names: tuple[str, ...]
    channel_units: tuple[str, ...]
    channel_sensor: tuple[str, ...]

    @property
    def n_states(self) -> int:
        return self.A.shape[0]

    def output_rows(self, phys_row: np.ndarray, quantity: str) -> tuple[np.ndarray, np.ndarray]:
        """(C row on x, D row on u) of a physical-coordinate row for ``displacement``,
        ``velocity`` or ``acceleration``."""
        r = self.reduced.n_modes
        modal = phys_row @ self.reduced.S
        c = np.zeros(2 * r)
        d = np.zeros(self.Bu.shape[1])
        if quantity == "displacement":
            c[:r] = modal
        elif quantity == "velocity":
            c[r:] = modal
        elif quantity == "acceleration":
            # rows of A and Bu are already in scaled coordinates on the right; undo T on the left
            tr = self.T[r:]
            c = modal @ (tr[:, None] * self.A[r:])
            d = modal @ (tr[:, None] * self.Bu[r:])
            return c, d
        else:
            raise ValueError(f"quantity: {quantity!r}")
        return c * self.T, d


def build_state_space(rotor: RotorDescription, n_modes: int | None = None,
                      speed_rad_s: float | None = None) -> FlexibleStateSpace:
    """Assemble, reduce (``n_modes`` overrides the rotor file) and discretize."""
    fe = assemble(rotor)
    red = reduce(fe, rotor.options.n_modes if n_modes is None else n_modes)
    r = red.n_modes
    speed = rotor.speed_rad_s if speed_rad_s is None else speed_rad_s
    A, Bf = state_matrices(red.M, red.C, red.K, red.G, speed)
    Bu = Bf @ (red.S.T @ fe.unbalance_input)
    nodes = len(fe.nodes_m)
    Bw_phys = np.zeros((fe.n_dof, 2 * nodes))
    for i in range(nodes):
        Bw_phys[4 * i, 2 * i] = Bw_phys[4 * i + 1, 2 * i + 1] = 1.0
    Bw = Bf @ (red.S.T @ Bw_phys)
    q = rotor.options.process_noise_force_N_sqrt_s ** 2
    dt = 1.0 / rotor.sample_rate_hz
    Pc, Qc = _noise_covariances(A, np.sqrt(q) * Bw, dt)
    scale = np.sqrt(np.clip(np.diag(Pc), 0.0, None))
    T = np.where(scale > 0, scale, 1.0)
    Ts = (1.0 / T)[:, None] * A * T[None, :]
    Bus = Bu / T[:, None]
    F, Bd, _ = discretize(Ts, Bus, dt)
    F[np.abs(F) < 1e-100] = 0.0  # decayed stiff modes: avoid denormal arithmetic
    TT = np.outer(T, T)
    P0 = Pc / TT if q > 0 else np.eye(2 * r) * 1e-12
    Qd = Qc / TT
    ss = FlexibleStateSpace(rotor, fe, red, LinearGaussianModel(F, Qd, np.zeros((0, 2 * r)), np.zeros((0, 0)), Bd,
                                                                np.zeros((0, 2))),
                            Ts, Bus, T, 0.5 * (P0 + P0.T), dt, (), (), ())
    rows_c, rows_d, names, units, owner, noise = [], [], [], [], [], []
    for s in rotor.sensors:
        pi = rotor.pedestal_index(s.pedestal) if s.pedestal is not None else None
        for d in s.directions:
            if s.kind == "probe":
                phys = fe.shaft_row(s.station_axial_m, d)
                if pi is not None:
                    phys = phys - fe.pedestal_row(pi, s.station_axial_m, d)
                c, dd = ss.output_rows(phys, "displacement")
            else:
                phys = fe.pedestal_row(pi, s.station_axial_m, d) if pi is not None else fe.shaft_row(
                    s.station_axial_m, d)
                c, dd = ss.output_rows(phys, "acceleration")
            rows_c.append(c)
            rows_d.append(dd)
            names.append(f"{s.name}_{d}")
            units.append(s.unit)
            owner.append(s.name)
            noise.append(s.noise_std ** 2)
    p = len(names)
    model = LinearGaussianModel(F, Qd, np.array(rows_c).reshape(p, 2 * r), np.diag(noise).reshape(p, p), Bd,
                                np.array(rows_d).reshape(p, 2))
    return FlexibleStateSpace(rotor, fe, red, model, Ts, Bus, T, ss.P0, dt, tuple(names), tuple(units),
                              tuple(owner))


def _psd(P: np.ndarray) -> np.ndarray:
    lam, V = np.linalg.eigh(0.5 * (P + P.T))
    return (V * np.clip(lam, 0.0, None)) @ V.T


def _noise_covariances(A: np.ndarray, G: np.ndarray, dt_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Stationary covariance P and one-sample covariance Q_d of ``x' = A x + G w`` (w
    unit white noise), in A's eigenbasis: with ``W = V^-1 G G^T V^-H``,
    ``P_ij = -W_ij / (l_i + conj(l_j))`` and ``Q_ij = W_ij (e^{(l_i + conj(l_j)) dt} - 1) /
    (l_i + conj(l_j))``. Exact, and free of the overflow of Van Loan's ``exp(-A dt)`` for
    stiff (overdamped, high-frequency) modes."""
    lam, V = np.linalg.eig(A)
    if np.linalg.cond(V) > 1e8:  # (nearly) defective: Bartels-Stewart, then P = F P F^T + Q_d
        P = _psd(scipy.linalg.solve_continuous_lyapunov(A, -G @ G.T))
        F = scipy.linalg.expm(A * dt_s)
        return P, _psd(P - F @ P @ F.T)
    Vi = np.linalg.inv(V)
    W = Vi @ G @ G.T @ Vi.conj().T
    s = lam[:, None] + lam.conj()[None, :]
    P = V @ (-W / s) @ V.conj().T
    Q = V @ (W * np.expm1(s * dt_s) / s) @ V.conj().T
    return _psd(P.real), _psd(Q.real)


def station_outputs(ss: FlexibleStateSpace, station_axial_m: float) -> tuple[np.ndarray, np.ndarray, tuple[str, ...]]:
    """(C (6, n), D (6, 2), names) of absolute shaft displacement, velocity and
    acceleration in x and y at any axial station (m, m/s, m/s^2)."""
    rows_c, rows_d, names = [], [], []
    for qty in ("displacement", "velocity", "acceleration"):
        for d in ("x", "y"):
            c, dd = ss.output_rows(ss.fe.shaft_row(station_axial_m, d), qty)
            rows_c.append(c)
            rows_d.append(dd)
            names.append(f"{qty}_{d}")
    return np.array(rows_c), np.array(rows_d), tuple(names)


def unbalance_inputs(ss: FlexibleStateSpace, t_s: np.ndarray | None, shaft_angle_rad: np.ndarray | None = None,
                     speed_rad_s: float | None = None) -> np.ndarray:
    """u[k] = Omega^2 [cos theta_k, sin theta_k] (N, 2); theta = Omega t unless measured."""
    w = ss.rotor.speed_rad_s if speed_rad_s is None else speed_rad_s
    theta = w * np.asarray(t_s, dtype=float) if shaft_angle_rad is None else np.asarray(shaft_angle_rad, float)
    return w ** 2 * np.stack([np.cos(theta), np.sin(theta)], axis=-1)


def periodic_steady_state(ss: FlexibleStateSpace, theta0_rad: float = 0.0,
                          speed_rad_s: float | None = None) -> np.ndarray:
    """Synchronous steady state of the discrete model at shaft angle ``theta0``:
    ``x = Re(X e^{i theta})``, ``X = (e^{i Omega dt} I - F)^-1 B_d Omega^2 [1, -i]``."""
    w = ss.rotor.speed_rad_s if speed_rad_s is None else speed_rad_s
    m = ss.model
    X = np.linalg.solve(np.exp(1j * w * ss.dt_s) * np.eye(ss.n_states) - m.F, m.B @ (w ** 2 * np.array([1, -1j])))
    return np.real(X * np.exp(1j * theta0_rad))


@dataclass(frozen=True)
class Simulation:
    """Model-consistent data: ``t`` (N,), ``u`` (N, 2), ``z`` (N, p) measurements,
    ``z_clean`` (N, p) without sensor noise, ``x`` (N, n) true states."""

    t: np.ndarray
    u: np.ndarray
    z: np.ndarray
    z_clean: np.ndarray
    x: np.ndarray


def _sqrtm_psd(Q: np.ndarray) -> np.ndarray:
    lam, V = np.linalg.eigh(0.5 * (Q + Q.T))
    return V * np.sqrt(np.clip(lam, 0.0, None))


def simulate(ss: FlexibleStateSpace, n_samples: int, seed: int = 0) -> Simulation:
    """Draw data from exactly the filter's model: x0 ~ N(steady state, P0), process
    noise N(0, Q_d) and sensor noise N(0, R)."""
    rng = np.random.default_rng(seed)
    m = ss.model
    t = np.arange(n_samples) * ss.dt_s
    u = unbalance_inputs(ss, t)
    n, p = ss.n_states, m.H.shape[0]
    Lq, Lp = _sqrtm_psd(m.Q), _sqrtm_psd(ss.P0)
    W = rng.standard_normal((n_samples, n)) @ Lq.T
    xs = np.empty((n_samples, n))
    x = periodic_steady_state(ss) + Lp @ rng.standard_normal(n)
    for k in range(n_samples):
        xs[k] = x
        x = m.F @ x + m.B @ u[k] + W[k]
    z_clean = xs @ m.H.T + u @ m.D.T
    z = z_clean + rng.standard_normal((n_samples, p)) * np.sqrt(np.diag(m.R))
    return Simulation(t, u, z, z_clean, xs)
