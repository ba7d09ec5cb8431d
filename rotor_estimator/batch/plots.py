# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Summary figure of a batch table (matplotlib, Agg backend, written through safe_write).

replay/identify: each coefficient against the recording's speed (or start date) with 1-sigma error
bars; diagnose: verdict counts and shrink against the gap; virtual-sensing: coverage per recording.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from rotor_estimator.batch.table import COEFFICIENT_COLUMNS, COEFFICIENT_STD_COLUMNS, OK, normalize
from rotor_estimator.core.config import COEFFICIENT_NAMES, COEFFICIENT_UNITS
from rotor_estimator.core.errors import InputError

#: x axes of the coefficient figure.
X_AXES = ("speed", "date")


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _num(value: float | None) -> float:
    return math.nan if value is None else float(value)


def _x_values(rows: list[dict], x: str) -> tuple[list, str]:
    if x == "speed":
        return [_num(r["speed_rpm"]) for r in rows], "speed (rpm)"
    import datetime

    values = [datetime.datetime.fromisoformat(r["recording_start_utc"]) if r["recording_start_utc"] else None
              for r in rows]
    return values, "recording start (UTC)"


def plot_table(rows: list[dict], command: str, path: str | Path, *, x: str = "speed") -> Path:
    """Write the summary figure of ``rows`` (a ``command`` table) to ``path``; returns the path."""
    from rotor_estimator.io.safe_write import save_figure

    if x not in X_AXES:
        raise InputError(f"--x must be one of {', '.join(X_AXES)}, got {x!r}")
    plt = _pyplot()
    rows = [normalize(r, command) for r in rows]
    ok = [r for r in rows if r["status"] == OK]
    n_err = len(rows) - len(ok)
    title = f"batch {command}: {len(ok)} ok, {n_err} error(s)"
    if command in ("replay", "identify"):
        if x == "date":
            ok = [r for r in ok if r["recording_start_utc"]]
        xs, xlabel = _x_values(ok, x)
        fig, axes = plt.subplots(2, 4, figsize=(14, 6), sharex=True)
        for ax, col, std, name, unit in zip(axes.ravel(), COEFFICIENT_COLUMNS, COEFFICIENT_STD_COLUMNS,
                                            COEFFICIENT_NAMES, COEFFICIENT_UNITS):
            ys = [_num(r[col]) for r in ok]
            es = [_num(r[std]) for r in ok]
            ax.errorbar(xs, ys, yerr=es, fmt="o", ms=3, capsize=2)
            ax.set_title(f"{name} ({unit}), 1-sigma bars", fontsize=9)
            ax.grid(True, alpha=0.3)
        for ax in axes[1]:
            ax.set_xlabel(xlabel)
        if x == "date":
            fig.autofmt_xdate()
    elif command == "diagnose":
        fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4))
        counts: dict[str, int] = {}
        for r in ok:
            counts[r["verdict"]] = counts.get(r["verdict"], 0) + 1
        names = sorted(counts, key=lambda k: (-counts[k], k))
        a1.bar(range(len(names)), [counts[k] for k in names])
        a1.set_xticks(range(len(names)), names, rotation=30, ha="right", fontsize=8)
        a1.set_ylabel("recordings")
        a1.set_title("verdicts")
        a2.scatter([_num(r["gap_ratio_before"]) for r in ok], [_num(r["shrink_ratio"]) for r in ok], s=12)
        a2.set_xlabel("gap: residual RMS / noise before")
        a2.set_ylabel("shrink ratio (before / after)")
        a2.grid(True, alpha=0.3)
    elif command == "virtual-sensing":
        fig, ax = plt.subplots(figsize=(8, 4))
        ax.plot(range(len(ok)), [_num(r["coverage_mean"]) for r in ok], "o", label="mean coverage")
        ax.plot(range(len(ok)), [_num(r["coverage_min"]) for r in ok], "v", label="lowest channel")
        if ok:
            ax.axhline(ok[0]["confidence"], color="k", lw=0.8, ls="--", label="nominal")
        ax.set_xlabel("recording (table order)")
        ax.set_ylabel("interval coverage")
        ax.legend(fontsize=8)
    else:
        raise InputError(f"no figure for a {command!r} table")
    fig.suptitle(title)
    fig.tight_layout()
    try:
        return save_figure(fig, path, dpi=110)
    finally:
        plt.close(fig)
