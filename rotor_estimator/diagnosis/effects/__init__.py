# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""The library of candidate unmodelled effects: one module per effect, registered here.

Each effect is a frozen dataclass with its physical parameters (SI, unit in the name) and the
interface of :class:`.base.Effect` (``basis``, ``physical``, its kind: ``forcing``,
``transforms_signal``, structural through ``carrier``). To add an effect: write its module here
(subclass :class:`~rotor_estimator.diagnosis.effects.base.Effect`) and append an instance to
:data:`LIBRARY`. The library's order is the report order and breaks exact ties in the ranking.
"""
from __future__ import annotations

from rotor_estimator.diagnosis.effects.base import (CHANNELS, UNIT_CUBIC_N_PER_M3, UNIT_RUNOUT_M, UNIT_SKEW_S,
                                                     UNIT_UNBALANCE_KG_M, Effect)
from rotor_estimator.diagnosis.effects.bearing_cubic import BearingCubic
from rotor_estimator.diagnosis.effects.flexible_shaft import FlexibleShaft
from rotor_estimator.diagnosis.effects.hammer_force_scale import HammerForceScale
from rotor_estimator.diagnosis.effects.misalignment import Misalignment
from rotor_estimator.diagnosis.effects.pedestal import PedestalFlexibility
from rotor_estimator.diagnosis.effects.probe_gain_orientation import ProbeGainOrientation
from rotor_estimator.diagnosis.effects.probe_runout import ProbeRunout
from rotor_estimator.diagnosis.effects.residual_unbalance import ResidualUnbalance
from rotor_estimator.diagnosis.effects.tachometer_offset import TachometerOffset
from rotor_estimator.diagnosis.effects.timing_skew import TimingSkew

#: The candidate library, in report order.
LIBRARY: tuple[Effect, ...] = (ResidualUnbalance(), TachometerOffset(), ProbeRunout(), Misalignment(),
                               BearingCubic(), PedestalFlexibility(), FlexibleShaft(), ProbeGainOrientation(),
                               TimingSkew(), HammerForceScale())
EFFECT_NAMES: tuple[str, ...] = tuple(e.name for e in LIBRARY)


def effect_by_name(name: str) -> Effect:
    """The library's effect called ``name``; ``KeyError`` naming the known ones otherwise."""
    for e in LIBRARY:
        if e.name == name:
            return e
    raise KeyError(f"unknown effect {name!r}; known: {', '.join(EFFECT_NAMES)}")


__all__ = ["LIBRARY", "EFFECT_NAMES", "effect_by_name", "Effect", "CHANNELS", "UNIT_CUBIC_N_PER_M3", "UNIT_RUNOUT_M",
           "UNIT_SKEW_S", "UNIT_UNBALANCE_KG_M", "BearingCubic", "FlexibleShaft", "HammerForceScale", "Misalignment",
           "PedestalFlexibility", "ProbeGainOrientation", "ProbeRunout", "ResidualUnbalance", "TachometerOffset",
           "TimingSkew"]
