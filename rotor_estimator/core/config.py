# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Rig and estimator configuration: frozen, typed dataclasses validated at load.

All quantities are SI. Axial positions are signed coordinates along the shaft,
measured from the rotor's mass center, positive toward bearing 2 (the paper's
Fig. 2). The paper's lengths map as: ``bearing1 = -l1``, ``bearing2 = +l2``,
``probe1 = -p1``, ``probe2 = +p2``, imbalance plane 1 at ``-d1``, plane 2 at ``+d2``,
impact at ``zp``.

Coefficients are always ordered ``kxx kxy kyx kyy cxx cxy cyx cyy`` (stiffness in
N/m, damping in N*s/m). Note that Miller & Howard's Eq. 7 orders the damping
terms first; this package does not.

A bad or missing field raises :class:`~rotor_estimator.core.errors.ConfigError` naming
the field by its dotted path and the expected unit or range.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from rotor_estimator.core.errors import ConfigError

COEFFICIENT_NAMES: tuple[str, ...] = ("kxx", "kxy", "kyx", "kyy", "cxx", "cxy", "cyx", "cyy")
COEFFICIENT_UNITS: tuple[str, ...] = ("N/m",) * 4 + ("N*s/m",) * 4
#: Names that carry their SI unit, used on ROS topics and in output bags.
COEFFICIENT_NAMES_WITH_UNITS: tuple[str, ...] = tuple(
    f"{n}_N_per_m" if n.startswith("k") else f"{n}_N_s_per_m" for n in COEFFICIENT_NAMES
)
PROBE_CHANNELS: tuple[str, ...] = ("xp1", "yp1", "xp2", "yp2")

SEED_RIG_PATH = Path(__file__).resolve().parents[1] / "rigs" / "miller_howard_2008.yaml"


# --------------------------------------------------------------------------- helpers
def _kind(value: Any) -> str:
    """How a YAML value reads to a user: 'the number 5', 'a list', 'nothing (null)'."""
    if value is None:
        return "nothing (null)"
    if isinstance(value, bool):
        return f"the boolean {str(value).lower()}"
    if isinstance(value, (int, float)):
        return f"the number {value!r}" if len(repr(value)) <= 40 else "a number"
    if isinstance(value, str):
        return f"the string {value!r}" if len(value) <= 40 else "a string"
    if isinstance(value, list):
        return "a list"
    return f"a {type(value).__name__}"


def _require_mapping(value: Any, path: str) -> Mapping[str, Any]:
    if not isinstance(value, Mapping):
        raise ConfigError(f"{path}: expected a mapping (YAML object with named fields), got {_kind(value)}")
    return value


def get_field(mapping: Mapping[str, Any], key: str, path: str, *, default: Any = ...) -> Any:
    _require_mapping(mapping, path)
    if key not in mapping:
        if default is ...:
            raise ConfigError(f"{path}.{key}: missing required field")
        return default
    return mapping[key]


def number_field(value: Any, path: str, unit: str, *, low: float | None = None, high: float | None = None,
            low_open: bool = False, allow_zero: bool = True) -> float:
    if isinstance(value, str):
        # PyYAML (YAML 1.1) reads 500.0e3 as a string; accept plain numeric text.
        try:
            value = float(value.strip())
        except ValueError:
            pass
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        if isinstance(value, str):
            raise ConfigError(f"{path}: expected a plain number in {unit}, got the string {value!r} "
                              f"(write SI numbers without units, e.g. 0.1245 for 124.5 mm)")
        raise ConfigError(f"{path}: expected a number in {unit}, got {type(value).__name__}")
    try:
        v = float(value)
    except OverflowError:
        raise ConfigError(f"{path}: number too large ({unit})") from None
    if not math.isfinite(v):
        raise ConfigError(f"{path}: must be finite ({unit}), got {value!r}")
    if low is not None and (v < low or (low_open and v == low)):
        op = ">" if low_open else ">="
        raise ConfigError(f"{path}: must be {op} {low:g} {unit}, got {v:g}")
    if high is not None and v > high:
        raise ConfigError(f"{path}: must be <= {high:g} {unit}, got {v:g}")
    if not allow_zero and v == 0.0:
        raise ConfigError(f"{path}: must be non-zero ({unit})")
    return v


