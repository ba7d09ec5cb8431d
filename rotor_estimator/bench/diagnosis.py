# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Blind benchmark of the diagnosis: generate a fresh withheld-effect set, diagnose, then score.

The diagnosis step reads only ``cases/<id>/recording.npz`` and ``rig.yaml``; the labels
(``labels/labels.json``) are opened after every case has been diagnosed. Each case's result is kept in
``results/<id>.json`` as soon as it is done, so an interrupted run resumes where it stopped, and
:func:`score_sets` scores the cases diagnosed so far (the score says how many of the set they are).

Scores: confusion matrix (truth rows, verdict columns), top-1 and top-2 accuracy (a pair
case counts top-1 when the verdict is one of its effects and top-2 when both are in the
verdict's top two), accuracy where the gap is clear (nominal RMS >= 1.5 x the realized
noise RMS), pairs with both effects in the top two (all pairs, and apart those whose two
effects each show beyond the coefficients and the partner's model, the label's
``effect_gap``), false alarms on controls, and the shrink error ``|predicted / true - 1|`` with
``true = nominal residual RMS / realized noise RMS`` (the residual of the generating model).
"""
from __future__ import annotations

import collections
import functools
import hashlib
import json
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from rotor_estimator.bench.blind import MIN_GAP, load_recording, write_blind_set
from rotor_estimator.bench.parameter_truth import covered, independent_truth, own_truth
from rotor_estimator.batch.runner import map_ordered
from rotor_estimator.core.errors import InputError

#: Which generator(s) a benchmark draws its cases from: the package's own (``effect_sim`` and its ROSS
#: cases), the independent one (:mod:`.independent`), or both (scored apart).
GENERATORS = ("own", "independent", "both")


def generator_family(label: dict) -> str:
    """``"independent"`` for a case of :mod:`.independent`, ``"own"`` for the package's own generator."""
    return "independent" if label.get("generator") == "independent" else "own"


def from_ross(label: dict) -> bool:
    """The case's truth was simulated by ROSS: the own generator's ROSS cases and the independent generator's
    ROSS forms (``..:ross_..`` in its form)."""
    return label.get("generator") == "ross" or ":ross_" in label.get("form", "")


def write_sets(out_dir: str | Path, n_cases: int, seed: int, *, generator: str = "own", use_ross: bool = True,
               progress=None, jobs: int = 1) -> dict:
    """Write ``n_cases`` per chosen generator into ``out_dir`` (independent case ids ``ind_...`` next to the own
    ``case_...`` when both); one ``labels/labels.json`` holds them all. Returns the labels."""
    if generator not in GENERATORS:
        raise InputError(f"generator: expected one of {', '.join(GENERATORS)}, got {generator!r}")
    out = Path(out_dir)
    labels: dict = {}
    if generator in ("own", "both"):
        labels.update(write_blind_set(out, n_cases, seed, use_ross=use_ross, progress=progress, jobs=jobs))
    if generator in ("independent", "both"):
        from rotor_estimator.bench.independent import write_independent_set

        labels.update(write_independent_set(out, n_cases, seed, use_ross=use_ross, progress=progress,
                                            id_prefix="ind_" if generator == "both" else "case_"))
    (out / "labels" / "labels.json").write_text(json.dumps(dict(sorted(labels.items())), indent=1))
    return labels


def results_dir_name(decimate: int | str = "auto") -> str:
    """The directory of a set's kept results by the diagnosis's ``decimate``: ``results_auto`` (the default),
    ``results`` for the full rate (1, the default before), ``results_decimate<q>`` for the records decimated by
    ``q`` (:func:`.diagnosis.decimation.decimated`), so the rates of one set are kept apart."""
    if decimate == "auto":
        return "results_auto"
    return "results" if decimate == 1 else f"results_decimate{int(decimate)}"


