# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Pedestal flexibility: the bearing housings on a mass-spring-damper foundation, in four physical forms."""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from rotor_estimator.diagnosis import models
from rotor_estimator.diagnosis.effects.base import Effect
from rotor_estimator.diagnosis.linsim import free_response
from rotor_estimator.diagnosis.residuals import nonsync_peak_frequencies_hz


FOUNDATIONS = ("separate", "common")
PROBE_MOUNTS = ("absolute", "relative")


@dataclass(frozen=True)
class PedestalFlexibility(Effect):
    """Bearing housings on an isotropic mass-spring-damper foundation.

    ``foundation``: a separate mass under each bearing, or one common mass carrying both housings;
    ``probes``: fixed to ground (absolute shaft motion) or to the housings (shaft relative to the
    housing). The search fits every form (:meth:`variants`) and keeps the best; the report names it.

    In a record whose start transient is estimated (:attr:`.FitContext.start_transient`), its linear
    parameters are the initial state of the rotor on its foundation, the housings' included: the free
    response of this model from each state replaces the rigid nominal's start transient
    (:attr:`owns_start_transient`). A record from rest rings in the foundation's mode (a 40 Hz foundation
    decays over the whole record), and the rotor's own decay is that of the rotor on the foundation, not on
    rigid ground: with the rigid one's, an independent common foundation from rest was fitted to the noise
    by coefficients 4-5 of their std off. A record that starts steady has none (its housings start in the
    periodic state like the rotor).
    """

    foundation: str = "separate"
    probes: str = "absolute"

    def __post_init__(self) -> None:
        if self.foundation not in FOUNDATIONS:
            raise ValueError(f"pedestal.foundation: {self.foundation!r} is not one of {FOUNDATIONS}")
        if self.probes not in PROBE_MOUNTS:
            raise ValueError(f"pedestal.probes: {self.probes!r} is not one of {PROBE_MOUNTS}")

    def variants(self):
        return tuple(PedestalFlexibility(f, p) for f in FOUNDATIONS for p in PROBE_MOUNTS)

    @property
    def form(self) -> str:
        return f"{self.foundation} foundation mass{'es' if self.foundation == 'separate' else ''}, " \
               f"probes {'on the housings' if self.probes == 'relative' else 'fixed to ground'}"

    name: ClassVar[str] = "pedestal"
    kind: ClassVar[str] = "structural"
    starts_from_prior: ClassVar[bool] = True
    pair_always_refitted: ClassVar[bool] = True
    owns_start_transient: ClassVar[bool] = True
    responses: ClassVar[dict[str, str]] = {
        "housing_sensor": "shows housing motion at the rotor frequencies",
        "speed_change": "a resonance of the housing moves the 1X phase",
    }
    description: ClassVar[str] = "foundation/pedestal flexibility: housing mass, spring and damper under each bearing"
    nl_names: ClassVar[tuple[str, ...]] = ("log10_frequency_hz", "log10_damping_ratio", "log10_mass_kg")

    def _housings(self) -> int:
        return models.HOUSING_MAPS[self.foundation].shape[1]

    def lin_names(self, ctx):
        if not ctx.start_transient:
            return ()
        nh = self._housings()
        return tuple(f"rotor_start_state_{i}" for i in range(8)) \
            + tuple(f"housing_start_{q}{i}" for q in ("velocity_m_s_", "displacement_m_") for i in range(nh))

    def nl_grid(self, ctx):
        return [np.array([np.log10(f), np.log10(0.05), np.log10(m)])
                for f in (50.0, 100.0, 200.0, 400.0, 800.0, 1600.0) for m in (0.5, 2.0, 8.0)]

    def nl_bounds(self, ctx):
        fmax = 0.45 * ctx.sample_rate_hz
        return np.array([np.log10(20.0), -3.0, -1.5]), np.array([np.log10(fmax), 0.0, 2.0])

    def refine_starts(self, ctx):
        """A fixed ladder of foundation frequencies, plus one start per mode ringing in the nominal residual
        (:meth:`ringing_starts`)."""
        ladder = [np.array([np.log10(f), np.log10(0.05), np.log10(2.0)]) for f in (60.0, 120.0, 250.0, 500.0)]
        return ladder + self.ringing_starts(ctx)

    def evidence_starts(self, ctx):
        """The starts at the modes ringing in the nominal residual (:meth:`ringing_starts`)."""
        return self.ringing_starts(ctx)

    def ringing_starts(self, ctx, masses_kg: tuple[float, ...] = (2.0, 8.0),
                       damping_ratio: float = 0.03) -> list[np.ndarray]:
        """Starts at the non-synchronous peaks of the nominal residual (:func:`.residuals.nonsync_peak_frequencies_hz`).

        A peak is the whole system's mode: the foundation carries the rotor, so with bearings much stiffer than
        the foundation it rings at ``sqrt(k / (m + M)) / 2 pi``, ``M`` the rotor mass each housing coordinate
        carries (``T^T M_rotor T``; all of it for a common foundation). The peak fixes ``k / (m + M)`` only, so
        each peak gives a start per mass in ``masses_kg``, at the foundation frequency ``sqrt(k / m) / 2 pi``:
        the peak's times ``sqrt((m + M) / m)``. (An independent record of a 2 kg common foundation at 44.8 Hz,
        damping ratio 0.025, rang at 28.6 Hz; from the ladder alone the refits stopped at 79 Hz, damping ratio
        0.33, and runout won at a 13x gap; refitted from that frequency the foundation explains the record to
        the noise.)"""
        rows = ctx.mask
        peaks = nonsync_peak_frequencies_hz(ctx.t_s[rows], ctx.residual_m[rows], ctx.shaft.angle_rad[rows],
                                            ctx.shaft.speed_rad_s[rows])
        t = models.HOUSING_MAPS[self.foundation]
        carried_kg = float(np.mean(np.diag(t.T @ ctx.mats.mass_matrix @ t)))
        lo, hi = self.nl_bounds(ctx)
        out = []
        for f_system in peaks:
            for mass_kg in masses_kg:  # the peak fixes k / (m + M) only: a light and a heavy foundation
                x = np.array([np.log10(f_system * np.sqrt((mass_kg + carried_kg) / mass_kg)),
                              np.log10(damping_ratio), np.log10(mass_kg)])
                if lo[0] <= x[0] <= hi[0]:
                    out.append(x)
        return out

    @staticmethod
    def housing(nl: np.ndarray) -> tuple[float, float, float]:
        f, zeta, m = 10 ** nl[0], 10 ** nl[1], 10 ** nl[2]
        k = m * (2 * np.pi * f) ** 2
        return m, k, 2 * zeta * np.sqrt(k * m)

    def basis(self, ctx, nl):
        carrier = self.carrier(ctx, nl)
        y = carrier.response(ctx.known_smooth_n, ctx.known_step_n)
        build_a, b, c = carrier.response_model
        if not ctx.start_transient:
            return y - ctx.y_nom_m, np.zeros((ctx.t_s.size, 4, 0))
        start = free_response(build_a, b, c[:4], ctx.period_s, ctx.schedule, states=np.arange(8 + 2 * self._housings()))
        return y - ctx.y_nom_m, start

    def carrier(self, ctx, nl):
        """The context whose forces (a partner's unbalance, misalignment) act on the shaft on its pedestals."""
        from dataclasses import replace

        m, k, c = self.housing(nl)
        mats, r = ctx.mats, ctx.coefficients
        t = models.HOUSING_MAPS[self.foundation]
        model = (lambda w: models.pedestal_state_matrix(mats, r, w, m, k, c, t), models.pedestal_input(mats, t),
                 models.pedestal_output(mats, t, relative=self.probes == "relative"))
        return replace(ctx, response_model=model, _cache={})

    def physical(self, nl, lin):
        m, k, c = self.housing(nl)
        return {"pedestal_frequency_hz": float(10 ** nl[0]), "pedestal_damping_ratio": float(10 ** nl[1]),
                "pedestal_mass_kg": m, "pedestal_stiffness_N_per_m": k, "pedestal_damping_N_s_per_m": c}
