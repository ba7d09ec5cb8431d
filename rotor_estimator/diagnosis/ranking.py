"""Fit every candidate effect, rank by evidence (BIC) and by held-out prediction, pick a winner.

Decision rule (documented in the report):

* ``delta_bic = BIC(nominal) - BIC(nominal + effect)``; a positive value is evidence for
  the effect after paying ``ln n`` per extra parameter (Schwarz 1978).
* The winner is the effect with the largest ``delta_bic``. It is reported only when
  ``delta_bic >= SIGNIFICANCE_DELTA_BIC`` **and** it predicts the held-out later part of
  the record better than the nominal model; otherwise ``best_effect = "none"``.
* A second effect is searched on top of the winner (forward selection) with the same rule.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares

from .context import FitContext
from .effects import LIBRARY, Effect
from .fitting import LinearSolution, Projector, bic, coefficients_after, held_out_rms, solve_linear

#: Minimum BIC improvement for an effect to count (``exp(-10)`` posterior odds against chance: "very strong").
SIGNIFICANCE_DELTA_BIC = 30.0
#: Nominal parameters counted in the BIC: 8 coefficients + 4 DC offsets.
NOMINAL_PARAMS = 12
#: Candidates re-linearized (outer Gauss-Newton on the coefficients) after the first pass.
REFINE_TOP = 2
#: Residuals are handed to least_squares in micrometres so that its tolerances mean something.
RESIDUAL_SCALE = 1e6
#: Effects that change the 1X forcing: the nominal fit absorbs them by moving the coefficients far,
#: so their joint refit also starts from the prior coefficients r0.
FORCING_1X = ("residual_unbalance", "tach_offset")


@dataclass
class EffectFit:
    """One fitted candidate (possibly on top of ``base`` effects)."""

    name: str
    base: tuple[str, ...]
    nl: np.ndarray
    nl_std: np.ndarray
    lin: np.ndarray
    lin_std: np.ndarray
    physical: dict
    physical_std: dict
    n_params: int
    rss_m2: float
    n_obs: int
    bic: float
    delta_bic: float
    held_out_rms_m: float
    residual_rms_m: np.ndarray        # (4,) per channel, after
    coefficients: np.ndarray          # (8,) SI after the joint correction
    prediction_m: np.ndarray          # (N, 4)
    offset: np.ndarray | None = field(repr=False, default=None)
    cols: np.ndarray | None = field(repr=False, default=None)
    ctx: FitContext | None = field(repr=False, default=None)
    effect: Effect | None = field(repr=False, default=None)

    def summary(self) -> dict:
        return {"name": self.name, "delta_bic": round(self.delta_bic, 2), "bic": round(self.bic, 2),
                "n_params": self.n_params, "held_out_rms_m": self.held_out_rms_m,
                "residual_rms_m": [float(v) for v in self.residual_rms_m],
                "parameters": {k: {"value": float(v), "std": float(self.physical_std.get(k, np.nan))}
                               for k, v in self.physical.items()}}


def _stack(parts: list[np.ndarray], n: int) -> np.ndarray:
    parts = [p for p in parts if p is not None and p.shape[2]]
    return np.concatenate(parts, axis=2) if parts else np.zeros((n, 4, 0))


def _sum(parts: list[np.ndarray | None]) -> np.ndarray | None:
    parts = [p for p in parts if p is not None]
    return sum(parts) if parts else None


def nominal_solution(ctx: FitContext) -> tuple[LinearSolution, float, float]:
    """The nominal model's (re-)solution, its BIC and held-out RMS."""
    sol = solve_linear(ctx, None, None)
    return sol, bic(sol.rss_m2, sol.n_obs, NOMINAL_PARAMS), held_out_rms(ctx, None, None)


