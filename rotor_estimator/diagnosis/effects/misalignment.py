# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Misalignment: forces at twice the shaft speed at the bearings, and in a second form a backward 1X force too."""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from rotor_estimator.diagnosis import models
from rotor_estimator.diagnosis.effects.base import Effect


BEARINGS = ("b1", "b2")
#: The physical forms: ``False``, 2X forces alone (an angular or parallel offset seen through a coupling that
#: transmits it twice per revolution); ``True``, also a 1X force of backward whirl (a parallel offset through a
#: flexible coupling: its reaction ``(sqrt(r^2 + d^2 + 2 r d sin phi) - r)`` along a rotating unit vector has a
#: mean part, a once-per-revolution force along the offset, of both whirls; ROSS's ``MisalignmentFlex``). Its
#: forward 1X part is the force of an unbalance: at one speed no record tells them apart, so it is left to
#: the residual unbalance (the pair), and the form claims only the part no unbalance makes.
FORMS: tuple[bool, ...] = (False, True)


@dataclass(frozen=True)
class Misalignment(Effect):
    """Misalignment: a 2X force at each bearing, any forward and backward whirl (its static preload only shifts DC),
    and with ``backward_1x`` a 1X force of backward whirl at each bearing.

    Each bearing's force ``fx = A cos 2theta + B sin 2theta``, ``fy = C cos 2theta + D sin 2theta`` spans every
    2X force there: a rotating (forward or backward) one and one of fixed direction (equal forward and backward
    parts), which is the form a coupling's angular or parallel offset takes. The reported forward/backward
    split says which. The backward 1X force ``fx + i fy = F e^{-i theta}`` is the part of a fixed-direction 1X
    reaction that no unbalance makes (see :data:`FORMS`).
    """

    backward_1x: bool = False

    forcing: ClassVar[bool] = True
    name: ClassVar[str] = "misalignment"
    kind: ClassVar[str] = "force"
    responses: ClassVar[dict[str, str]] = {
        "slow_roll": "2X shrinks with the transmitted torque; the static offset stays",
        "speed_change": "2X (and 1X) follow the dynamic stiffness, the force about constant (an unbalance's 1X force "
                        "grows with the speed squared)",
    }
    description: ClassVar[str] = "misalignment, 2X (and 1X) forces at both bearings (x and y, forward and backward)"

    def variants(self):
        return tuple(Misalignment(f) for f in FORMS)

    def companions(self):
        return ("residual_unbalance",) if self.backward_1x else ()

    @property
    def form(self) -> str:
        return "2X forces and a backward 1X force at the bearings" if self.backward_1x else "2X forces at the bearings"

    def lin_names(self, ctx):
        names = tuple(f"f{axis}_{b}_2x_{part}_n" for b in BEARINGS for axis in "xy" for part in ("cos", "sin"))
        if self.backward_1x:
            names += tuple(f"f_{b}_1x_backward_{part}_n" for b in BEARINGS for part in ("re", "im"))
        return names

    def basis(self, ctx, nl):
        two = 2 * ctx.shaft.angle_rad
        zero = np.zeros_like(two)
        forces = []
        for s in (ctx.rig.bearing1_position_m, ctx.rig.bearing2_position_m):
            forces += [models.point_generalized_force(ctx.rig, s, np.cos(two), zero),
                       models.point_generalized_force(ctx.rig, s, np.sin(two), zero),
                       models.point_generalized_force(ctx.rig, s, zero, np.cos(two)),
                       models.point_generalized_force(ctx.rig, s, zero, np.sin(two))]
        if self.backward_1x:
            one = ctx.shaft.angle_rad
            cos1, sin1 = np.cos(one), np.sin(one)
            for s in (ctx.rig.bearing1_position_m, ctx.rig.bearing2_position_m):
                # fx + i fy = F e^{-i theta}, F = re + i im: (re cos + im sin, -re sin + im cos)
                forces += [models.point_generalized_force(ctx.rig, s, cos1, -sin1),
                           models.point_generalized_force(ctx.rig, s, sin1, cos1)]
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
        if self.backward_1x:
            for i, b in enumerate(BEARINGS):
                out[f"force_1x_{b}_backward_n"] = float(np.hypot(lin[8 + 2 * i], lin[9 + 2 * i]))
        return out
