# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""``diagnose``: nominal fit, residual budget, effect ranking and the before/after table.

The JSON summary (``Diagnosis.summary()``) carries at least ``where``, ``ranking``,
``best_effect`` (``"none"`` when the nominal model explains the data to the noise
level), ``residual_rms_before`` / ``residual_rms_after`` (m, all probe channels) and
``shrink_ratio`` (before / after; 1 means no shrink).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from rotor_estimator.core.config import COEFFICIENT_NAMES_WITH_UNITS, EstimatorConfig, RigConfig
from rotor_estimator.core.linear_filters import single_threaded_blas
from rotor_estimator.core.recording import RigRecording
from rotor_estimator.diagnosis.context import (COEFFICIENT_SCALE, WARMUP_S, FitContext, build_context,
                                              only_steady_1x, recentered, slowest_decay_rate_1_per_s,
                                              start_transient_sensitivity)
from rotor_estimator.diagnosis.effects import LIBRARY, Effect
from rotor_estimator.diagnosis.effects.base import separating_measurements
from rotor_estimator.diagnosis.ranking import (HELD_OUT_TOLERANCE, SIGNIFICANCE_DELTA_BIC, TIE_LR_QUANTILE,
                                              TIE_MARGIN_BIC, EffectFit, Ranking, coefficients_cov_over_models,
                                              misfit, exact_nominal, parameter_covariance, profiled_or_local,
                                              rank_effects, sampled_coefficient_cov)
from rotor_estimator.diagnosis.residuals import CHANNELS, budget, innovation_consistency

#: Residual RMS over noise RMS above which the gap left after the verdict is reported as unexplained.
UNEXPLAINED_RATIO = 1.2

# 2: decision_rule.held_out_no_worse_than_nominal and held_out_tolerance; 3: data;
# 4: verdict_set, tie, unexplained, provenance, finding, the table's coefficients_std; 6: data.decimation always,
# gap_ratio_before, and the gap figures (residual RMS, noise, shrink) at the record's rate when it was decimated
SCHEMA_VERSION = 6

NO_IMPACT_WARNING = ("no impact in the record: the bearing coefficients are then fitted to the synchronous "
                     "response alone and absorb most effects (unbalance, keyphasor offset, runout, probe gain, "
                     "pedestal), so a 'none' verdict is weak evidence; record at least one impact")


