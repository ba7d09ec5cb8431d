# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""The batch table: one row per recording, its columns (units in the names), and reading/writing it.

A table holds the rows of one command. Columns are fixed per command (:func:`columns`) so a CSV and a
Parquet file of the same rows read back with the same names and types. Writes are atomic
(:mod:`rotor_estimator.io.safe_write`): a reader, or an interrupted batch, never sees half a table.
"""
from __future__ import annotations

import io
import math
from pathlib import Path
from typing import Any, Iterable

from rotor_estimator.core.config import COEFFICIENT_NAMES, COEFFICIENT_UNITS
from rotor_estimator.core.errors import InputError

#: The commands a batch runs.
COMMANDS = ("replay", "identify", "diagnose", "virtual-sensing")
#: ``status`` of a row.
OK, ERROR = "ok", "error"
#: Table formats, by file extension.
FORMATS = {".parquet": "parquet", ".pq": "parquet", ".csv": "csv"}


def unit_suffix(unit: str) -> str:
    """``N*s/m`` -> ``n_s_per_m`` (a unit as a column-name suffix)."""
    return unit.replace("*", "_").replace("/", "_per_").lower()


#: Coefficient columns: ``kxx_n_per_m``, ``kxx_std_n_per_m``, ... ``cyy_std_n_s_per_m``.
COEFFICIENT_COLUMNS = tuple(f"{n}_{unit_suffix(u)}" for n, u in zip(COEFFICIENT_NAMES, COEFFICIENT_UNITS))
COEFFICIENT_STD_COLUMNS = tuple(f"{n}_std_{unit_suffix(u)}" for n, u in zip(COEFFICIENT_NAMES, COEFFICIENT_UNITS))

# (name, type): type is one of "string", "float", "int", "bool".
_HEAD = [("recording", "string"), ("command", "string"), ("status", "string"), ("error", "string"),
         ("rig", "string"), ("speed_rpm", "float"), ("duration_s", "float"), ("n_samples", "int"),
         ("recording_start_utc", "string")]
_TAIL = [("seconds", "float"), ("worker", "string"), ("version", "string"), ("date_utc", "string")]
_COEFFICIENTS = [(c, "float") for pair in zip(COEFFICIENT_COLUMNS, COEFFICIENT_STD_COLUMNS) for c in pair]
_PER_COMMAND = {
    "replay": _COEFFICIENTS + [
        ("passes", "int"), ("nis_mean", "float"), ("nis_band_low", "float"), ("nis_band_high", "float"),
        ("nis_dof", "int"), ("model_mismatch", "bool"), ("rms_autocorrelation", "float"),
        ("whiteness_p_value", "float"), ("filter_status_level", "int"), ("converged", "bool"),
        ("divergence_recoveries", "int"), ("samples_processed", "int"), ("samples_rejected", "int"),
        ("not_determined", "string")],
    "identify": _COEFFICIENTS + [
        ("method", "string"), ("converged", "bool"), ("residual_rms_m", "float"), ("residual_over_noise", "float"),
        ("normalized_squared_residual_mean", "float"), ("nsr_band_low", "float"), ("nsr_band_high", "float"),
        ("model_mismatch", "bool"), ("imbalance_plane1_g_mm", "float"), ("imbalance_plane1_angle_deg", "float"),
        ("imbalance_plane2_g_mm", "float"), ("imbalance_plane2_angle_deg", "float"), ("not_determined", "string")],
    "diagnose": _COEFFICIENTS + [
        ("verdict", "string"), ("second_effect", "string"), ("verdict_set", "string"), ("top_two", "string"),
        ("residual_rms_before_m", "float"), ("residual_rms_after_m", "float"), ("noise_std_m", "float"),
        ("gap_ratio_before", "float"), ("gap_ratio_after", "float"), ("shrink_ratio", "float"),
        ("best_delta_bic", "float"), ("dominant_channel", "string"), ("dominant_band", "string"),
        ("tie_set", "string"), ("unexplained", "string"), ("samples_used", "int"), ("decimate", "string"),
        ("decimation_factor", "int")],
    "virtual-sensing": [
        ("filter", "string"), ("confidence", "float"), ("channels", "int"), ("channels_calibrated", "int"),
        ("coverage_mean", "float"), ("coverage_min", "float"), ("rms_error_max_m", "float"),
        ("width_to_signal_rms_mean", "float"), ("samples_rejected", "int")],
}


def columns(command: str) -> list[tuple[str, str]]:
    """The (name, type) columns of a ``command`` table, in order."""
    if command not in _PER_COMMAND:
        raise InputError(f"batch: unknown command {command!r}; choose one of {', '.join(COMMANDS)}")
    return _HEAD + _PER_COMMAND[command] + _TAIL


def table_format(path: str | Path) -> str:
    """``parquet`` or ``csv`` from the file name."""
    fmt = FORMATS.get(Path(path).suffix.lower())
    if fmt is None:
        raise InputError(f"--out {path}: the table is written as Parquet (.parquet) or CSV (.csv); "
                         f"got the extension {Path(path).suffix!r}")
    return fmt


def normalize(row: dict[str, Any], command: str) -> dict[str, Any]:
    """``row`` with exactly the command's columns, each of its type; missing or empty values are None."""
    out: dict[str, Any] = {}
    unknown = set(row) - {name for name, _ in columns(command)}
    if unknown:
        raise ValueError(f"row has columns outside the {command} table: {sorted(unknown)}")
    for name, kind in columns(command):
        v = row.get(name)
        if v is None or (isinstance(v, str) and v == ""):
            out[name] = None
        elif kind == "float":
            out[name] = float(v)
        elif kind == "int":
            out[name] = int(v)
        elif kind == "bool":
            out[name] = bool(v)
        else:
            out[name] = str(v)
    return out


