# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""The diagnosis report: Markdown with PNG figures (matplotlib Agg) and the JSON summary.

Plotting lives here, not in the numerical modules. Figures: residual spectra before and
after the winning effect (per probe channel), measured vs model orbits (both probe
planes, last two revolutions), the evidence ranking (delta BIC, log scale).
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from rotor_estimator.io.safe_write import output_directory, save_figure, write_text
from rotor_estimator.diagnosis.api import Diagnosis
from rotor_estimator.diagnosis.ranking import SIGNIFICANCE_DELTA_BIC
from rotor_estimator.diagnosis.residuals import CHANNELS


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


#: Orders marked on the residual spectra (1X is the shaft speed).
MARKED_ORDERS = (1, 2, 3, 4)


def residual_spectra(d: Diagnosis) -> dict:
    """Welch amplitude spectral density (m/sqrt(Hz), one-sided) of the residual before and after the verdict, per
    channel, with the white-noise floor each channel's noise std implies (``sigma sqrt(2 / fs)``) and the
    order frequencies: what :func:`plot_spectra` draws."""
    from scipy.signal import welch

    ctx = d.ctx
    fs = ctx.sample_rate_hz
    models = {"nominal": ctx.y_m - d.nominal_prediction_m}
    if d.after_fit is not None:
        models["+ " + " + ".join(d.verdict_set)] = ctx.y_m - d.after_fit.prediction_m
    n = int(ctx.mask.sum())
    seg = int(min(n, max(256, 8 * round(2 * np.pi / ctx.mean_speed_rad_s * fs))))  # >= 8 revolutions a segment
    out: dict = {"asd_m_per_sqrt_hz": {}, "noise_floor_m_per_sqrt_hz": ctx.noise_std_m * np.sqrt(2.0 / fs),
                 "order_hz": {f"{k}X": k * ctx.mean_speed_rad_s / (2 * np.pi) for k in MARKED_ORDERS}}
    for label, e in models.items():
        f, psd = welch(e[ctx.mask], fs=fs, nperseg=seg, axis=0, detrend="constant")
        out["frequency_hz"] = f
        out["asd_m_per_sqrt_hz"][label] = np.sqrt(psd)
    return out


def plot_spectra(d: Diagnosis, path: Path) -> None:
    """Residual spectra (Welch) before / after, the noise floor, and the 1X-4X order markers."""
    plt = _plt()
    spec = residual_spectra(d)
    f = spec["frequency_hz"]
    fig, axes = plt.subplots(2, 2, figsize=(10, 6), sharex=True)
    f_max = min(f[-1], (MARKED_ORDERS[-1] + 2) * spec["order_hz"]["1X"])
    for c, ax in enumerate(axes.ravel()):
        for label, asd in spec["asd_m_per_sqrt_hz"].items():
            ax.semilogy(f, asd[:, c] + 1e-18, lw=0.8, label=label)
        ax.axhline(spec["noise_floor_m_per_sqrt_hz"][c], color="k", ls=":", lw=0.8, label="noise floor")
        for name, fo in spec["order_hz"].items():
            if fo < f_max:
                ax.axvline(fo, color="tab:gray", lw=0.5, alpha=0.6)
                ax.text(fo, 1.0, name, transform=ax.get_xaxis_transform(), ha="center", va="bottom", fontsize=7)
        ax.set_title(CHANNELS[c], pad=12)
        ax.set_xlim(0, f_max)
        ax.grid(True, alpha=0.3)
    axes[1, 0].set_xlabel("frequency (Hz)")
    axes[1, 1].set_xlabel("frequency (Hz)")
    axes[0, 0].set_ylabel("residual ASD (m/sqrt(Hz))")
    axes[1, 0].set_ylabel("residual ASD (m/sqrt(Hz))")
    axes[0, 0].legend(fontsize=7)
    fig.suptitle("Residual spectra (Welch) before / after the verdict, with the noise floor and shaft orders")
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
    plt.close(fig)


