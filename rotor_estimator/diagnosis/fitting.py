# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Variable-projection least squares shared by every candidate effect.

The augmented model's probe output is written as

    y ~ y_nom + offset(theta_nl) + J dr + D d + S s0 + X(theta_nl) theta_lin

with ``J`` the nominal sensitivity to the 8 bearing coefficients, ``D`` one DC column per
probe, ``S`` the start transient's (the free response from each of the 8 initial states,
:func:`.context.start_columns`), ``X`` the effect's columns and ``offset`` its fixed-gain part. For fixed nonlinear
parameters ``theta_nl`` the rest is linear and eliminated (Golub & Pereyra's variable
projection); the nonlinear parameters are found by a grid then
:func:`scipy.optimize.least_squares`. Evidence: the Bayesian information criterion
``BIC = n ln(RSS/n) + k ln n`` of the Gaussian output error (smaller is better), where RSS includes
the coefficient prior's 8 pseudo-observations (:class:`.context.CoefficientPrior`): every design carries
them as 8 more rows on ``dr``, so each fit is a MAP fit and the criterion a penalized (log-posterior) one.
An effect's linear parameters carry a magnitude prior the same way (:func:`linear_prior_weights`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rotor_estimator.diagnosis.context import COEFFICIENT_SCALE, PRIOR_ROWS, FitContext, nuisance_columns


def fixed_columns(ctx: FitContext) -> int:
    """Columns ahead of an effect's in every design: 8 coefficient sensitivities, 4 DC gaps, the start
    transient's (0 or 8; 0 when the fitted effect's own columns carry it, :attr:`.FitContext.start_in_effect`)."""
    return 12 + ctx.design_start_columns_m.shape[2]


@dataclass(frozen=True)
class LinearSolution:
    """Solution of the linear part on a set of rows."""

    dr: np.ndarray            # (8,) coefficient correction, scaled units (times COEFFICIENT_SCALE = SI)
    dc_m: np.ndarray          # (4,)
    start_state: np.ndarray   # (0 or 8,) initial deviation from the periodic steady state
    theta: np.ndarray         # (k,) effect (and extra) linear parameters
    theta_cov: np.ndarray     # (k, k)
    rss_m2: float             # of the data rows
    n_obs: int
    prediction_m: np.ndarray  # (N, 4) full model output incl. DC on all samples
    prior_m2: float = 0.0     # the coefficient prior's sum of squares at the solution (added to rss_m2 in a BIC)


def _design(ctx: FitContext, cols: np.ndarray | None) -> np.ndarray:
    """``[J, D, S, cols]`` (N, 4, fixed_columns(ctx) + k)."""
    parts = [ctx.jacobian, nuisance_columns(ctx.design_start_columns_m)]
    if cols is not None and cols.shape[2]:
        parts.append(cols)
    return np.concatenate(parts, axis=2)


def prior_rows(ctx: FitContext, k: int) -> tuple[np.ndarray, np.ndarray]:
    """The coefficient prior's 8 pseudo-observations on a design of ``k`` columns (``dr`` first): rows (8, k)
    and target (8,) at the context's linearization point (m)."""
    a = np.zeros((PRIOR_ROWS, k))
    a[:, :8] = ctx.prior.design_rows()
    return a, -ctx.prior.residual_m(ctx.coefficients)


#: One sigma of the magnitude prior on an effect's linear parameters (:func:`linear_prior_weights`): the probe
#: output one parameter alone moves, in RMS, as a multiple of the measured signal's RMS.
LINEAR_PRIOR_SIGNAL_RATIO = 3.0


def linear_prior_weights(ctx: FitContext, cols: np.ndarray | None) -> np.ndarray:
    """(k,) weights ``w_j`` of the pseudo-observations ``w_j theta_j`` (m) on an effect's linear gains: a
    zero-mean Gaussian prior whose std ``s_j`` makes the gain's own output ``s_j x_j`` (column ``x_j``) carry
    :data:`LINEAR_PRIOR_SIGNAL_RATIO` times the measured signal's RMS (DC removed), at the coefficient prior's
    noise level: ``w_j = noise_std rms(x_j) / (ratio rms(y))``. A diagonal form of Zellner's g-prior scaled by
    the data instead of the noise.

    A physical effect's gains sit far inside it (an effect larger than the whole measured signal is not a
    small augmentation of the model); what it stops is two effects cancelling each other at any size (a
    runout of 2 cm against the response of 20 kg mm of unbalance, at a constant speed where the two are one
    1X signal, was a pair's "fit" of a 30 um record).
    """
    if cols is None or cols.shape[2] == 0:
        return np.zeros(0)
    return linear_prior_weights_on_rows(ctx, cols[ctx.mask])


