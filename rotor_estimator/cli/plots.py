# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Figures (matplotlib, Agg backend). Reporting only: nothing here feeds back into the core."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from rotor_estimator.core.config import COEFFICIENT_NAMES, RigConfig
from rotor_estimator.core.model import rotor_matrices
from rotor_estimator.io.safe_write import save_figure


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def coefficient_error_history(t_s: np.ndarray, history: np.ndarray, true: np.ndarray, path: Path,
                              title: str) -> Path:
    """Percent error of each coefficient vs time (like Miller & Howard's Fig. 4)."""
    plt = _pyplot()
    fig, axes = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    err = 100 * (history - true) / np.abs(true)
    for i, name in enumerate(COEFFICIENT_NAMES):
        ax = axes[0] if name.startswith("k") else axes[1]
        ax.plot(t_s * 1e3, err[:, i], label=name)
    for ax, label in zip(axes, ("stiffness", "damping")):
        ax.axhline(0, color="k", lw=0.5)
        ax.set_ylabel(f"{label} error (%)")
        ax.set_ylim(-100, 100)
        ax.legend(ncol=4, fontsize=8)
        ax.grid(alpha=0.3)
    axes[1].set_xlabel("time after first processed sample (ms)")
    fig.suptitle(title)
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
    plt.close(fig)
    return path


def orbit_comparison(rig: RigConfig, measured_probes_m: np.ndarray, resimulated_probes_m: np.ndarray,
                     samples_per_rev: int, path: Path, title: str) -> Path:
    """One revolution of the bearing-2 orbit: measured (noisy) vs re-simulated (like Fig. 5)."""
    plt = _pyplot()
    t_from_p = rotor_matrices(rig).bearing_from_probe
    meas = measured_probes_m[-samples_per_rev:] @ t_from_p.T
    sim = resimulated_probes_m[-samples_per_rev:] @ t_from_p.T
    fig, ax = plt.subplots(figsize=(5, 5))
    ax.plot(meas[:, 2] * 1e6, meas[:, 3] * 1e6, ".", ms=3, label="measured (noisy)")
    ax.plot(sim[:, 2] * 1e6, sim[:, 3] * 1e6, "-", label="re-simulated with estimates")
    ax.set_xlabel("x2 (um)")
    ax.set_ylabel("y2 (um)")
    ax.set_aspect("equal")
    ax.legend(fontsize=8)
    ax.set_title(title, fontsize=9)
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
    plt.close(fig)
    return path
