# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Probe calibration: gain and mounting-angle errors of each probe."""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from rotor_estimator.diagnosis.effects.base import CHANNELS, Effect


@dataclass(frozen=True)
class ProbeGainOrientation(Effect):
    """Sensitivity and mounting-angle error of each probe: a general 2x2 map per probe plane.

    A probe at angle error ``d_i`` with gain error ``g_i`` reads
    ``(1 + g_i) (x cos d_i + y sin d_i)`` (x probe) or ``(1 + g_i) (-x sin d_i + y cos d_i)``
    (y probe): each plane's pair is the exact linear map ``[x', y'] = A_p [x, y]`` with
    4 free entries (per-probe gain and angle, so non-orthogonal probes too), fitted as
    ``A_p - I`` on the nominal output, its start transient included (:attr:`.FitContext.motion_m`): the
    map acts on every motion the probe sees, and in a record from rest the decay from the initial state is
    as large as the periodic response at first (an independent record from rest, one probe turned 17.7 deg:
    with the map on the periodic response alone its joint refit moved cyx 112 % and read the other three
    probes 1.0-1.3 deg off, 3 std; with the transient 8.7 % and 0.05-0.4 deg).

    Its other forms (:meth:`variants`, ``probe`` set) are one probe's row of its plane's map alone (its gain and
    angle, 2 parameters): a loose or mis-set probe is one probe, and the eight-entry map pays for six the data
    do not need (an independent record of one probe turned 20 deg, with an impact: the map fitted 26 better in
    ``-2 ln L`` than a four-channel delay and lost to it on BIC by 14, seed 7430 case 32).
    """

    #: Index into :data:`CHANNELS` of the one probe this form maps; ``None``: every probe (two 2x2 maps).
    probe: int | None = None

    name: ClassVar[str] = "probe_gain_orientation"
    kind: ClassVar[str] = "measurement"
    responses: ClassVar[dict[str, str]] = {
        "probe_calibration": "the calibration shows the gain or angle error",
    }
    description: ClassVar[str] = "probe gain and mounting-angle error per probe (2x2 map per probe plane)"

    def variants(self):
        return (ProbeGainOrientation(), *(ProbeGainOrientation(c) for c in range(len(CHANNELS))))

    @property
    def form(self) -> str:
        return "every probe (a 2x2 map per plane)" if self.probe is None else f"probe {CHANNELS[self.probe]} alone"

    def _entries(self) -> tuple[int, ...]:
        """The map entries fitted, as indices into the full form's 8 (plane p: 4p + (axx, axy, ayx, ayy))."""
        if self.probe is None:
            return tuple(range(8))
        first = 4 * (self.probe // 2) + 2 * (self.probe % 2)  # an x probe's row (axx, axy), a y probe's (ayx, ayy)
        return (first, first + 1)

    def lin_names(self, ctx):
        names = tuple(f"{plane}_{entry}" for plane in ("p1", "p2")
                      for entry in ("axx_minus_1", "axy", "ayx", "ayy_minus_1"))
        return tuple(names[i] for i in self._entries())

    def basis(self, ctx, nl):
        y = ctx.motion_m
        cols = np.zeros((y.shape[0], 4, 8))
        for p in range(2):
            x_c, y_c = 2 * p, 2 * p + 1
            cols[:, x_c, 4 * p] = y[:, x_c]
            cols[:, x_c, 4 * p + 1] = y[:, y_c]
            cols[:, y_c, 4 * p + 2] = y[:, x_c]
            cols[:, y_c, 4 * p + 3] = y[:, y_c]
        return None, cols[:, :, list(self._entries())]

    def physical(self, nl, lin):
        full = np.zeros(8)
        full[list(self._entries())] = lin
        out = {}
        for p in range(2):
            axx, axy, ayx, ayy = 1 + full[4 * p], full[4 * p + 1], full[4 * p + 2], 1 + full[4 * p + 3]
            x_ch, y_ch = CHANNELS[2 * p], CHANNELS[2 * p + 1]
            out[f"gain_error_{x_ch}"] = float(np.hypot(axx, axy) - 1)
            out[f"gain_error_{y_ch}"] = float(np.hypot(ayx, ayy) - 1)
            out[f"angle_error_{x_ch}_deg"] = float(np.degrees(np.arctan2(axy, axx)))
            out[f"angle_error_{y_ch}_deg"] = float(np.degrees(np.arctan2(-ayx, ayy)))
        if self.probe is None:
            return out
        ch = CHANNELS[self.probe]
        return {k: v for k, v in out.items() if k in (f"gain_error_{ch}", f"angle_error_{ch}_deg")}