def plot_orbits(d: Diagnosis, path: Path) -> None:
    plt = _plt()
    ctx = d.ctx
    spr = int(round(2 * np.pi / ctx.mean_speed_rad_s * ctx.sample_rate_hz))
    idx = np.flatnonzero(ctx.mask)[-2 * spr:]
    fig, axes = plt.subplots(1, 2, figsize=(10, 4.5))
    for p, ax in enumerate(axes):
        x, y = 2 * p, 2 * p + 1
        ax.plot(ctx.y_m[idx, x] * 1e6, ctx.y_m[idx, y] * 1e6, ".", ms=2, label="measured")
        ax.plot(d.nominal_prediction_m[idx, x] * 1e6, d.nominal_prediction_m[idx, y] * 1e6, lw=1, label="nominal model")
        if d.after_fit:
            ax.plot(d.after_fit.prediction_m[idx, x] * 1e6, d.after_fit.prediction_m[idx, y] * 1e6, lw=1, ls="--",
                    label=f"+ {d.best_effect}")
        ax.set_title(f"probe plane {p + 1}")
        ax.set_xlabel("x (um)")
        ax.set_ylabel("y (um)")
        ax.axis("equal")
        ax.grid(True, alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.suptitle("Orbits, last two revolutions: measured vs model")
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
    plt.close(fig)


#: Pairs shown in the ranking plot (best first).
PLOTTED_PAIRS = 3


def ranking_bars(d: Diagnosis) -> list[tuple[str, float, str]]:
    """``(label, delta BIC against the nominal, role)`` of every single and the best pairs, best first; role is
    ``verdict``, ``tied``, ``pair`` or ``other``. Negative evidence is kept as it is (an effect that fits
    worse than its parameter cost), not clipped."""
    verdict = set(d.verdict_set)
    tied = {f.name for f in d.ranking.tied}
    bars = []
    for f in d.ranking.singles:
        role = "tied" if f.name in tied else ("verdict" if f.name in verdict and len(verdict) == 1 else "other")
        bars.append((f.name, float(f.delta_bic), role))
    for p in d.ranking_pairs(PLOTTED_PAIRS):
        role = "verdict" if set(p["effects"]) == verdict else "pair"
        bars.append((" + ".join(p["effects"]), float(p["delta_bic"]), role))
    return sorted(bars, key=lambda b: -b[1])


def plot_ranking(d: Diagnosis, path: Path) -> None:
    """Signed evidence of every candidate on a symmetric-log axis (negative evidence to the left of zero)."""
    plt = _plt()
    bars = ranking_bars(d)[::-1]
    colors = {"verdict": "tab:red", "tied": "tab:orange", "pair": "tab:blue", "other": "tab:gray"}
    fig, ax = plt.subplots(figsize=(8, 0.3 * len(bars) + 1.5))
    ax.barh([b[0] for b in bars], [b[1] for b in bars], color=[colors[b[2]] for b in bars])
    threshold = SIGNIFICANCE_DELTA_BIC  # the decision rule's (d.summary() would recompute the whole summary)
    ax.axvline(threshold, color="k", ls="--", lw=0.8, label=f"significance ({threshold:g})")
    ax.axvline(0.0, color="k", lw=0.6)
    ax.set_xscale("symlog", linthresh=10.0)
    ax.set_xlabel("evidence: BIC(nominal) - BIC(model)   (red: verdict, orange: tied, blue: pairs)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
    plt.close(fig)


def _fmt_um(v: float) -> str:
    return f"{v * 1e6:.3f}"


def markdown(d: Diagnosis, summary: dict) -> str:
    w = summary["where"]
    lines = ["# Sim-to-real gap diagnosis", ""]
    prov = summary.get("provenance")
    if prov:
        lines += [f"Record `{prov['source'] or 'unnamed'}` on rig `{prov['rig']}`: {prov['mean_speed_rpm']:.0f} rpm, "
                  f"{prov['duration_s']:.3g} s, {prov['impacts']} impact(s); rotor_estimator "
                  f"{prov['rotor_estimator_version']}, {prov['date_utc']} UTC.", ""]
    if summary.get("finding"):
        lines += [summary["finding"], ""]
    lines.append(f"**Verdict: `{summary['best_effect']}`**"
                 + (f" (second effect: `{summary['second_effect']}`)" if summary["second_effect"] != "none" else ""))
    tie = summary.get("tie")
    if tie:
        lines += ["", f"> **Tie:** `{tie['effects'][0]}` and `{tie['effects'][1]}` explain the data equally well "
                      f"(misfits -2 ln L differ by {tie['misfit_difference']:.1f} with {tie['parameters'][0]} and "
                      f"{tie['parameters'][1]} parameters: {tie['rule']}); the record cannot tell them apart, only "
                      "the parameter count would. Measurements that would:"]
        for m in tie["separating_measurements"]:
            lines.append(f"> - {m['measurement']} ({m['how']}): `{tie['effects'][0]}` {m[tie['effects'][0]]}; "
                         f"`{tie['effects'][1]}` {m[tie['effects'][1]]}")
    gap_left = summary.get("unexplained")
    if gap_left:
        lines += ["", f"> **Unexplained:** {gap_left['residual_over_noise']:.2f} x noise remains after the verdict: "
                      f"{gap_left['signature']}. An effect of this signature is not in the library, or the verdict "
                      "is incomplete."]
    lines.append("")
    lines.append(f"Residual RMS {_fmt_um(summary['residual_rms_before'])} um before, "
                 f"{_fmt_um(summary['residual_rms_after'])} um after; shrink ratio {summary['shrink_ratio']:.2f}; "
                 f"noise {_fmt_um(summary['noise_std_m'])} um (gap ratio {summary['gap_ratio_before']:.2f}).")
    data = summary["data"]
    lines.append("")
    lines.append(f"Data: {data['samples_used']} of {data['samples']} samples used ({data['non_finite_probe_samples']} "
                 f"non-finite, {data['outside_tachometer_span_samples']} outside the keyphasor's span, "
                 f"{data['warm_up_samples']} warm-up), {data['impacts']} impact(s).")
    dec = data.get("decimation")
    if dec and dec["factor"] > 1:
        lines.append(f"Decimated by {dec['factor']} to {dec['sample_rate_hz']:.0f} Hz before the fits "
                     f"({dec['why']}; the {dec['edge_samples']} samples at each end, where the filter runs off "
                     f"the record, {dec['edges']}: {dec['edges_why']}; `--decimate 1` keeps the full rate). "
                     "The residual RMS, noise and gap ratio above are at the "
                     f"record's rate (noise {_fmt_um(dec['noise_std_m_at_record_rate'])} um); the tables below "
                     f"are at the fits' rate (noise {_fmt_um(dec['noise_std_m_at_fit_rate'])} um).")
    elif dec:
        lines.append(f"Full rate, {dec['sample_rate_hz']:.0f} Hz ({dec['why']}).")
    for text in data["warnings"]:
        lines += ["", f"> **Warning:** {text}."]
    lines += ["", "## 1. Where the gap lies", ""]
    lines.append(f"Dominant channel **{w['dominant_channel']}**, dominant band **{w['dominant_band']}**.")
    lines += ["", "| band | share of excess power | RMS (um) |", "|---|---|---|"]
    for r in w["bands"]:
        lines.append(f"| {r['band']} | {100 * r['share']:.1f} % | {_fmt_um(r['rms_m'])} |")
    lines += ["", "| channel | RMS (um) | excess over noise (um) | share |", "|---|---|---|---|"]
    for r in w["channels"]:
        lines.append(f"| {r['channel']} | {_fmt_um(r['rms_m'])} | {_fmt_um(r['excess_rms_m'])} "
                     f"| {100 * r['share']:.1f} % |")
    if w["nonsync_peaks"]:
        lines.append("")
        lines.append("Non-synchronous peaks: " + ", ".join(f"{p['frequency_hz']:.1f} Hz" for p in w["nonsync_peaks"]))
    lines += ["", "Whirl (orders 1X-3X, per plane, forward/backward amplitude in um):", ""]
    for plane, v in w["whirl"].items():
        lines.append(f"- {plane}: " + ", ".join(f"{k} {_fmt_um(o['forward_m'])}/{_fmt_um(o['backward_m'])}"
                                                 for k, o in v["orders"].items()))
    lines += ["", "Time segments:", ""]
    for r in w["time"]:
        lines.append(f"- {r['segment']}: {_fmt_um(r['rms_m'])} um over {r['samples']} samples")
    inn = summary["innovations"]
    lines += ["", f"EKF innovations: NIS mean {inn.get('nis_mean', float('nan')):.2f} (expected 4, "
                  f"{'consistent' if inn.get('consistent') else 'INCONSISTENT'}), "
                  f"{'white' if inn.get('white') else 'NOT white'} (Ljung-Box min p "
                  f"{min(inn.get('ljung_box_p', [float('nan')])):.2g}).", ""]
    lines += ["![residual spectra](spectra.png)", "", "![orbits](orbits.png)", ""]
    lines += ["## 2. Which effect", "", "| effect | delta BIC | params | held-out RMS (um) | residual RMS (um) |",
              "|---|---|---|---|---|"]
    for r in summary["ranking"]:
        lines.append(f"| {r['effect']} | {r['delta_bic']:.1f} | {r['n_params']} | {_fmt_um(r['held_out_rms_m'])} | "
                     f"{_fmt_um(r['residual_rms_m'])} |")
    if summary.get("ranking_pairs"):
        lines += ["", "Best pairs (delta BIC against the nominal model, as the singles; a pair is the verdict only "
                      f"when it beats the top single by {summary['decision_rule']['min_delta_bic']:g} too):", "",
                  "| pair | delta BIC | over the top single | params | held-out RMS (um) | residual RMS (um) |",
                  "|---|---|---|---|---|---|"]
        for r in summary["ranking_pairs"]:
            lines.append(f"| {' + '.join(r['effects'])} | {r['delta_bic']:.1f} | {r['delta_bic_over_top_single']:.1f} "
                         f"| {r['n_params']} | {_fmt_um(r['held_out_rms_m'])} | {_fmt_um(r['residual_rms_m'])} |")
    lines.append("")
    lines.append(f"Nominal held-out RMS {_fmt_um(summary['decision_rule']['nominal_held_out_rms_m'])} um; an effect "
                 f"counts when delta BIC >= {summary['decision_rule']['min_delta_bic']} and it predicts the held-out "
                 "last 40 % of the record no worse than the nominal model (within "
                 f"{100 * summary['decision_rule']['held_out_tolerance']:.1f} %).")
    pair = summary["second_effect"] != "none"
    for key, partner in (("best_effect_fit", summary["second_effect"]), ("second_effect_fit", summary["best_effect"])):
        fit = summary.get(key)
        if fit:
            jointly = f", estimated jointly with `{partner}`" if pair else ""
            lines += ["", f"Fitted parameters of `{fit['name']}` (value +- std{jointly}):", ""]
            for k, v in fit["parameters"].items():
                lines.append(f"- {k}: {v['value']:.6g} +- {v['std']:.2g}")
    lines += ["", "![ranking](ranking.png)", "", "## 3. How far it shrinks", "",
              "| model | RMS (um) | 1X | 2X | 3X | non-sync | broadband | output NIS | held-out (um) "
              "| kxx | kyy | cxx | cyy |",
              "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in summary["table"]:
        b, c = r["excess_band_rms_m"], r["coefficients"]
        lines.append(f"| {r['model']} | {_fmt_um(r['residual_rms_m'])} | {_fmt_um(b['1X'])} | {_fmt_um(b['2X'])} | "
                     f"{_fmt_um(b['3X'])} | {_fmt_um(b['nonsync_peaks'])} | {_fmt_um(b['broadband'])} | "
                     f"{r['output_nis_mean']:.2f} | {_fmt_um(r['held_out_rms_m'])} | {c['kxx_N_per_m']:.4g} | "
                     f"{c['kyy_N_per_m']:.4g} | {c['cxx_N_s_per_m']:.4g} | {c['cyy_N_s_per_m']:.4g} |")
    lines += ["", "Band columns are RMS in excess of the noise (um); output NIS is the mean of "
                  "sum_c e_c^2 / sigma_c^2 (4 when the model explains the data to the noise)."]
    names = list(summary["table"][0]["coefficients"])
    lines += ["", "Bearing coefficients, value +- std (N/m, N*s/m; the std is a sandwich estimate that allows for a "
                  "residual that is not white):", "",
              "| model | " + " | ".join(n.split("_")[0] for n in names) + " |",
              "|---|" + "---|" * len(names)]
    for r in summary["table"]:
        std = r.get("coefficients_std", {})
        lines.append(f"| {r['model']} | " + " | ".join(
            f"{r['coefficients'][n]:.4g} +- {std.get(n, float('nan')):.2g}" for n in names) + " |")
    return "\n".join(lines) + "\n"


def write_report(d: Diagnosis, out_dir: str | Path) -> dict:
    """Write ``report.md``, ``summary.json`` and the PNG figures into ``out_dir``; return the summary."""
    out = output_directory(out_dir, "--report")
    summary = d.summary()
    plot_spectra(d, out / "spectra.png")
    plot_orbits(d, out / "orbits.png")
    plot_ranking(d, out / "ranking.png")
    write_text(out / "summary.json", json.dumps(summary, indent=1))
    write_text(out / "report.md", markdown(d, summary))
    return summary