def diagnose_case(case_dir: str, clock: Callable[[], float] = time.monotonic, decimate: int | str = "auto") -> dict:
    """Diagnose one case directory (labels never read here); ``clock`` (seconds) times it and its stages;
    ``decimate``: the diagnosis's own (``diagnose(..., decimate=...)``)."""
    import warnings

    from rotor_estimator.bench.reference_workload import reference_seconds
    from rotor_estimator.core.config import load_rig_file
    from rotor_estimator.diagnosis.api import diagnose
    from rotor_estimator.diagnosis.ranking import REFIT_LEDGER

    warnings.simplefilter("ignore")
    d = Path(case_dir)
    rig_file = load_rig_file(d / "rig.yaml")
    reference_before = reference_seconds()
    t0 = clock()
    events: list[tuple[float, str]] = [(0.0, "reading the record")]
    progress = lambda line: events.append((clock() - t0, line))  # noqa: E731
    refits: list[dict] = []  # each joint refit, with the stage it ran in
    ledger = REFIT_LEDGER.set(lambda entry: refits.append({**entry, "stage": stage_name(events[-1][1])}))
    try:
        s = diagnose(load_recording(d / "recording.npz"), rig_file.rig, rig_file.estimator, decimate=decimate,
                     progress=progress).summary()
    except Exception as exc:  # a failed case is scored as a miss, not a crash of the benchmark
        return {"case": d.name, "error": repr(exc), "seconds": clock() - t0}
    finally:
        REFIT_LEDGER.reset(ledger)
    seconds = clock() - t0
    # the fixed workload timed beside the case, before and after it (:mod:`.reference_workload`)
    reference = 0.5 * (reference_before + reference_seconds())
    return {**result_of_summary(d.name, s, seconds), "stage_seconds": stage_seconds(events, seconds),
            "refits": refits, "reference_seconds": reference}


def stage_name(line: str) -> str:
    """A diagnosis stage's name from its progress line: up to the first colon ("coefficient uncertainty"), a
    numbered stage up to any parenthesis ("stage 2/4 joint refits with the bearing coefficients", whose
    parenthesis names the leader, which changes between runs)."""
    head = line.split("(", 1)[0]
    if head.startswith("stage "):
        return " ".join(head.replace(":", "", 1).split())
    return head.split(":", 1)[0].strip()


def stage_seconds(events: list[tuple[float, str]], end_s: float) -> dict[str, float]:
    """Seconds spent in each stage of a diagnosis from its progress lines ``(elapsed s, line)``: a stage runs
    from its line to the next one (the last to ``end_s``), is named by :func:`stage_name`, and adds up when
    entered twice."""
    out: dict[str, float] = {}
    for (t, line), t_next in zip(events, [*(e[0] for e in events[1:]), end_s]):
        name = stage_name(line)
        out[name] = out.get(name, 0.0) + max(float(t_next) - float(t), 0.0)
    return out


#: A refit "lowered its model's BIC" when by at least this much (:func:`refit_yield`).
REFIT_GAIN_BIC = 1.0


def refit_yield(results: list[dict]) -> dict:
    """The joint refits of the cases that report them (:func:`diagnose_case`): how many per case, their share of
    the cases' summed wall time, and the share of refit time spent in refits that did not lower their model's
    BIC by :data:`REFIT_GAIN_BIC`, over all and per stage (largest refit time first), and each stage's refits by the
    search's reason for them (their share of the wall time and their idle share). Not a verdict on those
    refits (a refit that finds nothing better is how the search knows): a map for making the search cheaper."""
    cases = [r for r in results if r.get("refits") is not None]
    if not cases:
        return {}
    refits = [f for r in cases for f in r["refits"]]
    total = sum(f["seconds"] for f in refits)
    wall = sum(float(r["seconds"]) for r in cases)
    idle = lambda f: f["bic_before"] - f["bic_after"] < REFIT_GAIN_BIC  # noqa: E731

    def spent_by(key) -> dict[str, list[float]]:
        """Seconds and idle seconds of the refits by ``key(refit)``, largest first."""
        out: dict[str, list[float]] = {}
        for f in refits:
            spent = out.setdefault(key(f), [0.0, 0.0])
            spent[0] += f["seconds"]
            spent[1] += f["seconds"] if idle(f) else 0.0
        return dict(sorted(out.items(), key=lambda kv: -kv[1][0]))

    by_stage = spent_by(lambda f: f["stage"])
    # the search's reason for each refit (ranking.refine's ``why``; results written before it have none)
    by_reason = spent_by(lambda f: f"{f['stage'][:7]}: {f.get('why') or 'reason not recorded'}")
    return {"refits_per_case_median": float(np.median([len(r["refits"]) for r in cases])),
            "refit_share_of_wall": total / wall if wall > 0 else 0.0,
            "idle_share_of_refit_time": sum(f["seconds"] for f in refits if idle(f)) / total if total > 0 else 0.0,
            "idle_share_by_stage": {k: (v[1] / v[0] if v[0] > 0 else 0.0) for k, v in by_stage.items()},
            "by_reason": {k: {"share_of_wall": v[0] / wall if wall > 0 else 0.0,
                              "idle_share": v[1] / v[0] if v[0] > 0 else 0.0} for k, v in by_reason.items()}}