def _name(value: Any, path: str) -> str:
    if isinstance(value, bool) or not isinstance(value, (str, int, float)):
        raise ConfigError(f"{path}: expected a name (text), got {_kind(value)}")
    text = str(value)
    if not 0 < len(text) <= 200:
        raise ConfigError(f"{path}: expected 1 to 200 characters, got {len(text)}")
    return text


def reject_unknown_keys(mapping: Mapping[str, Any], allowed: set[str], path: str) -> None:
    _require_mapping(mapping, path)
    unknown = sorted((str(k) for k in mapping if k not in allowed))
    if unknown:
        raise ConfigError(f"{path}: unknown field(s) {unknown}; allowed: {sorted(allowed)}")


# --------------------------------------------------------------------------- records
@dataclass(frozen=True)
class BearingCoefficients:
    """Linearized bearing force coefficients (Eq. 1 of Miller & Howard).

    Stiffness ``k..`` in N/m, damping ``c..`` in N*s/m.
    """

    kxx: float
    kxy: float
    kyx: float
    kyy: float
    cxx: float
    cxy: float
    cyx: float
    cyy: float

    def as_array(self) -> np.ndarray:
        """The 8 coefficients as ``[kxx kxy kyx kyy cxx cxy cyx cyy]`` (SI)."""
        return np.array([getattr(self, n) for n in COEFFICIENT_NAMES], dtype=float)

    @classmethod
    def from_array(cls, values: np.ndarray) -> "BearingCoefficients":
        values = np.asarray(values, dtype=float)
        if values.shape != (8,):
            raise ConfigError(f"coefficients: expected 8 values, got shape {values.shape}")
        return cls(*map(float, values))

    @classmethod
    def from_mapping(cls, mapping: Mapping[str, Any], path: str) -> "BearingCoefficients":
        """Read ``kxx_N_per_m ... cyy_N_s_per_m`` keys (plain ``kxx`` also accepted)."""
        _require_mapping(mapping, path)
        values = []
        for name, long_name, unit in zip(COEFFICIENT_NAMES, COEFFICIENT_NAMES_WITH_UNITS, COEFFICIENT_UNITS):
            key = long_name if long_name in mapping else name
            values.append(number_field(get_field(mapping, key, path), f"{path}.{long_name}", unit))
        reject_unknown_keys(mapping, set(COEFFICIENT_NAMES) | set(COEFFICIENT_NAMES_WITH_UNITS), path)
        return cls(*values)

    def to_mapping(self) -> dict[str, float]:
        return {ln: float(v) for ln, v in zip(COEFFICIENT_NAMES_WITH_UNITS, self.as_array())}


@dataclass(frozen=True)
class Imbalance:
    """One imbalance mass: ``mass_kg`` at ``radius_m``, angle ``phase_rad`` from the
    keyphasor mark (shaft angle zero), in the plane at ``axial_position_m``."""

    mass_kg: float
    radius_m: float
    phase_rad: float
    axial_position_m: float

    @property
    def moment_kg_m(self) -> float:
        return self.mass_kg * self.radius_m


@dataclass(frozen=True)
class RigConfig:
    """Geometry and inertia of the rigid rotor-bearing rig (Table 1 of Miller & Howard)."""

    name: str
    shaft_mass_kg: float
    polar_inertia_kg_m2: float
    transverse_inertia_kg_m2: float
    bearing1_position_m: float
    bearing2_position_m: float
    probe1_position_m: float
    probe2_position_m: float
    impact_position_m: float
    imbalances: tuple[Imbalance, ...]
    speed_rad_s: float
    sample_rate_hz: float
    noise_std_m: float
    true_coefficients: BearingCoefficients | None = None

    @property
    def bearing_span_m(self) -> float:
        """L = l1 + l2 of Eq. 3."""
        return self.bearing2_position_m - self.bearing1_position_m

    @property
    def sample_period_s(self) -> float:
        return 1.0 / self.sample_rate_hz

    def validate(self) -> "RigConfig":
        p = "rig"
        number_field(self.shaft_mass_kg, f"{p}.shaft.mass_kg", "kg", low=0.0, low_open=True)
        number_field(self.polar_inertia_kg_m2, f"{p}.shaft.polar_inertia_kg_m2", "kg*m^2", low=0.0)
        number_field(self.transverse_inertia_kg_m2, f"{p}.shaft.transverse_inertia_kg_m2", "kg*m^2", low=0.0,
                     low_open=True)
        if not self.bearing1_position_m < self.bearing2_position_m:
            raise ConfigError(f"{p}.bearings: bearing1.axial_position_m ({self.bearing1_position_m:g} m) must be "
                              f"less than bearing2.axial_position_m ({self.bearing2_position_m:g} m)")
        if self.probe1_position_m == self.probe2_position_m:
            raise ConfigError(f"{p}.probes: probe1 and probe2 must be at different axial positions "
                              f"(both at {self.probe1_position_m:g} m): the rigid-body tilt would be unobservable")
        if self.speed_rad_s < 0:
            raise ConfigError(f"{p}.operating.speed_rpm: must be >= 0 rpm")
        number_field(self.sample_rate_hz, f"{p}.operating.sample_rate_hz", "Hz", low=1.0, high=1e7)
        number_field(self.noise_std_m, f"{p}.operating.noise_std_m", "m", low=0.0, high=1e-2)
        return self


