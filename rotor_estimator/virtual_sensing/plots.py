# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Figures of a virtual-sensing run (``rotor-estimator virtual-sensing --report DIR``).

* ``orbit_<station>.png``: the estimated displacement orbit at each station over the
  last revolutions, with the ``confidence`` uncertainty ellipse drawn at points around
  it (and the true orbit when known, e.g. on synthetic data).
* ``loo_<sensor>.png``: leave-one-station-out time traces: the prediction of each
  hidden channel with its ``confidence`` band (including the sensor's own noise) against
  the hidden measurement.
* ``leave_one_out.txt``: the table.

Matplotlib's Agg canvas is used directly (no pyplot, no global backend switch), so this
works headless and inside other programs. Plotting is kept out of the numerical core.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Sequence

import numpy as np

from rotor_estimator.io.safe_write import output_directory, save_figure, write_text
from rotor_estimator.virtual_sensing.estimator import (HiddenTrace, LeaveOneOutReport, StationEstimate,
                                                      confidence_ellipse)

__all__ = ["plot_station_orbit", "plot_hidden_trace", "write_report"]

_SCALE = {"m": (1e6, "µm"), "m/s^2": (1.0, "m/s²")}


def _figure(width: float, height: float):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _window(n: int, samples_per_rev: float, revolutions: float) -> slice:
    k = int(min(n, max(8, round(revolutions * samples_per_rev))))
    return slice(n - k, n)


def plot_station_orbit(est: StationEstimate, path: str | Path, *, samples_per_rev: float, confidence: float = 0.95,
                       revolutions: float = 3.0, truth_xy_m: np.ndarray | None = None, n_ellipses: int = 16) -> Path:
    """Orbit (x, y in µm) over the last ``revolutions`` with ``n_ellipses`` uncertainty
    ellipses spread over the last revolution; ``truth_xy_m`` (N, 2) overlays the truth."""
    from matplotlib.patches import Ellipse

    sl = _window(len(est.t_s), samples_per_rev, revolutions)
    s = 1e6
    fig = _figure(5.5, 5.2)
    ax = fig.add_subplot()
    x, y = est.mean[sl, 0] * s, est.mean[sl, 1] * s
    ax.plot(x, y, color="C0", lw=1.2, label="estimate")
    if truth_xy_m is not None:
        ax.plot(truth_xy_m[sl, 0] * s, truth_xy_m[sl, 1] * s, color="k", lw=0.8, ls="--", label="truth")
    last = np.arange(len(est.t_s))[sl][-int(min(len(x), max(1, round(samples_per_rev)))):]
    for k in last[:: max(1, len(last) // n_ellipses)]:
        a, b, ang = confidence_ellipse(est.disp_cov[k], confidence)
        ax.add_patch(Ellipse((est.mean[k, 0] * s, est.mean[k, 1] * s), 2 * a * s, 2 * b * s,
                             angle=math.degrees(ang), fill=False, color="C3", lw=0.8))
    ax.plot([], [], color="C3", lw=0.8, label=f"{100 * confidence:.0f}% ellipse")
    a, b, _ = confidence_ellipse(est.disp_cov[-1], confidence)
    ax.set_title(f"{est.name} (z = {est.station_axial_m:g} m): orbit, {100 * confidence:.0f}% ellipse "
                 f"{2 * a * s:.2g} x {2 * b * s:.2g} µm", fontsize=9)
    ax.set_xlabel("x displacement (µm)")
    ax.set_ylabel("y displacement (µm)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, loc="upper right")
    path = Path(path)
    save_figure(fig, path, dpi=110)
    return path


def plot_hidden_trace(trace: HiddenTrace, t_s: np.ndarray, path: str | Path, *, samples_per_rev: float,
                      confidence: float = 0.95, revolutions: float = 4.0, coverage: Sequence[float] = ()) -> Path:
    """Prediction of each hidden channel with its band vs the hidden measurement over the
    last ``revolutions``; ``coverage`` (per channel) goes into the titles."""
    t = np.asarray(t_s, dtype=float)
    sl = _window(len(t), samples_per_rev, revolutions)
    fig = _figure(8.0, 2.4 * len(trace.channels))
    axes = fig.subplots(len(trace.channels), 1, sharex=True, squeeze=False)[:, 0]
    for j, (ax, ch, unit) in enumerate(zip(axes, trace.channels, trace.units)):
        scale, label = _SCALE.get(unit, (1.0, unit))
        tt = t[sl] - t[0]
        mean, half = trace.predicted[sl, j] * scale, trace.half_width[sl, j] * scale
        ax.fill_between(tt, mean - half, mean + half, color="C0", alpha=0.25, lw=0,
                        label=f"{100 * confidence:.0f}% interval")
        ax.plot(tt, mean, color="C0", lw=1.0, label="predicted from the other sensors")
        ax.plot(tt, trace.measured[sl, j] * scale, ".", color="k", ms=2.0, label="hidden measurement")
        cov = f", coverage {coverage[j]:.3f}" if j < len(coverage) else ""
        ax.set_title(f"{ch} hidden{cov}", fontsize=9)
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
    axes[0].legend(fontsize=7, loc="upper right", ncol=3)
    axes[-1].set_xlabel("time (s)")
    path = Path(path)
    save_figure(fig, path, dpi=110)
    return path


def write_report(directory: str | Path, estimates: Sequence[StationEstimate], report: LeaveOneOutReport | None,
                 t_s: np.ndarray, *, speed_rad_s: float, sample_rate_hz: float, confidence: float = 0.95,
                 truth: dict[str, np.ndarray] | None = None) -> list[Path]:
    """Write every figure (and ``leave_one_out.txt``) into ``directory``; return the paths.
    ``truth``: optional ``{station name: (N, 2) true displacement}``."""
    out = output_directory(directory, "--report")
    spr = sample_rate_hz * 2 * math.pi / speed_rad_s if speed_rad_s > 0 else 256.0
    paths = [plot_station_orbit(e, out / f"orbit_{e.name}.png", samples_per_rev=spr, confidence=confidence,
                                truth_xy_m=None if truth is None else truth.get(e.name))
             for e in estimates]
    if report is not None:
        for tr in report.traces:
            cov = [r.coverage_measured for r in report.rows if r.sensor == tr.sensor]
            paths.append(plot_hidden_trace(tr, t_s, out / f"loo_{tr.sensor}.png", samples_per_rev=spr,
                                           confidence=confidence, coverage=cov))
        write_text(out / "leave_one_out.txt", report.format_table() + "\n")
        paths.append(out / "leave_one_out.txt")
    return paths