def time_by_stage(results: list[dict]) -> dict[str, float]:
    """Each stage's share of the summed wall time of the cases that report stage times (:func:`stage_seconds`),
    largest first: where a speed-up must come from."""
    totals: dict[str, float] = {}
    for r in results:
        for name, sec in (r.get("stage_seconds") or {}).items():
            totals[name] = totals.get(name, 0.0) + float(sec)
    whole = sum(totals.values())
    if whole <= 0.0:
        return {}
    return dict(sorted(((k, v / whole) for k, v in totals.items()), key=lambda kv: -kv[1]))


def reference_units(results: list[dict]) -> dict:
    """The cases' seconds over the reference workload's timed beside each (:mod:`.reference_workload`): their
    median (the cost per case in reference units, comparable across machines and loads) and the reference's
    median seconds; empty when no case carries a reference (results from before it)."""
    pairs = [(float(r["seconds"]), float(r["reference_seconds"])) for r in results
             if r.get("reference_seconds") and "seconds" in r]
    if not pairs:
        return {}
    return {"median_reference_units_per_case": float(np.median([s / ref for s, ref in pairs])),
            "reference_seconds_median": float(np.median([ref for _, ref in pairs])),
            "n_cases_with_reference": len(pairs)}


def result_of_summary(case: str, s: dict, seconds: float) -> dict:
    """What a case keeps of a diagnosis summary (:meth:`.Diagnosis.summary`, as the CLI's ``--json`` prints it):
    the verdict and what :func:`score` reads, and the whole ranking of singles and the best pairs with their
    parameter counts and the tie's margins, so that a decision rule can be re-scored offline without diagnosing
    again."""
    return {"case": case, "best_effect": s["best_effect"], "second_effect": s["second_effect"],
            "verdict_set": s["verdict_set"], "tie": s["tie"] is not None,
            "coefficients": list(s["coefficients_verdict"].values()),
            "coefficients_std": list(s["coefficients_verdict_std"].values()),
            "top_two": s["top_two"], "before": s["residual_rms_before"], "after": s["residual_rms_after"],
            "shrink_ratio": s["shrink_ratio"],
            "ranking": [(r["effect"], r["delta_bic"], r["n_params"]) for r in s["ranking"]],
            # each single's held-out RMS, which the decision rule also reads (a pair must predict it no worse)
            "ranking_held_out_rms_m": {r["effect"]: r["held_out_rms_m"] for r in s["ranking"]},
            "nominal_held_out_rms_m": s["decision_rule"]["nominal_held_out_rms_m"],
            "ranking_pairs": s["ranking_pairs"], "tie_detail": s["tie"],
            # the verdict's effect parameters with their reported std (scored by :func:`_parameter_coverage`)
            "best_effect_fit": s["best_effect_fit"], "second_effect_fit": s["second_effect_fit"],
            "seconds": seconds}


