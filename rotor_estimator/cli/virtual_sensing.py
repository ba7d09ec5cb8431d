# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Command-line wiring for virtual sensing (argparse; no ROS).

``rotor-estimator virtual-sensing``: leave-one-station-out validation on a bundled
example (synthetic, model-consistent data), an NPZ file or a multi-sensor bag
(``--bag``, one PointCloud2 topic per sensor, see :mod:`msg_adapters.stations`), printed
as a table or ``--json``; ``--report DIR`` writes figures, ``--out-bag`` the station
estimates as topics. Bag and plotting modules are imported only when asked for, so this
module imports neither rosbags nor matplotlib. ``rotor-estimator bench virtual-sensing``: the paper-scale speed test
(UKF, 150 states, 8 observations, 8192 samples) plus the exact Kalman filter and the
leave-one-station-out coverage. Handlers take the parsed args and return an exit code.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np

from rotor_estimator.core.errors import InputError, RotorEstimatorError
from rotor_estimator.cli import arguments as cli_types
from rotor_estimator.io.safe_write import save_npz
from rotor_estimator.virtual_sensing.loaders import (MAX_NPZ_ELEMENTS, load_bag_channels, load_npz_channels,
                                                     read_npz_arrays)
from rotor_estimator.core.flexible.description import load_rotor_description
from rotor_estimator.core.flexible.state_space import (build_state_space, simulate,
                                   station_outputs)
from rotor_estimator.virtual_sensing.estimator import (FILTERS, VirtualSensingConfig, estimate_stations,
                                                       leave_one_station_out,
                              resolve_stations)

__all__ = ["add_parser", "run_virtual_sensing", "load_npz_channels", "load_bag_channels", "pulses_from_inputs",
           "read_npz_arrays", "MAX_NPZ_ELEMENTS"]

DEFAULT_ROTOR = "three_probe_rig"


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    p = subparsers.add_parser(
        "virtual-sensing", help="estimate unmeasured stations; leave-one-station-out validation",
        description="Hide each sensor in turn, estimate it from the others and report the error, the "
                    "coverage of the 95%% interval and its width (Neisi et al. 2022, Table 6). Without "
                    "--data, runs on model-consistent synthetic data from the rotor file.")
    p.add_argument("--rotor", default=DEFAULT_ROTOR,
                   help=f"rotor description YAML, or a bundled name (default: {DEFAULT_ROTOR})")
    src = p.add_mutually_exclusive_group()
    src.add_argument("--data", type=Path, help="NPZ file: 't' (s) and one array per channel '<sensor>_<x|y>' "
                                               "(m or m/s^2); optional 'shaft_angle_rad'")
    src.add_argument("--bag", type=Path, help="rosbag2 (MCAP) with one PointCloud2 topic per sensor "
                                              "(<prefix>/<sensor name>) and keyphasor TimeReference pulses")
    p.add_argument("--sensor-topic-prefix", default="/rotor", help="sensor topics of --bag (default /rotor)")
    p.add_argument("--keyphasor-topic", default="/rotor/keyphasor", help="keyphasor topic of --bag")
    p.add_argument("--samples", type=cli_types.positive_int, default=4096,
                   help="synthetic samples when no --data (default 4096)")
    p.add_argument("--seed", type=cli_types.seed, default=0, help="random seed of the synthetic data")
    p.add_argument("--filter", choices=FILTERS, default="kf", help="kf (exact), ekf or ukf (default kf)")
    p.add_argument("--alpha", type=float, default=1e-3, help="UKF alpha (default 1e-3)")
    p.add_argument("--beta", type=float, default=2.0, help="UKF beta (default 2)")
    p.add_argument("--kappa", type=float, default=0.0, help="UKF kappa (default 0)")
    p.add_argument("--n-modes", type=cli_types.non_negative_int, help="modes kept (overrides the rotor file; 0: all)")
    p.add_argument("--hide", action="append", metavar="SENSOR", help="sensor to hide (repeatable; default all)")
    p.add_argument("--burn-in", type=cli_types.non_negative_int, default=0, help="samples left out of the statistics")
    p.add_argument("--estimates-out", type=Path, help="write station estimates (mean, std, ellipse) to NPZ")
    p.add_argument("--station", action="append", metavar="NAME[=AXIAL_M]",
                   help="station to estimate (repeatable): a station or sensor of the rotor file, or name=axial "
                        "position in m; default: the rotor file's stations")
    p.add_argument("--report", type=Path, metavar="DIR", help="write figures: orbit with 95%% ellipse per station, "
                                                               "leave-one-out traces with 95%% bands (PNG)")
    p.add_argument("--write-input-bag", type=Path, metavar="OUT",
                   help="also write the input data (channels and keyphasor pulses at the shaft angle's zero "
                        "crossings) as a multi-sensor bag, e.g. to replay it to virtual_sensing_node")
    p.add_argument("--out", "--out-bag", dest="out_bag", type=Path, metavar="OUT",
                   help="write station estimates (and leave-one-out predictions) as topics to a new MCAP bag")
    p.add_argument("--strict", action="store_true", help="exit 1 when a coverage is off by more than the tolerance")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.set_defaults(func=run_virtual_sensing)
    return p




# --------------------------------------------------------------------------- data
# --------------------------------------------------------------------------- handlers
def _config(args: argparse.Namespace) -> VirtualSensingConfig:
    return VirtualSensingConfig(filter=args.filter, ukf_alpha=args.alpha, ukf_beta=args.beta,
                                ukf_kappa=args.kappa, burn_in_samples=args.burn_in)


