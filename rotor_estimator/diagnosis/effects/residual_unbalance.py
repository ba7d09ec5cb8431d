# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Residual unbalance: rotating masses in the rig's two correction planes (a 1X force)."""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from rotor_estimator.diagnosis.effects.base import UNIT_UNBALANCE_KG_M, Effect, unbalance_force, unbalance_planes


@dataclass(frozen=True)
class ResidualUnbalance(Effect):
    """Unknown residual unbalance in two correction planes (1X forcing through Eq. 2)."""

    forcing: ClassVar[bool] = True
    name: ClassVar[str] = "residual_unbalance"
    kind: ClassVar[str] = "force"
    refit_always: ClassVar[bool] = True
    responses: ClassVar[dict[str, str]] = {
        "slow_roll": "vanishes (force grows as speed^2)",
        "speed_change": "1X grows as speed^2 through the dynamic stiffness",
        "trial_weight": "unchanged (the trial response adds to it)",
    }
    description: ClassVar[str] = "unknown residual unbalance in two planes (1X forward forcing)"

    def lin_names(self, ctx):
        return ("u1_cos_g_mm", "u1_sin_g_mm", "u2_cos_g_mm", "u2_sin_g_mm")

    def basis(self, ctx, nl):
        return None, ctx.responses([unbalance_force(ctx, s, ph, UNIT_UNBALANCE_KG_M)
                                    for s in unbalance_planes(ctx) for ph in (0.0, np.pi / 2)])

    def physical(self, nl, lin):
        u1, u2 = complex(lin[0], lin[1]), complex(lin[2], lin[3])
        return {"plane1_unbalance_g_mm": abs(u1), "plane1_phase_deg": float(np.degrees(np.angle(u1))),
                "plane2_unbalance_g_mm": abs(u2), "plane2_phase_deg": float(np.degrees(np.angle(u2)))}
