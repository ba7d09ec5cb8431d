# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Jacobians of an expensive residual by secant (Broyden) updates between forward-difference refreshes.

The diagnosis's joint refits (:func:`.ranking.refine`) re-simulate the model at every residual evaluation.
A forward-difference Jacobian costs one evaluation per parameter (8 bearing coefficients plus the effect's) at
every accepted step of :func:`scipy.optimize.least_squares`: 88 % of the evaluations of an independent record
(cProfile, 191 s). Here the Jacobian of the first point is a forward difference; after it, each
accepted point ``x_t`` updates it by Broyden's rank-one secant formula (Nocedal & Wright, *Numerical Optimization*,
Eq. 11.27, applied to the residual vector)

    J <- J + (f(x_t) - f(x_b) - J dx) dx^T / (dx^T dx),    dx = x_t - x_b,

from the previous accepted point ``x_b``. A fresh forward difference is taken every ``refresh_every`` accepted
steps and whenever a trial step was rejected since the last one (the local model predicted badly). The
optimizer's own acceptance test (actual against predicted reduction) keeps the iteration honest with an
inexact Jacobian; the path, and so the optimum reached in a fixed budget, can differ from a forward
difference's.
"""
from __future__ import annotations

from typing import Callable

import numpy as np


class SecantJacobian:
    """``fun`` and ``jac`` for :func:`scipy.optimize.least_squares`: pass ``sj.fun`` and ``jac=sj.jac``.

    ``rel_step`` is the forward-difference step relative to ``max(1, |x_i|)`` (scipy's ``diff_step``); the
    step is reversed where it would leave the bounds ``lo``, ``hi``.
    """

    def __init__(self, fun: Callable[[np.ndarray], np.ndarray], lo: np.ndarray, hi: np.ndarray, *,
                 rel_step: float = 1e-4, refresh_every: int = 3) -> None:
        if refresh_every < 1:
            raise ValueError(f"refresh_every must be >= 1, got {refresh_every}")
        self._fun = fun
        self._lo = np.asarray(lo, float)
        self._hi = np.asarray(hi, float)
        self._rel_step = float(rel_step)
        self._refresh_every = int(refresh_every)
        self._pending: list[tuple[np.ndarray, np.ndarray]] = []  # points evaluated since the last jac call
        self._base: tuple[np.ndarray, np.ndarray] | None = None  # the last point the Jacobian refers to
        self._jac: np.ndarray | None = None
        self._steps_since_refresh = 0
        self.last_was_secant = False  # whether the last Jacobian handed out was a secant update
        self.evaluations = 0          # calls of the residual, the forward differences' included
        self.difference_evaluations = 0

    def fun(self, x: np.ndarray) -> np.ndarray:
        """The residual at ``x``, remembered for the secant updates."""
        f = np.asarray(self._fun(x), float)
        self.evaluations += 1
        self._pending.append((np.array(x, float), f.copy()))
        return f

    def _value_at(self, x: np.ndarray) -> np.ndarray:
        for xp, fp in reversed(self._pending):
            if np.array_equal(xp, x):
                return fp
        if self._base is not None and np.array_equal(self._base[0], x):
            return self._base[1]
        return self.fun(x)

    def _forward_difference(self, x: np.ndarray, f: np.ndarray) -> np.ndarray:
        jac = np.empty((f.size, x.size))
        for i in range(x.size):
            h = self._rel_step * max(1.0, abs(float(x[i])))
            if x[i] + h > self._hi[i]:
                h = -h
            xs = x.copy()
            xs[i] += h
            h = float(xs[i] - x[i])  # the step actually taken, after rounding
            jac[:, i] = (np.asarray(self._fun(xs), float) - f) / h
            self.evaluations += 1
            self.difference_evaluations += 1
        return jac

    def jac(self, x: np.ndarray) -> np.ndarray:
        """The Jacobian at ``x`` (an accepted point): secant-updated, or a fresh forward difference."""
        x = np.array(x, float)
        f = self._value_at(x)
        rejected = sum(1 for xp, _ in self._pending if not np.array_equal(xp, x))
        refresh = (self._jac is None or self._base is None or rejected >= 1
                   or self._steps_since_refresh >= self._refresh_every
                   or self._jac.shape != (f.size, x.size))
        self.last_was_secant = not refresh
        if refresh:
            self._jac = self._forward_difference(x, f)
            self._steps_since_refresh = 0
        else:
            assert self._jac is not None and self._base is not None
            xb, fb = self._base
            dx = x - xb
            dd = float(dx @ dx)
            if dd > 0.0 and np.all(np.isfinite(f)):
                self._jac += np.outer(f - fb - self._jac @ dx, dx / dd)
            self._steps_since_refresh += 1
        self._base = (x, f)
        self._pending = []
        return self._jac.copy()


def least_squares_secant(fun: Callable[[np.ndarray], np.ndarray], x0: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                         *, max_nfev: int, rel_step: float = 1e-4, refresh_every: int = 3):
    """:func:`scipy.optimize.least_squares` (trust-region reflective within ``lo``, ``hi``, ``x_scale=1``) with
    the Jacobian of :class:`SecantJacobian`. ``max_nfev`` counts the optimizer's trial points, not the forward
    differences (as scipy's own finite differences); the result's ``evaluations`` counts every call of ``fun``."""
    from scipy.optimize import least_squares

    sj = SecantJacobian(fun, lo, hi, rel_step=rel_step, refresh_every=refresh_every)
    res = least_squares(sj.fun, x0, jac=sj.jac, bounds=(lo, hi), max_nfev=max_nfev, x_scale=1.0)
    evaluations = sj.evaluations
    left = max_nfev - int(res.nfev)
    if res.status > 0 and sj.last_was_secant and left > 0:
        # converged on a secant Jacobian: a tolerance met with an inexact model can be a stall (a keyphasor offset
        # stopped 18 deg short), so the run continues from there on a fresh forward difference
        again = SecantJacobian(fun, lo, hi, rel_step=rel_step, refresh_every=refresh_every)
        more = least_squares(again.fun, res.x, jac=again.jac, bounds=(lo, hi), max_nfev=left, x_scale=1.0)
        evaluations += again.evaluations
        if more.cost <= res.cost:
            res = more
    res.evaluations = evaluations
    return res
