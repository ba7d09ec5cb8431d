# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Rotor description file: frozen, validated records of a flexible rotor on bearings.

All quantities are SI and the unit is in every field name. Axial stations
(``station_axial_m``) are measured along the shaft from its first end (the start of
the first shaft section), unlike the rigid rig file (measured from the mass center).
Lateral directions: ``x`` horizontal, ``y`` vertical; the shaft spins from +x toward
+y (the same convention as :mod:`rotor_estimator.core.model`).

A bad or missing field raises :class:`~rotor_estimator.core.errors.ConfigError` naming the
field by its dotted path (e.g. ``rotor.bearings[1].kxx_N_per_m``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

from rotor_estimator.core.config import get_field, number_field, reject_unknown_keys, load_yaml_file
from rotor_estimator.core.errors import ConfigError

ROTORS_DIR = Path(__file__).resolve().parents[2] / "rotors"

__all__ = [
    "Material", "ShaftSection", "Disk", "Pedestal", "Bearing", "Unbalance", "Sensor", "Station",
    "ModelOptions", "RotorDescription", "rotor_from_mapping", "load_rotor_description", "ROTORS_DIR",
]


@dataclass(frozen=True)
class Material:
    density_kg_m3: float
    youngs_modulus_pa: float
    poisson_ratio: float

    @property
    def shear_modulus_pa(self) -> float:
        return self.youngs_modulus_pa / (2.0 * (1.0 + self.poisson_ratio))


@dataclass(frozen=True)
class ShaftSection:
    """A uniform tube of ``length_m`` (``inner_diameter_m`` 0 for a solid shaft)."""

    length_m: float
    outer_diameter_m: float
    inner_diameter_m: float = 0.0


@dataclass(frozen=True)
class Disk:
    """A rigid disk (lumped mass and inertia) at a shaft station (Nelson & McVaugh)."""

    name: str
    station_axial_m: float
    mass_kg: float
    polar_inertia_kg_m2: float
    transverse_inertia_kg_m2: float


@dataclass(frozen=True)
class Pedestal:
    """A rigid support body on springs to ground (Neisi et al., Fig. 9).

    Translations ``x, y`` always; a yaw rotation (about the vertical axis, tilting the
    x-z plane) and a pitch rotation (about the horizontal axis, tilting the y-z
    plane) about ``axial_position_m`` when their inertia is > 0.
    """

    name: str
    mass_kg: float
    kxx_N_per_m: float
    kyy_N_per_m: float
    cxx_N_s_per_m: float = 0.0
    cyy_N_s_per_m: float = 0.0
    axial_position_m: float = 0.0
    yaw_inertia_kg_m2: float = 0.0
    pitch_inertia_kg_m2: float = 0.0
    k_yaw_N_m_per_rad: float = 0.0
    k_pitch_N_m_per_rad: float = 0.0
    c_yaw_N_m_s_per_rad: float = 0.0
    c_pitch_N_m_s_per_rad: float = 0.0


@dataclass(frozen=True)
class Bearing:
    """Linear bearing between the shaft and ground or a pedestal (``kxx ... cyy``, SI)."""

    name: str
    station_axial_m: float
    kxx_N_per_m: float
    kxy_N_per_m: float
    kyx_N_per_m: float
    kyy_N_per_m: float
    cxx_N_s_per_m: float
    cxy_N_s_per_m: float
    cyx_N_s_per_m: float
    cyy_N_s_per_m: float
    pedestal: str | None = None


@dataclass(frozen=True)
class Unbalance:
    """``mass_kg`` at ``radius_m``, angle ``phase_rad`` from the keyphasor (Eq. 7 of Neisi et al.)."""

    station_axial_m: float
    mass_kg: float
    radius_m: float
    phase_rad: float


@dataclass(frozen=True)
class Sensor:
    """A measurement location giving one channel per direction (``<name>_x``, ``<name>_y``).

    ``kind='probe'``: proximity probe, shaft displacement relative to its housing (the
    pedestal named by ``pedestal``, or ground); ``noise_std`` in m.
    ``kind='accelerometer'``: absolute acceleration of the pedestal point at the
    station (``pedestal`` set; the paper's housing accelerometers) or of the shaft
    station (``pedestal`` None); ``noise_std`` in m/s^2.
    """

    name: str
    kind: str
    station_axial_m: float
    directions: tuple[str, ...]
    noise_std: float
    pedestal: str | None = None

    @property
    def channel_names(self) -> tuple[str, ...]:
        return tuple(f"{self.name}_{d}" for d in self.directions)

    @property
    def unit(self) -> str:
        return "m" if self.kind == "probe" else "m/s^2"


@dataclass(frozen=True)
class Station:
    """A place to estimate: absolute shaft displacement, velocity and acceleration."""

    name: str
    station_axial_m: float


@dataclass(frozen=True)
class ModelOptions:
    """Model and filter settings.

    * ``n_modes``: modes kept by the reduction (Appendix A of Neisi et al.); 0 keeps all.
    * ``max_element_length_m``: mesh size; nodes are also put at every disk, bearing,
      unbalance, section end.
    * ``shaft_damping_stiffness_proportional_s``: beta of C_shaft = beta K_shaft.
    * ``process_noise_force_N_sqrt_s``: sqrt of the two-sided density q (N^2 s) of an
      unknown white random force at every shaft node in x and y (absorbs unmodelled
      forcing such as residual unbalance).
    """

    n_modes: int = 8
    max_element_length_m: float = 0.05
    shaft_damping_stiffness_proportional_s: float = 0.0
    process_noise_force_N_sqrt_s: float = 0.01


@dataclass(frozen=True)
class RotorDescription:
    name: str
    material: Material
    sections: tuple[ShaftSection, ...]
    disks: tuple[Disk, ...]
    bearings: tuple[Bearing, ...]
    pedestals: tuple[Pedestal, ...]
    unbalances: tuple[Unbalance, ...]
    sensors: tuple[Sensor, ...]
    stations: tuple[Station, ...]
    speed_rad_s: float
    sample_rate_hz: float
    options: ModelOptions

    @property
    def length_m(self) -> float:
        return float(sum(s.length_m for s in self.sections))

    @property
    def channel_names(self) -> tuple[str, ...]:
        return tuple(c for s in self.sensors for c in s.channel_names)

    def pedestal_index(self, name: str) -> int:
        for i, p in enumerate(self.pedestals):
            if p.name == name:
                return i
        raise ConfigError(f"rotor: no pedestal named {name!r}; defined: {[p.name for p in self.pedestals]}")


# --------------------------------------------------------------------------- loading
def _list(data: Mapping[str, Any], key: str, path: str) -> list[Any]:
    items = get_field(data, key, path, default=[]) or []
    if not isinstance(items, list):
        raise ConfigError(f"{path}.{key}: expected a list")
    return items


def _station(item: Mapping[str, Any], ip: str, length: float) -> float:
    return number_field(get_field(item, "station_axial_m", ip), f"{ip}.station_axial_m", "m", low=0.0, high=length)


def _opt_name(item: Mapping[str, Any], key: str, ip: str, names: set[str]) -> str | None:
    value = item.get(key)
    if value is None:
        return None
    if str(value) not in names:
        raise ConfigError(f"{ip}.{key}: no pedestal named {value!r}; defined: {sorted(names)}")
    return str(value)


def rotor_from_mapping(data: Mapping[str, Any], path: str = "rotor") -> RotorDescription:
    """Build and validate a :class:`RotorDescription` from a parsed YAML mapping."""
    reject_unknown_keys(data, {"name", "material", "shaft", "disks", "bearings", "pedestals", "unbalances",
                           "sensors", "stations", "operating", "model"}, path)
    mat = get_field(data, "material", path)
    reject_unknown_keys(mat, {"density_kg_m3", "youngs_modulus_pa", "poisson_ratio"}, f"{path}.material")
    material = Material(
        number_field(get_field(mat, "density_kg_m3", f"{path}.material"), f"{path}.material.density_kg_m3", "kg/m^3",
                low=0.0, low_open=True),
        number_field(get_field(mat, "youngs_modulus_pa", f"{path}.material"), f"{path}.material.youngs_modulus_pa",
                     "Pa",
                low=0.0, low_open=True),
        number_field(get_field(mat, "poisson_ratio", f"{path}.material"), f"{path}.material.poisson_ratio", "-",
                low=-0.99, high=0.5))
    sections = []
    for i, item in enumerate(_list(data, "shaft", path)):
        ip = f"{path}.shaft[{i}]"
        reject_unknown_keys(item, {"length_m", "outer_diameter_m", "inner_diameter_m"}, ip)
        od = number_field(get_field(item, "outer_diameter_m", ip), f"{ip}.outer_diameter_m", "m", low=0.0,
                          low_open=True)
        idm = number_field(item.get("inner_diameter_m", 0.0), f"{ip}.inner_diameter_m", "m", low=0.0)
        if idm >= od:
            raise ConfigError(f"{ip}.inner_diameter_m: must be < outer_diameter_m ({od:g} m), got {idm:g}")
        sections.append(ShaftSection(number_field(get_field(item, "length_m", ip), f"{ip}.length_m", "m", low=0.0,
                                             low_open=True), od, idm))
    if not sections:
        raise ConfigError(f"{path}.shaft: needs at least one section")
    length = sum(s.length_m for s in sections)

    pedestals = []
    for i, item in enumerate(_list(data, "pedestals", path)):
        ip = f"{path}.pedestals[{i}]"
        allowed = {f for f in Pedestal.__dataclass_fields__}
        reject_unknown_keys(item, allowed, ip)
        kw: dict[str, Any] = {"name": str(get_field(item, "name", ip))}
        for f in allowed - {"name"}:
            if f in item or f in {"mass_kg", "kxx_N_per_m", "kyy_N_per_m"}:
                kw[f] = number_field(get_field(item, f, ip), f"{ip}.{f}", "SI",
                                     low=None if f == "axial_position_m" else 0.0)
        if kw["mass_kg"] <= 0:
            raise ConfigError(f"{ip}.mass_kg: must be > 0 kg")
        pedestals.append(Pedestal(**kw))
    ped_names = {p.name for p in pedestals}
    if len(ped_names) != len(pedestals):
        raise ConfigError(f"{path}.pedestals: names must be unique")

    disks = []
    for i, item in enumerate(_list(data, "disks", path)):
        ip = f"{path}.disks[{i}]"
        reject_unknown_keys(item, {"name", "station_axial_m", "mass_kg", "polar_inertia_kg_m2",
                               "transverse_inertia_kg_m2"}, ip)
        disks.append(Disk(str(item.get("name", f"disk{i + 1}")), _station(item, ip, length),
                          *(number_field(get_field(item, f, ip), f"{ip}.{f}", "SI", low=0.0)
                            for f in ("mass_kg", "polar_inertia_kg_m2", "transverse_inertia_kg_m2"))))
    bearings = []
    coef = ("kxx_N_per_m", "kxy_N_per_m", "kyx_N_per_m", "kyy_N_per_m",
            "cxx_N_s_per_m", "cxy_N_s_per_m", "cyx_N_s_per_m", "cyy_N_s_per_m")
    for i, item in enumerate(_list(data, "bearings", path)):
        ip = f"{path}.bearings[{i}]"
        reject_unknown_keys(item, {"name", "station_axial_m", "pedestal", *coef}, ip)
        values = [number_field(item.get(f, 0.0), f"{ip}.{f}", "SI") for f in coef]
        for f in ("kxx_N_per_m", "kyy_N_per_m"):
            if f not in item:
                raise ConfigError(f"{ip}.{f}: missing required field")
        bearings.append(Bearing(str(item.get("name", f"bearing{i + 1}")), _station(item, ip, length), *values,
                                pedestal=_opt_name(item, "pedestal", ip, ped_names)))
    if not bearings:
        raise ConfigError(f"{path}.bearings: needs at least one bearing (a free-free rotor cannot be filtered)")

    unbalances = []
    for i, item in enumerate(_list(data, "unbalances", path)):
        ip = f"{path}.unbalances[{i}]"
        reject_unknown_keys(item, {"station_axial_m", "mass_kg", "radius_m", "phase_deg"}, ip)
        unbalances.append(Unbalance(
            _station(item, ip, length), number_field(get_field(item, "mass_kg", ip), f"{ip}.mass_kg", "kg", low=0.0),
            number_field(get_field(item, "radius_m", ip), f"{ip}.radius_m", "m", low=0.0),
            math.radians(number_field(item.get("phase_deg", 0.0), f"{ip}.phase_deg", "deg", low=-360, high=360))))

    sensors = []
    for i, item in enumerate(_list(data, "sensors", path)):
        ip = f"{path}.sensors[{i}]"
        reject_unknown_keys(item, {"name", "kind", "station_axial_m", "directions", "noise_std_m", "noise_std_m_s2",
                               "pedestal"}, ip)
        kind = str(get_field(item, "kind", ip))
        if kind not in ("probe", "accelerometer"):
            raise ConfigError(f"{ip}.kind: must be 'probe' or 'accelerometer', got {kind!r}")
        noise_key = "noise_std_m" if kind == "probe" else "noise_std_m_s2"
        directions = tuple(str(d) for d in item.get("directions", ["x", "y"]))
        if not directions or any(d not in ("x", "y") for d in directions) or len(set(directions)) != len(directions):
            raise ConfigError(f"{ip}.directions: a list of distinct 'x' and 'y', got {directions!r}")
        sensors.append(Sensor(str(get_field(item, "name", ip)), kind, _station(item, ip, length), directions,
                              number_field(get_field(item, noise_key, ip), f"{ip}.{noise_key}", "SI", low=0.0,
                                           low_open=True),
                              _opt_name(item, "pedestal", ip, ped_names)))
    names = [s.name for s in sensors]
    if len(set(names)) != len(names):
        raise ConfigError(f"{path}.sensors: names must be unique, got {names}")

    stations = []
    for i, item in enumerate(_list(data, "stations", path)):
        ip = f"{path}.stations[{i}]"
        reject_unknown_keys(item, {"name", "station_axial_m"}, ip)
        stations.append(Station(str(get_field(item, "name", ip)), _station(item, ip, length)))

    op = get_field(data, "operating", path)
    reject_unknown_keys(op, {"speed_rpm", "sample_rate_hz"}, f"{path}.operating")
    speed = number_field(get_field(op, "speed_rpm", f"{path}.operating"), f"{path}.operating.speed_rpm", "rpm", low=0.0)
    rate = number_field(get_field(op, "sample_rate_hz", f"{path}.operating"), f"{path}.operating.sample_rate_hz", "Hz",
                   low=1.0, high=1e7)
    mo = data.get("model", {}) or {}
    reject_unknown_keys(mo, set(ModelOptions.__dataclass_fields__), f"{path}.model")
    n_modes = mo.get("n_modes", ModelOptions.n_modes)
    if isinstance(n_modes, bool) or not isinstance(n_modes, int) or n_modes < 0:
        raise ConfigError(f"{path}.model.n_modes: must be an integer >= 0 (0: keep all), got {n_modes!r}")
    options = ModelOptions(
        n_modes=n_modes,
        max_element_length_m=number_field(mo.get("max_element_length_m", ModelOptions.max_element_length_m),
                                     f"{path}.model.max_element_length_m", "m", low=0.0, low_open=True),
        shaft_damping_stiffness_proportional_s=number_field(
            mo.get("shaft_damping_stiffness_proportional_s", 0.0),
            f"{path}.model.shaft_damping_stiffness_proportional_s", "s", low=0.0),
        process_noise_force_N_sqrt_s=number_field(
            mo.get("process_noise_force_N_sqrt_s", ModelOptions.process_noise_force_N_sqrt_s),
            f"{path}.model.process_noise_force_N_sqrt_s", "N*sqrt(s)", low=0.0))
    return RotorDescription(str(data.get("name", "unnamed rotor")), material, tuple(sections), tuple(disks),
                            tuple(bearings), tuple(pedestals), tuple(unbalances), tuple(sensors), tuple(stations),
                            speed * 2.0 * math.pi / 60.0, rate, options)


def load_rotor_description(path: str | Path) -> RotorDescription:
    """Load a rotor YAML file; a bare name (e.g. ``'three_probe_rig'``) loads a bundled example."""
    p = Path(path)
    if not p.exists() and (ROTORS_DIR / f"{p.name}.yaml").exists():
        p = ROTORS_DIR / f"{p.name}.yaml"
    data = load_yaml_file(p, "rotor file")  # size, UTF-8, duplicate-key and alias limits
    if not isinstance(data, Mapping) or "rotor" not in data:
        raise ConfigError(f"rotor file {p}: expected a mapping with a top-level 'rotor' section")
    reject_unknown_keys(data, {"rotor"}, "(top level)")
    try:
        return rotor_from_mapping(data["rotor"])
    except ConfigError as exc:
        raise ConfigError(f"rotor file {p}: {exc}") from None
