# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Read the channels of a virtual-sensing input: an NPZ file (``t`` and one array per channel) or a
multi-sensor bag (one PointCloud2 topic per sensor and keyphasor pulses). Used by the
``virtual-sensing`` command and ``batch virtual-sensing``; bad files are :class:`InputError` lines.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from rotor_estimator.core.errors import InputError
from rotor_estimator.core.flexible.state_space import FlexibleStateSpace, unbalance_inputs
from rotor_estimator.virtual_sensing.estimator import shaft_angle_from_pulses


#: Largest array read from ``--data`` (elements); 10^8 samples is 83 min at 20 kHz.
MAX_NPZ_ELEMENTS = 100_000_000


def read_npz_arrays(path: Path, names: Any, flag: str = "--data") -> dict[str, np.ndarray]:
    """The members ``names`` (those present) of an NPZ archive, as real-number arrays.

    Refuses with one :class:`InputError` line: a directory, a ``.npy`` or other non-NPZ file, a
    truncated or corrupt archive, an object (pickled) array (never unpickled), a non-numeric or
    complex dtype and an array over :data:`MAX_NPZ_ELEMENTS` (checked from its header, before
    it is decompressed)."""
    import zipfile
    import zlib

    path = Path(path)
    where = f"{flag} {path}"
    if path.is_dir():
        raise InputError(f"{where}: is a directory; expected an NPZ file (numpy.savez)")
    try:
        with open(path, "rb") as fh:
            magic = fh.read(6)
    except OSError as exc:
        raise InputError(f"{where}: cannot be read ({exc.strerror or exc})") from None
    if magic.startswith(b"\x93NUMPY"):
        raise InputError(f"{where}: is a single .npy array, not an NPZ archive; save the channels with "
                         f"numpy.savez(path, t=..., <channel>=...)")
    if not magic.startswith(b"PK"):
        raise InputError(f"{where}: not an NPZ archive (numpy.savez): it does not start like a zip file")
    bad = (OSError, EOFError, ValueError, zipfile.BadZipFile, zlib.error, NotImplementedError)
    out: dict[str, np.ndarray] = {}
    try:
        archive = zipfile.ZipFile(path)
    except bad as exc:
        raise InputError(f"{where}: truncated or corrupt NPZ archive ({exc})") from None
    with archive:
        members = {m[:-4]: m for m in archive.namelist() if m.endswith(".npy")}
        for name in names:
            if name not in members:
                continue
            what = f"{where}: array {name!r}"
            try:
                with archive.open(members[name]) as fh:
                    version = np.lib.format.read_magic(fh)
                    read_header = (np.lib.format.read_array_header_1_0 if version == (1, 0)
                                   else np.lib.format.read_array_header_2_0)
                    shape, _, dtype = read_header(fh)
                    if dtype.hasobject:
                        raise InputError(f"{what} holds Python objects (dtype=object); --data reads numeric "
                                         f"arrays only and never unpickles")
                    if dtype.kind not in "iuf":
                        raise InputError(f"{what} has dtype {dtype}; expected real numbers (integer or float)")
                    if int(np.prod(shape, dtype=np.float64)) > MAX_NPZ_ELEMENTS:
                        raise InputError(f"{what} has shape {shape}: more than {MAX_NPZ_ELEMENTS} values")
                with archive.open(members[name]) as fh:
                    arr = np.lib.format.read_array(fh, allow_pickle=False)
            except InputError:
                raise
            except bad as exc:
                raise InputError(f"{what} cannot be read: truncated or corrupt ({exc})") from None
            out[name] = np.asarray(arr, dtype=float)
        out["__members__"] = np.asarray(sorted(members), dtype=str)
    return out


def load_npz_channels(path: Path, ss: FlexibleStateSpace) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t, z (N, p), u (N, 2)) from an NPZ file; channels in the rotor file's order
    (a channel missing from the file becomes NaN and is never used; NaN or inf samples are
    rejected and counted by the filter). Bad files: see :func:`read_npz_arrays`."""
    data = read_npz_arrays(path, ("t", *ss.channel_names, "shaft_angle_rad"))
    files = data.pop("__members__").tolist()
    if "t" not in data:
        raise InputError(f"--data {path}: needs an array 't' (s); has {files}")
    t = data["t"]
    if t.ndim != 1 or len(t) < 2 or not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
        raise InputError(f"--data {path}: 't' must be 1-D, finite and strictly increasing (s)")
    dt = float(np.median(np.diff(t)))
    if abs(dt - ss.dt_s) > 1e-3 * ss.dt_s:
        raise InputError(f"--data {path}: sample period {dt:g} s differs from the rotor file's "
                         f"operating.sample_rate_hz ({1 / ss.dt_s:g} Hz); resample or fix the rotor file")
    present = [c for c in ss.channel_names if c in data]
    if not present:
        raise InputError(f"--data {path}: none of the channels {list(ss.channel_names)} found; has {files}")
    z = np.full((len(t), len(ss.channel_names)), np.nan)
    for j, c in enumerate(ss.channel_names):
        if c in data:
            arr = data[c]
            if arr.shape != t.shape:
                raise InputError(f"--data {path}: channel {c!r} has shape {arr.shape}, 't' has {t.shape}")
            z[:, j] = arr
    angle = data.get("shaft_angle_rad")
    if angle is not None and (angle.shape != t.shape or not np.all(np.isfinite(angle))):
        raise InputError(f"--data {path}: 'shaft_angle_rad' must be finite with the shape of 't' {t.shape}, "
                         f"got {angle.shape}")
    return t, z, unbalance_inputs(ss, t - t[0], angle)


def load_bag_channels(path: Path, ss: FlexibleStateSpace, prefix: str = "/rotor",
                      keyphasor_topic: str = "/rotor/keyphasor") -> tuple[np.ndarray, np.ndarray, np.ndarray, dict]:
    """(stamps_ns, z (N, p), u (N, 2), info) from a multi-sensor bag; the shaft angle
    comes from the keyphasor pulses (centered fit), as :func:`load_npz_channels` but
    with measured phase."""
    from rotor_estimator.virtual_sensing.inputs import read_sensor_bag  # I/O layer: rosbags only when asked for

    data = read_sensor_bag(path, ss.rotor, prefix=prefix, keyphasor_topic=keyphasor_topic)
    stamps = data.stamps_ns
    if len(stamps) < 2:
        raise InputError(f"--bag {path}: needs at least 2 samples, has {len(stamps)}")
    dt = float(np.median(np.diff(stamps))) * 1e-9
    if abs(dt - ss.dt_s) > 1e-3 * ss.dt_s:
        raise InputError(f"--bag {path}: sample period {dt:g} s differs from the rotor file's "
                         f"operating.sample_rate_hz ({1 / ss.dt_s:g} Hz); resample or fix the rotor file")
    angle, n_extrapolated = shaft_angle_from_pulses(ss, stamps, data.pulse_stamps_ns)
    info = {"pulses": int(len(data.pulse_stamps_ns)), "samples_without_keyphasor_fit": n_extrapolated,
            **{k: v for k, v in data.counters.items() if v and not k.startswith(("received_", "released"))}}
    return stamps, data.z, unbalance_inputs(ss, None, angle), info
