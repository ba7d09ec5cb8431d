# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Adapters for the estimator's output topics (``sensor_msgs/msg/JointState`` and diagnostics).

Every JointState output is read by ``name``, so a subscriber does not depend on
the order of entries. Stamps are integer ns (``header.stamp``).

* ``~/coefficients``: name = ``COEFFICIENT_NAMES_WITH_UNITS``, position = estimate, velocity = std.
* ``~/coefficients/covariance``: name = ``cov(a,b)`` row-major (64), position = covariance.
* ``~/innovation``: name = ``xp1_m yp1_m xp2_m yp2_m``, position = y = z - h(x), velocity = sqrt(diag S).
* ``~/nis``: name = ``nis nis_window_mean nis_dof``.
* ``~/shaft``: name = ``speed_rad_s angle_rad``.
* ``~/identifiability``: name = ``COEFFICIENT_NAMES_WITH_UNITS``; position = estimate, NaN when the
  data do not determine it; velocity = predicted std from the information in the data alone
  (the Cramer-Rao bound, prior removed); effort = status code (0 determined, 1 weakly
  determined, 2 not determined; see ``IDENTIFIABILITY_STATUS``).
* ``/diagnostics``: ``diagnostic_msgs/msg/DiagnosticArray``.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Mapping, NamedTuple, Sequence

import numpy as np

from rotor_estimator.core.config import COEFFICIENT_NAMES_WITH_UNITS
from rotor_estimator.core.errors import InputError

from msg_adapters._common import expect_type, header_stamp_ns
from msg_adapters.factory import MessageFactory, make_header

JOINT_STATE = "sensor_msgs/msg/JointState"
DIAGNOSTIC_ARRAY = "diagnostic_msgs/msg/DiagnosticArray"
COVARIANCE_NAMES: tuple[str, ...] = tuple(
    f"cov({a},{b})" for a in COEFFICIENT_NAMES_WITH_UNITS for b in COEFFICIENT_NAMES_WITH_UNITS)
INNOVATION_NAMES: tuple[str, ...] = ("xp1_m", "yp1_m", "xp2_m", "yp2_m")
NIS_NAMES: tuple[str, ...] = ("nis", "nis_window_mean", "nis_dof")
SHAFT_NAMES: tuple[str, ...] = ("speed_rad_s", "angle_rad")
#: Status codes carried in ``~/identifiability`` ``effort``.
IDENTIFIABILITY_STATUS: tuple[str, ...] = ("determined", "weakly determined", "not determined")
_N_COEF = len(COEFFICIENT_NAMES_WITH_UNITS)


class Coefficients(NamedTuple):
    stamp_ns: int
    estimate: np.ndarray  #: (8,) kxx..kyy in N/m, cxx..cyy in N*s/m
    std: np.ndarray  #: (8,) standard deviations, same units


class Covariance(NamedTuple):
    stamp_ns: int
    covariance: np.ndarray  #: (8, 8) in coefficient order


class Innovation(NamedTuple):
    stamp_ns: int
    innovation_m: np.ndarray  #: (4,) measured - predicted, xp1 yp1 xp2 yp2
    std_m: np.ndarray  #: (4,) sqrt(diag S)


class Nis(NamedTuple):
    stamp_ns: int
    nis: float
    nis_window_mean: float
    nis_dof: float


class Shaft(NamedTuple):
    stamp_ns: int
    speed_rad_s: float
    angle_rad: float


class Identifiability(NamedTuple):
    stamp_ns: int
    estimate: np.ndarray        #: (8,) NaN where not determined
    predicted_std: np.ndarray   #: (8,) from the data's information alone
    status: tuple[str, ...]     #: one of IDENTIFIABILITY_STATUS per coefficient


@dataclass(frozen=True)
class DiagnosticRecord:
    """One ``diagnostic_msgs/msg/DiagnosticStatus``; level 0 OK, 1 WARN, 2 ERROR, 3 STALE."""

    name: str
    level: int
    message: str
    hardware_id: str = ""
    values: Mapping[str, str] = field(default_factory=dict)


class Diagnostics(NamedTuple):
    stamp_ns: int
    statuses: tuple[DiagnosticRecord, ...]