def score(results: list[dict], labels: dict, rigs: dict | None = None) -> dict:
    """Score diagnosed cases against their labels. ``rigs``: case id -> ``(correction planes m, sample rate Hz)``
    of its rig file (the independent labels' unbalance station and delay in samples need them; without, those
    parameters count as having no counterpart)."""
    rows, cm_labels = [], set()
    for r in results:
        lab = labels[r["case"]]
        truth = lab["effects"]
        best = r.get("best_effect", "error")
        top2 = set(r.get("top_two", []))
        if r.get("second_effect", "none") != "none":
            top2 = {best, r["second_effect"]}
        # a tie is a set verdict: a hit when it has at most two members and holds the truth
        tied = set(r.get("verdict_set", [])) if r.get("tie") else set()
        if not truth:
            t1 = t2 = best == "none"
        elif len(truth) == 1:
            t1 = best == truth[0] or (len(tied) <= 2 and truth[0] in tied)
            t2 = best != "none" and truth[0] in top2
        else:  # a pair: both members in the top two, or a set verdict of at most two that holds both
            t1 = best in truth
            t2 = best != "none" and (set(truth) <= top2 or (len(tied) <= 2 and set(truth) <= tied))
        gap = r["before"] / lab["noise_rms_m"] if "before" in r else float("nan")
        shrink_err = float("nan")
        if truth and best != "none" and "before" in r:
            shrink_err = abs(r["shrink_ratio"] / gap - 1.0)
        key = "+".join(truth) if truth else "none"
        cm_labels |= {key, best}
        # a pair both of whose effects show beyond the coefficients and the partner's model (the label's
        # effect_gap; None when the label has none)
        own = lab.get("effect_gap") or {}
        separable = min(own.values()) >= MIN_GAP if len(truth) == 2 and len(own) == 2 else None
        cover, worst_direct, worst_cross = _coefficient_errors(r, lab)
        param_cover, no_counterpart = _parameter_coverage(r, lab, (rigs or {}).get(r["case"]))
        rows.append({"case": r["case"], "truth": key, "verdict": best, "top1": t1, "top2": t2, "gap": gap,
                     "set_verdict": bool(tied), "coefficients_covered": cover, "worst_direct_error": worst_direct,
                     "parameters_covered": param_cover, "parameters_without_counterpart": no_counterpart,
                     "worst_cross_error": worst_cross,
                     "generator": lab["generator"], "ross": from_ross(lab), "shrink_error": shrink_err,
                     "seconds": r.get("seconds", 0.0),
                     "pair_separable": separable, "true_gap": float(lab.get("true_gap", float("nan"))),
                     "form": lab.get("form", key)})
    arr = lambda k, sel=None: np.array([x[k] for x in rows if sel is None or sel(x)], dtype=float)  # noqa: E731
    controls = [x for x in rows if x["truth"] == "none"]
    clear = lambda x: x["gap"] >= 1.5 and x["truth"] != "none"  # noqa: E731
    near = lambda x: 1.2 <= x["gap"] < 2.0 and x["truth"] != "none"  # noqa: E731
    shrink = arr("shrink_error")
    shrink = shrink[np.isfinite(shrink)]
    return {"cases": len(rows), "controls": len(controls),
            "top1": float(arr("top1").mean()), "top2": float(arr("top2").mean()),
            "top1_clear_gap": float(np.mean(arr("top1", clear))) if any(map(clear, rows)) else float("nan"),
            "n_clear_gap": int(sum(map(clear, rows))), "n_near_limit": int(sum(map(near, rows))),
            "top1_near_limit": float(np.mean(arr("top1", near))) if any(map(near, rows)) else float("nan"),
            "n_below_1p2": int(sum(1 for x in rows if x["truth"] != "none" and x["gap"] < 1.2)),
            "false_alarms": int(sum(1 for x in controls if x["verdict"] != "none")),
            "shrink_error_median": float(np.median(shrink)) if shrink.size else float("nan"),
            "shrink_within_20pct": float(np.mean(shrink <= 0.2)) if shrink.size else float("nan"),
            "pairs_both_in_top2": [x["top2"] for x in rows if "+" in x["truth"]],
            "separable_pairs_both_in_top2": [x["top2"] for x in rows if x["pair_separable"]],
            "ross_top1": [x["top1"] for x in rows if x["ross"]],
            "set_verdicts": int(sum(x["set_verdict"] for x in rows)),
            "coefficient_coverage": _mean_of([c for x in rows for c in x["coefficients_covered"]]),
            "n_coefficients_scored": sum(len(x["coefficients_covered"]) for x in rows),
            # calibration apart from the misses: a wrong verdict's coefficients carry the wrong model's bias
            "coefficient_coverage_of_hits": _mean_of([c for x in rows if x["top1"] for c in x["coefficients_covered"]]),
            "n_coefficients_scored_of_hits": sum(len(x["coefficients_covered"]) for x in rows if x["top1"]),
            "parameter_coverage": _mean_of([c for x in rows for c in x["parameters_covered"].values()]),
            "n_parameters_scored": sum(len(x["parameters_covered"]) for x in rows),
            "n_parameters_without_counterpart": sum(x["parameters_without_counterpart"] for x in rows),
            "worst_direct_error_median": _median_of([x["worst_direct_error"] for x in rows]),
            "worst_cross_error_median": _median_of([x["worst_cross_error"] for x in rows]),
            # the independent generator labels the gap of its true model (never a fit of the diagnosis)
            "n_true_gap_clear": int(sum(1 for x in rows if x["truth"] != "none" and x["true_gap"] >= 1.5)),
            "top1_true_gap_clear": (float(np.mean([x["top1"] for x in rows
                                                   if x["truth"] != "none" and x["true_gap"] >= 1.5]))
                                    if any(x["truth"] != "none" and x["true_gap"] >= 1.5 for x in rows)
                                    else float("nan")),
            "mean_seconds_per_case": float(arr("seconds").mean()),
            "median_seconds_per_case": float(np.median(arr("seconds"))),
            **reference_units(results),
            "time_share_by_stage": time_by_stage(results), "refit_yield": refit_yield(results),
            "rows": rows, "confusion": _confusion(rows)}


