# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Figures for identification (matplotlib, imported lazily; kept out of the numerical modules)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from rotor_estimator.identification.speed_dependent import RPM, SpeedTable
from rotor_estimator.io.safe_write import output_directory, save_figure


def coefficients_vs_speed(tab: SpeedTable, path: str | Path, *, truth: SpeedTable | None = None,
                          title: str = "Bearing coefficients versus speed (95% confidence band)") -> Path:
    """One panel per coefficient: estimate, 95% band and (optionally) the true curve."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(tab.names)
    cols = 4
    rows = int(np.ceil(n / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(4 * cols, 3 * rows), squeeze=False)
    rpm = tab.speeds_rad_s / RPM
    for j, name in enumerate(tab.names):
        ax = axes[j // cols, j % cols]
        ax.fill_between(rpm, tab.lower95()[:, j], tab.upper95()[:, j], alpha=0.3, label="95% band")
        ax.plot(rpm, tab.values[:, j], label="estimate")
        if truth is not None:
            ax.plot(truth.speeds_rad_s / RPM, truth.values[:, j], "k--", label="true")
        ax.set_title(name)
        ax.set_xlabel("speed (rpm)")
    axes[0, 0].legend(fontsize=7)
    fig.suptitle(title)
    fig.tight_layout()
    path = output_directory(Path(path).parent, "--plots") / Path(path).name
    save_figure(fig, path, dpi=110)
    plt.close(fig)
    return path
