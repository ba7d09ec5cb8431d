# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Keyphasor angular offset: the once-per-revolution mark is not where the model puts it."""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from rotor_estimator.core.model import imbalance_force
from rotor_estimator.diagnosis.effects.base import Effect


@dataclass(frozen=True)
class TachometerOffset(Effect):
    """Keyphasor mark off by an angle: the known imbalance is applied at ``angle + offset``."""

    forcing: ClassVar[bool] = True
    name: ClassVar[str] = "tach_offset"
    kind: ClassVar[str] = "force"
    refit_always: ClassVar[bool] = True
    responses: ClassVar[dict[str, str]] = {
        "slow_roll": "vanishes (it rotates the known imbalance response)",
        "speed_change": "same angle at every speed",
        "trial_weight": "the trial mass's response is rotated by the offset angle",
    }
    description: ClassVar[str] = "keyphasor angular offset (imbalance phase reference rotated)"
    nl_names: ClassVar[tuple[str, ...]] = ("offset_rad",)

    def lin_names(self, ctx):
        return ()

    def nl_grid(self, ctx):
        # small offsets finely, and the rest of the circle: a mark may sit anywhere on the shaft
        return [np.array([v]) for v in (-0.3, -0.1, 0.1, 0.3, -np.pi / 2, np.pi / 2, np.pi)]

    def nl_bounds(self, ctx):
        # the whole circle, with room on both sides so that an offset near +-180 deg is not held at a bound
        # (the optimizer moves on the unwrapped angle; :meth:`physical` wraps it)
        return np.array([-2 * np.pi]), np.array([2 * np.pi])

    def basis(self, ctx, nl):
        shifted = imbalance_force(ctx.mats, ctx.shaft.angle_rad + nl[0], ctx.shaft.speed_rad_s,
                                  ctx.shaft.accel_rad_s2)
        return ctx.response(shifted - ctx.known_smooth_n), np.zeros((ctx.t_s.size, 4, 0))

    def physical(self, nl, lin):
        return {"offset_deg": float((np.degrees(nl[0]) + 180.0) % 360.0 - 180.0)}