@dataclass
class Diagnosis:
    """Everything the report shows; ``summary()`` is the JSON."""

    ctx: FitContext
    ranking: Ranking
    where: dict
    innovations: dict
    nominal_prediction_m: np.ndarray
    table: list[dict]
    data: dict
    #: Where the record came from (a bag or file path; the recording's ``meta['source']`` by default).
    source: str | None = None
    #: (4,) noise std per channel (m) of the record at its own rate when the fits ran on it decimated
    #: (:func:`record_rate_noise_std_m`), else None: the summary's gap figures refer to the record's rate.
    record_noise_std_m: np.ndarray | None = None

    def _noise_offset_m2(self) -> np.ndarray:
        """(4,) what the record's rate adds to each channel's residual power over the fit rate's: the noise
        outside the kept band (the effect's and the misfit's power is in it), zero without decimation."""
        if self.record_noise_std_m is None:
            return np.zeros(4)
        return self.record_noise_std_m ** 2 - self.ctx.noise_std_m ** 2

    def at_record_rate_m(self, rms_m: float | np.ndarray) -> float | np.ndarray:
        """A residual RMS of the fits (all channels, or per channel) as the record's own rate has it."""
        offset = self._noise_offset_m2()
        rms = np.asarray(rms_m, float)
        out = np.sqrt(np.maximum(rms ** 2 + (offset if rms.ndim else offset.mean()), 0.0))
        return out if rms.ndim else float(out)

    @property
    def noise_std_m(self) -> np.ndarray:
        """(4,) noise std per channel (m) at the record's rate."""
        return self.ctx.noise_std_m if self.record_noise_std_m is None else self.record_noise_std_m

    @property
    def best_effect(self) -> str:
        return self.ranking.best.name if self.ranking.best else "none"

    @property
    def after_fit(self) -> EffectFit | None:
        """The final model: winner, plus the second effect when one was found."""
        return self.ranking.second or self.ranking.best

    @property
    def verdict_set(self) -> list[str]:
        """The verdict's effects: the winner (and the pair's second), or the tied set; ``[]`` for none."""
        rk = self.ranking
        if rk.best is None:
            return []
        return [rk.best.name] + ([rk.second.name] if rk.second else [f.name for f in rk.tied])

    def ranking_pairs(self, limit: int = 5) -> list[dict]:
        """The best ``limit`` pairs, their evidence on the singles' scale (``delta_bic`` against the nominal
        model) and over the top single (``delta_bic_over_top_single``: the pair needs the significance
        threshold there to be the verdict). A pair fitted on two forms of its base is listed once, in its better
        form (the ranking keeps both)."""
        rk = self.ranking
        best_form = {}
        for p in rk.pairs:  # sorted by BIC
            best_form.setdefault((p.base[0], p.name), p)
        return [{"effects": [p.base[0], p.name], "delta_bic": round(rk.nominal_bic - p.bic, 2),
                 "delta_bic_over_top_single": round(p.delta_bic, 2),
                 "n_params": p.n_params + p.base_n_params, "held_out_rms_m": p.held_out_rms_m,
                 "residual_rms_m": _total(p.residual_rms_m)} for p in list(best_form.values())[:limit]]

    def tie(self) -> dict | None:
        """``None`` when the data decide; else the tied effects, their evidence margin and the measurements
        that would separate them (each effect's declared response to each)."""
        rk = self.ranking
        if rk.best is None or not rk.tied:
            return None
        other = rk.tied[0]
        return {"effects": [rk.best.name, other.name],
                "margin_delta_bic": round(rk.best.delta_bic - other.delta_bic, 2),
                "misfit_difference": round(misfit(other) - misfit(rk.best), 2),
                "parameters": [rk.best.n_params, other.n_params],
                "rule": f"-2 ln L within {TIE_MARGIN_BIC:g}, or within the chi-square {TIE_LR_QUANTILE:g} quantile of "
                        "the extra parameters when the richer fits better",
                "separating_measurements": separating_measurements(rk.best.effect, other.effect)
                if rk.best.effect is not None and other.effect is not None else []}

    def unexplained(self) -> dict | None:
        """The gap left after the verdict when it is still over :data:`UNEXPLAINED_RATIO` x noise: where it lies
        (band, channel), so a gap of a kind not in the library is described rather than forced onto a name."""
        ctx = self.ctx
        pred = self.after_fit.prediction_m if self.after_fit else self.nominal_prediction_m
        e = (ctx.y_m - pred)[ctx.mask]
        ratio = float(np.sqrt((np.mean(e ** 2) + self._noise_offset_m2().mean()) / np.mean(self.noise_std_m ** 2)))
        if ratio < UNEXPLAINED_RATIO:
            return None
        b = budget(ctx.t_s[ctx.mask], e, ctx.shaft.angle_rad[ctx.mask], ctx.shaft.speed_rad_s[ctx.mask],
                   ctx.impact_force_n[ctx.mask], ctx.noise_std_m)
        return {"residual_over_noise": ratio, "signature": gap_signature(b), "dominant_band": b["dominant_band"],
                "dominant_channel": b["dominant_channel"],
                "bands": {r["band"]: {"rms_m": r["rms_m"], "share": r["share"]} for r in b["bands"]},
                "nonsync_peaks_hz": [p["frequency_hz"] for p in b["nonsync_peaks"]]}

    def provenance(self) -> dict:
        """What was diagnosed, with what: record source, rig, mean speed, span, package version, UTC date."""
        import datetime
        from importlib import metadata

        try:
            version = metadata.version("rotor_estimator")
        except metadata.PackageNotFoundError:
            version = "unknown"
        ctx = self.ctx
        return {"source": self.source, "rig": ctx.rig.name,
                "mean_speed_rpm": float(ctx.mean_speed_rad_s * 30 / np.pi),
                "duration_s": float(ctx.t_s[-1] - ctx.t_s[0]), "impacts": self.data.get("impacts"),
                "rotor_estimator_version": version,
                "date_utc": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M")}

    def finding(self) -> str:
        """One sentence: the verdict (or tie, or none) and the verdict's most significant parameter with its std."""
        rk = self.ranking
        if rk.best is None:
            return ("The nominal model explains the record to the noise level: no unmodelled effect is significant "
                    f"(the best candidate, `{rk.singles[0].name if rk.singles else '-'}`, stays under delta BIC "
                    f"{SIGNIFICANCE_DELTA_BIC:g}).")
        fits = [rk.best] + ([rk.second] if rk.second else [])
        parts = []
        for f in fits:
            sig = [(abs(v) / s, k, v, s) for k, v in f.physical.items()
                   if (s := f.physical_std.get(k, np.nan)) > 0 and np.isfinite(s)]
            if sig:
                _, k, v, s_ = max(sig)
                parts.append(f"`{f.name}` ({k} = {v:.4g} +- {s_:.2g})")
            else:
                parts.append(f"`{f.name}`")
        text = " together with ".join(parts)
        if rk.tied:
            text += f", or equally `{rk.tied[0].name}` (a tie: see the measurements that separate them)"
        return f"The gap is explained by {text}."

    def verdict_row(self) -> dict:
        """The table's row of the verdict's model (the nominal's when the verdict is none)."""
        best, second = self.ranking.best, self.ranking.second
        label = ("+ " + best.name + (" + " + second.name if second else "")) if best else "nominal"
        return next((r for r in self.table if r["model"] == label), self.table[0])

    def summary(self) -> dict:
        ctx, rk = self.ctx, self.ranking
        # the gap figures at the record's rate (the fits' rate when it was decimated has less noise per sample)
        before = self.at_record_rate_m(_rms(ctx.y_m - self.nominal_prediction_m, ctx.mask))
        after = (self.at_record_rate_m(_rms(ctx.y_m - self.after_fit.prediction_m, ctx.mask)) if self.after_fit
                 else before)
        best = rk.best
        top2 = [f.name for f in rk.singles[:2]]
        final_row = self.verdict_row()
        if best is not None:
            top2 = [best.name, (rk.second.name if rk.second else
                                next(f.name for f in rk.singles if f.name != best.name))]
        return {
            "schema_version": SCHEMA_VERSION,
            "provenance": self.provenance(),
            "finding": self.finding(),
            "data": self.data,
            "where": self.where,
            "innovations": self.innovations,
            "ranking": [{"effect": f.name, "delta_bic": round(f.delta_bic, 2), "n_params": f.n_params,
                         "held_out_rms_m": f.held_out_rms_m, "residual_rms_m": _total(f.residual_rms_m)}
                        for f in rk.singles],
            "ranking_pairs": self.ranking_pairs(),
            "decision_rule": {"min_delta_bic": SIGNIFICANCE_DELTA_BIC,
                              "held_out_no_worse_than_nominal": True,
                              "held_out_tolerance": HELD_OUT_TOLERANCE,
                              "nominal_held_out_rms_m": rk.nominal_held_out_rms_m},
            "best_effect": self.best_effect,
            "best_effect_fit": best.summary() if best else None,
            "second_effect": rk.second.name if rk.second else "none",
            "second_effect_fit": rk.second.summary() if rk.second else None,
            "top_two": top2,
            "verdict_set": self.verdict_set,
            "tie": self.tie(),
            "unexplained": self.unexplained(),
            "residual_rms_before": float(before),
            "residual_rms_after": float(after),
            "residual_rms_before_per_channel_m": dict(zip(CHANNELS, map(float, self.at_record_rate_m(_per_channel(
                ctx.y_m - self.nominal_prediction_m, ctx.mask))))),
            "residual_rms_after_per_channel_m": dict(zip(CHANNELS, map(float, self.at_record_rate_m(_per_channel(
                ctx.y_m - (self.after_fit.prediction_m if self.after_fit else self.nominal_prediction_m),
                ctx.mask))))),
            "shrink_ratio": float(before / after) if after > 0 else 1.0,
            "noise_std_m": float(np.sqrt(np.mean(self.noise_std_m ** 2))),
            "gap_ratio_before": float(before / np.sqrt(np.mean(self.noise_std_m ** 2))),
            "coefficients_ekf": dict(zip(COEFFICIENT_NAMES_WITH_UNITS, map(float, ctx.coefficients_ekf))),
            "coefficients_nominal": dict(zip(COEFFICIENT_NAMES_WITH_UNITS, map(float, ctx.coefficients))),
            # the bearing coefficients of the verdict's model (the nominal fit's when the verdict is none)
            "coefficients_verdict": dict(zip(COEFFICIENT_NAMES_WITH_UNITS,
                                             map(float, final_row["coefficients"].values()))),
            "coefficients_verdict_std": dict(zip(COEFFICIENT_NAMES_WITH_UNITS,
                                                 map(float, final_row["coefficients_std"].values()))),
            "table": self.table,
        }


def gap_signature(b: dict) -> str:
    """A residual budget (:func:`.residuals.budget`) in words: the kind of gap, for one not in the library.

    An order (nX) is called fixed in direction when its forward and backward whirl are within a factor of two
    (a force or a reading along one line, as a misalignment's 2X), else forward or backward; a non-synchronous
    peak is named with its frequency; a residual at least twice as strong in the 50 ms after the impacts as
    in steady running is "after the impact"."""
    band = b["dominant_band"]
    words = []
    if band.endswith("X") and band[:-1].isdigit():
        plane = max(b["whirl"].values(), key=lambda p: sum(p["orders"].get(band, {}).values()))
        o = plane["orders"].get(band)
        if o:
            f, bw = o["forward_m"], o["backward_m"]
            kind = ("fixed in direction (forward and backward whirl alike)" if 0.5 <= f / max(bw, 1e-300) <= 2.0
                    else "forward whirl" if f > bw else "backward whirl")
            words.append(f"{band} {kind}")
        else:
            words.append(band)
    elif band == "nonsync_peaks" and b["nonsync_peaks"]:
        peaks = ", ".join(f"{p['frequency_hz']:.1f}" for p in b["nonsync_peaks"][:3])
        words.append(f"fixed-frequency peak(s) at {peaks} Hz")
    else:
        words.append(band)
    seg = {r["segment"]: r["rms_m"] for r in b["time"]}
    if "after_impact_50ms" in seg and seg["after_impact_50ms"] >= 2.0 * seg.get("steady", np.inf):
        words.append("strongest in the 50 ms after the impacts")
    return "; ".join(words) + f", mostly on {b['dominant_channel']}"


def data_accounting(recording: RigRecording, ctx: FitContext) -> dict:
    """Which samples the fits used, why the others were left out, the impacts, and warnings on what
    the data cannot show (counted rejections, never silent)."""
    n = len(recording)
    non_finite = ~np.all(np.isfinite(recording.probes_m), axis=1)
    outside_tach = ~ctx.shaft.valid
    hit = np.any(recording.impact_force_n != 0.0, axis=1)
    impacts = int(hit[0]) + int(np.sum(hit[1:] & ~hit[:-1]))
    warnings = []
    if non_finite.any():
        warnings.append(f"{int(non_finite.sum())} probe sample(s) with a non-finite value were left out")
    if outside_tach.mean() > 0.1:
        warnings.append(f"{100 * outside_tach.mean():.0f} % of the samples lie outside the span the keyphasor "
                        "tracks and were left out")
    if impacts == 0:
        warnings.append(NO_IMPACT_WARNING)
    return {"samples": n, "samples_used": int(ctx.mask.sum()), "non_finite_probe_samples": int(non_finite.sum()),
            "outside_tachometer_span_samples": int(outside_tach.sum()),
            "warm_up_samples": int(np.sum(ctx.t_s < ctx.t_s[0] + WARMUP_S)), "impacts": impacts,
            "warnings": warnings}


def nominal_stability(ctx: FitContext) -> tuple[float, list[str]]:
    """The nominal model's slowest decay rate (1/s) and a warning when the stability wall of the nominal fit
    holds it at the limit (:func:`at_stability_limit`)."""
    decay = slowest_decay_rate_1_per_s(ctx.mats, ctx.coefficients, ctx.mean_speed_rad_s)
    used_s = fitted_span_s(ctx)
    if not at_stability_limit(decay, used_s):
        return decay, []
    return decay, [f"the nominal model sits at its stability limit (slowest mode decays at {decay:.3g} 1/s, less "
                   f"than once over the {used_s:.3g} s fitted): a stable rotor on the 8 coefficients alone could "
                   "not fit the record, so an unmodelled effect drags them and the nominal row is no bearing "
                   "estimate"]


def fitted_span_s(ctx: FitContext) -> float:
    """Duration (s) of the samples the fits use."""
    return float(np.ptp(ctx.t_s[ctx.mask]))


def at_stability_limit(decay_1_per_s: float, span_s: float) -> bool:
    """True when a model's slowest mode decays less than once (by e) over ``span_s``, grows, or its rate is not a
    number: the rig ran with a bounded, settled response, which such a rotor does not explain."""
    return not decay_1_per_s * span_s > 1.0


def _rms(e: np.ndarray, mask: np.ndarray) -> float:
    return float(np.sqrt(np.mean(e[mask] ** 2)))


def _per_channel(e: np.ndarray, mask: np.ndarray) -> list[float]:
    return [float(v) for v in np.sqrt(np.mean(e[mask] ** 2, axis=0))]


def _total(per_channel: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.asarray(per_channel) ** 2)))


