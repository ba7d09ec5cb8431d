# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""The library of candidate unmodelled effects: small, physical augmentations of Eq. 2.

Each effect is a frozen dataclass with its physical parameters (SI, unit in the name)
and two functions used by :mod:`.fitting`:

* ``basis(ctx, nl)`` -> ``(offset (N,4) or None, columns (N,4,k))``: the effect's
  contribution to the probe output about the nominal fit, for nonlinear parameters
  ``nl``; the columns' gains are the linear parameters.
* ``physical(nl, lin)`` -> the named physical parameters.

Measurement-side effects act on the probe signals, ``y = g(y_true)``; force-side
effects add a generalized force ``F_e`` to Eq. 5 and enter through the nominal model's
response (linear in their amplitudes); structural effects (pedestal, bending mode)
change the state-space model (:mod:`.models`) and are re-simulated.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from rotor_estimator.core.config import RigConfig
from rotor_estimator.diagnosis import models
from rotor_estimator.diagnosis.context import FitContext

CHANNELS = ("xp1", "yp1", "xp2", "yp2")
UNIT_UNBALANCE_KG_M = 1e-6   # 1 g*mm
UNIT_CUBIC_N_PER_M3 = 1e12
UNIT_RUNOUT_M = 1e-6
UNIT_SKEW_S = 1e-6


#: Measurements that separate effects the record alone cannot, cheapest first: key -> what to do. Each
#: effect declares its response to them in :attr:`Effect.responses` (undeclared: ``UNAFFECTED``).
MEASUREMENTS: dict[str, str] = {
    "slow_roll": "record at under 10 % of the running speed (forces that grow with speed vanish)",
    "trial_weight": "add a known trial mass at a marked angle and record again",
    "speed_change": "record again at another steady speed",
    "impact_amplitude": "repeat the impact at twice and half the force",
    "housing_sensor": "put an accelerometer or a probe on each bearing housing",
    "probe_calibration": "calibrate each probe statically (gap vs micrometer) and check its mounting angle",
    "daq_test_signal": "feed one test signal to every acquisition channel at once",
    "hammer_calibration": "calibrate the hammer's force sensor against a reference",
}
UNAFFECTED = "no change"