@dataclass(frozen=True)
class EstimatorConfig:
    """EKF tuning (Miller & Howard, section "Estimating Bearing Properties").

    * ``initial_coefficients``: r0 (the paper's initial guess).
    * ``initial_coefficient_std``: sqrt(diag P0) for the 8 coefficients, SI.
    * ``initial_displacement_std_m`` / ``initial_velocity_std_m_s``: sqrt(diag P0) of the
      motion states (the paper does not state them; the shaft starts near equilibrium).
    * ``measurement_noise_std_m``: sqrt(diag R); the paper's "R = 1.0 um" is a standard
      deviation (see errata 4 in the seeds README).
    * ``coefficient_random_walk``: Q_r as a standard deviation rate, SI per sqrt(s); 0 in the paper.
    * ``motion_process_noise_accel_m_s2``: sqrt of the continuous Q_v density (m/s^2/sqrt(Hz)).
    * ``innovation_gate_nis``: samples whose normalized innovation squared exceeds this are
      rejected as outliers (chi-square with 4 dof; 40 is p < 1e-7).
    * ``passes``: number of passes over the same data, each seeded by the previous
      pass's final coefficients (the paper's multi-pass use).
    """

    initial_coefficients: BearingCoefficients
    initial_coefficient_std: BearingCoefficients
    initial_displacement_std_m: float = 1e-4
    initial_velocity_std_m_s: float = 0.05
    measurement_noise_std_m: float = 1e-6
    coefficient_random_walk: BearingCoefficients = field(
        default_factory=lambda: BearingCoefficients(*([0.0] * 8)))
    motion_process_noise_accel_m_s2: float = 0.0
    innovation_gate_nis: float = 40.0
    passes: int = 1

    def validate(self) -> "EstimatorConfig":
        p = "estimator"
        for name, value in zip(COEFFICIENT_NAMES_WITH_UNITS, self.initial_coefficient_std.as_array()):
            if not value > 0:
                raise ConfigError(f"{p}.initial_coefficient_std.{name}: must be > 0, got {value:g}")
        for name, value in zip(COEFFICIENT_NAMES_WITH_UNITS, self.coefficient_random_walk.as_array()):
            if value < 0:
                raise ConfigError(f"{p}.coefficient_random_walk.{name}: must be >= 0, got {value:g}")
        number_field(self.initial_displacement_std_m, f"{p}.initial_displacement_std_m", "m", low=0.0, low_open=True)
        number_field(self.initial_velocity_std_m_s, f"{p}.initial_velocity_std_m_s", "m/s", low=0.0, low_open=True)
        number_field(self.measurement_noise_std_m, f"{p}.measurement_noise_std_m", "m", low=0.0, low_open=True,
                     high=1e-2)
        number_field(self.motion_process_noise_accel_m_s2, f"{p}.motion_process_noise_accel_m_s2", "m/s^2/sqrt(Hz)",
                     low=0.0)
        number_field(self.innovation_gate_nis, f"{p}.innovation_gate_nis", "(dimensionless)", low=1.0)
        if not isinstance(self.passes, int) or isinstance(self.passes, bool) or not 1 <= self.passes <= 20:
            raise ConfigError(f"{p}.passes: must be an integer from 1 to 20, got {self.passes!r}")
        return self


@dataclass(frozen=True)
class RigFile:
    """A whole rig file: the rig and the estimator tuning that goes with it."""

    rig: RigConfig
    estimator: EstimatorConfig


# --------------------------------------------------------------------------- loading
_RIG_KEYS = {"name", "shaft", "bearings", "probes", "impact", "imbalances", "operating", "true_coefficients"}


