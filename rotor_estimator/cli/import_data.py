# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""``rotor-estimator import``: a DAQ recording (CSV, NPZ, HDF5) as an input bag.

A thin shell over :mod:`rotor_estimator.io.daq_import`: everything is read and validated before the
bag is written, and the bag is written all-or-nothing (:class:`~rotor_estimator.io.bags.BagWriter`).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import numpy as np

from rotor_estimator.core.errors import BagError, InputError


def _mapping(text: str | None, option: str) -> dict[str, str]:
    """``a=b,c=d`` -> {"a": "b", "c": "d"} (one line naming the bad pair otherwise)."""
    if not text:
        return {}
    out = {}
    for pair in text.split(","):
        key, sep, value = pair.partition("=")
        if not sep or not key.strip() or not value.strip():
            raise InputError(f"{option}: expected NAME=VALUE pairs separated by commas, got {pair!r}")
        if key.strip() in out:
            raise InputError(f"{option}: {key.strip()!r} given twice")
        out[key.strip()] = value.strip()
    return out


def _sensitivity(text: str | None) -> dict[str, float]:
    """``7870`` (all four probe channels) or ``xp1=7870,yp1=7900,...`` in V/m."""
    from rotor_estimator.io.daq_import import PROBE_CHANNELS

    if not text:
        return {}
    try:
        if "=" not in text:
            value = float(text)
            return {ch: value for ch in PROBE_CHANNELS}
        return {k: float(v) for k, v in _mapping(text, "--sensitivity-v-per-m").items()}
    except ValueError:
        raise InputError(f"--sensitivity-v-per-m: numbers in V/m expected (7.87 V/mm = 7870), got {text!r}") from None


def _angles(text: str | None) -> tuple[float, float] | None:
    if not text:
        return None
    try:
        a, b = (float(v) for v in text.split(","))
    except ValueError:
        raise InputError(f"--probe-angles-deg: two angles in degrees 'A,B' expected (e.g. 45,135), got {text!r}") \
            from None
    return a, b


def cmd_import(args: argparse.Namespace) -> int:
    from rotor_estimator.io.bags import write_input_bag
    from rotor_estimator.core.config import load_rig_file
    from rotor_estimator.io.daq_import import ImportConfig, read_table, recording_from_table
    from rotor_estimator.core.tachometer import TachometerConfig, max_speed_for_rig

    if Path(args.out).exists():
        raise BagError(f"bag {args.out} already exists; remove it or choose another output path")
    rig = load_rig_file(args.rig).rig
    columns = _mapping(args.columns, "--columns")
    if args.tach_column:
        columns["tach"] = args.tach_column
    config = ImportConfig(columns=columns, delimiter=args.delimiter, hdf5_group=args.hdf5_group,
                          sensitivity_v_per_m=_sensitivity(args.sensitivity_v_per_m),
                          probe_angles_deg=_angles(args.probe_angles_deg), time_offset_s=args.time_offset_s,
                          tach_threshold_v=args.tach_threshold_v, tach_hysteresis_v=args.tach_hysteresis_v,
                          rig_sample_rate_hz=rig.sample_rate_hz,
                          rig_speed_range_rad_s=(TachometerConfig().min_speed_rad_s,
                                                  max_speed_for_rig(rig.speed_rad_s)))
    table = read_table(args.signals, "SIGNALS", delimiter=args.delimiter, hdf5_group=args.hdf5_group)
    pulses = None
    if args.tach is not None:
        tcols = read_table(args.tach, "PULSES", delimiter=args.delimiter, hdf5_group=args.hdf5_group)
        key = next((k for k in tcols if k.lower() == "pulse_times"), None)
        if key is None:
            raise InputError(f"PULSES file {args.tach}: missing column pulse_times (s); found {sorted(tcols)}")
        pulses = tcols[key]
    rec, warnings = recording_from_table(table, config, pulses, str(args.signals))
    for w in warnings:
        print(f"rotor-estimator import: warning: {w}", file=sys.stderr)
    rec.meta["rig"] = rig.name
    write_input_bag(args.out, rec, block_size=args.block_size)
    speed_rpm = 60.0 / float(np.median(np.diff(rec.pulse_stamps_ns)) * 1e-9)
    print(f"wrote {args.out}: {len(rec)} samples per probe plane "
          f"({(rec.stamps_ns[-1] - rec.stamps_ns[0]) * 1e-9:.4g} s), {rec.pulse_stamps_ns.size} keyphasor pulses "
          f"(median {speed_rpm:.6g} rpm), {int(np.any(rec.impact_force_n != 0, axis=1).sum())} samples with impact "
          f"force")
    return 0


def add_parser(subparsers: Any) -> None:
    """The ``import`` subcommand."""
    p = subparsers.add_parser(
        "import", help="convert a DAQ recording (CSV, NPZ, HDF5) to an input bag",
        description="Read probe displacements, a keyphasor and optional hammer force from a DAQ export, check "
                    "them, and write the estimator's input bag. Refuses (exit 2, nothing written) what would give "
                    "wrong numbers: values not in metres, no or misaligned keyphasor, duplicate columns.")
    p.add_argument("signals", type=Path, metavar="SIGNALS",
                   help="CSV (header row), NPZ or HDF5 (.h5) with t (s), xp1, yp1, xp2, yp2 (m, or V with "
                        "--sensitivity-v-per-m), optional impact_fx, impact_fy (N, zero-order hold)")
    p.add_argument("--tach", type=Path, default=None, metavar="PULSES",
                   help="CSV, NPZ or HDF5 with pulse_times (s, same clock as t, one per revolution at angle 0)")
    p.add_argument("--tach-column", default=None, metavar="NAME",
                   help="a raw keyphasor voltage column of SIGNALS; pulses at its rising threshold crossings")
    p.add_argument("--tach-threshold-v", type=float, default=None, metavar="V",
                   help="voltage at which a keyphasor pulse starts (with --tach-column)")
    p.add_argument("--tach-hysteresis-v", type=float, default=None, metavar="V",
                   help="the signal must fall this far below the threshold before the next pulse "
                        "(default 10 %% of its range)")
    p.add_argument("--columns", default=None, metavar="MAP",
                   help="column names in the file, e.g. t=Time,xp1=CH1,yp1=CH2,xp2=CH3,yp2=CH4,impact_fx=F1")
    p.add_argument("--delimiter", default=None,
                   help="CSV field delimiter (default: sniffed among , ; and tab; 'whitespace' for spaces)")
    p.add_argument("--hdf5-group", default="/", metavar="PATH", help="HDF5 group holding the datasets (default /)")
    p.add_argument("--sensitivity-v-per-m", default=None, metavar="S",
                   help="probe sensitivity in V/m when the probe columns are volts: one value (7870 = 7.87 V/mm) "
                        "or per channel xp1=7870,yp1=7910,...")
    p.add_argument("--probe-angles-deg", default=None, metavar="A,B",
                   help="measuring directions of each plane's two probes, degrees from horizontal towards vertical "
                        "(e.g. 45,135 for X/Y probes at 45 degrees); default: xp along x, yp along y")
    p.add_argument("--time-offset-s", type=float, default=0.0, metavar="S",
                   help="added to t and to the pulse times (a DAQ clock offset); negative times are shifted")
    p.add_argument("--rig", type=Path, default=None,
                   help="rig YAML: its sample rate and speed are checked against the data (default: the seed rig)")
    p.add_argument("--block-size", type=int, default=200, help="samples per probe message (default 200)")
    p.add_argument("--out", type=Path, required=True, help="new bag directory")
    p.set_defaults(func=cmd_import)


__all__ = ["add_parser", "cmd_import"]
