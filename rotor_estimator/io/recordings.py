# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Open one recording file as a :class:`~rotor_estimator.core.recording.RigRecording`: a rosbag2 bag
(:mod:`rotor_estimator.io.bags`) or a ``.npz`` (``stamps_ns, probes_m, pulse_stamps_ns, impact_force_n``,
as the blind-set generator writes). Used by ``diagnose`` and ``batch``.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any


def load_recording_file(path: str | Path, salvage: bool = False) -> Any:
    """The recording in ``path``: a ``.npz`` (blind-set format) or a rosbag2 bag (directory or ``.mcap``)."""
    from rotor_estimator.core.errors import InputError

    path = Path(path)
    if path.suffix == ".npz":
        from rotor_estimator.bench.blind import load_recording

        return load_recording(path)
    if not path.exists():
        raise InputError(f"{path}: no such bag or recording")
    from rotor_estimator.io.bags import read_input_bag

    return read_input_bag(path, salvage=salvage)
