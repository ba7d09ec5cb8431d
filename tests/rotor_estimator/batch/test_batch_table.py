# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""The batch table: CSV and Parquet round-trip the same columns (units in the names), types and values;
a table of another command or a bad extension is refused; the summary figures are written."""
import math

import pytest

from rotor_estimator.batch.plots import plot_table
from rotor_estimator.batch.table import columns, read_table, same_values, write_table
from rotor_estimator.core.errors import InputError


def _rows(command):
    base = {"command": command, "rig": "miller_howard_2008", "speed_rpm": 1500.0, "duration_s": 0.5,
            "n_samples": 10000, "recording_start_utc": "2023-11-14T22:13:20+00:00", "seconds": 1.25,
            "worker": "tcp://127.0.0.1:1", "version": "0.1.0", "date_utc": "2026-01-01T00:00:00+00:00"}
    ok = dict(base, recording="/data/a b,c.mcap", status="ok", error=None)
    if command == "replay":
        ok.update(kxx_n_per_m=5.2e5, kxx_std_n_per_m=2.1e4, cyy_n_s_per_m=1200.0, cyy_std_n_s_per_m=math.nan,
                  nis_mean=4.02, model_mismatch=False, converged=True, passes=2, not_determined="cxy;cyx")
    else:
        ok.update(verdict="misalignment", second_effect="none", top_two="misalignment;rub", shrink_ratio=2.5,
                  gap_ratio_before=3.0, samples_used=9000)
    err = dict(base, recording="/data/bad", status="error", error='cannot open bag: "truncated", line 2\nmore')
    return [ok, err]


@pytest.mark.parametrize("command", ["replay", "diagnose"])
def test_csv_and_parquet_round_trip_the_same_columns_types_and_values(tmp_path, command):
    """Rows written as CSV and as Parquet read back with the command's columns in order (coefficients
    as kxx_n_per_m, kxx_std_n_per_m, cxx_n_s_per_m...), the same values (None stays None, NaN stays NaN,
    a path with a comma and an error with quotes and a newline survive) and the same types."""
    rows = _rows(command)
    got = {}
    for ext in ("csv", "parquet"):
        path = write_table(tmp_path / f"t.{ext}", rows, command)
        cmd, back = read_table(path)
        assert cmd == command and list(back[0]) == [n for n, _ in columns(command)]
        got[ext] = back
    for a, b, src in zip(got["csv"], got["parquet"], rows):
        assert same_values(a, b, ignore=())
        for k, v in src.items():
            assert same_values({k: a[k]}, {k: v}, ignore=()), (k, a[k], v)
        assert type(a["n_samples"]) is int and a["kxy_n_per_m" if command == "replay" else "noise_std_m"] is None
    names = [n for n, _ in columns("replay")]
    assert {"kxx_n_per_m", "kxx_std_n_per_m", "cxx_n_s_per_m", "cyy_std_n_s_per_m", "nis_mean", "speed_rpm",
            "duration_s", "seconds", "status", "error"} <= set(names)


def test_a_table_of_another_command_or_an_unknown_extension_is_refused(tmp_path):
    """Resuming a diagnose batch into a replay table is an error naming the command; `.xlsx` is refused."""
    from rotor_estimator.batch.driver import run_batch
    from rotor_estimator.batch.tasks import BatchOptions

    out = write_table(tmp_path / "t.parquet", _rows("replay"), "replay")
    with pytest.raises(InputError, match="holds replay rows"):
        run_batch(BatchOptions("diagnose", rig_path="rig.yaml"), ["/data/x"], out, progress=False)
    with pytest.raises(InputError, match="Parquet"):
        write_table(tmp_path / "t.xlsx", [], "replay")


@pytest.mark.parametrize("command", ["replay", "diagnose"])
def test_the_summary_figure_is_written_for_coefficient_and_verdict_tables(tmp_path, command):
    """`batch plot`: a PNG of coefficients vs speed (replay) or of verdict counts (diagnose)."""
    path = plot_table(_rows(command), command, tmp_path / "f.png")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    if command == "replay":
        plot_table(_rows(command), command, tmp_path / "d.png", x="date")
        assert (tmp_path / "d.png").stat().st_size > 1000