#: Direct and cross-coupled positions, stiffness then damping, in the order kxx kxy kyx kyy cxx cxy cyx cyy.
DIRECT, CROSS = ((0, 3), (4, 7)), ((1, 2), (5, 6))


def _coefficient_errors(result: dict, label: dict) -> tuple[list[bool], float, float]:
    """Per coefficient after the verdict: is the truth within +-1.96 reported std; and the worst error of the
    direct and of the cross-coupled terms, each relative to the larger true direct term of its kind (stiffness
    or damping: a cross term near zero has no relative error of its own).

    The truth is the coefficients linearized about the true static equilibrium when the label has them
    (``true_tangent_coefficients``: a nonlinear bearing under gravity), else the linear ones: the probes' DC
    is unknown, so what a fit of the motion about the operating point can identify is the tangent there
    (the radial-cubic effect reports its law about the static load point on top of it)."""
    truth = label.get("true_tangent_coefficients") or label.get("true_coefficients")
    est, std = result.get("coefficients"), result.get("coefficients_std")
    if not truth or not est or not std or len(est) != 8 or len(std) != 8:
        return [], float("nan"), float("nan")
    t, e, s = (np.asarray(v, dtype=float) for v in (truth, est, std))
    covered = [bool(abs(e[i] - t[i]) <= 1.96 * s[i]) for i in range(8) if np.isfinite(s[i]) and s[i] > 0]
    worst = {}
    for name, groups in (("direct", DIRECT), ("cross", CROSS)):
        worst[name] = max(abs(e[i] - t[i]) / max(abs(t[j]) for j in direct)
                          for idx, direct in zip(groups, DIRECT) for i in idx)
    return covered, worst["direct"], worst["cross"]


def _parameter_coverage(result: dict, label: dict, rig: tuple | None) -> tuple[dict[str, bool], int]:
    """Each true effect parameter of a verdict that holds the effect: is it within +-1.96 reported std
    (``{effect.parameter: covered}``), and how many true parameters have no counterpart in the verdict's
    reported ones (another physical form, no std, or no rig data). A verdict without the effect scores nothing:
    that is top-1's business."""
    fits = {f["name"]: f for f in (result.get("best_effect_fit"), result.get("second_effect_fit")) if f}
    out, missing = {}, 0
    for effect in label.get("effects", []):
        fit = fits.get(effect)
        if fit is None:
            continue
        try:
            if generator_family(label) == "independent":
                truth = {} if rig is None else independent_truth(
                    effect, label.get("effect_params", {}).get(effect, {}), rig[0], rig[1])
            else:
                truth = own_truth(effect, label.get("effects_params") or {})
        except (KeyError, IndexError, TypeError, ValueError):  # a label without this effect's parameters
            truth = {}
        missing += 0 if truth else 1
        reported = fit.get("parameters", {})
        for name, value in truth.items():
            est = reported.get(name)
            std = float(est["std"]) if est else float("nan")
            if est is None or not (np.isfinite(std) and std > 0):
                missing += 1
                continue
            out[f"{effect}.{name}"] = covered(name, float(est["value"]), std, float(value))
    return out, missing


def _mean_of(values: list) -> float:
    return float(np.mean(values)) if values else float("nan")


def _median_of(values: list) -> float:
    v = [x for x in values if np.isfinite(x)]
    return float(np.median(v)) if v else float("nan")


def _confusion(rows: list[dict]) -> dict:
    truths = sorted({x["truth"] for x in rows})
    verdicts = sorted({x["verdict"] for x in rows})
    return {"truths": truths, "verdicts": verdicts,
            "counts": [[sum(1 for x in rows if x["truth"] == t and x["verdict"] == v) for v in verdicts]
                       for t in truths]}


def score_by_generator(results: list[dict], labels: dict, rigs: dict | None = None) -> dict[str, dict]:
    """:func:`score` of each generator's cases apart (keys ``own`` / ``independent``)."""
    families = sorted({generator_family(labels[r["case"]]) for r in results})
    return {g: score([r for r in results if generator_family(labels[r["case"]]) == g], labels, rigs)
            for g in families}


def rig_facts(case_dir: str | Path) -> tuple[tuple[float, float], float] | None:
    """``(correction planes m, sample rate Hz)`` of a case's rig file, the planes by the unbalance effect's own rule
    (:func:`.effects.base.rig_unbalance_planes`); ``None`` when the file cannot be read."""
    from rotor_estimator.core.config import load_rig_file
    from rotor_estimator.core.errors import ConfigError
    from rotor_estimator.diagnosis.effects.base import rig_unbalance_planes

    try:
        rig = load_rig_file(Path(case_dir) / "rig.yaml").rig
    except (OSError, ConfigError, InputError):
        return None
    return rig_unbalance_planes(rig), float(rig.sample_rate_hz)


