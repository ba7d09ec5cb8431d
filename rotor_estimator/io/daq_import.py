# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""DAQ recordings (CSV, NPZ, HDF5) -> a validated :class:`RigRecording`, refusing what would be wrong.

Pure core: no ROS, no bag library (``rotor-estimator import`` writes the bag with :mod:`rotor_estimator.io.bags`).

What a rig's data acquisition really exports, and how each is handled:

* **Columns** are mapped by name (``ImportConfig.columns``: ``t=Time,xp1=CH1,...``); a duplicate
  column name is refused (it would otherwise silently win).
* **Units**: probe channels in volts are scaled by the probe sensitivity (V/m, e.g. 7.87 V/mm is
  7870 V/m), one value or one per channel. Values that are still clearly not metres after that
  (above :data:`MAX_PROBE_M`, i.e. um or mm, or volts without a sensitivity) are refused.
* **Probe mounting**: X/Y probes are often mounted at 45 degrees either side of vertical. With
  ``probe_angles_deg = (a_x, a_y)`` (each probe's measuring direction, from the horizontal x axis
  towards the vertical y axis) the readings ``m = x cos a + y sin a`` are solved for the rig frame.
* **Time**: ``t`` may start negative (pre-trigger data) or at any offset; ``time_offset_s`` is added
  to ``t`` and to the pulses alike, and a recording still starting before 0 is shifted as a whole
  (both clocks together; the shift is kept in the bag's metadata).
* **Keyphasor**: pulse times (s, same clock as ``t``), or a raw voltage channel turned into pulse times
  at the rising crossings of a threshold (with hysteresis, interpolated between samples). Pulses
  before the first sample are kept (they phase the first revolution). No pulse, or pulses that do
  not overlap the signals (ms instead of s, another clock), or a pulse rate outside the tracker's
  speed range, are refused.
* **Impact force** (N, optional): zero-order hold, like the estimator's input topic: the force
  sample at ``t[i]`` acts from ``t[i]`` until ``t[i + 1]``.
"""
from __future__ import annotations

import csv
import io
import math
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping

import numpy as np

from rotor_estimator.core.errors import InputError
from rotor_estimator.core.recording import RigRecording

__all__ = ["ImportConfig", "read_table", "keyphasor_from_voltage", "rotate_probes", "recording_from_table",
           "PROBE_CHANNELS", "MAX_PROBE_M"]

PROBE_CHANNELS = ("xp1", "yp1", "xp2", "yp2")
IMPACT_CHANNELS = ("impact_fx", "impact_fy")
OUR_COLUMNS = ("t", *PROBE_CHANNELS, *IMPACT_CHANNELS, "tach")
#: Largest plausible probe reading, m: a proximity probe's whole linear range is ~2 mm, so values
#: above 5 mm are um, mm or volts.
MAX_PROBE_M = 5e-3
SAMPLE_RATE_TOLERANCE = 0.01


@dataclass(frozen=True)
class ImportConfig:
    """How to read one DAQ export (see the module docstring). Validated on construction."""

    columns: Mapping[str, str] = field(default_factory=dict)   # our name -> name in the file
    delimiter: str | None = None                               # CSV: None sniffs , ; tab or spaces
    hdf5_group: str = "/"
    sensitivity_v_per_m: Mapping[str, float] = field(default_factory=dict)  # per probe channel; {} = metres
    probe_angles_deg: tuple[float, float] | None = None
    time_offset_s: float = 0.0
    tach_threshold_v: float | None = None                      # tach column is a raw voltage
    tach_hysteresis_v: float | None = None
    rig_sample_rate_hz: float | None = None
    rig_speed_range_rad_s: tuple[float, float] | None = None   # the tracker's accepted pulse rates

    def __post_init__(self) -> None:
        unknown = sorted(set(self.columns) - set(OUR_COLUMNS))
        if unknown:
            raise InputError(f"import.columns: unknown name(s) {unknown}; map any of {list(OUR_COLUMNS)}")
        if len(set(self.columns.values())) != len(self.columns):
            raise InputError(f"import.columns: two names map to the same file column: {dict(self.columns)}")
        for ch, s in self.sensitivity_v_per_m.items():
            if ch not in PROBE_CHANNELS:
                raise InputError(f"import.sensitivity_v_per_m: unknown channel {ch!r}; use {list(PROBE_CHANNELS)}")
            if not (isinstance(s, (int, float)) and math.isfinite(s) and s != 0):
                raise InputError(f"import.sensitivity_v_per_m.{ch}: must be a non-zero number in V/m, got {s!r}")
        if self.probe_angles_deg is not None:
            a, b = (math.radians(v) for v in self.probe_angles_deg)
            if abs(math.sin(b - a)) < 0.1:
                raise InputError(f"import.probe_angles_deg: the two probes of a plane must measure in different "
                                 f"directions (>= 6 degrees apart), got {self.probe_angles_deg}")
        if not math.isfinite(self.time_offset_s):
            raise InputError(f"import.time_offset_s: must be finite, got {self.time_offset_s!r}")
        if self.tach_hysteresis_v is not None and not self.tach_hysteresis_v >= 0:
            raise InputError(f"import.tach_hysteresis_v: must be >= 0 V, got {self.tach_hysteresis_v!r}")


# --------------------------------------------------------------------------- reading
def read_table(path: str | Path, what: str = "SIGNALS", *, delimiter: str | None = None,
               hdf5_group: str = "/") -> dict[str, np.ndarray]:
    """Numeric 1-D columns of a CSV (header row), NPZ or HDF5 (.h5/.hdf5) file, by name as written."""
    p = Path(path)
    if not p.exists():
        raise InputError(f"{what} file {p} not found")
    if p.is_dir():
        raise InputError(f"{what} {p} is a directory; give a .csv, .npz or .h5 file")
    suffix = p.suffix.lower()
    if suffix == ".npz":
        return _read_npz(p, what)
    if suffix in (".h5", ".hdf5", ".hdf"):
        return _read_hdf5(p, what, hdf5_group)
    if suffix == ".npy":
        raise InputError(f"{what} file {p}: a single .npy array has no column names; save the columns with "
                         f"numpy.savez (NPZ) or as CSV")
    return _read_csv(p, what, delimiter)


def _read_npz(p: Path, what: str) -> dict[str, np.ndarray]:
    if not zipfile.is_zipfile(p):
        raise InputError(f"{what} file {p}: not an NPZ archive (a renamed .npy or another format?)")
    try:
        with np.load(p, allow_pickle=False) as data:
            out = {}
            for k in data.files:
                arr = data[k]
                if arr.dtype.kind not in "biuf":
                    raise InputError(f"{what} file {p}: array {k!r} has dtype {arr.dtype}; numbers only "
                                     f"(object arrays are never unpickled)")
                out[k] = np.asarray(arr, dtype=float).reshape(-1)
            return out
    except InputError:
        raise
    except (ValueError, OSError, EOFError, zipfile.BadZipFile, KeyError) as exc:
        raise InputError(f"{what} file {p}: not a readable NPZ archive (truncated or corrupt: {exc})") from exc


def _read_hdf5(p: Path, what: str, group: str) -> dict[str, np.ndarray]:
    try:
        import h5py
    except ImportError as exc:
        raise InputError(f"{what} file {p}: reading HDF5 needs h5py (pip install h5py)") from exc
    try:
        with h5py.File(p, "r") as f:
            if group not in f:
                raise InputError(f"{what} file {p}: no group {group!r}; it has {sorted(f.keys())}")
            g = f[group]
            out = {}
            for name, ds in g.items():
                if not isinstance(ds, h5py.Dataset):
                    continue
                if ds.dtype.kind not in "biuf":
                    continue
                out[name] = np.asarray(ds[()], dtype=float).reshape(-1)
            if not out:
                raise InputError(f"{what} file {p}: no numeric dataset in group {group!r}")
            return out
    except InputError:
        raise
    except (OSError, ValueError) as exc:
        raise InputError(f"{what} file {p}: not a readable HDF5 file ({exc})") from exc


def _read_csv(p: Path, what: str, delimiter: str | None) -> dict[str, np.ndarray]:
    try:
        text = p.read_text(encoding="utf-8-sig")
    except (UnicodeDecodeError, OSError) as exc:
        raise InputError(f"{what} file {p}: not a UTF-8 text table ({exc})") from exc
    lines = text.splitlines()
    if not lines or not lines[0].strip():
        raise InputError(f"{what} file {p}: the first line must be a header of column names")
    if delimiter is None:
        try:
            delimiter = csv.Sniffer().sniff(lines[0], delimiters=",;\t").delimiter
        except csv.Error:
            delimiter = ","
    if delimiter in (" ", "whitespace"):
        split = [ln.split() for ln in lines]
    else:
        split = list(csv.reader(io.StringIO(text), delimiter=delimiter))
    names = [h.strip().strip('"') for h in split[0]]
    if any(not n for n in names):
        raise InputError(f"{what} file {p}: an empty column name in the header {lines[0]!r} "
                         f"(delimiter {delimiter!r}; choose another with --delimiter)")
    seen: dict[str, int] = {}
    for i, n in enumerate(names):
        if n.lower() in seen:
            raise InputError(f"{what} file {p}: column {n!r} appears twice (columns {seen[n.lower()] + 1} and "
                             f"{i + 1}); rename one, a duplicate would silently win")
        seen[n.lower()] = i
    rows = [r for r in split[1:] if any(c.strip() for c in r)]
    if not rows:
        raise InputError(f"{what} file {p}: no data rows")
    table = np.full((len(rows), len(names)), np.nan)
    for i, r in enumerate(rows):
        if len(r) != len(names):
            raise InputError(f"{what} file {p}: row {i + 2} has {len(r)} fields, the header {len(names)} "
                             f"(delimiter {delimiter!r})")
        for j, c in enumerate(r):
            c = c.strip()
            if c in ("", "nan", "NaN"):
                continue
            try:
                table[i, j] = float(c)
            except ValueError:
                raise InputError(f"{what} file {p}: row {i + 2}, column {names[j]!r}: {c!r} is not a number") \
                    from None
    return {n: table[:, j] for j, n in enumerate(names)}


# --------------------------------------------------------------------------- transforms
def keyphasor_from_voltage(t_s: np.ndarray, v: np.ndarray, threshold_v: float,
                           hysteresis_v: float | None = None) -> np.ndarray:
    """Pulse times (s) at the rising crossings of ``threshold_v``, linearly interpolated between the
    two samples around each crossing. A new pulse is armed only after the signal has fallen below
    ``threshold_v - hysteresis_v`` (default: 10 % of the signal's range), so noise on an edge makes one
    pulse, not several."""
    t_s, v = np.asarray(t_s, float), np.asarray(v, float)
    finite = np.isfinite(v)
    if not finite.any():
        return np.zeros(0)
    if hysteresis_v is None:
        hysteresis_v = 0.1 * float(np.ptp(v[finite]))
    low = threshold_v - hysteresis_v
    pulses = []
    armed = bool(v[0] < low) if finite[0] else False
    for i in range(1, v.size):
        if not finite[i]:
            continue
        if armed and v[i] >= threshold_v and finite[i - 1]:
            a, b = v[i - 1], v[i]
            frac = (threshold_v - a) / (b - a) if b != a else 0.0
            pulses.append(t_s[i - 1] + frac * (t_s[i] - t_s[i - 1]))
            armed = False
        elif v[i] < low:
            armed = True
    return np.asarray(pulses)


def rotate_probes(readings: np.ndarray, angles_deg: tuple[float, float]) -> np.ndarray:
    """Rig-frame (x horizontal, y vertical) displacement from two probe readings per plane.

    ``readings`` (N, 2) are ``[m_a, m_b]`` of probes measuring along ``angles_deg = (a, b)`` from the
    x axis towards y: ``m = x cos(angle) + y sin(angle)``; solved exactly (also non-orthogonal)."""
    a, b = (math.radians(v) for v in angles_deg)
    m = np.array([[math.cos(a), math.sin(a)], [math.cos(b), math.sin(b)]])
    return np.asarray(readings, float) @ np.linalg.inv(m).T


# --------------------------------------------------------------------------- assembly
def _column(table: Mapping[str, np.ndarray], name: str, config: ImportConfig, source: str) -> np.ndarray | None:
    wanted = config.columns.get(name, name)
    by_lower = {k.lower(): k for k in table}
    key = wanted if wanted in table else by_lower.get(wanted.lower())
    if key is None:
        if name in config.columns:
            raise InputError(f"{source}: mapped column {wanted!r} (for {name}) not found; found {sorted(table)}")
        return None
    return table[key]


def recording_from_table(table: Mapping[str, np.ndarray], config: ImportConfig = ImportConfig(),
                         pulse_times_s: np.ndarray | None = None,
                         source: str = "signals") -> tuple[RigRecording, list[str]]:
    """Validate the columns, apply units, mounting and time conventions; return the recording and
    the warnings (everything that would make the estimate wrong is an :class:`InputError`)."""
    cols = {name: _column(table, name, config, source) for name in OUR_COLUMNS}
    missing = [c for c in ("t", *PROBE_CHANNELS) if cols[c] is None]
    if missing:
        raise InputError(f"{source}: missing column(s) {missing}; found {sorted(table)}. Expected t (s), xp1, yp1, "
                         f"xp2, yp2 (m, or V with a sensitivity) and optionally impact_fx, impact_fy (N); map other "
                         f"names with --columns t=Time,xp1=CH1,...")
    if (cols["impact_fx"] is None) != (cols["impact_fy"] is None):
        raise InputError(f"{source}: give both impact_fx and impact_fy (N) or neither")
    t = cols["t"] + config.time_offset_s
    n = t.size
    for c in OUR_COLUMNS:
        if cols[c] is not None and cols[c].size != n:
            raise InputError(f"{source}: column {c} has {cols[c].size} values, t has {n}")
    if n < 2:
        raise InputError(f"{source}: needs at least 2 samples, got {n}")
    if not np.all(np.isfinite(t)):
        bad = np.flatnonzero(~np.isfinite(t))
        raise InputError(f"{source}: t has {bad.size} NaN/inf value(s) (first at row {int(bad[0])}); "
                         f"every sample needs a time")
    steps = np.diff(t)
    if np.any(steps <= 0):
        i = int(np.argmax(steps <= 0)) + 1
        raise InputError(f"{source}: t must increase strictly; row {i} has t = {t[i]!r} s after {t[i - 1]!r} s")
    warnings: list[str] = []

    probes = np.column_stack([cols[c] for c in PROBE_CHANNELS])
    for j, ch in enumerate(PROBE_CHANNELS):
        if ch in config.sensitivity_v_per_m:
            probes[:, j] = probes[:, j] / config.sensitivity_v_per_m[ch]
    if config.probe_angles_deg is not None:
        for cols_of_plane in (slice(0, 2), slice(2, 4)):
            probes[:, cols_of_plane] = rotate_probes(probes[:, cols_of_plane], config.probe_angles_deg)
    for j, ch in enumerate(PROBE_CHANNELS):
        bad = int((~np.isfinite(probes[:, j])).sum())
        if bad:
            warnings.append(f"{ch}: {bad} NaN/inf value(s) kept; the estimator rejects those samples (non_finite)")
    finite = np.abs(probes[np.isfinite(probes)])
    if finite.size and finite.max() > MAX_PROBE_M:
        hint = ("give the probe sensitivity (--sensitivity-v-per-m) if these are volts, or convert to metres"
                if not config.sensitivity_v_per_m else "check the sensitivity's unit (V/m: 7.87 V/mm = 7870 V/m)")
        raise InputError(f"{source}: probe values up to {finite.max():.4g} after scaling: more than "
                         f"{MAX_PROBE_M * 1e3:g} mm, so not metres (um, mm or volts?): {hint}")

    force = np.zeros((n, 2))
    if cols["impact_fx"] is not None:
        force = np.column_stack([cols["impact_fx"], cols["impact_fy"]])
        bad = ~np.isfinite(force)
        if bad.any():
            warnings.append(f"impact force: {int(bad.any(axis=1).sum())} NaN/inf row(s) read as 0 N")
            force[bad] = 0.0

    if pulse_times_s is None and cols["tach"] is not None:
        if config.tach_threshold_v is None:
            raise InputError(f"{source}: a tach column needs --tach-threshold-v (the voltage at which a "
                             f"once-per-revolution pulse starts)")
        pulse_times_s = keyphasor_from_voltage(t, cols["tach"], config.tach_threshold_v, config.tach_hysteresis_v)
    elif pulse_times_s is not None:
        pulse_times_s = np.asarray(pulse_times_s, float) + config.time_offset_s
    if pulse_times_s is None:
        raise InputError(f"{source}: no keyphasor: give pulse times (--tach PULSES) or a raw tach channel "
                         f"(--tach-column NAME --tach-threshold-v V). Without the shaft angle the imbalance force "
                         f"cannot be phased and no sample can be filtered")
    pt = np.asarray(pulse_times_s, float)
    if not np.all(np.isfinite(pt)):
        warnings.append(f"pulse_times: {int((~np.isfinite(pt)).sum())} NaN/inf value(s) dropped")
        pt = pt[np.isfinite(pt)]
    pt = np.unique(pt)
    _check_pulses(pt, t, config, source)

    shift = -min(t[0], pt[0]) if min(t[0], pt[0]) < 0 else 0.0
    if shift:
        warnings.append(f"times start at {min(t[0], pt[0]):.6g} s (pre-trigger): signals and pulses shifted by "
                        f"+{shift:.6g} s together (bag times are unsigned)")
    median_step = float(np.median(steps))
    if config.rig_sample_rate_hz:
        rate = 1.0 / median_step
        if abs(rate / config.rig_sample_rate_hz - 1) > SAMPLE_RATE_TOLERANCE:
            warnings.append(f"sample rate {rate:.6g} Hz differs from the rig file's {config.rig_sample_rate_hz:g} Hz "
                            f"by {100 * (rate / config.rig_sample_rate_hz - 1):+.1f} %: set the rig's sample_rate_hz "
                            f"to the recording's")
    if np.max(steps) > 1.5 * median_step:
        warnings.append(f"t is not evenly sampled (median step {median_step:.6g} s, largest {np.max(steps):.6g} s): "
                        f"gaps are predicted across")
    stamps = np.round((t + shift) * 1e9).astype(np.int64)
    pulses = np.round((pt + shift) * 1e9).astype(np.int64)
    meta = {"source": source, "time_shift_s": shift, "time_offset_s": config.time_offset_s,
            "sensitivity_v_per_m": dict(config.sensitivity_v_per_m),
            "probe_angles_deg": list(config.probe_angles_deg) if config.probe_angles_deg else None,
            "impact_force_convention": "zero-order hold: the force at t[i] acts until t[i+1]"}
    return RigRecording(stamps, probes, pulses, force, meta), warnings


def _check_pulses(pt: np.ndarray, t: np.ndarray, config: ImportConfig, source: str) -> None:
    """Refuse pulses that cannot be the shaft's: too few, not overlapping the signals, implausible rate."""
    if pt.size < 2:
        raise InputError(f"{source}: {pt.size} keyphasor pulse(s); at least 2 are needed to track the shaft angle")
    inside = np.sum((pt >= t[0]) & (pt <= t[-1]))
    if inside < 2:
        raise InputError(f"{source}: the keyphasor pulses ({pt[0]:.6g}-{pt[-1]:.6g} s) do not overlap the signals "
                         f"({t[0]:.6g}-{t[-1]:.6g} s): pulses on another clock or in other units (ms?); "
                         f"use --time-offset-s or fix the pulse times")
    if config.rig_speed_range_rad_s is not None:
        lo, hi = config.rig_speed_range_rad_s
        speed = 2 * math.pi / float(np.median(np.diff(pt)))
        if not lo <= speed <= hi:
            raise InputError(f"{source}: the keyphasor pulses give {speed * 60 / (2 * math.pi):.6g} rpm, outside the "
                             f"tracked range {lo * 60 / (2 * math.pi):.4g}-{hi * 60 / (2 * math.pi):.6g} rpm: pulse "
                             f"times in other units, or several pulses per revolution?")
