# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""One table row per recording: run the single-recording command's own core function and flatten its
summary into the columns of :mod:`rotor_estimator.batch.table`.

``replay`` calls :func:`rotor_estimator.ros.replay.replay_bag`, ``identify``
:func:`rotor_estimator.identification.recordings.identify_recordings`, ``diagnose``
:func:`rotor_estimator.diagnosis.api.diagnose` on the recording
:func:`rotor_estimator.io.recordings.load_recording_file` opens, ``virtual-sensing``
:func:`rotor_estimator.virtual_sensing.estimator.leave_one_station_out` on the channels
:mod:`rotor_estimator.virtual_sensing.loaders` reads (as the command). :func:`run_row` never raises an
``Exception``: a failure is a row with ``status`` error and the error's text.
"""
from __future__ import annotations

import glob
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rotor_estimator.batch.table import COEFFICIENT_COLUMNS, COEFFICIENT_STD_COLUMNS, COMMANDS, ERROR, OK
from rotor_estimator.core.errors import InputError, RotorEstimatorError

#: Files read as a list of recordings (one path a line, ``#`` comments), not as a recording.
LIST_SUFFIXES = (".txt", ".list", ".lst")
#: Default rotor description of ``virtual-sensing`` (as the command's).
DEFAULT_ROTOR = "three_probe_rig"


@dataclass(frozen=True)
class BatchOptions:
    """What every row of a batch shares: the command and its settings."""

    command: str
    rig_path: str | None = None          # rig YAML (replay, identify, diagnose); None: the bundled seed rig
    rotor: str = DEFAULT_ROTOR           # rotor description (virtual-sensing)
    passes: int = 2                      # EKF passes of diagnose's nominal fit
    method: str = "auto"                 # identify's method
    salvage: bool = False                # use the intact part of a damaged bag
    decimate: int | str | None = None    # diagnose's ``--decimate`` (None: its default, auto)

    @property
    def diagnose_decimate(self) -> int | str:
        """The ``decimate`` diagnose runs with."""
        return "auto" if self.decimate is None else self.decimate

    def validate(self) -> "BatchOptions":
        if self.command not in COMMANDS:
            raise InputError(f"batch: command must be one of {', '.join(COMMANDS)}, got {self.command!r}")
        if not 1 <= int(self.passes) <= 20:
            raise InputError(f"batch: passes must be from 1 to 20, got {self.passes}")
        if self.decimate is not None and self.decimate != "auto" and (
                isinstance(self.decimate, bool) or not isinstance(self.decimate, int) or self.decimate < 1):
            raise InputError(f"batch: decimate must be auto or a positive integer, got {self.decimate!r}")
        if self.decimate is not None and self.command != "diagnose":
            raise InputError(f"batch {self.command}: decimate is an option of diagnose only, got {self.decimate}")
        if self.command == "diagnose" and self.rig_path is None:
            raise InputError("batch diagnose: --rig is required (as for `rotor-estimator diagnose`)")
        return self


# ------------------------------------------------------------------------------------------ inputs
def _is_recording(p: Path) -> bool:
    return p.suffix in (".npz", ".mcap") or (p.is_dir() and (any(p.glob("*.mcap")) or (p / "metadata.yaml").exists()))


def expand_inputs(specs: list[str]) -> tuple[list[str], int]:
    """(absolute recording paths in order without repeats, files skipped) from globs, paths and list files.

    A glob keeps the bag directories, ``.mcap`` and ``.npz`` files it matches (other files are counted
    as skipped); a ``.txt``/``.list``/``.lst`` file lists paths, one a line (relative to the list's
    folder); any other path is taken as given (a missing one becomes an error row)."""
    out: list[str] = []
    skipped = 0
    for spec in specs:
        p = Path(spec)
        if p.suffix in LIST_SUFFIXES and p.is_file():
            for line in p.read_text().splitlines():
                line = line.strip()
                if line and not line.startswith("#"):
                    q = Path(line)
                    out.append(str((q if q.is_absolute() else p.parent / q).resolve()))
        elif glob.has_magic(spec):
            matches = sorted(glob.glob(spec))
            if not matches:
                raise InputError(f"batch: {spec!r} matches no file")
            for m in matches:
                if _is_recording(Path(m)):
                    out.append(str(Path(m).resolve()))
                else:
                    skipped += 1
        else:
            out.append(str(p.resolve()))
    if not out:
        raise InputError("batch: no recording to process")
    return list(dict.fromkeys(out)), skipped


# ------------------------------------------------------------------------------------------ rows
def recording_facts(recording: Any) -> dict[str, Any]:
    """speed (median keyphasor rate), duration, samples and start time of a rig recording."""
    import datetime

    import numpy as np

    n = len(recording)
    pulses = np.asarray(recording.pulse_stamps_ns, dtype=np.int64)
    speed = math.nan
    if pulses.size >= 2:
        period_s = float(np.median(np.diff(pulses))) * 1e-9
        speed = 60.0 / period_s if period_s > 0 else math.nan
    start = recording.start_ns
    stamp = None
    if start > 10**17:  # a wall-clock stamp (after 1973), not a time from zero
        stamp = datetime.datetime.fromtimestamp(start * 1e-9, datetime.timezone.utc).isoformat(timespec="seconds")
    return {"speed_rpm": speed, "n_samples": n, "recording_start_utc": stamp,
            "duration_s": float(recording.stamps_ns[-1] - recording.stamps_ns[0]) * 1e-9 if n else 0.0}


def _replay(path: Path, options: BatchOptions, row: dict) -> None:
    import tempfile

    from rotor_estimator.io.recordings import load_recording_file
    from rotor_estimator.ros.replay import replay_bag
    from rotor_estimator.core.config import COEFFICIENT_NAMES

    recording = load_recording_file(path, options.salvage)
    row.update(recording_facts(recording))
    if path.suffix == ".npz":  # replay reads messages: the recording goes through an input bag first
        from rotor_estimator.io.bags import write_input_bag

        with tempfile.TemporaryDirectory(prefix="batch_replay_") as tmp:
            bag = Path(tmp) / "bag"
            write_input_bag(bag, recording)
            r = replay_bag(bag, options.rig_path, progress=False)
    else:
        r = replay_bag(path, options.rig_path, progress=False, salvage=options.salvage)
    for name, col, std_col in zip(COEFFICIENT_NAMES, COEFFICIENT_COLUMNS, COEFFICIENT_STD_COLUMNS):
        row[col] = r["coefficients"][name]["mean"]
        row[std_col] = r["coefficients"][name]["std"]
    c, st = r["consistency"], r["status"]
    row.update(rig=r["rig"], passes=r["passes"], nis_mean=c["nis_mean"], nis_band_low=c["nis_band"][0],
               nis_band_high=c["nis_band"][1], nis_dof=c["nis_dof"], model_mismatch=c["model_mismatch"],
               rms_autocorrelation=c["rms_autocorrelation"], whiteness_p_value=c["whiteness_p_value"],
               filter_status_level=st["level"], converged=st["converged"],
               divergence_recoveries=st["divergence_recoveries"], samples_processed=r["samples"]["processed"],
               samples_rejected=r["samples"]["rejected"], not_determined=";".join(r["not_determined"]))


def _identify(path: Path, options: BatchOptions, row: dict) -> None:
    from rotor_estimator.io.recordings import load_recording_file
    from rotor_estimator.identification.recordings import identify_recordings
    from rotor_estimator.core.config import load_rig_file
    from rotor_estimator.core.identifiability import NOT_DETERMINED

    rig_file = load_rig_file(options.rig_path)
    row["rig"] = rig_file.rig.name
    recording = load_recording_file(path, options.salvage)
    row.update(recording_facts(recording))
    out = identify_recordings(rig_file, [recording], method=options.method)
    # the estimate also where the data do not determine it (identify hides it there): not_determined names them
    for e, col, std_col in zip(out.report.entries, COEFFICIENT_COLUMNS, COEFFICIENT_STD_COLUMNS):
        row[col], row[std_col] = e.estimate, e.predicted_std
    q = out.quality
    row.update(method=out.res.method, converged=out.res.converged, residual_rms_m=q.get("residual_rms_m"),
               residual_over_noise=q.get("residual_over_noise"),
               normalized_squared_residual_mean=q.get("normalized_squared_residual_mean"),
               nsr_band_low=q["band"][0] if q else None, nsr_band_high=q["band"][1] if q else None,
               model_mismatch=q.get("model_mismatch"),
               not_determined=";".join(e.name for e in out.report.entries if e.status == NOT_DETERMINED))
    for b in out.imbalance[:2]:
        row[f"imbalance_plane{b['plane']}_g_mm"] = b["g_mm"]
        row[f"imbalance_plane{b['plane']}_angle_deg"] = b["angle_deg"]


def _joined(value: Any) -> str | None:
    if value is None:
        return None
    if isinstance(value, (list, tuple, set)):
        return ";".join(map(str, value))
    return str(value)


def _diagnose(path: Path, options: BatchOptions, row: dict) -> None:
    import warnings

    from rotor_estimator.io.recordings import load_recording_file
    from rotor_estimator.core.config import load_rig_file
    from rotor_estimator.diagnosis.api import diagnose

    rig_file = load_rig_file(options.rig_path)
    row["rig"] = rig_file.rig.name
    recording = load_recording_file(path, options.salvage)
    row.update(recording_facts(recording))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # as the diagnose command
        s = diagnose(recording, rig_file.rig, rig_file.estimator, passes=options.passes,
                     decimate=options.diagnose_decimate).summary()
    noise = s["noise_std_m"]
    verdict = s["best_effect"]
    bic = [r["delta_bic"] for r in s["ranking"] if r["effect"] == verdict]
    row.update(verdict=verdict, second_effect=s["second_effect"], top_two=_joined(s["top_two"]),
               residual_rms_before_m=s["residual_rms_before"], residual_rms_after_m=s["residual_rms_after"],
               noise_std_m=noise, gap_ratio_before=s["residual_rms_before"] / noise if noise > 0 else None,
               gap_ratio_after=s["residual_rms_after"] / noise if noise > 0 else None,
               shrink_ratio=s["shrink_ratio"], best_delta_bic=bic[0] if bic else None,
               dominant_channel=s["where"].get("dominant_channel"), dominant_band=s["where"].get("dominant_band"),
               verdict_set=_joined(s["verdict_set"]),
               tie_set=_joined(s["tie"]["effects"]) if s["tie"] else None,
               unexplained=(f"{s['unexplained']['residual_over_noise']:.2f} x noise: {s['unexplained']['signature']}"
                            if s["unexplained"] else None),
               samples_used=s["data"].get("samples_used"), decimate=str(options.diagnose_decimate),
               decimation_factor=s["data"]["decimation"]["factor"])
    # the bearing coefficients of the verdict's model (the nominal fit's when the verdict is none), with std
    for col, std_col, value, std in zip(COEFFICIENT_COLUMNS, COEFFICIENT_STD_COLUMNS,
                                        s["coefficients_verdict"].values(), s["coefficients_verdict_std"].values()):
        row[col], row[std_col] = value, std


def _virtual_sensing(path: Path, options: BatchOptions, row: dict) -> None:
    import numpy as np

    from rotor_estimator.virtual_sensing.loaders import load_bag_channels, load_npz_channels
    from rotor_estimator.core.flexible.description import load_rotor_description
    from rotor_estimator.core.flexible.state_space import build_state_space
    from rotor_estimator.virtual_sensing.estimator import VirtualSensingConfig, leave_one_station_out

    rotor = load_rotor_description(options.rotor)
    row.update(rig=rotor.name, speed_rpm=rotor.speed_rad_s * 30 / math.pi)
    ss = build_state_space(rotor)
    if path.suffix == ".npz":
        t, z, u = load_npz_channels(path, ss)
    else:
        stamps, z, u, _ = load_bag_channels(path, ss)
        t = (stamps - stamps[0]).astype(float) * 1e-9
    row.update(n_samples=int(len(t)), duration_s=float(t[-1] - t[0]))
    report = leave_one_station_out(ss, z, u, VirtualSensingConfig())
    rows = report.rows
    metres = [r.rms_error for r in rows if r.unit == "m"]
    row.update(filter=report.filter, confidence=report.confidence, channels=len(rows),
               channels_calibrated=sum(1 for r in rows if r.calibrated),
               coverage_mean=float(np.mean([r.coverage_measured for r in rows])),
               coverage_min=float(np.min([r.coverage_measured for r in rows])),
               rms_error_max_m=max(metres) if metres else None,
               width_to_signal_rms_mean=float(np.mean([r.width_to_signal_rms for r in rows])),
               samples_rejected=report.n_rejected)


_RUNNERS = {"replay": _replay, "identify": _identify, "diagnose": _diagnose, "virtual-sensing": _virtual_sensing}


def package_version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    from rotor_estimator import __version__

    try:
        return version("rotor_estimator")
    except PackageNotFoundError:
        return __version__


def run_row(task: tuple[str, BatchOptions]) -> dict[str, Any]:
    """The table row of one recording ``(path, options)``; a failure is a row with ``status`` error."""
    import datetime
    import os

    from rotor_estimator.batch.runner import worker_name

    path, options = task
    row: dict[str, Any] = {"recording": str(path), "command": options.command}
    t0 = time.perf_counter()
    try:
        p = Path(path)
        if not os.path.exists(p):
            raise InputError(f"{p}: no such bag or recording")
        _RUNNERS[options.command](p, options, row)
        row.update(status=OK, error=None)
    except Exception as exc:  # one bad recording is a row, never the end of the batch
        text = str(exc) or type(exc).__name__
        if not isinstance(exc, RotorEstimatorError):  # an unexpected failure: name its type
            text = f"{type(exc).__name__}: {text}"
        row.update(status=ERROR, error=text)
    row.update(seconds=time.perf_counter() - t0, worker=worker_name(), version=package_version(),
               date_utc=datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"))
    return row