def format_score(s: dict) -> str:
    """The score as text: one block per generator when ``s`` carries ``by_generator``; first, when a run kept
    results from an earlier one (:func:`run`), how many (and how many other code made), and when the results
    come from more than one version of the code (:func:`code_stamp`; unstamped: made before the stamp), which."""
    kept = s.get("cases_kept_from_earlier_run", 0)
    other = s.get("cases_kept_from_other_code", 0)
    head = (f"KEPT: {kept} of the {s.get('cases_in_set', kept)} cases' results were kept from an earlier run in "
            f"{s.get('results_dir', 'the set')}, not diagnosed again by this code"
            f"{f', {other} of them made by other code' if other else ''} (--fresh diagnoses every case)\n"
            if kept else "")
    by_code = s.get("results_by_code", {})
    if len(by_code) > 1:
        head += ("CODE: the results were made by " + str(len(by_code)) + " versions of the code ("
                 + ", ".join(f"{stamp}: {n}" for stamp, n in by_code.items()) + ")\n")
    if s.get("by_generator"):
        return head + "\n\n".join(f"== generator: {g} ({sub['cases']} cases) ==\n" + _format_one(sub)
                                   for g, sub in s["by_generator"].items())
    return head + _format_one(s)


def _format_one(s: dict) -> str:
    cm = s["confusion"]
    short = {v: v[:10] for v in cm["verdicts"]}
    w = max(len(t) for t in cm["truths"]) + 2
    out = ["Confusion matrix (rows: hidden effect(s); columns: verdict)",
           " " * w + " ".join(f"{short[v]:>10s}" for v in cm["verdicts"])]
    for t, row in zip(cm["truths"], cm["counts"]):
        out.append(f"{t:<{w}s}" + " ".join(f"{c:>10d}" for c in row))
    partial = [f"PARTIAL: {s['cases']} of the set's {s['cases_in_set']} cases diagnosed so far"] \
        if s.get("cases_in_set", s["cases"]) > s["cases"] else []
    out += ["", *partial, f"cases {s['cases']} (controls {s['controls']}, clear gap >= 1.5x: {s['n_clear_gap']}, "
                f"near limit 1.2-2x: {s['n_near_limit']}, below 1.2x: {s['n_below_1p2']})",
            f"top-1 accuracy           {100 * s['top1']:.1f} %",
            f"top-2 accuracy           {100 * s['top2']:.1f} %",
            f"top-1 where gap >= 1.5x  {100 * s['top1_clear_gap']:.1f} %",
            f"top-1 near limit         {100 * s['top1_near_limit']:.1f} %",
            f"false alarms on controls {s['false_alarms']} / {s['controls']}",
            f"pairs with both in top 2 {sum(s['pairs_both_in_top2'])} / {len(s['pairs_both_in_top2'])} "
            f"(each effect's own gap >= {MIN_GAP}x: {sum(s['separable_pairs_both_in_top2'])} / "
            f"{len(s['separable_pairs_both_in_top2'])})",
            f"ROSS cases top-1         {sum(s['ross_top1'])} / {len(s['ross_top1'])}",
            f"set verdicts (ties)      {s['set_verdicts']} (a hit when <= 2 members and holding the truth)",
            f"coefficient coverage     {100 * s['coefficient_coverage']:.1f} % of {s['n_coefficients_scored']} "
            "within +-1.96 reported std (target 90-98 %)"
            + (f"; {100 * s['coefficient_coverage_of_hits']:.1f} % of the {s['n_coefficients_scored_of_hits']} of "
               "the top-1 hits" if s.get("n_coefficients_scored_of_hits") else ""),
            f"parameter coverage       {100 * s['parameter_coverage']:.1f} % of {s['n_parameters_scored']} "
            f"effect parameters of verdicts holding the effect ({s['n_parameters_without_counterpart']} without a "
            "counterpart in the reported form, not scored)",
            f"worst coefficient error  median {100 * s['worst_direct_error_median']:.1f} % direct, "
            f"{100 * s['worst_cross_error_median']:.1f} % cross-coupled (of the largest true term of each kind)",
            *([f"top-1 where true gap >= 1.5x {100 * s['top1_true_gap_clear']:.1f} % of {s['n_true_gap_clear']}"]
              if s.get("n_true_gap_clear") else []),
            f"shrink error median      {100 * s['shrink_error_median']:.1f} %, within 20 %: "
            f"{100 * s['shrink_within_20pct']:.1f} % of detected cases",
            f"time per case            median {s['median_seconds_per_case']:.1f} s, "
            f"mean {s['mean_seconds_per_case']:.1f} s (wall clock of each case's diagnosis, as run: see --jobs)"]
    if s.get("n_cases_with_reference"):
        out.append(f"time in reference units  median {s['median_reference_units_per_case']:.0f} x the fixed NumPy "
                   f"workload timed beside each case in its process (median {1e3 * s['reference_seconds_median']:.0f}"
                   f" ms; {s['n_cases_with_reference']} of {s['cases']} cases): comparable across machines and loads")
    if s.get("time_share_by_stage"):
        out.append("time by stage            " + ", ".join(f"{name} {100 * share:.0f} %" for name, share
                                                            in s["time_share_by_stage"].items()))
    y = s.get("refit_yield")
    if y:
        out.append(f"joint refits             median {y['refits_per_case_median']:.0f} per case, "
                   f"{100 * y['refit_share_of_wall']:.0f} % of the wall time; "
                   f"{100 * y['idle_share_of_refit_time']:.0f} % of their time in refits that did not lower their "
                   f"model's BIC by {REFIT_GAIN_BIC:g} ("
                   + ", ".join(f"{name} {100 * share:.0f} %" for name, share in y["idle_share_by_stage"].items())
                   + ")")
        out.append("refits by reason         " + "; ".join(
            f"{why} {100 * r['share_of_wall']:.1f} % of the wall time ({100 * r['idle_share']:.0f} % idle)"
            for why, r in y.get("by_reason", {}).items()))
    return "\n".join(out)