def pulses_from_inputs(stamps_ns: np.ndarray, u: np.ndarray, speed_rad_s: float) -> np.ndarray:
    """Keyphasor pulse stamps (ns) where the shaft angle of ``u = Omega^2 [cos, sin]``
    passes a multiple of 2 pi, interpolated at ``speed_rad_s``."""
    theta = np.unwrap(np.arctan2(u[:, 1], u[:, 0]))
    turns = np.floor(theta / (2 * math.pi))
    i = np.flatnonzero(np.diff(turns) > 0)
    out = [int(stamps_ns[0])] if abs(theta[0] % (2 * math.pi)) < 1e-12 else []
    for k in i:
        out.append(int(stamps_ns[k] + round((2 * math.pi * turns[k + 1] - theta[k]) / speed_rad_s * 1e9)))
    return np.asarray(out, dtype=np.int64)


def run_virtual_sensing(args: argparse.Namespace) -> int:
    try:
        rotor = load_rotor_description(args.rotor)
        ss = build_state_space(rotor, n_modes=args.n_modes)
        config = _config(args)
        x_true, info = None, {}
        if args.bag is not None:
            stamps, z, u, info = load_bag_channels(args.bag, ss, args.sensor_topic_prefix, args.keyphasor_topic)
            t = (stamps - stamps[0]).astype(float) * 1e-9
            source = str(args.bag)
        elif args.data is not None:
            t, z, u = load_npz_channels(args.data, ss)
            stamps = np.rint(t * 1e9).astype(np.int64)
            source = str(args.data)
        else:
            if args.samples < 10:
                raise InputError("--samples: at least 10")
            sim = simulate(ss, args.samples, seed=args.seed)
            t, z, u, x_true = sim.t, sim.z, sim.u, sim.x
            stamps = np.rint(t * 1e9).astype(np.int64)
            source = f"synthetic (model-consistent, seed {args.seed})"
        want_traces = args.report is not None or args.out_bag is not None
        report = leave_one_station_out(ss, z, u, config, hidden=args.hide, x_true=x_true, keep_traces=want_traces)
        estimates = []
        if args.estimates_out is not None or want_traces:
            stations = resolve_stations(ss, args.station) if (args.station or rotor.stations) else []
            estimates = estimate_stations(ss, t, z, u, config, stations) if stations else []
        if args.estimates_out is not None and estimates:
            _write_estimates(args.estimates_out, estimates, config.confidence)
        written = []
        if args.report is not None:
            from rotor_estimator.virtual_sensing.plots import write_report

            truth = None
            if x_true is not None:
                truth = {e.name: x_true @ station_outputs(ss, e.station_axial_m)[0][:2].T for e in estimates}
            written = write_report(args.report, estimates, report, t, speed_rad_s=rotor.speed_rad_s,
                                   sample_rate_hz=rotor.sample_rate_hz, confidence=config.confidence, truth=truth)
        if args.write_input_bag is not None:
            from rotor_estimator.virtual_sensing.inputs import write_sensor_bag

            write_sensor_bag(args.write_input_bag, rotor, stamps, z, pulses_from_inputs(stamps, u, rotor.speed_rad_s),
                             meta={"source": source})
        if args.out_bag is not None:
            from rotor_estimator.virtual_sensing.inputs import write_estimates_bag

            write_estimates_bag(args.out_bag, estimates, stamps, report=report, hardware_id=rotor.name)
    except RotorEstimatorError as exc:
        print(f"rotor-estimator: error: {exc}", file=sys.stderr)
        return 2
    flagged = any(not r.calibrated for r in report.rows)
    if args.json:
        out = {"rotor": rotor.name, "data": source, "n_states": ss.n_states, "n_samples": int(len(t)),
               **({"bag": info} if info else {}), **report.to_dict()}
        print(json.dumps(out, indent=2, default=cli_types.json_default))
    else:
        print(f"rotor {rotor.name}: {ss.n_states} states ({ss.reduced.n_modes} modes), {len(t)} samples, "
              f"data: {source}")
        if info:
            print("bag: " + ", ".join(f"{k} {v}" for k, v in info.items()))
        print(report.format_table())
        if flagged:
            print("coverage off by more than the tolerance on the channels marked NO: the intervals are not "
                  "calibrated there (model, Q or R do not match the data)")
        if written:
            print(f"report: {len(written)} files in {args.report}")
        if args.write_input_bag is not None:
            print(f"input data written to {args.write_input_bag}")
        if args.out_bag is not None:
            print(f"station estimates written to {args.out_bag}")
    return 1 if (flagged and args.strict) else 0



def _write_estimates(path: Path, estimates: list, confidence: float) -> None:
    arrays: dict[str, np.ndarray] = {}
    for e in estimates:
        arrays["t"] = e.t_s
        for j, name in enumerate(e.names):
            arrays[f"{e.name}_{name}"] = e.mean[:, j]
            arrays[f"{e.name}_{name}_std"] = e.std[:, j]
        ell = np.array([e.ellipse(k, confidence) for k in range(len(e.t_s))])
        arrays[f"{e.name}_ellipse_semi_major_m"] = ell[:, 0]
        arrays[f"{e.name}_ellipse_semi_minor_m"] = ell[:, 1]
        arrays[f"{e.name}_ellipse_angle_rad"] = ell[:, 2]
    save_npz(path, **arrays)  # never through a symbolic link (safe_write)


# --------------------------------------------------------------------------- bench