# --------------------------------------------------------------------------- JointState helpers
def joint_state(factory: MessageFactory, stamp_ns: int, names: Sequence[str], position: Any,
                 velocity: Any | None, frame_id: str, effort: Any | None = None) -> Any:
    position = np.asarray(position, dtype=np.float64).reshape(-1)
    if position.size != len(names):
        raise InputError(f"JointState position needs {len(names)} values, got {position.size}")
    vel = np.empty(0) if velocity is None else np.asarray(velocity, dtype=np.float64).reshape(-1)
    if velocity is not None and vel.size != len(names):
        raise InputError(f"JointState velocity needs {len(names)} values, got {vel.size}")
    eff = np.empty(0) if effort is None else np.asarray(effort, dtype=np.float64).reshape(-1)
    if effort is not None and eff.size != len(names):
        raise InputError(f"JointState effort needs {len(names)} values, got {eff.size}")
    return factory.new(JOINT_STATE, header=make_header(factory, stamp_ns, frame_id), name=list(names),
                       position=factory.float64_seq(position), velocity=factory.float64_seq(vel),
                       effort=factory.float64_seq(eff))


def joint_values(msg: Any, names: Sequence[str], what: str) -> tuple[int, np.ndarray, np.ndarray]:
    """``(stamp_ns, position, velocity)`` for ``names``; velocity NaN if the message has none."""
    expect_type(msg, {JOINT_STATE}, what)
    index = {str(n): i for i, n in enumerate(msg.name)}
    missing = [n for n in names if n not in index]
    if missing:
        raise InputError(f"{what}: JointState lacks names {missing[:4]}{'...' if len(missing) > 4 else ''}")
    idx = np.fromiter((index[n] for n in names), dtype=np.intp, count=len(names))
    pos = np.asarray(msg.position, dtype=np.float64)
    vel = np.asarray(msg.velocity, dtype=np.float64)
    if pos.size != len(index):
        raise InputError(f"{what}: JointState has {len(index)} names but {pos.size} positions")
    velocity = vel[idx] if vel.size == len(index) else np.full(len(names), np.nan)
    return header_stamp_ns(msg), pos[idx], velocity


# --------------------------------------------------------------------------- encoders
def coefficients_to_msg(factory: MessageFactory, stamp_ns: int, estimate: Any, std: Any,
                        *, frame_id: str = "") -> Any:
    """``~/coefficients``: estimate (SI) in position, standard deviation in velocity."""
    return joint_state(factory, stamp_ns, COEFFICIENT_NAMES_WITH_UNITS, estimate, std, frame_id)


def covariance_to_msg(factory: MessageFactory, stamp_ns: int, covariance: Any, *, frame_id: str = "") -> Any:
    """``~/coefficients/covariance``: the 8x8 covariance row-major in position."""
    p = np.asarray(covariance, dtype=np.float64)
    if p.shape != (_N_COEF, _N_COEF):
        raise InputError(f"covariance must have shape ({_N_COEF}, {_N_COEF}), got {p.shape}")
    return joint_state(factory, stamp_ns, COVARIANCE_NAMES, p.reshape(-1), None, frame_id)


def innovation_to_msg(factory: MessageFactory, stamp_ns: int, innovation_m: Any, std_m: Any,
                      *, frame_id: str = "") -> Any:
    """``~/innovation``: y = z - h(x) in position, sqrt(diag S) in velocity (m)."""
    return joint_state(factory, stamp_ns, INNOVATION_NAMES, innovation_m, std_m, frame_id)


def nis_to_msg(factory: MessageFactory, stamp_ns: int, nis: float, nis_window_mean: float, nis_dof: float,
               *, frame_id: str = "") -> Any:
    """``~/nis``: normalized innovation squared, its window mean and degrees of freedom."""
    return joint_state(factory, stamp_ns, NIS_NAMES, [nis, nis_window_mean, nis_dof], None, frame_id)


def shaft_to_msg(factory: MessageFactory, stamp_ns: int, speed_rad_s: float, angle_rad: float,
                 *, frame_id: str = "") -> Any:
    """``~/shaft``: shaft speed (rad/s) and angle since the last keyphasor pulse (rad)."""
    return joint_state(factory, stamp_ns, SHAFT_NAMES, [speed_rad_s, angle_rad], None, frame_id)