@functools.lru_cache(maxsize=1)
def code_stamp() -> str:
    """The first 12 hex digits of a SHA-256 over the package's Python sources (their paths and bytes, in path
    order): two runs share it exactly when their code is the same, whatever git says (a working tree with edits,
    an installed wheel). Kept with each result (:func:`diagnose_and_keep`), so a rerun and the score can say which
    results another code made."""
    root = Path(__file__).resolve().parents[1]
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        digest.update(str(path.relative_to(root)).encode())
        digest.update(b"\0")
        digest.update(path.read_bytes())
    return digest.hexdigest()[:12]


def diagnose_and_keep(case_dir: str, results_dir: str, decimate: int | str = "auto") -> dict:
    """:func:`diagnose_case`, its result also written to ``results_dir/<case>.json`` (atomically: a run
    stopped mid-write leaves no half file, and the case is diagnosed again on resume), stamped with the code
    that made it (``code``: :func:`code_stamp`)."""
    import os

    r = {**diagnose_case(case_dir, decimate=decimate), "code": code_stamp()}
    target = Path(results_dir) / f"{Path(case_dir).name}.json"
    tmp = target.with_suffix(f".json.tmp{os.getpid()}")
    tmp.write_text(json.dumps(r, indent=1, default=str))
    os.replace(tmp, target)
    return r


def kept_results(results_dir: Path, case_dirs: list[str]) -> dict[str, dict]:
    """The results already in ``results_dir`` of the given cases, by case id (unreadable files are redone)."""
    kept = {}
    for d in case_dirs:
        f = results_dir / f"{Path(d).name}.json"
        if f.is_file():
            try:
                kept[Path(d).name] = json.loads(f.read_text())
            except (OSError, ValueError):
                continue
    return kept


