# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Misalignment: 2X forces and a static preload at the bearings."""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from rotor_estimator.diagnosis import models
from rotor_estimator.diagnosis.effects.base import Effect


BEARINGS = ("b1", "b2")


@dataclass(frozen=True)
class Misalignment(Effect):
    """Misalignment: a 2X force at each bearing, any forward and backward whirl (its static preload only shifts DC).

    Each bearing's force ``fx = A cos 2theta + B sin 2theta``, ``fy = C cos 2theta + D sin 2theta`` spans every
    2X force there: a rotating (forward or backward) one and one of fixed direction (equal forward and backward
    parts), which is the form a coupling's angular or parallel offset takes. The reported forward/backward
    split says which.
    """

    forcing: ClassVar[bool] = True
    name: ClassVar[str] = "misalignment"
    kind: ClassVar[str] = "force"
    responses: ClassVar[dict[str, str]] = {
        "slow_roll": "2X shrinks with the transmitted torque; the static offset stays",
        "speed_change": "2X follows the dynamic stiffness at 2X, force about constant",
    }
    description: ClassVar[str] = "misalignment, 2X forces at both bearings (x and y, forward and backward)"

    def lin_names(self, ctx):
        return tuple(f"f{axis}_{b}_2x_{part}_n" for b in BEARINGS for axis in "xy" for part in ("cos", "sin"))

    def basis(self, ctx, nl):
        two = 2 * ctx.shaft.angle_rad
        zero = np.zeros_like(two)
        forces = []
        for s in (ctx.rig.bearing1_position_m, ctx.rig.bearing2_position_m):
            forces += [models.point_generalized_force(ctx.rig, s, np.cos(two), zero),
                       models.point_generalized_force(ctx.rig, s, np.sin(two), zero),
                       models.point_generalized_force(ctx.rig, s, zero, np.cos(two)),
                       models.point_generalized_force(ctx.rig, s, zero, np.sin(two))]
        return None, ctx.responses(forces)

    def physical(self, nl, lin):
        out = {}
        for i, b in enumerate(BEARINGS):
            a, bb, c, d = (float(v) for v in lin[4 * i:4 * i + 4])
            fx, fy = complex(a, -bb), complex(c, -d)  # f = Re[F e^{i 2 theta}]
            out[f"force_2x_{b}_x_amplitude_n"] = abs(fx)
            out[f"force_2x_{b}_y_amplitude_n"] = abs(fy)
            out[f"force_2x_{b}_forward_n"] = abs(fx + 1j * fy) / 2
            out[f"force_2x_{b}_backward_n"] = abs(fx.conjugate() + 1j * fy.conjugate()) / 2
        return out