def rig_from_mapping(data: Mapping[str, Any], path: str = "rig") -> RigConfig:
    """Build and validate a :class:`RigConfig` from a parsed YAML mapping."""
    reject_unknown_keys(data, _RIG_KEYS, path)
    shaft = get_field(data, "shaft", path)
    reject_unknown_keys(shaft, {"mass_kg", "polar_inertia_kg_m2", "transverse_inertia_kg_m2"}, f"{path}.shaft")
    bearings = get_field(data, "bearings", path)
    reject_unknown_keys(bearings, {"bearing1", "bearing2"}, f"{path}.bearings")
    probes = get_field(data, "probes", path)
    reject_unknown_keys(probes, {"probe1", "probe2"}, f"{path}.probes")
    operating = get_field(data, "operating", path)
    reject_unknown_keys(operating, {"speed_rpm", "sample_rate_hz", "noise_std_m"}, f"{path}.operating")
    impact = get_field(data, "impact", path, default={"axial_position_m": 0.0})
    reject_unknown_keys(impact, {"axial_position_m"}, f"{path}.impact")

    def position(section: Mapping[str, Any], key: str, sp: str) -> float:
        item = get_field(section, key, sp)
        reject_unknown_keys(item, {"axial_position_m"}, f"{sp}.{key}")
        return number_field(get_field(item, "axial_position_m", f"{sp}.{key}"), f"{sp}.{key}.axial_position_m", "m",
                       low=-100.0, high=100.0)

    imbalances = []
    raw_imbalances = get_field(data, "imbalances", path, default=[])
    if not isinstance(raw_imbalances, list):
        raise ConfigError(f"{path}.imbalances: expected a list of imbalance masses")
    for i, item in enumerate(raw_imbalances):
        ip = f"{path}.imbalances[{i}]"
        reject_unknown_keys(item, {"mass_kg", "radius_m", "phase_deg", "axial_position_m"}, ip)
        imbalances.append(Imbalance(
            mass_kg=number_field(get_field(item, "mass_kg", ip), f"{ip}.mass_kg", "kg", low=0.0, high=100.0),
            radius_m=number_field(get_field(item, "radius_m", ip), f"{ip}.radius_m", "m", low=0.0, high=10.0),
            phase_rad=math.radians(number_field(get_field(item, "phase_deg", ip), f"{ip}.phase_deg", "deg",
                                           low=-360.0, high=360.0)),
            axial_position_m=number_field(get_field(item, "axial_position_m", ip), f"{ip}.axial_position_m", "m",
                                     low=-100.0, high=100.0),
        ))
    true_coefficients = None
    if "true_coefficients" in data and data["true_coefficients"] is not None:
        true_coefficients = BearingCoefficients.from_mapping(data["true_coefficients"], f"{path}.true_coefficients")
    rig = RigConfig(
        name=_name(get_field(data, "name", path, default="unnamed rig"), f"{path}.name"),
        shaft_mass_kg=number_field(get_field(shaft, "mass_kg", f"{path}.shaft"), f"{path}.shaft.mass_kg", "kg",
                              low=0.0, low_open=True, high=1e6),
        polar_inertia_kg_m2=number_field(get_field(shaft, "polar_inertia_kg_m2", f"{path}.shaft"),
                                    f"{path}.shaft.polar_inertia_kg_m2", "kg*m^2", low=0.0, high=1e6),
        transverse_inertia_kg_m2=number_field(get_field(shaft, "transverse_inertia_kg_m2", f"{path}.shaft"),
                                         f"{path}.shaft.transverse_inertia_kg_m2", "kg*m^2",
                                         low=0.0, low_open=True, high=1e6),
        bearing1_position_m=position(bearings, "bearing1", f"{path}.bearings"),
        bearing2_position_m=position(bearings, "bearing2", f"{path}.bearings"),
        probe1_position_m=position(probes, "probe1", f"{path}.probes"),
        probe2_position_m=position(probes, "probe2", f"{path}.probes"),
        impact_position_m=number_field(get_field(impact, "axial_position_m", f"{path}.impact", default=0.0),
                                  f"{path}.impact.axial_position_m", "m", low=-100.0, high=100.0),
        imbalances=tuple(imbalances),
        speed_rad_s=number_field(get_field(operating, "speed_rpm", f"{path}.operating"), f"{path}.operating.speed_rpm",
                            "rpm", low=0.0, high=1e6) * 2.0 * math.pi / 60.0,
        sample_rate_hz=number_field(get_field(operating, "sample_rate_hz", f"{path}.operating"),
                               f"{path}.operating.sample_rate_hz", "Hz", low=1.0, high=1e7),
        noise_std_m=number_field(get_field(operating, "noise_std_m", f"{path}.operating"),
                                 f"{path}.operating.noise_std_m",
                            "m", low=0.0, high=1e-2),
        true_coefficients=true_coefficients,
    )
    return rig.validate()