def score_sets(set_dirs: list[str | Path], decimate: int | str = "auto") -> dict:
    """Score the kept results of several blind sets together (e.g. two seeds of one generator): case ids are
    prefixed with their set's directory name, ``cases_in_set`` counts every case of every set (the score says
    PARTIAL when some are not diagnosed yet), and each generator is scored apart. With one set the ids are
    kept as they are. ``decimate``: score the diagnoses of the records decimated by it (:func:`results_dir_name`)."""
    results, labels, families, total, rigs = [], {}, [], 0, {}
    for out in map(Path, set_dirs):
        if not (out / "cases").is_dir() or not (out / "labels" / "labels.json").is_file():
            raise InputError(f"{out}: not a blind set (expected cases/ and labels/labels.json)")
        case_dirs = sorted(str(p) for p in (out / "cases").iterdir() if p.is_dir())
        set_labels = json.loads((out / "labels" / "labels.json").read_text())
        total += len(case_dirs)
        families += [generator_family(set_labels[Path(d).name]) for d in case_dirs]
        for cid, r in kept_results(out / results_dir_name(decimate), case_dirs).items():
            key = f"{out.name}/{cid}" if len(set_dirs) > 1 else cid
            results.append({**r, "case": key})
            labels[key] = set_labels[cid]
            rigs[key] = rig_facts(out / "cases" / cid)
    if not results:
        raise InputError(f"{', '.join(map(str, set_dirs))}: no case diagnosed yet ({results_dir_name(decimate)}/ "
                         "is empty)")
    s = score(results, labels, rigs)
    s["cases_in_set"] = total
    # which code made the results (a pool of seeds may mix them by design; a rerun should not by accident)
    by_code = collections.Counter(r.get("code", "unstamped") for r in results)
    s["results_by_code"] = dict(sorted(by_code.items(), key=lambda kv: (-kv[1], kv[0])))  # most first, then by name
    s["by_generator"] = score_by_generator(results, labels, rigs)
    for g, sub in s["by_generator"].items():
        sub["cases_in_set"] = families.count(g)
    return s


def run(n_cases: int = 36, seed: int = 2024, out_dir: str | Path | None = None, *, jobs: int = 2,
        use_ross: bool = True, progress=None, generator: str = "own", generate: bool = True,
        on_diagnosed=None, decimate: int | str = "auto", fresh: bool = False, on_kept=None) -> dict:
    """Generate (``generator``: own, independent or both; ``generate=False`` diagnoses the set already in
    ``out_dir``, skipping the cases with a kept result), diagnose (``jobs`` processes; ``on_diagnosed(done,
    total)`` after each case; ``decimate``: the diagnosis's, its results kept apart by :func:`results_dir_name`),
    score each generator apart (:func:`score_sets`). Returns the score dict, with ``cases_kept_from_earlier_run``
    and ``cases_kept_from_other_code`` (reported by ``on_kept(kept, total, results_dir, other_code)`` before any
    case is diagnosed: a rerun after a code change would otherwise score the old code's results as its own;
    other code: a result whose :func:`code_stamp` is not this run's, or has none). ``fresh``: delete the set's
    kept results first, so every case is diagnosed by this code."""
    import tempfile

    tmp = None
    if out_dir is None:
        tmp = tempfile.TemporaryDirectory(prefix="blind_")
        out_dir = tmp.name
    out = Path(out_dir)
    t0 = time.time()
    if generate:
        write_sets(out, n_cases, seed, generator=generator, use_ross=use_ross, progress=progress, jobs=jobs)
    elif not (out / "cases").is_dir() or not (out / "labels" / "labels.json").is_file():
        raise InputError(f"{out}: not a blind set (expected cases/ and labels/labels.json)")
    t_gen = time.time() - t0
    case_dirs = sorted(str(p) for p in (out / "cases").iterdir() if p.is_dir())
    results_dir = out / results_dir_name(decimate)
    results_dir.mkdir(exist_ok=True)
    if fresh:
        for d in case_dirs:
            (results_dir / f"{Path(d).name}.json").unlink(missing_ok=True)
    kept = kept_results(results_dir, case_dirs)
    other_code = sum(1 for r in kept.values() if r.get("code") != code_stamp())
    if kept and on_kept:
        on_kept(len(kept), len(case_dirs), results_dir, other_code)
    pending = [d for d in case_dirs if Path(d).name not in kept]
    done = [len(kept)]

    def _tick(_n: int) -> None:
        done[0] += 1
        if on_diagnosed:
            on_diagnosed(done[0], len(case_dirs))

    # a local Dask cluster of ``jobs`` single-thread processes (rotor_estimator.batch.runner)
    if pending:  # each result is kept in results/ by the worker itself
        map_ordered(functools.partial(diagnose_and_keep, results_dir=str(results_dir), decimate=decimate), pending,
                    workers=max(1, jobs), inline=False, progress=_tick)
    s = score_sets([out], decimate)  # the labels are opened only now
    results = list(kept_results(results_dir, case_dirs).values())
    s["cases_kept_from_earlier_run"] = len(kept)
    s["cases_kept_from_other_code"] = other_code
    s["results_dir"] = str(results_dir)
    s["generation_seconds"] = t_gen
    s["total_seconds"] = time.time() - t0
    (out / "results.json").write_text(json.dumps({"results": results, "score": s}, indent=1, default=str))
    if tmp is not None:
        tmp.cleanup()
    return s