def linear_prior_weights_on_rows(ctx: FitContext, picked: np.ndarray) -> np.ndarray:
    """:func:`linear_prior_weights` of columns already taken on the fit's rows, ``cols[ctx.mask]``."""
    if picked.shape[2] == 0:
        return np.zeros(0)
    col_rms = np.sqrt(np.einsum("nck,nck->k", picked, picked) / (picked.shape[0] * picked.shape[1]))
    return ctx.prior.noise_std_m * col_rms / (LINEAR_PRIOR_SIGNAL_RATIO * max(_signal_rms_m(ctx.y_m, ctx.mask), 1e-300))


#: The last ``(y, rows, rms)`` of :func:`_signal_rms_m`: every fit of one record asks for the same value, tens of
#: thousands of times (the arrays are held, so their identity cannot be reused by others).
_last_signal_rms: tuple | None = None


def _signal_rms_m(y_m: np.ndarray, rows: np.ndarray) -> float:
    """RMS of the measured probes ``y_m`` on ``rows``, each channel's mean removed."""
    global _last_signal_rms
    last = _last_signal_rms
    if last is not None and last[0] is y_m and last[1] is rows:
        return last[2]
    y = y_m[rows]
    value = float(np.sqrt(np.mean((y - y.mean(axis=0)) ** 2)))
    _last_signal_rms = (y_m, rows, value)
    return value


def gain_prior_rows(weights: np.ndarray, n_columns: int) -> np.ndarray:
    """The magnitude prior's pseudo-observation rows (k, ``n_columns``) on a design whose last k = ``weights.size``
    columns are an effect's gains (:func:`linear_prior_weights`): ``diag(weights)`` there, zero elsewhere. Their
    target is zero (a zero-mean prior)."""
    rows = np.zeros((weights.size, n_columns))
    rows[:, n_columns - weights.size:] = np.diag(weights)
    return rows


def solve_linear(ctx: FitContext, offset: np.ndarray | None, cols: np.ndarray | None,
                 rows: np.ndarray | None = None, *, hold_coefficients: bool = False) -> LinearSolution:
    """MAP least squares of ``y - y_nom - offset`` on ``[J, D, S, cols]`` over ``rows`` (default: ctx.mask),
    with the coefficient prior's pseudo-observations (:func:`prior_rows`) and the magnitude prior's on the
    columns' gains (:func:`linear_prior_weights`). ``hold_coefficients``: ``dr = 0`` (the coefficients stay at
    the context's, an exact optimum's, instead of taking the linearized step)."""
    rows = ctx.mask if rows is None else rows
    full = _design(ctx, cols)
    a_prior, b_prior = prior_rows(ctx, full.shape[2])
    target = ctx.y_m - ctx.y_nom_m - (0.0 if offset is None else offset)
    a_data = full[rows].reshape(-1, full.shape[2])  # a copy (boolean rows)
    b_data = target[rows].ravel()
    if hold_coefficients:  # zero columns: the pseudo-inverse below gives them a zero coefficient
        a_data[:, :8] = 0.0
        a_prior[:, :8] = 0.0
    weights = linear_prior_weights(ctx, cols)
    if weights.size:
        a_prior = np.vstack([a_prior, gain_prior_rows(weights, full.shape[2])])
        b_prior = np.concatenate([b_prior, np.zeros(weights.size)])
    # normal equations of the data rows plus the prior's, columns unit-normed (summed, not stacked: a stacked
    # copy of a long record's design is ~100 MB)
    norm = np.sqrt(np.einsum("ij,ij->j", a_data, a_data) + np.einsum("ij,ij->j", a_prior, a_prior))
    norm[norm == 0] = 1.0
    gram = (a_data.T @ a_data + a_prior.T @ a_prior) / np.outer(norm, norm)
    ata_inv = np.linalg.pinv(gram, rcond=1e-12, hermitian=True)
    coef_n = ata_inv @ ((a_data.T @ b_data + a_prior.T @ b_prior) / norm)
    coef = coef_n / norm
    if hold_coefficients:
        coef[:8] = 0.0  # exactly (the pseudo-inverse leaves rounding there)
    resid = b_data - a_data @ coef
    rss = float(resid @ resid)
    n_obs, k_all = a_data.shape
    sigma2 = rss / max(n_obs - k_all, 1)
    cov = ata_inv * sigma2 / np.outer(norm, norm)
    pred = ctx.y_nom_m + (0.0 if offset is None else offset) + np.einsum("nck,k->nc", full, coef)
    k0 = fixed_columns(ctx)
    return LinearSolution(dr=coef[:8], dc_m=coef[8:12], start_state=coef[12:k0], theta=coef[k0:],
                          theta_cov=cov[k0:, k0:], rss_m2=rss, n_obs=int(n_obs), prediction_m=pred,
                          prior_m2=ctx.prior.penalty_m2(ctx.coefficients + coef[:8] * COEFFICIENT_SCALE)
                          + float(np.sum((weights * coef[k0:]) ** 2)))


