# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Keyphasor angular offset: the once-per-revolution mark is not where the model puts it."""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from rotor_estimator.core.model import imbalance_force
from rotor_estimator.diagnosis import models
from rotor_estimator.diagnosis.effects.base import Effect
from rotor_estimator.diagnosis.linsim import harmonic_phasors, harmonic_state_phasor


@dataclass(frozen=True)
class TachometerOffset(Effect):
    """Keyphasor mark off by an angle: the known imbalance is applied at ``angle + offset``."""

    forcing: ClassVar[bool] = True
    name: ClassVar[str] = "tach_offset"
    kind: ClassVar[str] = "force"
    refit_always: ClassVar[bool] = True
    #: Its refit's start angle is read against the prior coefficients' 1X (:meth:`refine_starts`), so it is also
    #: tried at those coefficients: a large offset drags the nominal fit, and the first pass's coefficients with it
    starts_from_prior: ClassVar[bool] = True
    nests_in: ClassVar[str | None] = "residual_unbalance"
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

    def refine_starts(self, ctx):
        """The angle the record's 1X is turned by from the prior model's, ``arg sum_c conj(Y0_c) Y_c`` over the
        four probes' 1X phasors: an offset turns the known imbalance's force, so its response, by itself. ``Y0``
        is the known imbalance's steady 1X response of the prior coefficients r0 at the mean speed (the
        frequency response of Eq. 2), not the nominal fit's: a large offset drags that fit until its 1X is
        nearly turned with the record's (a mark at 160 deg read 5 deg off the fit, 18 deg in the first pass,
        and the joint refit from there stayed in that basin; from this start, at the first pass's coefficients,
        it reached 160.2 deg). None without a known imbalance."""
        rows = ctx.mask
        angle = ctx.shaft.angle_rad[rows]
        force = harmonic_phasors(ctx.known_smooth_n[rows], angle, 1)
        if not np.any(np.abs(force[1]) > 0):
            return []
        speed = ctx.mean_speed_rad_s
        state = harmonic_state_phasor(models.rigid_state_matrix(ctx.mats, ctx.prior_coefficients, speed),
                                      models.rigid_input(ctx.mats), force[1], 1, speed)
        prior_1x = (models.rigid_output(ctx.mats) @ state)[:4]
        measured_1x = harmonic_phasors(ctx.y_m[rows], angle, 1)[1]
        return [np.array([float(np.angle(np.vdot(prior_1x, measured_1x)))])]

    def basis(self, ctx, nl):
        shifted = imbalance_force(ctx.mats, ctx.shaft.angle_rad + nl[0], ctx.shaft.speed_rad_s,
                                  ctx.shaft.accel_rad_s2)
        return ctx.response(shifted - ctx.known_smooth_n), np.zeros((ctx.t_s.size, 4, 0))

    def physical(self, nl, lin):
        return {"offset_deg": float((np.degrees(nl[0]) + 180.0) % 360.0 - 180.0)}