def _schema(command: str) -> Any:
    import pyarrow as pa

    types = {"string": pa.string(), "float": pa.float64(), "int": pa.int64(), "bool": pa.bool_()}
    return pa.schema([(name, types[kind]) for name, kind in columns(command)])


def table_bytes(rows: Iterable[dict], command: str, fmt: str) -> bytes:
    """The rows serialized as a Parquet or CSV file."""
    import pyarrow as pa

    rows = [normalize(r, command) for r in rows]
    schema = _schema(command)
    table = pa.Table.from_pylist(rows, schema=schema)
    buf = io.BytesIO()
    if fmt == "parquet":
        import pyarrow.parquet as pq

        pq.write_table(table, buf)
    else:
        import pyarrow.csv as pcsv

        pcsv.write_csv(table, buf)
    return buf.getvalue()


def write_table(path: str | Path, rows: Iterable[dict], command: str) -> Path:
    """Write ``rows`` to ``path`` (format from the extension) atomically."""
    from rotor_estimator.io.safe_write import write_bytes

    return write_bytes(path, table_bytes(rows, command, table_format(path)))


def read_table(path: str | Path) -> tuple[str | None, list[dict]]:
    """(command, rows) of a batch table; an empty table gives (None, [])."""
    import pyarrow as pa

    path = Path(path)
    fmt = table_format(path)
    try:
        if fmt == "parquet":
            import pyarrow.parquet as pq

            table = pq.read_table(path)
        else:
            import pyarrow.csv as pcsv

            head = path.read_text().partition("\n")[0]
            names = [h.strip('"') for h in head.split(",")] if head else []
            command = _command_of(names)
            if command is None:
                return None, []
            table = pcsv.read_csv(path, convert_options=pcsv.ConvertOptions(
                column_types=_schema(command), strings_can_be_null=True, null_values=[""],
                quoted_strings_can_be_null=False))
    except (OSError, pa.ArrowException) as exc:
        raise InputError(f"{path}: not a readable batch table ({exc})") from None
    command = _command_of(table.column_names)
    if command is None:
        raise InputError(f"{path}: not a batch table (columns {table.column_names[:6]}...)")
    table = table.cast(_schema(command))
    return command, table.to_pylist()


def _command_of(names: list[str]) -> str | None:
    """The command whose columns are exactly ``names`` (None for no column at all)."""
    if not names:
        return None
    for command in COMMANDS:
        if [n for n, _ in columns(command)] == list(names):
            return command
    return None


def finished(rows: Iterable[dict]) -> set[str]:
    """The recordings with a status-ok row (skipped on resume)."""
    return {r["recording"] for r in rows if r.get("status") == OK}


def same_values(a: dict, b: dict, ignore: Iterable[str] = ("seconds", "worker", "date_utc")) -> bool:
    """Rows equal column by column (NaN equals NaN), ``ignore`` left out."""
    skip = set(ignore)
    if set(a) - skip != set(b) - skip:
        return False
    for k in set(a) - skip:
        x, y = a[k], b[k]
        if isinstance(x, float) and isinstance(y, float) and math.isnan(x) and math.isnan(y):
            continue
        if x != y:
            return False
    return True
