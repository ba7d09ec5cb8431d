# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Bag commands: ``replay``, ``simulate``, ``import`` and ``bench live``.

``replay`` runs the estimator node's logic (:class:`~rotor_estimator.core.pipeline.EstimatorPipeline`
after :func:`~rotor_estimator.ros.pipeline_io.feed_message`) over a bag message by message, with no
ROS graph, and can write the node's output topics into a new MCAP bag. With ``passes: 2``
in the rig file (the seed rig's setting) it runs the paper's multi-pass use: pass 2 starts
from pass 1's final coefficients with the configured P0 and replays the same messages; only
the last pass's outputs are written and printed.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

from rotor_estimator.cli import arguments as cli_types
from rotor_estimator.cli.arguments import add_bag_argument, bag_from_args
from rotor_estimator.core.errors import BagError, InputError, NoDataError
from rotor_estimator.core.identifiability import LABEL_RULE, NOT_DETERMINED


# ---------------------------------------------------------------------------------- replay
#: replay's exit codes: 0 an estimate; 2 bad input or usage; 3 nothing could be filtered (no
#: estimate, the cause is named); 4 an estimate was printed but the filter diverged (status ERROR).
EXIT_DIVERGED = 4
def replay_bag(bag: str | Path, rig_path: str | Path | None = None, out_bag: str | Path | None = None, *,
               progress: bool = True, publish_period_s: float = 0.005, salvage: bool = False,
               csv_path: str | Path | None = None) -> dict[str, Any]:
    """Replay ``bag`` through the pipeline (``passes`` from the rig file); return the summary dict.

    One estimate every ``publish_period_s`` of sample time goes to ``out_bag`` and to the
    coefficient-history CSV ``csv_path`` (last pass)."""
    from tqdm import tqdm

    import msg_adapters as ma

    from rotor_estimator.core.alignment import AlignmentConfig
    from rotor_estimator.io.bags import OutputBagWriter, bag_damage, bag_topics, iter_bag_messages
    from rotor_estimator.core.config import COEFFICIENT_NAMES, COEFFICIENT_UNITS, load_rig_file
    from rotor_estimator.ros.pipeline_io import feed_message, output_messages, stream_by_topic
    from rotor_estimator.core.pipeline import EstimatorPipeline

    rig_file = load_rig_file(rig_path)
    topics = ma.DEFAULT_INPUT_TOPICS
    damage = bag_damage(bag) if salvage else None
    available = bag_topics(bag) if damage is None else None
    missing = [t for t in (topics.probe1, topics.probe2, topics.keyphasor) if available is not None and t not in available]
    if missing:
        raise BagError(f"bag {bag} lacks input topic(s) {missing}; it has {sorted(available)}")
    if out_bag is not None and Path(out_bag).exists():
        raise BagError(f"output bag {out_bag} already exists; remove it or choose another path")
    streams = stream_by_topic(topics)
    passes = rig_file.estimator.passes
    initial = None
    written = 0
    final = None
    history: list = []
    if out_bag is None and csv_path is None:  # nothing writes the intermediate estimates: make fewer
        publish_period_s = max(publish_period_s, 0.05)
    for k in range(passes):
        pipe = EstimatorPipeline(rig_file.rig, rig_file.estimator, None,
                                 AlignmentConfig(sample_rate_hz=rig_file.rig.sample_rate_hz), publish_period_s,
                                 initial_coefficients=initial)
        last = k == passes - 1
        writer = OutputBagWriter(out_bag).open() if (last and out_bag is not None) else None
        try:
            with tqdm(desc=f"replay pass {k + 1}/{passes}", unit="msg", file=sys.stderr, disable=not progress,
                      leave=False) as bar:
                for m in iter_bag_messages(bag, list(streams), salvage=salvage, warn=k == 0):
                    feed_message(pipe, streams[m.topic], m.msg)
                    outs = pipe.process()
                    if writer is not None:
                        written += _write(writer, outs, output_messages, rig_file.rig.name)
                    if last and csv_path is not None:
                        history += outs
                    bar.update()
                outs = pipe.flush()
                if writer is not None:
                    written += _write(writer, outs, output_messages, rig_file.rig.name)
                if last and csv_path is not None:
                    history += outs
        except BaseException:  # error or Ctrl-C: no partial output bag is left behind
            if writer is not None:
                writer.abort()
            raise
        if writer is not None:
            writer.close()
        if pipe.accounting().processed == 0 or not outs:
            raise NoDataError(f"bag {bag}: no probe sample could be filtered, so there is no estimate: "
                              f"{pipe.no_data_cause()}")
        final = outs[-1]
        initial = final.coefficients
    if csv_path is not None:
        _write_history_csv(csv_path, history)
    acc = pipe.accounting()
    coefficients = {}
    ident = {e.name: e for e in final.identifiability.entries}
    for name, unit, mean, std in zip(COEFFICIENT_NAMES, COEFFICIENT_UNITS, final.coefficients, final.std):
        coefficients[name] = {"mean": float(mean), "std": float(std), "unit": unit,
                              "status": ident[name].status, "predicted_std_from_data": ident[name].predicted_std,
                              "relative_std_used_for_status": ident[name].relative_std}
    not_determined = final.identifiability.names_with(NOT_DETERMINED)
    table = final.identifiability.format(posterior_std=final.std, units=COEFFICIENT_UNITS)
    summary = acc.summary()
    samples = {"processed": summary["processed"], "rejected": summary["rejected"],
               **{k: v for k, v in summary.items() if k not in ("processed", "rejected")}}
    d = final.diagnostics
    consistency = pipe.consistency.verdict()
    return {"bag": str(bag), "rig": rig_file.rig.name, "passes": passes, "stamp_ns": final.stamp_ns,
            "coefficients": coefficients, "not_determined": not_determined, "samples": samples,
            "accounting_balanced": acc.balanced(), "pulses": dict(acc.pulses),
            "status": {"level": d.level, "message": d.message, "converged": d.converged,
                       "nis_window_mean": d.nis_window_mean, "divergence_recoveries": d.divergence_recoveries},
            "out": str(out_bag) if out_bag is not None else None, "outputs_written": written,
            "salvaged": damage.describe() if damage is not None else None,
            "consistency": consistency.as_dict(), "table": table}


def _write_history_csv(path: str | Path, outputs: list) -> None:
    """The coefficient history as CSV, one row per published estimate; units in the header."""
    from rotor_estimator.core.config import COEFFICIENT_NAMES, COEFFICIENT_UNITS
    from rotor_estimator.io.safe_write import write_text

    units = [u.replace("*", "_").replace("/", "_per_") for u in COEFFICIENT_UNITS]
    header = ["stamp_ns", "time_s"] + [f"{n}_{u}" for n, u in zip(COEFFICIENT_NAMES, units)] + \
        [f"{n}_std_{u}" for n, u in zip(COEFFICIENT_NAMES, units)] + ["nis_window_mean", "status_level"]
    t0 = outputs[0].stamp_ns if outputs else 0
    rows = [",".join(header)]
    for o in outputs:
        rows.append(",".join([str(o.stamp_ns), f"{(o.stamp_ns - t0) * 1e-9:.9f}"]
                             + [f"{v:.9g}" for v in o.coefficients] + [f"{v:.6g}" for v in o.std]
                             + [f"{o.nis_window_mean:.6g}", str(o.diagnostics.level)]))
    write_text(path, "\n".join(rows) + "\n")


def _write(writer, outs, output_messages, hardware_id: str) -> int:
    for out in outs:
        for topic, msg in output_messages(writer.factory, out, hardware_id=hardware_id):
            writer.write(topic, msg, out.stamp_ns)
    return len(outs)


def format_replay(r: dict[str, Any]) -> str:
    c = r["consistency"]
    lines = [f"bag {r['bag']} (rig {r['rig']}, {r['passes']} pass{'es' if r['passes'] > 1 else ''}); "
             f"estimate at stamp {r['stamp_ns']} ns", "", r["table"], ""]
    if c["samples"] and c["nis_band"][0] == c["nis_band"][0]:
        lines += [f"fit: mean NIS {c['nis_mean']:.3f} (consistent: {c['nis_band'][0]:.3f}-{c['nis_band'][1]:.3f} for "
                  f"{c['nis_dof']} channels over {c['samples']} samples); innovation whiteness: RMS autocorrelation "
                  f"{c['rms_autocorrelation']:.3f} over lags 1-{len(c['autocorrelation_by_lag'])} "
                  f"(Ljung-Box p = {c['whiteness_p_value']:.2g})"]
        if c["model_mismatch"]:
            lines.append(f"MODEL MISMATCH: {c['reason']}. The model does not fit these data, so the coefficients "
                         f"absorb what it lacks and their std is not their error: run `rotor-estimator diagnose "
                         f"{r['bag']}` to find the effect")
        else:
            lines.append("the model fits these data to the noise; a wrong probe or hammer sensitivity can still "
                         "shift the coefficients unseen (calibration is outside the std): run `diagnose` to check")
    s = r["samples"]
    reasons = {k: v for k, v in s.items() if v and k not in ("processed", "rejected") and not
               k.startswith(("received", "pending", "reordered"))}
    lines += [f"samples: {s['processed']} processed, {s['rejected']} rejected"
              + (f" ({', '.join(f'{k} {v}' for k, v in reasons.items())})" if reasons else ""),
              f"status: {r['status']['message']}"]
    if r["out"]:
        lines.append(f"outputs: {r['outputs_written']} estimates written to {r['out']}")
    return "\n".join(lines)


def cmd_replay(args: argparse.Namespace) -> int:
    args.bag = bag_from_args(args)
    if not args.publish_rate_hz > 0:
        raise InputError(f"--publish-rate must be > 0 Hz, got {args.publish_rate_hz:g}")
    result = replay_bag(args.bag, args.rig, args.out, progress=not args.no_progress, salvage=args.salvage,
                        publish_period_s=1.0 / args.publish_rate_hz, csv_path=args.csv)
    print(json.dumps(result, indent=1) if args.json else format_replay(result))
    return EXIT_DIVERGED if result["status"]["level"] >= 2 else 0


# ---------------------------------------------------------------------------------- simulate
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
          + (f", trial weight {weight.mass_kg * 1e3:.4g} g at {weight.radius_m * 1e3:.4g} mm, plane {weight.plane + 1}, "
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


# ---------------------------------------------------------------------------------- bench
def cmd_bench_live(args: argparse.Namespace) -> int:
    try:
        from rotor_estimator.bench.live_nodes import format_result, run
    except ImportError as exc:
        from rotor_estimator.core.errors import RotorEstimatorError

        raise RotorEstimatorError(f"bench live needs rclpy ({exc}); install the 'ros' extra or source ROS 2") from exc
    result = run(step_s=args.step_s, rates_hz=tuple(args.rates), progress=not args.json)
    print(json.dumps(result, indent=1) if args.json else format_result(result))
    return 0


# ---------------------------------------------------------------------------------- parsers
def add_parsers(subparsers: Any) -> None:
    p = subparsers.add_parser("replay", help="run the estimator node's logic over a bag (no ROS graph)")
    add_bag_argument(p, "rosbag2 directory or .mcap file with the input topics")
    p.add_argument("--rig", type=Path, default=None, help="rig YAML (default: the bundled seed rig)")
    p.add_argument("--out", type=Path, default=None, help="write the node's output topics to this new MCAP bag")
    p.add_argument("--publish-rate", dest="publish_rate_hz", type=float, default=200.0, metavar="HZ",
                   help="estimates per second of sample time written to --out and --csv (default 200)")
    p.add_argument("--csv", type=Path, default=None, metavar="FILE",
                   help="write the coefficient history (time_s, each coefficient and its std, NIS) as CSV")
    p.add_argument("--salvage", action="store_true", help="use the intact part of a damaged bag (the messages lost are counted and reported on stderr); without it a damaged bag is an error")
    p.add_argument("--json", action="store_true", help="print JSON (SI units)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_replay)

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



def add_bench_parsers(bench_subparsers: Any) -> None:
    b = bench_subparsers.add_parser("live", help="live rclpy throughput and latency (publisher + estimator node)")
    b.add_argument("--json", action="store_true")
    b.add_argument("--step-s", type=float, default=3.0, help="seconds per rate step (default 3)")
    b.add_argument("--rates", type=float, nargs="+", default=[5000.0, 10000.0, 20000.0, 40000.0, 80000.0],
                   help="probe sample rates per plane to try, Hz (200-sample blocks)")
    b.set_defaults(func=cmd_bench_live)