_EST_KEYS = {"initial_coefficients", "initial_coefficient_std", "initial_displacement_std_m",
             "initial_velocity_std_m_s", "measurement_noise_std_m", "coefficient_random_walk",
             "motion_process_noise_accel_m_s2", "innovation_gate_nis", "passes"}


def estimator_from_mapping(data: Mapping[str, Any], path: str = "estimator") -> EstimatorConfig:
    """Build and validate an :class:`EstimatorConfig` from a parsed YAML mapping."""
    reject_unknown_keys(data, _EST_KEYS, path)
    defaults = EstimatorConfig(initial_coefficients=BearingCoefficients(*([0.0] * 8)),
                               initial_coefficient_std=BearingCoefficients(*([1.0] * 8)))
    kwargs: dict[str, Any] = {
        "initial_coefficients": BearingCoefficients.from_mapping(
            get_field(data, "initial_coefficients", path), f"{path}.initial_coefficients"),
        "initial_coefficient_std": BearingCoefficients.from_mapping(
            get_field(data, "initial_coefficient_std", path), f"{path}.initial_coefficient_std"),
    }
    if "coefficient_random_walk" in data:
        kwargs["coefficient_random_walk"] = BearingCoefficients.from_mapping(
            data["coefficient_random_walk"], f"{path}.coefficient_random_walk")
    for f in fields(EstimatorConfig):
        if f.name in kwargs or f.name not in data:
            continue
        if f.name == "passes":
            kwargs["passes"] = data["passes"]
        else:
            kwargs[f.name] = number_field(data[f.name], f"{path}.{f.name}", "SI", low=0.0)
    del defaults
    return EstimatorConfig(**kwargs).validate()


#: Largest YAML file read (rig and rotor files are a few kB).
MAX_YAML_BYTES = 1 << 20
#: Largest number of nodes a YAML document may expand to once its aliases are followed
#: (the bundled rig has about 100; a 2.8 kB "billion laughs" file expands to 10^9).
MAX_YAML_NODES = 100_000


@functools.lru_cache(maxsize=None)
def _strict_loader_class():
    """A ``yaml.SafeLoader`` subclass (no Python tags, ever) that refuses duplicate mapping keys
    and documents whose aliases expand beyond :data:`MAX_YAML_NODES` nodes (or into a cycle)."""
    import yaml
    from yaml.nodes import MappingNode, SequenceNode

    class StrictSafeLoader(yaml.SafeLoader):
        def compose_document(self):
            node = super().compose_document()
            _check_expansion(node)
            return node

        def construct_mapping(self, node, deep=False):
            if isinstance(node, MappingNode):
                seen: dict[Any, int] = {}
                for key_node, _ in node.value:
                    if key_node.tag == "tag:yaml.org,2002:merge":
                        continue  # '<<' merges are overridden by explicit keys, by design
                    key = self.construct_object(key_node, deep=True)
                    try:
                        hash(key)
                    except TypeError:
                        continue  # unhashable: the base class reports it
                    line = key_node.start_mark.line + 1
                    if key in seen:
                        raise _DuplicateKey(key, seen[key], line)
                    seen[key] = line
            return super().construct_mapping(node, deep=deep)

    def _check_expansion(root) -> None:
        sizes: dict[int, int] = {}
        active: set[int] = set()

        def size(node) -> int:
            key = id(node)
            if key in sizes:
                return sizes[key]
            if key in active:
                raise _AliasBomb("an alias refers to a node that contains it (a recursive structure)")
            total = 1
            if isinstance(node, (SequenceNode, MappingNode)):
                active.add(key)
                children = node.value if isinstance(node, SequenceNode) else [n for kv in node.value for n in kv]
                for child in children:
                    total += size(child)
                    if total > MAX_YAML_NODES:
                        raise _AliasBomb(f"its aliases expand to more than {MAX_YAML_NODES} values")
                active.discard(key)
            sizes[key] = total
            return total

        if root is not None:
            size(root)

    return StrictSafeLoader