def _row(ctx: FitContext, label: str, prediction: np.ndarray, held_out: float, coefficients: np.ndarray,
         coefficients_std: np.ndarray) -> dict:
    e = (ctx.y_m - prediction)[ctx.mask]
    b = budget(ctx.t_s[ctx.mask], e, ctx.shaft.angle_rad[ctx.mask], ctx.shaft.speed_rad_s[ctx.mask],
               ctx.impact_force_n[ctx.mask], ctx.noise_std_m)
    bands = {r["band"]: r["rms_m"] for r in b["bands"]}
    nis = float(np.mean(np.sum(e ** 2 / ctx.noise_std_m ** 2, axis=1)))
    return {"model": label, "residual_rms_m": _rms(ctx.y_m - prediction, ctx.mask),
            "per_channel_rms_m": dict(zip(CHANNELS, _per_channel(ctx.y_m - prediction, ctx.mask))),
            "excess_band_rms_m": {k: bands.get(k, 0.0) for k in ("1X", "2X", "3X", "nonsync_peaks", "broadband")},
            "output_nis_mean": nis, "held_out_rms_m": held_out,
            "coefficients": dict(zip(COEFFICIENT_NAMES_WITH_UNITS, map(float, coefficients))),
            "coefficients_std": dict(zip(COEFFICIENT_NAMES_WITH_UNITS, map(float, coefficients_std))),
            "slowest_decay_1_per_s": slowest_decay_rate_1_per_s(ctx.mats, coefficients, ctx.mean_speed_rad_s)}