def fit_effect(ctx: FitContext, effect: Effect, base: tuple[EffectFit, ...] = (), *,
               reference_bic: float | None = None, max_nfev: int = 30, nl0: np.ndarray | None = None) -> EffectFit:
    """Fit ``effect`` (on top of the fixed-shape ``base`` fits) by variable projection."""
    n = ctx.t_s.size
    base_off = _sum([b.offset for b in base])
    base_cols = _stack([b.cols for b in base], n)
    nl = np.zeros(0)
    nl_std = np.zeros(0)
    if effect.nl_names:
        proj = Projector(ctx, base_cols, ctx.mask)

        def fun(p):
            off, cols = effect.basis(ctx, p)
            return proj.residual(_sum([base_off, off]), cols) * RESIDUAL_SCALE

        if nl0 is None:
            grid = effect.nl_grid(ctx)
            costs = [float(np.sum(fun(g) ** 2)) for g in grid]
            x0 = grid[int(np.argmin(costs))]
        else:
            x0 = np.asarray(nl0, dtype=float)
        lo, hi = effect.nl_bounds(ctx)
        res = least_squares(fun, np.clip(x0, lo + 1e-9, hi - 1e-9), bounds=(lo, hi), diff_step=1e-3,
                            max_nfev=max_nfev, x_scale=1.0)
        nl = res.x
        jtj = res.jac.T @ res.jac
        s2 = 2 * res.cost / max(res.fun.size - len(nl), 1) / RESIDUAL_SCALE ** 2
        nl_std = np.sqrt(np.abs(np.diag(np.linalg.pinv(jtj)))) * np.sqrt(s2)
    off, cols = effect.basis(ctx, nl)
    all_off = _sum([base_off, off])
    all_cols = _stack([base_cols, cols], n)
    sol = solve_linear(ctx, all_off, all_cols)
    k_base = sum(b.n_params for b in base)
    k_eff = effect.n_params(ctx)
    lin = sol.theta[base_cols.shape[2]:]
    lin_cov = sol.theta_cov[base_cols.shape[2]:, base_cols.shape[2]:]
    lin_std = np.sqrt(np.abs(np.diag(lin_cov))) if lin.size else np.zeros(0)
    physical = effect.physical(nl, lin)
    physical_std = _physical_std(effect, nl, nl_std, lin, lin_cov)
    b_val = bic(sol.rss_m2, sol.n_obs, NOMINAL_PARAMS + k_base + k_eff)
    ref = reference_bic if reference_bic is not None else nominal_solution(ctx)[1]
    resid = (ctx.y_m - sol.prediction_m)[ctx.mask]
    eff_off = off
    eff_cols = cols
    if effect.nl_names and cols.shape[2] == 0:
        eff_cols = np.zeros((n, 4, 0))
    return EffectFit(name=effect.name, base=tuple(b.name for b in base), nl=nl, nl_std=nl_std, lin=lin,
                     lin_std=lin_std, physical=physical, physical_std=physical_std, n_params=k_eff,
                     rss_m2=sol.rss_m2, n_obs=sol.n_obs, bic=b_val, delta_bic=ref - b_val,
                     held_out_rms_m=held_out_rms(ctx, all_off, all_cols),
                     residual_rms_m=np.sqrt(np.mean(resid ** 2, axis=0)), coefficients=coefficients_after(ctx, sol),
                     prediction_m=sol.prediction_m, offset=eff_off, cols=eff_cols, ctx=ctx, effect=effect)


def refine(ctx: FitContext, effect: Effect, fit: EffectFit, base: tuple[EffectFit, ...] = (), *,
           reference_bic: float, max_nfev: int = 20, extra_starts: tuple[np.ndarray, ...] = ()) -> EffectFit:
    """Joint nonlinear refit of the 8 bearing coefficients with the effect (and the ``base`` effects).

    The first pass linearizes the nominal model about its own fit, which a large effect
    may have dragged far off; here the coefficients (and the effect's nonlinear parameters)
    are free in :func:`scipy.optimize.least_squares`, the linear ones projected out, and
    the fit is kept only when its BIC improves.
    """
    from .context import COEFFICIENT_SCALE, recentered, with_coefficients

    n = ctx.t_s.size
    n_nl = len(effect.nl_names)
    rows = ctx.mask

    def fun(x):
        c2 = with_coefficients(ctx, x[:8] * COEFFICIENT_SCALE)
        offs, cols = [], []
        for b in base:
            o, c = b.effect.basis(c2, b.nl)
            offs.append(o)
            cols.append(c)
        o, c = effect.basis(c2, x[8:])
        offs.append(o)
        cols.append(c)
        off = _sum(offs)
        x_cols = _stack(cols, n)
        target = c2.y_m - c2.y_nom_m - (0.0 if off is None else off)
        b_vec = target[rows]
        b_vec = (b_vec - b_vec.mean(axis=0)).ravel()
        if x_cols.shape[2]:
            xc = x_cols[rows]
            xc = (xc - xc.mean(axis=0)).reshape(-1, x_cols.shape[2])
            coef, *_ = np.linalg.lstsq(xc, b_vec, rcond=None)
            b_vec = b_vec - xc @ coef
        return b_vec * RESIDUAL_SCALE

    lo = np.concatenate([np.full(8, -np.inf), effect.nl_bounds(ctx)[0]])
    hi = np.concatenate([np.full(8, np.inf), effect.nl_bounds(ctx)[1]])
    best = fit
    for r_start in (fit.coefficients, *extra_starts):
        x0 = np.concatenate([np.asarray(r_start, float) / COEFFICIENT_SCALE, fit.nl])
        x0 = np.clip(x0, lo + 1e-9, hi - 1e-9) if n_nl else x0
        try:
            res = least_squares(fun, x0, bounds=(lo, hi), diff_step=1e-4, max_nfev=max_nfev, x_scale=1.0)
            ctx_new = recentered(ctx, res.x[:8] * COEFFICIENT_SCALE)
            new = fit_effect(ctx_new, effect, tuple(_refit_base(ctx_new, b) for b in base),
                             reference_bic=reference_bic, nl0=res.x[8:] if n_nl else None, max_nfev=5)
        except (ValueError, np.linalg.LinAlgError):
            continue
        if new.bic < best.bic:
            best = new
    return best


