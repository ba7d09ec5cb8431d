# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""The same recordings through the default local cluster and through a separately started cluster
(`--scheduler ADDRESS`) give identical rows; identify rows equal the identify core run directly."""
import numpy as np

from rotor_estimator.batch.driver import run_batch
from rotor_estimator.batch.table import COEFFICIENT_COLUMNS, COEFFICIENT_STD_COLUMNS, read_table, same_values
from rotor_estimator.batch.tasks import BatchOptions, expand_inputs
from rotor_estimator.bench.blind import save_recording
from rotor_estimator.cli.main import main
from rotor_estimator.core.config import load_rig_file
from rotor_estimator.identification.recordings import identify_recordings


def test_batch_identify_local_default_and_external_scheduler_give_identical_rows(short_bags, dask_cluster, tmp_path):
    """Three bags and one .npz recording: `batch identify` on its own local cluster and on a
    LocalCluster reached by address (a real scheduler and 2 worker processes) give rows equal in every
    column but the timing, worker and date; each row's coefficients and std equal `identify_recordings`
    on the recording; the .npz copy of run1 gives run1's numbers."""
    folder, recordings = short_bags
    npz = tmp_path / "run1_copy.npz"
    run1 = next(p for p in recordings if p.endswith("run1"))
    save_recording(npz, recordings[run1])
    listing = tmp_path / "list.txt"
    listing.write_text(f"# the bags and one npz\n{folder}/run1\n{folder}/run2\n{folder}/run3\n{npz.name}\n")
    paths, skipped = expand_inputs([str(listing)])
    assert skipped == 0 and len(paths) == 4 and paths[-1] == str(npz)
    local = run_batch(BatchOptions("identify"), paths, tmp_path / "local.parquet", workers=2, progress=False)
    out = tmp_path / "remote.parquet"
    rc = main(["batch", "identify", str(listing), "--out", str(out), "--scheduler", dask_cluster.scheduler_address,
               "--no-progress"])
    assert rc == 0
    _, remote = read_table(out)
    assert [r["recording"] for r in remote] == paths == [r["recording"] for r in local.rows]
    workers = set(dask_cluster.scheduler_info["workers"])
    for a, b in zip(local.rows, remote):
        assert a["status"] == "ok", a["error"]
        assert same_values(a, b), {k: (a[k], b[k]) for k in a if a[k] != b[k]}
        assert b["worker"] in workers
    rig_file = load_rig_file()
    for row in remote[:1] + remote[3:]:  # run1 and its npz copy
        direct = identify_recordings(rig_file, [recordings[run1]])
        entries = direct.report.entries
        np.testing.assert_allclose([row[c] for c in COEFFICIENT_COLUMNS], [e.estimate for e in entries], rtol=1e-9)
        np.testing.assert_allclose([row[c] for c in COEFFICIENT_STD_COLUMNS], [e.predicted_std for e in entries],
                                   rtol=1e-9)
        assert row["not_determined"] == (";".join(e.name for e in entries if e.status == "not determined") or None)
        assert row["normalized_squared_residual_mean"] == direct.quality["normalized_squared_residual_mean"]