#: Longest stretch of a record the model fits run on (s). Their memory and time grow with the samples
#: fitted (about 130 MB and 12 s per second of record), so a long record is diagnosed on one window of
#: this length, chosen by :func:`analysis_window` and reported; see the README.
MAX_FIT_WINDOW_S = 1.0


def analysis_window(recording: RigRecording, max_s: float = MAX_FIT_WINDOW_S) -> tuple[int, int, str]:
    """``(start, stop, why)``: the whole record when it is short enough, else the ``max_s`` window that
    holds the most hammer impacts (each impact's free response is what separates the effects), starting a
    little before the first of them; with no impact, the last ``max_s`` (the steadiest part)."""
    n = len(recording)
    t = recording.time_s()
    if n == 0 or t[-1] - t[0] <= max_s:
        return 0, n, "the whole record"
    per = max(int(round(max_s / float(np.median(np.diff(t))))), 2)
    hit = np.any(recording.impact_force_n != 0.0, axis=1)
    onsets = np.flatnonzero(hit & ~np.concatenate(([False], hit[:-1])))
    if onsets.size == 0:
        return n - per, n, f"the last {max_s:g} s (no impact in the record)"
    lead = max(int(round(0.1 * per)), 1)
    best, best_count = 0, -1
    for i in onsets:
        start = int(min(max(i - lead, 0), n - per))
        count = int(np.sum((onsets >= start) & (onsets < start + per)))
        if count > best_count:
            best, best_count = start, count
    return best, best + per, f"the {max_s:g} s holding the most impacts ({best_count} of {onsets.size})"