def _refit_base(ctx: FitContext, b: EffectFit) -> EffectFit:
    """A base effect's basis re-evaluated at a new linearization point (same nonlinear parameters)."""
    from dataclasses import replace

    off, cols = b.effect.basis(ctx, b.nl)
    return replace(b, offset=off, cols=cols if b.effect.lin_names(ctx) else np.zeros((ctx.t_s.size, 4, 0)))


def _physical_std(effect: Effect, nl, nl_std, lin, lin_cov, draws: int = 200) -> dict:
    """Standard deviations of the physical parameters by Monte Carlo over the parameter covariance."""
    rng = np.random.default_rng(0)
    samples = []
    for _ in range(draws):
        nl_d = nl + rng.standard_normal(nl.shape) * nl_std
        try:
            lin_d = rng.multivariate_normal(lin, lin_cov) if lin.size else lin
        except (ValueError, np.linalg.LinAlgError):
            lin_d = lin
        samples.append(effect.physical(nl_d, lin_d))
    keys = samples[0].keys() if samples else ()
    return {k: float(np.nanstd([s[k] for s in samples])) for k in keys}


@dataclass
class Ranking:
    """Nominal reference, every single-effect fit (best first) and the forward-selected pair."""

    nominal_bic: float
    nominal_held_out_rms_m: float
    nominal_rss_m2: float
    singles: list[EffectFit]
    best: EffectFit | None
    second: EffectFit | None
    pairs: list[EffectFit]


def rank_effects(ctx: FitContext, library: tuple[Effect, ...] = LIBRARY, *, second_stage: bool = True,
                 threshold: float = SIGNIFICANCE_DELTA_BIC) -> Ranking:
    """Fit each candidate, sort by ``delta_bic``, apply the decision rule, then search a second effect."""
    sol0, bic0, ho0 = nominal_solution(ctx)
    singles = [fit_effect(ctx, e, reference_bic=bic0) for e in library]
    singles.sort(key=lambda f: -f.delta_bic)
    by_name = {e.name: e for e in library}
    for i, f in enumerate(singles):
        always = f.name in FORCING_1X
        if i < REFINE_TOP or always:
            if f.delta_bic > 0 or always:
                starts = (ctx.prior_coefficients,) if always else ()
                singles[i] = refine(ctx, by_name[f.name], f, reference_bic=bic0, extra_starts=starts)
    singles.sort(key=lambda f: -f.delta_bic)
    top = singles[0]
    best = top if (top.delta_bic >= threshold and top.held_out_rms_m < ho0) else None
    second, pairs = None, []
    if best is not None and second_stage:
        bctx = best.ctx or ctx
        for e in library:
            if e.name == best.name:
                continue
            pairs.append(fit_effect(bctx, e, (best,), reference_bic=best.bic))
        pairs.sort(key=lambda f: -f.delta_bic)
        for i in range(min(2, len(pairs))):
            if pairs[i].delta_bic > 0:
                pairs[i] = refine(bctx, by_name[pairs[i].name], pairs[i], (best,), reference_bic=best.bic)
        pairs.sort(key=lambda f: -f.delta_bic)
        cand = pairs[0]
        if cand.delta_bic >= threshold and cand.held_out_rms_m < best.held_out_rms_m:
            second = cand
    return Ranking(nominal_bic=bic0, nominal_held_out_rms_m=ho0, nominal_rss_m2=sol0.rss_m2, singles=singles,
                   best=best, second=second, pairs=pairs)