@dataclass(frozen=True)
class Effect:
    """Base of the candidate effects: ``name``, a one-line ``description`` and parameter names."""

    name: ClassVar[str] = "effect"
    description: ClassVar[str] = ""
    nl_names: ClassVar[tuple[str, ...]] = ()
    #: How this effect's signature responds to each of :data:`MEASUREMENTS` that changes it (others:
    #: :data:`UNAFFECTED`); a tie between two effects is broken by a measurement where they differ.
    responses: ClassVar[dict[str, str]] = {}
    #: What the effect is, for the report and the search: ``"force"`` (a force on the shaft, seen through the
    #: model), ``"structural"`` (changes the model itself: a foundation, a nonlinearity, a mode),
    #: ``"measurement"`` (adds to or maps the probe signals) or ``"signal_transform"`` (acts on every
    #: contribution of a channel: a delay).
    kind: ClassVar[str] = "measurement"
    # How the search refits it (ranking.rank_effects reads these; the defaults suit a measurement effect):
    #: The nominal fit absorbs this effect by dragging the coefficients far (a 1X force), so its joint refit
    #: with the coefficients always runs, whatever its first pass shows.
    refit_always: ClassVar[bool] = False
    #: Its refit's starts (:meth:`refine_starts`: structural starts, or a keyphasor offset's angle read against
    #: r0's response) are also tried from the prior coefficients r0: the effect can drag the nominal fit into a
    #: basin (negative or 10x stiffness) about which its first pass finds nothing.
    starts_from_prior: ClassVar[bool] = False
    #: Its pair on the top single is refitted jointly whatever the pair's first pass (it shows only once the
    #: coefficients move back from the values the top single absorbed it into).
    pair_always_refitted: ClassVar[bool] = False
    #: Its model has free dynamics of its own (a structural effect: a foundation mass): in a record whose start
    #: transient is estimated, its columns carry the free response of its own model from every initial state,
    #: the rotor's included, in place of the rigid nominal's (:func:`.context.start_in_effect`).
    owns_start_transient: ClassVar[bool] = False
    #: The effect whose signal family holds this one's with fewer parameters (a keyphasor offset turns the known
    #: imbalance's force: a residual unbalance in its planes, so the offset's single is dragged wherever a second
    #: effect is present and the unbalance's is not). In each leading pair that holds that effect, this one is
    #: refitted in its place from the pair's coefficients (:func:`.ranking.substituted_pairs`); the fewer
    #: parameters then win the pair's place when they fit as well. None: nests in nothing.
    nests_in: ClassVar[str | None] = None

    def variants(self) -> tuple["Effect", ...]:
        """The physical forms of this effect the search fits apart, keeping the best (default: itself only)."""
        return (self,)

    def companions(self) -> tuple[str, ...]:
        """Effects that carry a part of this form's physical signature the form itself leaves out (the forward 1X
        of a coupling's offset is an unbalance's force, :class:`.Misalignment`): the pair of the two is refitted
        jointly with the coefficients, from the prior r0 too, whatever its first pass (default: none)."""
        return ()

    @property
    def form(self) -> str:
        """Which of :meth:`variants` this is, in words (empty for a single-form effect)."""
        return ""

    def response_to(self, measurement: str) -> str:
        """This effect's declared response to ``measurement`` (a key of :data:`MEASUREMENTS`)."""
        return self.responses.get(measurement, UNAFFECTED)

    def lin_names(self, ctx: FitContext) -> tuple[str, ...]:
        raise NotImplementedError

    def n_params(self, ctx: FitContext) -> int:
        return len(self.nl_names) + len(self.lin_names(ctx))

    def nl_grid(self, ctx: FitContext) -> list[np.ndarray]:
        """Starting points of the nonlinear search (empty for a linear effect)."""
        return []

    def nl_bounds(self, ctx: FitContext) -> tuple[np.ndarray, np.ndarray]:
        return np.zeros(0), np.zeros(0)

    def refine_starts(self, ctx: FitContext) -> list[np.ndarray]:
        """Extra nonlinear starting points of the joint refit with the coefficients (structural effects)."""
        return []

    def evidence_starts(self, ctx: FitContext) -> list[np.ndarray]:
        """Nonlinear starts read off the record itself (a mode ringing in the nominal residual), which the joint
        refit runs to a full budget of their own instead of ranking them after a few evaluations with the
        generic ones (default: none)."""
        return []

    def basis(self, ctx: FitContext, nl: np.ndarray) -> tuple[np.ndarray | None, np.ndarray]:
        raise NotImplementedError

    def physical(self, nl: np.ndarray, lin: np.ndarray) -> dict[str, float]:
        """Physical parameter values (SI) from the fitted nonlinear and linear parameters."""
        return {}

    #: True for an effect that acts on the whole probe signal (a delay): in a pair it also acts
    #: on the other effect's contribution (:meth:`transform`).
    transforms_signal: ClassVar[bool] = False

    def transform(self, ctx: FitContext, nl: np.ndarray, signal_m: np.ndarray) -> np.ndarray:
        """The effect applied to another contribution ``signal_m`` ((N,4) or (N,4,k)); identity by default."""
        return signal_m

    #: True for a force effect: its contribution is the response to a force (``ctx.response``), so in a
    #: pair with a structural effect it is the response through that effect's model (:meth:`carrier`).
    forcing: ClassVar[bool] = False

    def carrier(self, ctx: FitContext, nl: np.ndarray) -> FitContext | None:
        """``ctx`` with its force response sent through this effect's structural model; ``None`` if it has none."""
        return None


def separating_measurements(a: Effect, b: Effect) -> list[dict[str, str]]:
    """The measurements (cheapest first) under which ``a`` and ``b`` respond differently, with each response."""
    return [{"measurement": m, "how": how, a.name: a.response_to(m), b.name: b.response_to(m)}
            for m, how in MEASUREMENTS.items() if a.response_to(m) != b.response_to(m)]


def rotating_mass_force(ctx: FitContext, phase_rad: float, moment_kg_m: float,
                        harmonic: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Point force ``(fx, fy)`` (N each) of a rotating mass ``m r`` at phase ``phase_rad`` from the
    keyphasor mark: ``m r (w^2 cos a + w' sin a, w^2 sin a - w' cos a)`` (Eq. 5 before the lever rule)."""
    a = harmonic * ctx.shaft.angle_rad + phase_rad
    w, acc = ctx.shaft.speed_rad_s, ctx.shaft.accel_rad_s2
    return moment_kg_m * (w * w * np.cos(a) + acc * np.sin(a)), moment_kg_m * (w * w * np.sin(a) - acc * np.cos(a))


def unbalance_force(ctx: FitContext, axial_position_m: float, phase_rad: float, moment_kg_m: float,
                     harmonic: int = 1) -> np.ndarray:
    """Generalized force of a rotating mass ``m r`` at ``axial_position_m`` (Eq. 5, single plane)."""
    fx, fy = rotating_mass_force(ctx, phase_rad, moment_kg_m, harmonic)
    return models.point_generalized_force(ctx.rig, axial_position_m, fx, fy)


def rig_unbalance_planes(rig: RigConfig) -> tuple[float, float]:
    """Correction planes (m) of a rig: its two outermost imbalance planes, else the bearing stations."""
    planes = sorted({u.axial_position_m for u in rig.imbalances})
    if len(planes) >= 2:
        return planes[0], planes[-1]
    return rig.bearing1_position_m, rig.bearing2_position_m


def unbalance_planes(ctx: FitContext) -> tuple[float, float]:
    """Correction planes of the context's rig (:func:`rig_unbalance_planes`)."""
    return rig_unbalance_planes(ctx.rig)
