# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Misalignment: 2X forces and a static preload at the bearings."""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from rotor_estimator.diagnosis import models
from rotor_estimator.diagnosis.effects.base import Effect


@dataclass(frozen=True)
class Misalignment(Effect):
    """Coupling misalignment: a 2X force at the drive-end bearing (its static preload only shifts DC)."""

    forcing: ClassVar[bool] = True
    name: ClassVar[str] = "misalignment"
    responses: ClassVar[dict[str, str]] = {
        "slow_roll": "2X shrinks with the transmitted torque; the static offset stays",
        "speed_change": "2X follows the dynamic stiffness at 2X, force about constant",
    }
    description: ClassVar[str] = "coupling misalignment, 2X force at bearing 1 (x and y)"

    def lin_names(self, ctx):
        return ("fx_2x_cos_n", "fx_2x_sin_n", "fy_2x_cos_n", "fy_2x_sin_n")

    def basis(self, ctx, nl):
        two = 2 * ctx.shaft.angle_rad
        s = ctx.rig.bearing1_position_m
        zero = np.zeros_like(two)
        cols = [ctx.response(models.point_generalized_force(ctx.rig, s, np.cos(two), zero)),
                ctx.response(models.point_generalized_force(ctx.rig, s, np.sin(two), zero)),
                ctx.response(models.point_generalized_force(ctx.rig, s, zero, np.cos(two))),
                ctx.response(models.point_generalized_force(ctx.rig, s, zero, np.sin(two)))]
        return None, np.stack(cols, axis=2)

    def physical(self, nl, lin):
        return {"force_2x_x_amplitude_n": float(abs(complex(lin[0], lin[1]))),
                "force_2x_y_amplitude_n": float(abs(complex(lin[2], lin[3])))}
