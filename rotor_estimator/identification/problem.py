# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""The identification problem: rig arrays, coefficient parameterization and test records.

* :class:`CoefficientModel` maps the estimated parameters ``theta`` to the 16 physical
  bearing coefficients (bearing 1 ``kxx kxy kyx kyy cxx cxy cyx cyy``, then bearing 2):
  identical bearings (8 parameters, the seed's Eq. 4) or non-identical (16), each
  optionally a polynomial of order ``speed_order`` in the normalized speed
  ``s = (Omega - speed_ref_rad_s) / speed_scale_rad_s``.
* :class:`Record` is one test record as plain arrays: sample times (s), the shaft
  angle/speed/acceleration per sample (from the tachometer or the truth), the
  generalized impact force per sample (Eq. 5, zero-order hold, impacts possibly at
  several axial stations), probe readings (m) and a mask of usable samples.
* :class:`RigArrays` holds the constant matrices of Eqs. 3, 5 and 6.

The imbalance is the vector ``b = [a_1, b_1, a_2, b_2, ...]`` (kg*m) of in-phase and
quadrature moments per imbalance plane: ``a = m r cos(phase)``, ``b = m r sin(phase)``.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from rotor_estimator.core.config import COEFFICIENT_NAMES, RigConfig
from rotor_estimator.core.errors import ConfigError, InputError
from rotor_estimator.core.model import point_force_weights, rotor_matrices

if TYPE_CHECKING:
    from rotor_estimator.core.offline import ShaftInputs
    from rotor_estimator.core.recording import RigRecording

BEARING_COEFFICIENT_NAMES: tuple[str, ...] = tuple(f"{n}_{b}" for b in (1, 2) for n in COEFFICIENT_NAMES)


@dataclass(frozen=True)
class RigArrays:
    """Constant arrays of the rigid rotor (Eqs. 3, 5, 6) for the kernels.

    ``wimb`` (2, planes): lever weights of each imbalance plane on bearings 1 and 2;
    ``imbalance_nominal_kg_m`` (2*planes,): the rig file's imbalance as ``[a, b]`` pairs.
    """

    minv: np.ndarray
    gyro: np.ndarray
    wimb: np.ndarray
    hp: np.ndarray
    bearing_from_probe: np.ndarray
    imbalance_nominal_kg_m: np.ndarray
    plane_positions_m: np.ndarray

    @classmethod
    def build(cls, rig: RigConfig) -> "RigArrays":
        mats = rotor_matrices(rig)
        b = np.zeros(2 * len(rig.imbalances))
        for i, u in enumerate(rig.imbalances):
            b[2 * i] = u.moment_kg_m * np.cos(u.phase_rad)
            b[2 * i + 1] = u.moment_kg_m * np.sin(u.phase_rad)
        if not rig.imbalances:
            raise ConfigError("rig.imbalances: identification needs at least one imbalance plane "
                              "(its axial position tells where the 1X forcing acts)")
        return cls(minv=np.ascontiguousarray(mats.mass_inverse), gyro=np.ascontiguousarray(mats.gyro_matrix),
                   wimb=np.ascontiguousarray(mats.imbalance_input.reshape(2, -1)),
                   hp=np.ascontiguousarray(mats.probe_from_bearing),
                   bearing_from_probe=np.ascontiguousarray(mats.bearing_from_probe),
                   imbalance_nominal_kg_m=b,
                   plane_positions_m=np.array([u.axial_position_m for u in rig.imbalances]))

    @property
    def n_imbalance(self) -> int:
        return int(self.imbalance_nominal_kg_m.shape[0])


@dataclass(frozen=True)
class CoefficientModel:
    """Parameterization of the bearing coefficients.

    * ``identical_bearings``: True -- 8 coefficients shared by both bearings (seed model);
      False -- 16 (bearing 1 then bearing 2).
    * ``speed_order``: 0 -- constant; p -- each coefficient a polynomial of order p in
      ``s = (Omega - speed_ref_rad_s) / speed_scale_rad_s``: ``c(Omega) = sum_i c_i s^i``.
    """

    identical_bearings: bool = True
    speed_order: int = 0
    speed_ref_rad_s: float = 0.0
    speed_scale_rad_s: float = 1.0

    def __post_init__(self) -> None:
        if not isinstance(self.speed_order, int) or not 0 <= self.speed_order <= 4:
            raise ConfigError(f"coefficient_model.speed_order: must be an integer 0..4, got {self.speed_order!r}")
        if not self.speed_scale_rad_s > 0:
            raise ConfigError("coefficient_model.speed_scale_rad_s: must be > 0 rad/s")

    @property
    def n_coefficients(self) -> int:
        return 8 if self.identical_bearings else 16

    @property
    def n_theta(self) -> int:
        return self.n_coefficients * (self.speed_order + 1)

    @property
    def coefficient_names(self) -> tuple[str, ...]:
        return COEFFICIENT_NAMES if self.identical_bearings else BEARING_COEFFICIENT_NAMES

    @property
    def parameter_names(self) -> tuple[str, ...]:
        if self.speed_order == 0:
            return self.coefficient_names
        return tuple(f"{n}_s{p}" for p in range(self.speed_order + 1) for n in self.coefficient_names)

    def dmap(self) -> np.ndarray:
        """(16, n_theta): physical coefficient = sum_j dmap[:, j] theta_j s^power_j."""
        base = np.vstack([np.eye(8), np.eye(8)]) if self.identical_bearings else np.eye(16)
        return np.ascontiguousarray(np.hstack([base] * (self.speed_order + 1)))

    def powers(self) -> np.ndarray:
        return np.repeat(np.arange(self.speed_order + 1), self.n_coefficients).astype(np.int64)

    def theta_from_coefficients(self, coefficients: np.ndarray) -> np.ndarray:
        """Constant coefficients (8 or 16; 8 are copied to both bearings) -> theta (higher orders 0)."""
        c = np.asarray(coefficients, dtype=float).ravel()
        if c.size == 8 and not self.identical_bearings:
            c = np.concatenate([c, c])
        if c.size != self.n_coefficients:
            raise InputError(f"coefficients: expected {self.n_coefficients} values, got {c.size}")
        theta = np.zeros(self.n_theta)
        theta[:self.n_coefficients] = c
        return theta

    def basis(self, speed_rad_s: np.ndarray) -> np.ndarray:
        """(len(speed), order+1) values of ``s**p``."""
        s = (np.asarray(speed_rad_s, dtype=float) - self.speed_ref_rad_s) / self.speed_scale_rad_s
        return s[:, None] ** np.arange(self.speed_order + 1)[None, :]

    def coefficients_at(self, theta: np.ndarray, speed_rad_s: np.ndarray,
                        covariance: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray | None]:
        """Coefficients (len(speed), n_coefficients) at the speeds and, with the theta
        covariance, their standard deviations (delta method; exact, the map is linear)."""
        phi = self.basis(np.atleast_1d(speed_rad_s))
        nc = self.n_coefficients
        th = np.asarray(theta, dtype=float).reshape(self.speed_order + 1, nc)
        values = phi @ th
        if covariance is None:
            return values, None
        std = np.empty_like(values)
        for c in range(nc):
            idx = np.arange(self.speed_order + 1) * nc + c
            cov_c = covariance[np.ix_(idx, idx)]
            std[:, c] = np.sqrt(np.einsum("ki,ij,kj->k", phi, cov_c, phi).clip(0))
        return values, std


@dataclass
class Record:
    """One test record as arrays (see module docstring). ``probes_m`` may be None (planning)."""

    t_s: np.ndarray
    angle_rad: np.ndarray
    speed_rad_s: np.ndarray
    accel_rad_s2: np.ndarray
    force_gen_n: np.ndarray
    probes_m: np.ndarray | None = None
    use: np.ndarray | None = None
    meta: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        n = np.asarray(self.t_s).shape[0]
        self.t_s = np.ascontiguousarray(self.t_s, dtype=float)
        for name in ("angle_rad", "speed_rad_s", "accel_rad_s2"):
            arr = np.ascontiguousarray(getattr(self, name), dtype=float)
            if arr.shape != (n,):
                raise InputError(f"record.{name}: expected shape ({n},), got {arr.shape}")
            setattr(self, name, arr)
        self.force_gen_n = np.ascontiguousarray(self.force_gen_n, dtype=float).reshape(n, 4)
        if self.probes_m is not None:
            self.probes_m = np.ascontiguousarray(self.probes_m, dtype=float).reshape(n, 4)
        use = np.ones(n, dtype=bool) if self.use is None else np.asarray(self.use, dtype=bool)
        if self.probes_m is not None:
            use = use & np.all(np.isfinite(self.probes_m), axis=1)
        self.use = np.ascontiguousarray(use)
        if n < 2 or np.any(np.diff(self.t_s) <= 0):
            raise InputError("record.t_s: needs at least 2 strictly increasing sample times")

    def __len__(self) -> int:
        return int(self.t_s.shape[0])

    @property
    def dt_s(self) -> np.ndarray:
        return np.ascontiguousarray(np.diff(self.t_s))

    def y(self) -> np.ndarray:
        return self.probes_m if self.probes_m is not None else np.zeros((0, 4))

    def decimated(self, factor: int) -> "Record":
        """Every ``factor``-th sample (the RK4 step becomes ``factor`` sample periods; only
        sensible when the forcing is smooth over that step, i.e. no impacts)."""
        if factor == 1:
            return self
        sl = slice(None, None, factor)
        if np.any(self.force_gen_n != 0):
            raise InputError("record.decimated: a record with impact forces cannot be decimated")
        return Record(self.t_s[sl], self.angle_rad[sl], self.speed_rad_s[sl], self.accel_rad_s2[sl],
                      self.force_gen_n[sl], None if self.probes_m is None else self.probes_m[sl], self.use[sl],
                      dict(self.meta))


def generalized_impact_force(rig: RigConfig, force_n: np.ndarray, axial_position_m: float | None = None) -> np.ndarray:
    """Eq. 5: ``(fx, fy)`` per sample (n, 2) at ``axial_position_m`` (default: the rig's
    impact station) as generalized forces ``[F_x1, F_y1, F_x2, F_y2]`` (n, 4)."""
    pos = rig.impact_position_m if axial_position_m is None else axial_position_m
    w1, w2 = point_force_weights(rig, pos)
    f = np.asarray(force_n, dtype=float).reshape(-1, 2)
    return np.column_stack([w1 * f[:, 0], w1 * f[:, 1], w2 * f[:, 0], w2 * f[:, 1]])


def record_from_recording(rig: RigConfig, recording: RigRecording, shaft: ShaftInputs | None = None, *,
                          impact_position_m: float | None = None) -> Record:
    """A :class:`Record` from a :class:`~rotor_estimator.core.recording.RigRecording`, with the
    shaft state read through the tachometer (:func:`rotor_estimator.core.offline.shaft_inputs_from_recording`)
    unless ``shaft`` is given. Samples without a valid shaft reference are not used."""
    from rotor_estimator.core.offline import shaft_inputs_from_recording

    shaft = shaft or shaft_inputs_from_recording(recording)
    return Record(t_s=recording.time_s(), angle_rad=shaft.angle_rad, speed_rad_s=shaft.speed_rad_s,
                  accel_rad_s2=shaft.accel_rad_s2,
                  force_gen_n=generalized_impact_force(rig, recording.impact_force_n, impact_position_m),
                  probes_m=recording.probes_m, use=shaft.valid, meta=dict(recording.meta))