@single_threaded_blas()  # small matrices: threaded BLAS only oversubscribes (2.3x slower measured)
def diagnose(recording: RigRecording, rig: RigConfig, config: EstimatorConfig, *, passes: int = 2,
             library: tuple[Effect, ...] = LIBRARY, max_fit_window_s: float = MAX_FIT_WINDOW_S,
             decimate: int | str = "auto", progress=None) -> Diagnosis:
    """Fit the nominal model, budget its residual, rank the candidate effects, tabulate before/after.

    A record longer than ``max_fit_window_s`` is diagnosed on one window of it (see
    :func:`analysis_window`); ``summary()['data']['analysis_window']`` says which. ``decimate``: that window is
    low-pass filtered and decimated by this factor first (:func:`.decimation.decimated`; fewer samples, the same
    band and information on the parameters); ``"auto"`` picks it (:func:`.decimation.automatic_factor`: up to 4
    where the speed and the record allow, else 1), ``1`` keeps the record's rate; ``summary()['data']['decimation']``
    says which and why; the fits' noise floor is read at the record's rate when the decimated one's band cannot
    show it (:func:`.decimation.fit_rate_noise_std_m`). ``progress``, when given, is called with one line of text
    at each stage."""
    from rotor_estimator.diagnosis.decimation import decimated, fit_rate_noise_std_m, resolved_factor

    full_n = len(recording)
    start, stop, why = analysis_window(recording, max_fit_window_s)
    window = None
    if (start, stop) != (0, full_n):
        t = recording.time_s()
        window = {"start_s": float(t[start] - t[0]), "stop_s": float(t[stop - 1] - t[0]),
                  "record_s": float(t[-1] - t[0]), "rule": why}
        recording = recording.slice(start, stop)
    undecimated_n = len(recording)
    factor, factor_why = resolved_factor(recording, decimate)
    record_rate = recording
    recording = decimated(recording, factor)
    say = progress or (lambda text: None)
    if factor > 1:
        say(f"decimated by {factor} ({factor_why}): {len(recording)} of {undecimated_n} samples")
    say(f"nominal fit: EKF ({passes} passes), then output-error refinement of the 8 coefficients")
    carried_noise = fit_rate_noise_std_m(record_rate, factor)  # None: read at the fits' rate
    ctx = build_context(recording, rig, config, passes=passes, noise_std_m=carried_noise)
    _, ho0, sol0 = exact_nominal(ctx)
    rk = rank_effects(ctx, library, progress=say)
    if rk.nominal_coefficients is not None:
        # a re-polish from an effect's refit found a better optimum of the nominal model than its own fit: the
        # nominal reported (its coefficients, residual and uncertainty) is that one, the one the evidence of every
        # effect is measured against (seen: the first nominal fit at kxx 8x and kyy negative, a clearance
        # contact's record, its coefficients reported 2e9 stds off)
        ctx = recentered(ctx, rk.nominal_coefficients)
        _, ho0, sol0 = exact_nominal(ctx)
        rk = replace(rk, nominal_rss_m2=sol0.rss_m2, nominal_held_out_rms_m=ho0)  # what the report compares with
    where = budget(ctx.t_s[ctx.mask], (ctx.y_m - sol0.prediction_m)[ctx.mask], ctx.shaft.angle_rad[ctx.mask],
                   ctx.shaft.speed_rad_s[ctx.mask], ctx.impact_force_n[ctx.mask], ctx.noise_std_m)
    innov = innovation_consistency(ctx.ekf_nis, ctx.ekf_innovation_m, ctx.ekf_innovation_std_m)
    # the coefficients' column carries the start transient's dependence on them too (a record from rest)
    cov_ctx = replace(ctx, jacobian=ctx.jacobian + start_transient_sensitivity(ctx, sol0.start_state))
    nominal_cov = parameter_covariance(cov_ctx, np.zeros((ctx.t_s.size, 4, 0)), np.zeros((ctx.t_s.size, 4, 0)),
                                       sol0.prediction_m)
    nominal_cov_si = nominal_cov[:8, :8] * np.outer(COEFFICIENT_SCALE, COEFFICIENT_SCALE)
    if rk.best is None:  # the nominal model is the verdict: its coefficients' likelihood profile too
        say("coefficient uncertainty: likelihood profiles of the nominal model")
        nominal_cov_si = profiled_or_local(ctx, None, ctx.coefficients, np.zeros(0), nominal_cov_si)
        if only_steady_1x(ctx):  # a curved valley of coefficient sets: its posterior drawn instead
            say("coefficient uncertainty: posterior draws of the nominal model (one steady speed, no impact)")
            nominal_cov_si = sampled_coefficient_cov(ctx, None, ctx.coefficients, np.zeros(0), nominal_cov_si)
        # and the spread of the other models' optima, weighted by their evidence
        nominal_cov_si = coefficients_cov_over_models(ctx.coefficients, nominal_cov_si, rk.nominal_bic,
                                                      [*rk.singles, *rk.pairs])
    nominal_std = np.sqrt(np.abs(np.diag(nominal_cov_si)))
    table = [_row(ctx, "nominal", sol0.prediction_m, ho0, ctx.coefficients, nominal_std)]
    shown = []
    if rk.best is not None:
        shown.append(("+ " + rk.best.name, rk.best))
    runner = next((f for f in rk.singles if rk.best is None or f.name != rk.best.name), None)
    if runner is not None:
        shown.append(("+ " + runner.name + " (runner-up)", runner))
    if rk.second is not None:
        shown.append(("+ " + rk.best.name + " + " + rk.second.name, rk.second))
    for label, fit in shown:
        table.append(_row(ctx, label, fit.prediction_m, fit.held_out_rms_m, fit.coefficients, fit.coefficients_std))
    data = data_accounting(recording, ctx)
    data["nominal_slowest_decay_1_per_s"], stability_warnings = nominal_stability(ctx)
    data["warnings"] += stability_warnings
    data["decimation"] = {**(recording.meta["decimation"] if factor > 1 else {"factor": 1}), "requested": decimate,
                          "why": factor_why, "samples_before": undecimated_n,
                          "sample_rate_hz": float(1.0 / np.median(np.diff(recording.time_s()))),
                          "noise_floor_read_at": "the fits' rate" if carried_noise is None else
                          "the record's rate, times the filter's white-noise gain"}
    if window is not None:
        data["analysis_window"] = window
        data["samples_in_record"] = full_n
        data["warnings"].append(f"the record is {window['record_s']:.3g} s long: the fits ran on "
                                f"{window['start_s']:.3f}-{window['stop_s']:.3f} s, {window['rule']} (memory and time "
                                f"bound); diagnose other spans by cutting the record")
    source = recording.meta.get("source") if isinstance(getattr(recording, "meta", None), dict) else None
    record_noise = record_rate_noise_std_m(record_rate, ctx.mean_speed_rad_s) if factor > 1 else None
    if record_noise is not None:  # the fits' figures, at the rate they ran at
        data["decimation"]["noise_std_m_at_fit_rate"] = float(np.sqrt(np.mean(ctx.noise_std_m ** 2)))
        data["decimation"]["noise_std_m_at_record_rate"] = float(np.sqrt(np.mean(record_noise ** 2)))
    found = Diagnosis(ctx=ctx, ranking=rk, where=where, innovations=innov, nominal_prediction_m=sol0.prediction_m,
                      table=table, data=data, source=None if source is None else str(source),
                      record_noise_std_m=record_noise)
    if rk.best is not None:
        data["warnings"] += verdict_stability_warnings(found.verdict_row(), fitted_span_s(ctx))
        verdict = rk.second or rk.best
        names = [rk.best.name] + ([rk.second.name] if rk.second else [])
        k = rk.best.n_params + (rk.second.n_params if rk.second else 0)
        data["warnings"] += prior_driven_warnings(rk.nominal_rss_m2, verdict.rss_m2, verdict.n_obs, k, names)
    return found


