# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""``rotor-estimator replay``: runs the estimator node's logic
(:class:`~rotor_estimator.core.pipeline.EstimatorPipeline`
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


from rotor_estimator.cli import arguments as cli_types
from rotor_estimator.cli.arguments import add_bag_argument, bag_from_args
from rotor_estimator.core.errors import BagError, InputError, NoDataError
from rotor_estimator.core.identifiability import NOT_DETERMINED

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
    missing = [t for t in (topics.probe1, topics.probe2, topics.keyphasor)
               if available is not None and t not in available]
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


def add_parser(subparsers: Any) -> None:
    """The ``replay`` subcommand."""
    p = subparsers.add_parser("replay", help="run the estimator node's logic over a bag (no ROS graph)")
    add_bag_argument(p, "rosbag2 directory or .mcap file with the input topics")
    p.add_argument("--rig", type=Path, default=None, help="rig YAML (default: the bundled seed rig)")
    p.add_argument("--out", type=Path, default=None, help="write the node's output topics to this new MCAP bag")
    p.add_argument("--publish-rate", dest="publish_rate_hz", type=float, default=200.0, metavar="HZ",
                   help="estimates per second of sample time written to --out and --csv (default 200)")
    p.add_argument("--csv", type=Path, default=None, metavar="FILE",
                   help="write the coefficient history (time_s, each coefficient and its std, NIS) as CSV")
    p.add_argument("--salvage", action="store_true", help=cli_types.SALVAGE_HELP)
    p.add_argument("--json", action="store_true", help="print JSON (SI units)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_replay)
