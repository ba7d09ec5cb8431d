# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""The secant (Broyden) Jacobian of the joint refits: exact on linear residuals, the same optimum as scipy's
forward differences on a nonlinear one for fewer residual evaluations, and no evaluation outside the bounds."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import least_squares

from rotor_estimator.diagnosis.secant_jacobian import SecantJacobian, least_squares_secant


def _damped_fit_problem(seed: int = 0):
    """A decaying 1X-like sinusoid plus a slow drift: 7 nonlinear parameters, 2000 residuals."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 1.0, 2000)

    def model(p):
        return p[0] * np.exp(-p[1] * t) * np.cos(p[2] * t + p[3]) + p[4] * t ** 2 + p[5] * np.sin(p[6] * t)

    truth = np.array([1.0, 2.0, 20.0, 0.3, 0.5, 0.2, 7.0])
    y = model(truth) + 0.01 * rng.standard_normal(t.size)
    return (lambda p: model(p) - y), truth


def test_linear_residual_jacobian_is_exact_after_secant_updates():
    """For f = A x - b every secant is exact, so Broyden's update leaves the forward-difference A unchanged and
    the solve reaches the least-squares solution."""
    rng = np.random.default_rng(1)
    a, b = rng.standard_normal((50, 4)), rng.standard_normal(50)
    sj = SecantJacobian(lambda x: a @ x - b, np.full(4, -np.inf), np.full(4, np.inf), refresh_every=100)
    x0 = np.zeros(4)
    sj.fun(x0)
    np.testing.assert_allclose(sj.jac(x0), a, rtol=1e-6, atol=1e-8)
    x1 = np.array([0.3, -0.2, 0.1, 0.5])
    sj.fun(x1)
    np.testing.assert_allclose(sj.jac(x1), a, rtol=1e-6, atol=1e-8)
    assert sj.difference_evaluations == 4  # the second Jacobian was a secant update, not a difference
    res = least_squares_secant(lambda x: a @ x - b, x0, np.full(4, -np.inf), np.full(4, np.inf), max_nfev=50)
    np.testing.assert_allclose(res.x, np.linalg.lstsq(a, b, rcond=None)[0], rtol=1e-7, atol=1e-9)


def test_nonlinear_fit_reaches_the_forward_difference_optimum_with_fewer_evaluations():
    """The same minimum as scipy's 2-point Jacobian (cost within 1e-6 relative), in fewer residual calls."""
    fun, truth = _damped_fit_problem()
    calls = {"n": 0}

    def counted(p):
        calls["n"] += 1
        return fun(p)

    x0 = truth * 1.15
    ref = least_squares(counted, x0, diff_step=1e-4, x_scale=1.0, max_nfev=60)
    ref_calls, calls["n"] = calls["n"], 0
    res = least_squares_secant(counted, x0, np.full(7, -np.inf), np.full(7, np.inf), max_nfev=60)
    assert res.evaluations == calls["n"]
    assert res.cost == pytest.approx(ref.cost, rel=1e-6)
    np.testing.assert_allclose(res.x, ref.x, rtol=1e-4)
    assert calls["n"] < ref_calls


def test_difference_step_stays_inside_the_bounds():
    """A parameter at its upper bound is differenced backwards: no residual is evaluated outside [lo, hi],
    and the Jacobian there is still the derivative."""
    seen = []

    def fun(x):
        seen.append(x.copy())
        return np.array([x[0] ** 2, 3.0 * x[1]])

    lo, hi = np.array([0.0, -1.0]), np.array([1.0, 1.0])
    sj = SecantJacobian(fun, lo, hi)
    x = np.array([1.0, 0.5])
    sj.fun(x)
    jac = sj.jac(x)
    assert all(np.all(p >= lo) and np.all(p <= hi) for p in seen)
    np.testing.assert_allclose(jac, [[2.0, 0.0], [0.0, 3.0]], rtol=1e-3)


def test_refresh_every_must_be_positive():
    """A configuration error names the bad setting."""
    with pytest.raises(ValueError, match="refresh_every"):
        SecantJacobian(lambda x: x, np.zeros(1), np.ones(1), refresh_every=0)
