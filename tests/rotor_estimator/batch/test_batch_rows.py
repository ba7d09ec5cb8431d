# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""`rotor-estimator batch replay` on the default local cluster: each row holds what the single-recording
core function gives, a truncated bag is an error row while the others complete."""
import math

import numpy as np

from rotor_estimator.batch.table import COEFFICIENT_COLUMNS, COEFFICIENT_STD_COLUMNS, read_table
from rotor_estimator.cli.main import main
from rotor_estimator.core.config import COEFFICIENT_NAMES
from rotor_estimator.ros.replay import replay_bag


def test_batch_replay_rows_equal_the_replay_core_and_a_truncated_bag_is_an_error_row(bag_copy, tmp_path):
    """Through the CLI and the default local cluster (2 worker processes): one row per bag, the coefficients,
    their std, NIS and sample counts equal `replay_bag` run directly on the same bag; the bag whose MCAP
    file was cut in half gives status error with the reader's message, the three others are ok; exit 1."""
    bad = bag_copy / "run_bad"
    bad.mkdir()
    src = next((bag_copy / "run1").glob("*.mcap"))
    data = src.read_bytes()
    (bad / "run_bad.mcap").write_bytes(data[: len(data) // 2])
    for f in (bag_copy / "run1").glob("*.yaml"):
        (bad / f.name).write_text(f.read_text().replace("run1", "run_bad"))
    (bag_copy / "notes.md").write_text("not a recording")  # matched by the glob, left out
    out = tmp_path / "table.csv"
    rc = main(["batch", "replay", str(bag_copy / "*"), "--out", str(out), "--workers", "2", "--no-progress"])
    assert rc == 1  # one recording failed
    command, rows = read_table(out)
    assert command == "replay"
    by_name = {r["recording"].rsplit("/", 1)[-1]: r for r in rows}
    assert sorted(by_name) == ["run1", "run2", "run3", "run_bad"]
    assert by_name["run_bad"]["status"] == "error"
    assert "truncated or corrupt" in by_name["run_bad"]["error"]
    assert math.isnan(by_name["run_bad"]["kxx_n_per_m"] or math.nan)
    for name in ("run1", "run2", "run3"):
        row = by_name[name]
        assert row["status"] == "ok" and row["error"] is None
        direct = replay_bag(bag_copy / name, progress=False)
        got = [row[c] for c in COEFFICIENT_COLUMNS]
        want = [direct["coefficients"][n]["mean"] for n in COEFFICIENT_NAMES]
        np.testing.assert_allclose(got, want, rtol=1e-12)
        np.testing.assert_allclose([row[c] for c in COEFFICIENT_STD_COLUMNS],
                                   [direct["coefficients"][n]["std"] for n in COEFFICIENT_NAMES], rtol=1e-12)
        assert row["nis_mean"] == direct["consistency"]["nis_mean"]
        assert row["samples_processed"] == direct["samples"]["processed"] == row["n_samples"]
        assert row["model_mismatch"] == direct["consistency"]["model_mismatch"]
        assert row["rig"] == direct["rig"] and row["passes"] == direct["passes"]
        assert abs(row["duration_s"] - 0.07) < 0.001 and row["speed_rpm"] > 0
        assert row["seconds"] > 0 and row["worker"].startswith("tcp://")
