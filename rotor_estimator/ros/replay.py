# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Replay a bag through the estimator node's logic
(:class:`~rotor_estimator.core.pipeline.EstimatorPipeline` after
:func:`~rotor_estimator.ros.pipeline_io.feed_message`) message by message, with no ROS graph: the core
of ``rotor-estimator replay`` and of ``rotor-estimator batch replay``. With ``passes: 2`` in the rig file
pass 2 starts from pass 1's final coefficients with the configured P0 and replays the same messages;
only the last pass's outputs are written and returned.
"""
from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

from rotor_estimator.core.errors import BagError, NoDataError
from rotor_estimator.core.identifiability import NOT_DETERMINED


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


def _write(writer: Any, outs: list, output_messages: Any, hardware_id: str) -> int:
    for out in outs:
        for topic, msg in output_messages(writer.factory, out, hardware_id=hardware_id):
            writer.write(topic, msg, out.stamp_ns)
    return len(outs)
