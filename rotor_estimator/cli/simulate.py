# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""``rotor-estimator simulate``: simulated input topics (the paper's cases, a ramp, a `plan` design) to an MCAP bag."""
from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np

from rotor_estimator.cli import arguments as cli_types
from rotor_estimator.core.errors import BagError, InputError

def _simulate_design(args: argparse.Namespace, rig) -> int:
    """One record of a planner test (``plan`` prints these command lines), as an input bag."""
    from rotor_estimator.io.bags import write_input_bag
    from rotor_estimator.core.config import load_rig_file
    from rotor_estimator.identification.planner import candidate_designs
    from rotor_estimator.identification.scenarios import simulate_design
    from rotor_estimator.core.recording import RigRecording

    rig_file = load_rig_file(args.rig)
    expected = (rig.true_coefficients or rig_file.estimator.initial_coefficients).as_array()
    designs = {d.name: d for d in candidate_designs(rig, expected, hammer_force_n=args.hammer_force_n)}
    design = designs.get(args.design)
    if design is None:
        raise InputError(f"--design {args.design!r}: not a test of `rotor-estimator plan` for this rig; "
                         f"choose one of: {'; '.join(designs)}")
    if not 0 <= args.record < design.n_records:
        raise InputError(f"--record: the test has {design.n_records} record(s): 0..{design.n_records - 1}")
    if Path(args.out).exists():
        raise BagError(f"bag {args.out} already exists; remove it or choose another output path")
    sim = simulate_design(rig, design, seed=args.seed)[args.record]
    dt = rig.sample_period_s
    first = int(round(design.discard_initial_s / dt))
    t = (np.arange(first, first + len(sim.record.t_s))) * dt
    force = np.zeros((t.size, 2))
    for imp in design.impacts:  # zero-order hold: the sample whose period holds the pulse carries it
        k = int(np.floor(imp.start_s / dt + 1e-9)) - first
        if 0 <= k < t.size:
            force[k] += (imp.force_x_n, imp.force_y_n)
    t0_ns = 1_700_000_000_000_000_000
    rec = RigRecording(t0_ns + np.round(t * 1e9).astype(np.int64), sim.record.probes_m,
                       t0_ns + np.round(sim.pulse_times_s * 1e9).astype(np.int64), force,
                       {"command": "rotor-estimator simulate --design", "design": design.name, "record": args.record,
                        "seed": args.seed})
    write_input_bag(args.out, rec, block_size=args.block_size)
    weight = design.trial_weights[args.record - 1] if args.record else None
    print(f"wrote {args.out}: record {args.record} of '{design.name}' ({len(rec)} samples"
          + (f", trial weight {weight.mass_kg * 1e3:.4g} g at {weight.radius_m * 1e3:.4g} mm, "
             f"plane {weight.plane + 1}, "
             f"{np.degrees(weight.phase_rad):.0f} deg" if weight else "") + ")")
    return 0


def cmd_simulate(args: argparse.Namespace) -> int:
    import dataclasses

    from rotor_estimator.io.bags import write_input_bag
    from rotor_estimator.core.config import load_rig_file
    from rotor_estimator.core.simulator import paper_scenario, simulate

    from rotor_estimator.core.simulator import MILLER_HOWARD_IMPACT, Impact

    rig = load_rig_file(args.rig).rig
    if args.design is not None:
        return _simulate_design(args, rig)
    scenario = paper_scenario(args.scenario)
    if args.duration is not None:
        scenario = dataclasses.replace(scenario, duration_s=float(args.duration))
    if args.speed_end_rpm is not None:  # a linear coast-down or run-up over the whole record
        scenario = dataclasses.replace(scenario, speed_end_rad_s=float(args.speed_end_rpm) * 2 * np.pi / 60,
                                       name=f"{scenario.name}, ramp to {args.speed_end_rpm:g} rpm")
    if args.impacts is not None:  # the paper's 515 N, 50 us pulse, alternating y and x, evenly spaced
        if args.impacts < 0:
            raise InputError("--impacts must be >= 0")
        start, span = scenario.discard_initial_s, scenario.duration_s - scenario.discard_initial_s
        hammer = MILLER_HOWARD_IMPACT
        impacts = tuple(Impact(start + span * (i + 0.5) / args.impacts, hammer.duration_s,
                               0.0 if i % 2 == 0 else -hammer.force_y_n, hammer.force_y_n if i % 2 == 0 else 0.0)
                        for i in range(args.impacts))
        scenario = dataclasses.replace(scenario, impacts=impacts, name=f"{scenario.name}, {args.impacts} impacts")
    if Path(args.out).exists():
        raise BagError(f"bag {args.out} already exists; remove it or choose another output path")
    rec = simulate(rig, scenario, seed=args.seed).recording
    rec.meta.update({"command": "rotor-estimator simulate", "duration_s": scenario.duration_s})
    write_input_bag(args.out, rec, block_size=args.block_size)
    print(f"wrote {args.out}: {len(rec)} samples per probe plane at {rig.sample_rate_hz:g} Hz, "
          f"{rec.pulse_stamps_ns.size} keyphasor pulses, scenario {scenario.name}, seed {args.seed}")
    return 0


def add_parser(subparsers: Any) -> None:
    """The ``simulate`` subcommand."""
    p = subparsers.add_parser("simulate", help="write simulated input topics to an MCAP bag")
    p.add_argument("--rig", type=Path, default=None, help="rig YAML (default: the bundled seed rig)")
    p.add_argument("--scenario", choices=["imbalance+impact", "imbalance"], default="imbalance+impact",
                   help="Miller & Howard's cases (default imbalance+impact)")
    p.add_argument("--duration", type=float, default=None,
                   help="simulated time from rest, s (default 0.125, the paper's; the first 0.03 s are dropped)")
    p.add_argument("--speed-end-rpm", type=float, default=None,
                   help="ramp the speed linearly from the rig's speed to this over the record (a coast-down "
                        "or run-up; e.g. --scenario imbalance --duration 2 --speed-end-rpm 3000)")
    p.add_argument("--design", default=None, metavar="NAME",
                   help="simulate a test of `rotor-estimator plan` by its name (plan prints the command lines)")
    p.add_argument("--record", type=int, default=0, help="which record of --design (0: without trial weight)")
    p.add_argument("--hammer-force-n", type=float, default=515.0, metavar="N",
                   help="hammer peak force used to build the --design tests, N (as given to plan)")
    p.add_argument("--impacts", type=int, default=None,
                   help="replace the scenario's impacts by N hammer pulses (515 N, 50 us) alternating y and x, "
                        "evenly spaced over the recorded time")
    p.add_argument("--seed", type=cli_types.seed, default=1, help="noise seed (default 1)")
    p.add_argument("--block-size", type=int, default=200, help="samples per probe message (default 200)")
    p.add_argument("--out", type=Path, required=True, help="new bag directory")
    p.set_defaults(func=cmd_simulate)