def identifiability_to_msg(factory: MessageFactory, stamp_ns: int, estimate: Any, predicted_std: Any,
                           status: Sequence[str], *, frame_id: str = "") -> Any:
    """``~/identifiability``: estimate (NaN when not determined), predicted std, status code in effort."""
    try:
        codes = [IDENTIFIABILITY_STATUS.index(s) for s in status]
    except ValueError as exc:
        raise InputError(f"identifiability status must be one of {IDENTIFIABILITY_STATUS}") from exc
    return joint_state(factory, stamp_ns, COEFFICIENT_NAMES_WITH_UNITS, estimate, predicted_std, frame_id, codes)


def diagnostics_to_msg(factory: MessageFactory, stamp_ns: int, statuses: Sequence[DiagnosticRecord]) -> Any:
    """``/diagnostics``: one DiagnosticStatus per record, values as KeyValue strings."""
    status = [factory.new("diagnostic_msgs/msg/DiagnosticStatus", level=factory.byte(s.level), name=s.name,
                          message=s.message, hardware_id=s.hardware_id,
                          values=[factory.new("diagnostic_msgs/msg/KeyValue", key=str(k), value=str(v))
                                  for k, v in s.values.items()])
              for s in statuses]
    return factory.new(DIAGNOSTIC_ARRAY, header=make_header(factory, stamp_ns), status=status)


# --------------------------------------------------------------------------- decoders
def coefficients_from_msg(msg: Any) -> Coefficients:
    """Decode ``~/coefficients`` into estimate and std in coefficient order."""
    return Coefficients(*joint_values(msg, COEFFICIENT_NAMES_WITH_UNITS, "coefficients message"))


def covariance_from_msg(msg: Any) -> Covariance:
    """Decode ``~/coefficients/covariance`` into an 8x8 matrix."""
    stamp_ns, pos, _ = joint_values(msg, COVARIANCE_NAMES, "covariance message")
    return Covariance(stamp_ns, pos.reshape(_N_COEF, _N_COEF))


def innovation_from_msg(msg: Any) -> Innovation:
    """Decode ``~/innovation``."""
    return Innovation(*joint_values(msg, INNOVATION_NAMES, "innovation message"))


def nis_from_msg(msg: Any) -> Nis:
    """Decode ``~/nis``."""
    stamp_ns, pos, _ = joint_values(msg, NIS_NAMES, "nis message")
    return Nis(stamp_ns, float(pos[0]), float(pos[1]), float(pos[2]))


def shaft_from_msg(msg: Any) -> Shaft:
    """Decode ``~/shaft``."""
    stamp_ns, pos, _ = joint_values(msg, SHAFT_NAMES, "shaft message")
    return Shaft(stamp_ns, float(pos[0]), float(pos[1]))


def identifiability_from_msg(msg: Any) -> Identifiability:
    """Decode ``~/identifiability``."""
    stamp_ns, pos, vel = joint_values(msg, COEFFICIENT_NAMES_WITH_UNITS, "identifiability message")
    index = {str(n): i for i, n in enumerate(msg.name)}
    effort = np.asarray(msg.effort, dtype=np.float64)
    if effort.size != len(index):
        raise InputError("identifiability message: effort must hold one status code per name")
    codes = [int(effort[index[n]]) for n in COEFFICIENT_NAMES_WITH_UNITS]
    if any(not 0 <= c < len(IDENTIFIABILITY_STATUS) for c in codes):
        raise InputError(f"identifiability message: unknown status code in {codes}")
    return Identifiability(stamp_ns, pos, vel, tuple(IDENTIFIABILITY_STATUS[c] for c in codes))


def _level(value: Any) -> int:
    return value[0] if isinstance(value, (bytes, bytearray)) else int(value)


def diagnostics_from_msg(msg: Any) -> Diagnostics:
    """Decode ``/diagnostics`` into :class:`DiagnosticRecord` entries."""
    expect_type(msg, {DIAGNOSTIC_ARRAY}, "diagnostics message")
    statuses = tuple(DiagnosticRecord(name=str(s.name), level=_level(s.level), message=str(s.message),
                                      hardware_id=str(s.hardware_id),
                                      values={str(kv.key): str(kv.value) for kv in s.values})
                     for s in msg.status)
    return Diagnostics(header_stamp_ns(msg), statuses)