#: Eigenvalues of the unit-column Gram matrix below this fraction of the largest are dropped by
#: :func:`residual_after_fit` (singular values under ~3e-7 of the largest: what the Gram matrix resolves).
GRAM_RCOND = 1e-13


def residual_after_fit(x: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``b`` minus its least-squares fit on the columns of ``x`` (m, k): the orthogonal projection off them.

    By the normal equations of the unit-normed columns, solved through their eigen-decomposition
    (rank-deficient columns are dropped): the same residual as an SVD ``lstsq`` to rounding, at a fifth of
    the cost for the diagnosis's tall designs (2.7 vs 14 ms for 20000 x 32), which the joint refits call
    tens of thousands of times.
    """
    if x.shape[1] == 0:
        return b
    norm = np.sqrt(np.einsum("ij,ij->j", x, x))
    norm[norm == 0] = 1.0
    # the unit-normed columns' Gram matrix and right-hand side, without a normed copy of the tall design
    w, v = np.linalg.eigh((x.T @ x) / np.outer(norm, norm))
    keep = w > GRAM_RCOND * max(float(w[-1]), 1e-300)
    v = v[:, keep]
    coef = v @ ((v.T @ ((x.T @ b) / norm)) / w[keep])
    return b - x @ (coef / norm)


class Projector:
    """Orthogonal projection off the fixed columns ``[J, D, S, base]`` on ``rows`` and the coefficient prior's
    8 pseudo-observation rows below them (:func:`prior_rows`), then the magnitude prior's on the base gains
    (:func:`linear_prior_weights`; an effect's columns and offset are zero there), QR computed once. An
    effect's own gains add their magnitude prior's rows at the end of :meth:`residual`."""

    def __init__(self, ctx: FitContext, base_cols: np.ndarray | None, rows: np.ndarray) -> None:
        self.ctx = ctx
        full = _design(ctx, base_cols)
        a_prior, b_prior = prior_rows(ctx, full.shape[2])
        weights = linear_prior_weights(ctx, base_cols)
        self.n_prior = PRIOR_ROWS + weights.size
        self.index = np.flatnonzero(rows)
        m = self.index.size * 4
        a = np.zeros((m + self.n_prior, full.shape[2]))  # filled in place: one copy of the design
        np.take(full, self.index, axis=0, out=a[:m].reshape(self.index.size, 4, full.shape[2]))
        a[m:m + PRIOR_ROWS] = a_prior
        if weights.size:
            a[m + PRIOR_ROWS:] = gain_prior_rows(weights, full.shape[2])
            b_prior = np.concatenate([b_prior, np.zeros(weights.size)])
        norm = np.sqrt(np.einsum("ij,ij->j", a, a))
        norm[norm == 0] = 1.0
        a /= norm
        self.q, _ = np.linalg.qr(a)
        self.base_target = np.concatenate([(ctx.y_m - ctx.y_nom_m)[rows].ravel(), b_prior])

    def _perp(self, v: np.ndarray) -> np.ndarray:
        return v - self.q @ (self.q.T @ v)

    def _rows(self, v: np.ndarray) -> np.ndarray:
        """(N, 4[, k]) on every sample -> the design's rows, zero on the priors'."""
        m = self.index.size * 4
        out = np.empty((m + self.n_prior, *v.shape[2:]))
        np.take(v, self.index, axis=0, out=out[:m].reshape(self.index.size, *v.shape[1:]))  # no second copy
        out[m:] = 0.0
        return out

    def residual_size(self, n_cols: int) -> int:
        """Length of :meth:`residual` with ``n_cols`` effect columns (data rows, prior rows, the columns' own)."""
        return self.base_target.size + n_cols

    def residual(self, offset: np.ndarray | None, cols: np.ndarray | None) -> np.ndarray:
        """Residual after eliminating the fixed and the effect's linear parameters (MAP: the effect's gains
        carry their magnitude prior's rows, appended)."""
        b = self.base_target if offset is None else self.base_target - self._rows(offset)
        b = self._perp(b)
        if cols is not None and cols.shape[2]:
            weights = linear_prior_weights(self.ctx, cols)
            x = np.vstack([self._perp(self._rows(cols)), gain_prior_rows(weights, weights.size)])
            b = residual_after_fit(x, np.concatenate([b, np.zeros(weights.size)]))
        return b


def correlation_segment(ctx: FitContext) -> int:
    """Welch segment of :func:`spectral_covariance`: four shaft revolutions in samples (at least 64), at most
    a quarter of the fitted samples, so that the residual spectrum resolves the 1X-3X bands."""
    per_rev = 2 * np.pi / max(ctx.mean_speed_rad_s, 1e-6) * ctx.sample_rate_hz
    return int(min(max(64, round(4 * per_rev)), max(int(ctx.mask.sum()) // 4, 16)))


#: Design columns transformed at once, and frequency lines summed at once, by :func:`spectral_covariance`.
SPECTRUM_BLOCK_COLUMNS = 8
SPECTRUM_CHUNK_LINES = 2048


def welch_cross_spectra(x: np.ndarray, segment: int) -> tuple[np.ndarray, np.ndarray]:
    """Two-sided cross-spectral densities ``S[f, i, j]`` of the columns of ``x`` (T, C) by Welch's method, as
    :func:`scipy.signal.csd` gives them one pair at a time (periodic Hann window of ``segment`` samples, half
    overlap, no detrending, full segments only, ``conj(X_i) X_j`` per segment averaged, density scaling at a unit
    sample rate), with each channel's segments transformed once instead of once per pair; and the frequencies
    (cycles per sample, FFT order)."""
    from scipy.signal import get_window

    seg = int(segment)
    t_n = x.shape[0]
    if not 1 <= seg <= t_n:
        raise ValueError(f"segment must be within 1..{t_n} samples, got {seg}")
    window = get_window("hann", seg)
    step = seg - seg // 2
    starts = step * np.arange((t_n - seg) // step + 1)
    spectra = np.fft.fft(x[starts[:, None] + np.arange(seg)[None, :]] * window[None, :, None], axis=1)
    cross = np.einsum("kfi,kfj->fij", spectra.conj(), spectra) / (starts.size * float((window ** 2).sum()))
    return np.fft.fftfreq(seg), cross


def spectral_covariance(design: np.ndarray, residual: np.ndarray, segment: int,
                        prior_precision: np.ndarray | None = None, prior_noise_var: float = 0.0) -> np.ndarray:
    """Covariance of least-squares parameters when the residual is not white (a sandwich estimate).

    ``design`` (T, C, p) and ``residual`` (T, C): T consecutive samples of C channels. The residual is
    taken as stationary with the C x C cross-spectral density ``S(nu)`` of Welch's method (segments of
    ``segment`` samples), so ``cov = B^-1 (int A(nu)^H S(nu) A(nu) dnu) B^-1`` with ``B = A^T A`` and
    ``A(nu)`` the design's Fourier transform: the meat weighs each parameter's columns by the residual
    power in their own band (a 1X parameter by the 1X misfit). With a white residual it reduces to
    ``sigma^2 B^-1``. Unlike a Newey-West sum over lags of the scores, it is not biased low by the
    fitted sinusoids (a long lag window on 1X-modulated scores halved the std of a fit with 16 columns).
    ``prior_precision`` (p,): the diagonal ``Lambda`` a Gaussian prior's pseudo-observations add to ``B`` (a MAP
    fit's bread ``(A^T A + Lambda)^-1``), and ``prior_noise_var`` the variance of those pseudo-observations
    (the noise level the prior's rows are written at), which they add to the meat as ``prior_noise_var *
    Lambda``: so the covariance is that of the parameters about the truth (the Laplace posterior's,
    ``sigma^2 B^-1`` with a white residual), not only the estimate's scatter over noise draws. Without that
    term a parameter the data leave free sits at its prior mean with a std near zero: a record of steady 1X
    without an impact fitted kyy at the prior's 0.30 MN/m against a true 0.58 with a std of 0.024 (12 std
    off), where the prior's own std is 0.32.
    """
    t_n, n_ch, p = design.shape
    a = design.reshape(-1, p)
    norm = np.sqrt((a * a).sum(axis=0))
    norm[norm == 0] = 1.0
    gram = (a / norm).T @ (a / norm)
    if prior_precision is not None:
        gram = gram + np.diag(np.asarray(prior_precision, float) / norm ** 2)
    bread = np.linalg.pinv(gram, rcond=1e-12, hermitian=True) / np.outer(norm, norm)
    seg = int(min(segment, t_n))
    # Welch's S is a cosine series of lags under ``seg``, so a DFT of T + seg points sums the quadratic form without
    # circular wrap-around (a 2T-point one costs three times the memory and time for nothing)
    from scipy.fft import next_fast_len

    m = int(next_fast_len(t_n + seg, real=True))
    nu = np.fft.fftfreq(m)
    cross = np.zeros((m, n_ch, n_ch), dtype=complex)
    f, s_all = welch_cross_spectra(residual, seg)
    order = np.argsort(f)
    for i in range(n_ch):
        for j in range(i, n_ch):
            s_ij = s_all[:, i, j]
            s_m = np.interp(nu, f[order], s_ij.real[order]) + 1j * np.interp(nu, f[order], s_ij.imag[order])
            cross[:, i, j] = s_m
            cross[:, j, i] = np.conj(s_m)
    # int A^H S A dnu with A(nu) = sum_t a_t e^{-2 pi i nu t}; csd's S_ij = sum_k E[x_i(t) x_j(t+k)] e^{-2 pi i nu k}.
    # The design is real and S Hermitian, so the integrand at -nu is the conjugate of that at nu: the sum runs
    # over the one-sided frequencies (weight 2 except DC and Nyquist), its real part kept. The design's spectrum
    # is held in single precision and the sum taken in frequency chunks: (m, C, p) in double precision was
    # ~370 MB for a 1 s record with 44 parameters, the diagnosis's peak.
    half = m // 2 + 1
    spec = np.empty((half, n_ch, p), dtype=np.complex64)
    for k in range(0, p, SPECTRUM_BLOCK_COLUMNS):
        spec[:, :, k:k + SPECTRUM_BLOCK_COLUMNS] = np.fft.rfft(design[:, :, k:k + SPECTRUM_BLOCK_COLUMNS], n=m, axis=0)
    weight = np.full(half, 2.0)
    weight[0] = 1.0
    if m % 2 == 0:
        weight[-1] = 1.0  # the last one-sided line is the Nyquist frequency
    cross_half = cross[:half] * weight[:, None, None]
    meat = np.zeros((p, p))
    for f0 in range(0, half, SPECTRUM_CHUNK_LINES):  # sum_f A_f^T S_f conj(A_f), as one matrix product per chunk
        a_f = spec[f0:f0 + SPECTRUM_CHUNK_LINES].astype(complex)
        s_a = np.matmul(cross_half[f0:f0 + SPECTRUM_CHUNK_LINES], a_f.conj())  # (F, C, p)
        meat += (a_f.reshape(-1, p).T @ s_a.reshape(-1, p)).real
    meat = meat / m
    if prior_precision is not None:
        meat = meat + prior_noise_var * np.diag(np.asarray(prior_precision, float))
    return bread @ meat @ bread


def bic(rss_m2: float, n_obs: int, n_params: int) -> float:
    """Bayesian information criterion of a Gaussian output error with unknown variance."""
    return float(n_obs * np.log(max(rss_m2, 1e-300) / n_obs) + n_params * np.log(n_obs))


def held_out_rms(ctx: FitContext, offset, cols, *, hold_coefficients: bool = False) -> float:
    """Fit on the first part of the record, return the RMS error on the rest (m).

    The coefficient correction ``dr`` is held at its full-record value (zero with ``hold_coefficients``): a
    first part without an impact cannot separate a coefficient change from a per-channel 1X pattern
    (runout), and the check is about the effect's parameters, not the coefficients'.
    """
    full = solve_linear(ctx, offset, cols, hold_coefficients=hold_coefficients)
    fixed = np.einsum("nck,k->nc", ctx.jacobian, full.dr)
    off = fixed if offset is None else offset + fixed
    n = ctx.t_s.size
    cols = np.zeros((n, 4, 0)) if cols is None else cols
    target = ctx.y_m - ctx.y_nom_m - off
    design = np.concatenate([nuisance_columns(ctx.design_start_columns_m), cols], axis=2)
    a = design[ctx.fit_rows].reshape(-1, design.shape[2])
    norm = np.sqrt((a * a).sum(axis=0))
    norm[norm == 0] = 1.0
    coef, *_ = np.linalg.lstsq(a / norm, target[ctx.fit_rows].ravel(), rcond=1e-10)
    pred = ctx.y_nom_m + off + np.einsum("nck,k->nc", design, coef / norm)
    err = (ctx.y_m - pred)[ctx.test_rows]
    return float(np.sqrt(np.mean(err ** 2)))


def coefficients_after(ctx: FitContext, sol: LinearSolution) -> np.ndarray:
    """Bearing coefficients (SI) after the joint correction."""
    return ctx.coefficients + sol.dr * COEFFICIENT_SCALE