class _DuplicateKey(Exception):
    def __init__(self, key: Any, first_line: int, line: int) -> None:
        super().__init__(f"duplicate key {str(key)[:60]!r} at line {line} (first given at line {first_line}); "
                         f"YAML would silently keep the last value: remove one")


class _AliasBomb(Exception):
    pass


def _yaml_error_line(exc: Exception) -> str:
    """One line from a PyYAML error (its own text spans several lines)."""
    problem = getattr(exc, "problem", None)
    mark = getattr(exc, "problem_mark", None)
    if problem:
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
        context = getattr(exc, "context", None)
        return f"{problem}{where}" + (f" ({context})" if context else "")
    return " ".join(str(exc).split())


def load_yaml_file(path: str | Path, what: str = "rig file") -> Any:
    """Parse a configuration YAML file safely: at most :data:`MAX_YAML_BYTES`, UTF-8, the safe
    schema only (``!!python/...`` tags are refused), no duplicate keys, no alias bombs.

    Every refusal is a :class:`~rotor_estimator.core.errors.ConfigError` starting ``{what} {path}:``."""
    import yaml

    path = Path(path)
    try:
        if path.is_dir():
            raise ConfigError(f"{what} {path}: is a directory, expected a YAML file")
        if path.exists() and not path.is_file():  # a FIFO would block the read forever
            raise ConfigError(f"{what} {path}: not a regular file (a pipe or device), expected a YAML file")
        with open(path, "rb") as fh:
            raw = fh.read(MAX_YAML_BYTES + 1)
    except OSError as exc:
        raise ConfigError(f"{what} {path}: cannot be read ({exc.strerror or exc})") from exc
    if len(raw) > MAX_YAML_BYTES:
        raise ConfigError(f"{what} {path}: larger than {MAX_YAML_BYTES // 1024} KiB; "
                          f"a {what} is a few kB of YAML")
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise ConfigError(f"{what} {path}: not UTF-8 text (byte 0x{raw[exc.start]:02x} at offset {exc.start}); "
                          f"save it as UTF-8") from None
    try:
        return yaml.load(text, Loader=_strict_loader_class())  # noqa: S506 - a SafeLoader subclass
    except _DuplicateKey as exc:
        raise ConfigError(f"{what} {path}: {exc}") from None
    except _AliasBomb as exc:
        raise ConfigError(f"{what} {path}: refused, {exc}") from None
    except RecursionError:
        raise ConfigError(f"{what} {path}: refused, it is nested too deeply") from None
    except yaml.constructor.ConstructorError as exc:
        tag = str(getattr(exc, "problem", "")).rpartition("tag ")[2].strip("'")
        if tag.startswith("tag:yaml.org,2002:python/"):
            mark = exc.problem_mark
            raise ConfigError(f"{what} {path}: refused the tag !!{tag.split(':', 2)[2]} at line {mark.line + 1} "
                              f"(configuration files hold plain data; Python objects are never built)") from None
        raise ConfigError(f"{what} {path}: not valid YAML: {_yaml_error_line(exc)}") from None
    except yaml.YAMLError as exc:
        raise ConfigError(f"{what} {path}: not valid YAML: {_yaml_error_line(exc)}") from None


def load_rig_file(path: str | Path | None = None) -> RigFile:
    """Load a rig YAML file (``None``: the bundled Miller & Howard seed rig); see :func:`load_yaml_file`."""
    path = Path(path) if path is not None else SEED_RIG_PATH
    data = load_yaml_file(path, "rig file")
    if not isinstance(data, Mapping):
        raise ConfigError(f"rig file {path}: expected a mapping with 'rig' and 'estimator' sections, "
                          f"got {_kind(data)}")
    reject_unknown_keys(data, {"rig", "estimator"}, "(top level)")
    try:
        rig = rig_from_mapping(get_field(data, "rig", "(top level)"))
        estimator = estimator_from_mapping(get_field(data, "estimator", "(top level)"))
    except ConfigError as exc:
        raise ConfigError(f"rig file {path}: {exc}") from None
    return RigFile(rig=rig, estimator=estimator)


def with_overrides(rig: RigConfig, **changes: Any) -> RigConfig:
    """A validated copy of ``rig`` with some fields replaced."""
    return replace(rig, **changes).validate()