def record_rate_noise_std_m(recording: RigRecording, mean_speed_rad_s: float) -> np.ndarray:
    """(4,) noise std per channel (m) of ``recording`` at its own rate, read as the fits read theirs (the band
    above 0.3 of the rate or 10x the speed, :func:`.context.noise_std_from_spectrum`): the rotor's response is
    far below it. Rows with a non-finite probe sample are left out."""
    from rotor_estimator.diagnosis.context import noise_band_low_hz, noise_std_from_spectrum

    y = recording.probes_m[np.all(np.isfinite(recording.probes_m), axis=1)]
    rate_hz = 1.0 / (float(np.median(np.diff(recording.stamps_ns))) * 1e-9)
    return noise_std_from_spectrum(y - y.mean(axis=0), rate_hz, noise_band_low_hz(rate_hz, mean_speed_rad_s))


def prior_driven_warnings(nominal_rss_m2: float, verdict_rss_m2: float, n_obs: int, n_params: int,
                          names: list[str]) -> list[str]:
    """A warning when the verdict's evidence comes from the coefficient prior rather than the data: its fit to
    the record, ``n ln(RSS_nominal / RSS_verdict)``, does not pay for its ``n_params`` parameters
    (``n_params ln n``, BIC's price), so what wins it the threshold is that its coefficients sit nearer the rig
    file's prior r0 than the nominal model's.

    Seen on an independent record at one steady speed without an impact (a one-channel delay of a few samples,
    1.5x gap): residual unbalance won by 37.5 in BIC with a residual RMS 1.00002 times smaller. Such a record
    holds only the 1X, which unbalance, a keyphasor offset, probe gain and orientation, a channel delay and 1X
    runout all change; the prior may prefer one, the data do not."""
    if n_obs <= 0 or not (nominal_rss_m2 > 0 and verdict_rss_m2 > 0):
        return []
    data_gain = n_obs * float(np.log(nominal_rss_m2 / verdict_rss_m2))
    price = n_params * float(np.log(n_obs))
    if data_gain >= price:
        return []
    return [f"the verdict ({' + '.join(names)}) fits the record no better than the nominal model for its "
            f"{n_params} parameters (data evidence {data_gain:.1f} against their price {price:.1f} in BIC): it wins on "
            "the bearing coefficient prior, its coefficients nearer the rig file's r0. The data do not tell it "
            "from other effects of the same signature (at one steady speed without an impact: unbalance, keyphasor "
            "offset, probe gain and orientation, a channel delay, 1X runout); record an impact or a second speed"]


def verdict_stability_warnings(row: dict, span_s: float) -> list[str]:
    """A warning when a table row's coefficients put the rigid rotor at or beyond its stability limit at the
    record's speed (:func:`at_stability_limit` over the fitted ``span_s``).

    The joint refits wall unstable rotors off, so a verdict's optimum can sit on the wall (seen on a record
    without an impact, whose steady 1X pins the coefficients down poorly): the data, through that effect's
    model, pull toward a rotor the rig's bounded response rules out."""
    decay = row["slowest_decay_1_per_s"]
    if not at_stability_limit(decay, span_s):
        return []
    return [f"the verdict's bearing coefficients put the rigid rotor at or beyond its stability limit at the "
            f"record's speed (slowest mode {decay:.3g} 1/s, over {span_s:.3g} s fitted): the data do not pin them "
            "down (often a record without an impact); do not use them as bearing estimates"]


