# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Hammer force scale: a sensitivity error of the impact hammer's force channel."""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from rotor_estimator.diagnosis.effects.base import Effect


@dataclass(frozen=True)
class HammerForceScale(Effect):
    """The impact hammer's sensitivity is off: the force acting is ``(1 + s)`` times the recorded one.

    One linear parameter, the response to the recorded impacts (the step input of Eq. 5); nothing to fit
    in a record without an impact. The filter cannot see this error in its innovations (the coefficients
    absorb it): only the shape of the free response after the impact against the 1X response tells it."""

    forcing: ClassVar[bool] = True
    name: ClassVar[str] = "hammer_force_scale"
    kind: ClassVar[str] = "force"
    responses: ClassVar[dict[str, str]] = {
        "hammer_calibration": "the calibration shows the gain error",
    }
    description: ClassVar[str] = "impact hammer sensitivity error (recorded force scaled)"

    def lin_names(self, ctx):
        return ("force_scale_error",) if np.any(ctx.known_step_n) else ()

    def basis(self, ctx, nl):
        if not np.any(ctx.known_step_n):
            return None, np.zeros((ctx.t_s.size, 4, 0))
        col = ctx.response(np.zeros_like(ctx.known_smooth_n), ctx.known_step_n)
        return None, col[:, :, None]

    def physical(self, nl, lin):
        if not len(lin):
            return {}
        return {"hammer_force_scale": 1.0 + float(lin[0]), "hammer_sensitivity_error_percent": 100.0 * float(lin[0])}
