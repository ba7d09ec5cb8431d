# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""An interrupted batch keeps its finished rows; rerunning computes only the missing recordings; --force
recomputes all; error rows are retried."""
import pytest

from rotor_estimator.batch.driver import run_batch
from rotor_estimator.batch.table import read_table
from rotor_estimator.batch.tasks import BatchOptions, expand_inputs
from rotor_estimator.cli.main import main


def test_interrupt_then_resume_computes_only_the_missing_recordings_and_force_recomputes_all(
        short_bags, dask_cluster, tmp_path, capsys):
    """A KeyboardInterrupt after the first row leaves a table with that row; the rerun computes the 2
    others (skips 1); a third run computes nothing; --force computes all 3; a recording that failed is
    retried on the next run and its row replaced."""
    folder, _ = short_bags
    paths, _ = expand_inputs([str(folder / "run*")])
    missing = str(tmp_path / "not_yet_recorded")
    out = tmp_path / "table.csv"
    options = BatchOptions("replay")
    address = dask_cluster.scheduler_address

    def stop(row):
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_batch(options, paths, out, scheduler=address, progress=False, on_row=stop, flush_every_s=3600)
    _, rows = read_table(out)
    assert len(rows) == 1 and rows[0]["status"] == "ok"
    first = rows[0]["recording"]

    seen = []
    again = run_batch(options, paths + [missing], out, scheduler=address, progress=False, on_row=seen.append)
    assert (again.computed, again.skipped, again.errors) == (3, 1, 1)
    assert first not in [r["recording"] for r in seen] and len(seen) == 3
    _, rows = read_table(out)
    assert [r["recording"] for r in rows] == paths + [missing]
    assert [r["status"] for r in rows] == ["ok", "ok", "ok", "error"]

    third = run_batch(options, paths + [missing], out, scheduler=address, progress=False)
    assert (third.computed, third.skipped) == (1, 3)  # only the error row is retried

    rc = main(["batch", "replay", str(folder / "run*"), "--out", str(out), "--scheduler", address, "--force",
               "--no-progress"])
    assert rc == 0
    assert "3 recording(s): 3 computed (0 error(s)), 0 skipped" in capsys.readouterr().err
    _, forced = read_table(out)
    assert len(forced) == 4
    fresh = {r["recording"]: r for r in forced}
    old = {r["recording"]: r for r in rows}
    assert all(fresh[p]["date_utc"] >= old[p]["date_utc"] and fresh[p]["seconds"] != old[p]["seconds"]
               for p in paths)  # recomputed: new timings
