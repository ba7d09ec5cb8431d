# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Kalman filter, EKF and vectorized UKF with one streaming interface.

Model (discrete time, sample k)::

    x[k+1] = F x[k] + B u[k] + w[k],   w ~ N(0, Q)
    z[k]   = H x[k] + D u[k] + v[k],   v ~ N(0, R)

Interface shared by :class:`KalmanFilter`, :class:`ExtendedKalmanFilter` and
:class:`UnscentedKalmanFilter`:

* ``x`` (n,), ``P`` (n, n): the current estimate; ``x0, P0`` is the prior at sample 0.
* ``predict(u=None)``: propagate one sample with input ``u`` held over it (ZOH).
* ``update(z, u=None, R=None, mask=None)``: condition on ``z`` (p,). ``u`` feeds the
  measurement's direct term (accelerometers see the known force), ``R`` overrides the
  noise covariance, ``mask`` (p,) bool selects present channels (leave-one-out);
  non-finite channels are dropped and counted in ``n_rejected``.
* Innovation gating (off by default): with ``gate_probability`` (e.g. 0.9999) an update
  whose normalized innovation squared ``NIS = y^T S^-1 y`` (the squared Mahalanobis
  distance of the innovation) exceeds the chi-square quantile
  ``chi2.ppf(gate_probability, dof)`` (dof = channels used) is skipped as a whole and
  counted in ``n_gated`` (robot_localization's outlier gate). ``last_nis`` still holds
  its NIS. A gate rejects good data at rate ``1 - gate_probability`` and, if the model
  is wrong, can lock the filter out: keep it generous.
* ``run(zs, us=None, masks=None, outputs=None)``: update at every sample, then predict
  to the next; returns a :class:`FilterRun` with posterior means, the diagonal of P and,
  for ``outputs=(C, D)``, the mean ``C x + D u`` and covariance ``C P C^T`` of outputs.

Numerics in one place (:func:`cholesky`, :func:`symmetrize`): Cholesky solves with a
jitter fallback, symmetrized covariances, Joseph-form updates for KF and EKF. The UKF
uses the scaled sigma points of Van der Merwe (Eqs. 13-22 of Neisi et al., with the
errata of the seeds README: w_i = 1/(2(L+lambda)), no R in P_xy) exactly as filterpy's
``MerweScaledSigmaPoints``/``UnscentedKalmanFilter`` (sigma points redrawn from the prior
before the update), but propagates all 2n+1 points with one matrix product.

A scalar random walk observed once, then an outlier that a 99.99% gate rejects:

>>> m = LinearGaussianModel(F=np.eye(1), Q=np.zeros((1, 1)), H=np.eye(1), R=np.eye(1))
>>> kf = KalmanFilter(m, x0=np.zeros(1), P0=np.eye(1), gate_probability=0.9999)
>>> kf.update(np.array([2.0]))          # channels used
1
>>> kf.x, kf.P, round(kf.last_nis, 9)  # K = 1/2; NIS = y^2 / S = 4 / 2
(array([1.]), array([[0.5]]), 2.0)
>>> kf.update(np.array([100.0])), kf.n_gated, kf.x   # NIS 6534 > chi2.ppf(0.9999, 1) = 15.1
(0, 1, array([1.]))
"""
from __future__ import annotations

import contextlib
from dataclasses import dataclass
from typing import Callable, Iterator

import numpy as np
import scipy.linalg

from rotor_estimator.core.errors import ConfigError, FilterDivergedError, InputError

__all__ = ["LinearGaussianModel", "discretize", "merwe_weights", "KalmanFilter", "ExtendedKalmanFilter",
           "UnscentedKalmanFilter", "FilterRun", "cholesky", "symmetrize", "single_threaded_blas", "nis_gate"]


def symmetrize(P: np.ndarray) -> np.ndarray:
    return 0.5 * (P + P.T)


def cholesky(S: np.ndarray, what: str = "covariance") -> np.ndarray:
    """Lower Cholesky factor; adds growing diagonal jitter if S is not numerically PD."""
    try:
        return scipy.linalg.cholesky(S, lower=True, check_finite=False)
    except np.linalg.LinAlgError:
        pass
    scale = max(float(np.max(np.abs(np.diag(S)))), np.finfo(float).tiny)
    for exponent in range(-12, -3):
        try:
            return scipy.linalg.cholesky(S + np.eye(len(S)) * scale * 10.0 ** exponent, lower=True,
                                         check_finite=False)
        except np.linalg.LinAlgError:
            continue
    raise FilterDivergedError(f"{what} lost positive definiteness (even with jitter); check Q, R and the model")


@contextlib.contextmanager
def single_threaded_blas() -> Iterator[None]:
    """Limit BLAS to one thread while filtering (uses threadpoolctl when installed).

    Per-sample matrices are small (n ~ 150): threaded BLAS gains nothing and, on a busy
    2-core machine, its spinning threads made each step 20-40x slower (measured).
    """
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # pragma: no cover - optional
        yield
        return
    with threadpool_limits(limits=1, user_api="blas"):
        yield


def _solve_right(A: np.ndarray, L: np.ndarray) -> np.ndarray:
    """A S^-1 for S = L L^T (two triangular solves)."""
    tmp = scipy.linalg.solve_triangular(L, A.T, lower=True, check_finite=False)
    return scipy.linalg.solve_triangular(L.T, tmp, lower=False, check_finite=False).T


def nis_gate(gate_probability: float | None, dof: int) -> float:
    """Chi-square threshold on the NIS for ``dof`` channels (inf when gating is off)."""
    if gate_probability is None or dof <= 0:
        return float("inf")
    from scipy.stats import chi2

    return float(chi2.ppf(gate_probability, dof))


def _check_gate(gate_probability: float | None) -> float | None:
    if gate_probability is None:
        return None
    g = float(gate_probability)
    if not 0.0 < g < 1.0:
        raise ConfigError(f"gate_probability: must be in (0, 1) or None (no gate), got {gate_probability!r}")
    return g


@dataclass(frozen=True)
class LinearGaussianModel:
    """Matrices of the model in the module docstring. Shapes: F, Q (n, n); H (p, n);
    R (p, p); B (n, m) and D (p, m) or None when there is no input."""

    F: np.ndarray
    Q: np.ndarray
    H: np.ndarray
    R: np.ndarray
    B: np.ndarray | None = None
    D: np.ndarray | None = None

    def __post_init__(self) -> None:
        n, p = self.F.shape[0], self.H.shape[0]
        for name, arr, shape in (("F", self.F, (n, n)), ("Q", self.Q, (n, n)), ("H", self.H, (p, n)),
                                 ("R", self.R, (p, p))):
            if np.shape(arr) != shape:
                raise InputError(f"LinearGaussianModel.{name}: expected shape {shape}, got {np.shape(arr)}")
        if self.B is not None and self.B.shape[0] != n:
            raise InputError(f"LinearGaussianModel.B: expected {n} rows, got {self.B.shape}")
        if self.D is not None and (self.D.shape[0] != p or self.B is None or self.D.shape[1] != self.B.shape[1]):
            raise InputError("LinearGaussianModel.D: expected (p, m) with the same m as B")

    def fx(self, X: np.ndarray, u: np.ndarray | None = None) -> np.ndarray:
        """Transition of one state (n,) or a batch (N, n)."""
        out = X @ self.F.T
        return out + self.B @ u if (u is not None and self.B is not None) else out

    def hx(self, X: np.ndarray, u: np.ndarray | None = None) -> np.ndarray:
        out = X @ self.H.T
        return out + self.D @ u if (u is not None and self.D is not None) else out


def discretize(A: np.ndarray, B: np.ndarray, dt_s: float, Bw: np.ndarray | None = None,
               Qc: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Exact discretization of ``x' = A x + B u + Bw w`` (u held over each sample, w white
    with density Qc): returns ``(F, B_d, Q_d)`` by matrix exponentials (Van Loan)."""
    n, m = A.shape[0], B.shape[1]
    blk = np.zeros((n + m, n + m))
    blk[:n, :n], blk[:n, n:] = A, B
    e = scipy.linalg.expm(blk * dt_s)
    F, Bd = e[:n, :n], e[:n, n:]
    if Bw is None or Qc is None:
        return F, Bd, np.zeros((n, n))
    vl = np.zeros((2 * n, 2 * n))
    vl[:n, :n], vl[:n, n:], vl[n:, n:] = -A, Bw @ Qc @ Bw.T, A.T
    ev = scipy.linalg.expm(vl * dt_s)
    Qd = symmetrize(ev[n:, n:].T @ ev[:n, n:])
    return F, Bd, Qd


def merwe_weights(n: int, alpha: float, beta: float, kappa: float) -> tuple[np.ndarray, np.ndarray, float]:
    """(Wm, Wc, lambda) of Van der Merwe's scaled sigma points (Eq. 14 with errata 5)."""
    lam = alpha ** 2 * (n + kappa) - n
    Wm = np.full(2 * n + 1, 0.5 / (n + lam))
    Wc = Wm.copy()
    Wm[0] = lam / (n + lam)
    Wc[0] = lam / (n + lam) + (1.0 - alpha ** 2 + beta)
    return Wm, Wc, lam


@dataclass(frozen=True)
class FilterRun:
    """Result of :meth:`run` over N samples: ``x`` (N, n) posterior means, ``P_diag``
    (N, n), ``y`` (N, q) / ``y_cov`` (N, q, q) output means / covariances (or None),
    ``nis`` (N,) normalized innovation squared (NaN when no channel was used),
    ``n_used`` (N,) channels used (0 when gated), ``n_rejected`` non-finite channels
    dropped, ``n_gated`` updates skipped by the innovation gate."""

    x: np.ndarray
    P_diag: np.ndarray
    y: np.ndarray | None
    y_cov: np.ndarray | None
    nis: np.ndarray
    n_used: np.ndarray
    n_rejected: int
    n_gated: int = 0


class _StreamingFilter:
    """The common streaming interface (see the module docstring)."""

    def __init__(self, R: np.ndarray, x0: np.ndarray, P0: np.ndarray,
                 gate_probability: float | None = None) -> None:
        self.R = np.asarray(R, dtype=float)
        self.gate_probability = _check_gate(gate_probability)
        self._gates: dict[int, float] = {}
        self.n_gated = 0
        self.last_gated = False
        self.x = np.array(x0, dtype=float)
        self.P = symmetrize(np.array(P0, dtype=float))
        n = self.x.shape[0]
        if self.P.shape != (n, n):
            raise InputError(f"P0: expected shape {(n, n)}, got {self.P.shape}")
        self.n_rejected = 0
        self.last_nis = float("nan")
        self.last_n_used = 0

    def predict(self, u: np.ndarray | None = None) -> None:  # pragma: no cover - abstract
        raise NotImplementedError

    def _condition(self, z: np.ndarray, u: np.ndarray | None, R: np.ndarray, sel: np.ndarray) -> None:
        raise NotImplementedError  # pragma: no cover - abstract

    def update(self, z: np.ndarray, u: np.ndarray | None = None, R: np.ndarray | None = None,
               mask: np.ndarray | None = None) -> int:
        """Condition on the present, finite channels of ``z``; returns how many were used."""
        z = np.asarray(z, dtype=float)
        present = np.ones(z.shape[0], bool) if mask is None else np.asarray(mask, bool)
        finite = np.isfinite(z)
        self.n_rejected += int(np.count_nonzero(present & ~finite))
        sel = np.flatnonzero(present & finite)
        self.last_n_used, self.last_nis, self.last_gated = len(sel), float("nan"), False
        if len(sel) == 0:
            return 0
        R_full = self.R if R is None else np.asarray(R, dtype=float)
        self._condition(z[sel], u, R_full[np.ix_(sel, sel)], sel)
        if self.last_gated:
            self.last_n_used = 0
            return 0
        if not np.all(np.isfinite(self.x)):
            raise FilterDivergedError("state became non-finite after an update")
        return len(sel)

    def _gate_passes(self, nis: float, dof: int) -> bool:
        """Record the NIS; False (and count it) when the innovation gate rejects the update."""
        self.last_nis = nis
        if self.gate_probability is None:
            return True
        gate = self._gates.get(dof)
        if gate is None:
            gate = self._gates[dof] = nis_gate(self.gate_probability, dof)
        if nis <= gate:
            return True
        self.n_gated += 1
        self.last_gated = True
        return False

    def run(self, zs: np.ndarray, us: np.ndarray | None = None, masks: np.ndarray | None = None,
            outputs: tuple[np.ndarray, np.ndarray | None] | None = None) -> FilterRun:
        """Bulk replay: at each sample k update with ``zs[k]`` (mask ``masks[k]`` or a
        single (p,) mask for all samples), record, then predict with ``us[k]``."""
        zs = np.asarray(zs, dtype=float)
        N, n = zs.shape[0], self.x.shape[0]
        masks_arr = None if masks is None else np.asarray(masks, bool)
        xs, pd, nis, used = np.empty((N, n)), np.empty((N, n)), np.full(N, np.nan), np.zeros(N, int)
        y = ycov = None
        if outputs is not None:
            C, Dm = outputs
            y, ycov = np.empty((N, C.shape[0])), np.empty((N, C.shape[0], C.shape[0]))
        with single_threaded_blas():
            self._run_loop(zs, us, masks_arr, outputs, xs, pd, nis, used, y, ycov)
        return FilterRun(xs, pd, y, ycov, nis, used, self.n_rejected, self.n_gated)

    def _run_loop(self, zs, us, masks_arr, outputs, xs, pd, nis, used, y, ycov) -> None:
        N = zs.shape[0]
        if outputs is not None:
            C, Dm = outputs
        for k in range(N):
            u = None if us is None else us[k]
            mk = None if masks_arr is None else (masks_arr if masks_arr.ndim == 1 else masks_arr[k])
            self.update(zs[k], u=u, mask=mk)
            xs[k], pd[k], nis[k], used[k] = self.x, np.diag(self.P), self.last_nis, self.last_n_used
            if outputs is not None:
                y[k] = C @ self.x + (Dm @ u if (Dm is not None and u is not None) else 0.0)
                ycov[k] = C @ self.P @ C.T
            if k + 1 < N:
                self.predict(u)


class KalmanFilter(_StreamingFilter):
    """The exact linear Kalman filter (Joseph-form update) of a :class:`LinearGaussianModel`."""

    def __init__(self, model: LinearGaussianModel, x0: np.ndarray, P0: np.ndarray,
                 gate_probability: float | None = None) -> None:
        super().__init__(model.R, x0, P0, gate_probability)
        self.model = model

    def predict(self, u: np.ndarray | None = None) -> None:
        m = self.model
        self.x = m.fx(self.x, u)
        self.P = symmetrize(m.F @ self.P @ m.F.T + m.Q)

    def _condition(self, z, u, R, sel) -> None:
        H = self.model.H[sel]
        y = z - self.model.hx(self.x, u)[sel]
        _joseph_update(self, H, y, R)


def _joseph_update(f: _StreamingFilter, H: np.ndarray, y: np.ndarray, R: np.ndarray) -> None:
    """1. S = H P H^T + R (Cholesky); 2. NIS = |L^-1 y|^2, gate; 3. K = P H^T S^-1;
    4. x += K y; 5. Joseph form P = (I - K H) P (I - K H)^T + K R K^T."""
    PHt = f.P @ H.T
    L = cholesky(H @ PHt + R, "innovation covariance")
    w = scipy.linalg.solve_triangular(L, y, lower=True, check_finite=False)
    if not f._gate_passes(float(w @ w), len(y)):
        return
    K = _solve_right(PHt, L)
    f.x = f.x + K @ y
    IKH = np.eye(len(f.x)) - K @ H
    f.P = symmetrize(IKH @ f.P @ IKH.T + K @ R @ K.T)


class ExtendedKalmanFilter(_StreamingFilter):
    """EKF: ``fx(x, u)``, ``hx(x, u)`` and their Jacobians ``F_jacobian(x, u)`` (n, n),
    ``H_jacobian(x, u)`` (p, n) evaluated at the current estimate."""

    def __init__(self, fx: Callable, F_jacobian: Callable, hx: Callable, H_jacobian: Callable,
                 Q: np.ndarray, R: np.ndarray, x0: np.ndarray, P0: np.ndarray,
                 gate_probability: float | None = None) -> None:
        super().__init__(R, x0, P0, gate_probability)
        self.fx, self.F_jacobian, self.hx, self.H_jacobian, self.Q = fx, F_jacobian, hx, H_jacobian, Q

    @classmethod
    def from_linear(cls, model: LinearGaussianModel, x0: np.ndarray, P0: np.ndarray,
                    gate_probability: float | None = None) -> "ExtendedKalmanFilter":
        return cls(model.fx, lambda x, u: model.F, model.hx, lambda x, u: model.H, model.Q, model.R, x0, P0,
                   gate_probability)

    def predict(self, u: np.ndarray | None = None) -> None:
        F = self.F_jacobian(self.x, u)
        self.x = np.asarray(self.fx(self.x, u), dtype=float)
        self.P = symmetrize(F @ self.P @ F.T + self.Q)

    def _condition(self, z, u, R, sel) -> None:
        H = np.asarray(self.H_jacobian(self.x, u))[sel]
        y = z - np.asarray(self.hx(self.x, u))[sel]
        _joseph_update(self, H, y, R)


class UnscentedKalmanFilter(_StreamingFilter):
    """UKF with Van der Merwe scaled sigma points (Eqs. 13-22 of Neisi et al.).

    ``fx(X, u)`` and ``hx(X, u)`` take a batch of sigma points X (2n+1, n) and return
    (2n+1, n) / (2n+1, p): write them with matrix products, not Python loops.
    """

    def __init__(self, fx: Callable, hx: Callable, Q: np.ndarray, R: np.ndarray, x0: np.ndarray,
                 P0: np.ndarray, alpha: float = 1e-3, beta: float = 2.0, kappa: float = 0.0,
                 gate_probability: float | None = None) -> None:
        super().__init__(R, x0, P0, gate_probability)
        if not alpha > 0:
            raise InputError(f"alpha: must be > 0, got {alpha!r}")
        self.fx, self.hx, self.Q = fx, hx, Q
        self.alpha, self.beta, self.kappa = alpha, beta, kappa
        self.Wm, self.Wc, self.lam = merwe_weights(len(self.x), alpha, beta, kappa)

    @classmethod
    def from_linear(cls, model: LinearGaussianModel, x0: np.ndarray, P0: np.ndarray, alpha: float = 1e-3,
                    beta: float = 2.0, kappa: float = 0.0,
                    gate_probability: float | None = None) -> "UnscentedKalmanFilter":
        return cls(model.fx, model.hx, model.Q, model.R, x0, P0, alpha, beta, kappa, gate_probability)

    def sigma_points(self, x: np.ndarray, P: np.ndarray) -> np.ndarray:
        """Eq. 13: rows ``x, x + (sqrt((n+lambda) P))_i, x - (...)_i``; (2n+1, n)."""
        Lt = cholesky((len(x) + self.lam) * P, "sigma-point covariance").T
        return np.vstack([x, x + Lt, x - Lt])

    def _moments(self, Y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Weighted mean (anchored at the center point against cancellation) and deviations."""
        mean = Y[0] + self.Wm[1:] @ (Y[1:] - Y[0])
        return mean, Y - mean

    def predict(self, u: np.ndarray | None = None) -> None:
        """Eqs. 15-16."""
        Y = self.fx(self.sigma_points(self.x, self.P), u)
        self.x, dev = self._moments(Y)
        self.P = symmetrize((dev.T * self.Wc) @ dev + self.Q)

    def _condition(self, z, u, R, sel) -> None:
        """Eqs. 17-22 (sigma points redrawn from the prior, as filterpy does)."""
        X = self.sigma_points(self.x, self.P)
        Z = self.hx(X, u)[:, sel]
        zp, dz = self._moments(Z)
        dx = X - self.x
        Pz = (dz.T * self.Wc) @ dz + R
        Pxz = (dx.T * self.Wc) @ dz
        L = cholesky(Pz, "innovation covariance")
        y = z - zp
        w = scipy.linalg.solve_triangular(L, y, lower=True, check_finite=False)
        if not self._gate_passes(float(w @ w), len(y)):
            return
        K = _solve_right(Pxz, L)
        self.x = self.x + K @ y
        self.P = symmetrize(self.P - K @ Pz @ K.T)
