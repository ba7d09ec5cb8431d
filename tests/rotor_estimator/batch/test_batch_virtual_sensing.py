# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""`batch virtual-sensing` rows hold the leave-one-station-out headline figures of each NPZ recording."""
import numpy as np

from rotor_estimator.batch.driver import run_batch
from rotor_estimator.batch.tasks import BatchOptions
from rotor_estimator.core.flexible.description import load_rotor_description
from rotor_estimator.core.flexible.state_space import build_state_space, simulate
from rotor_estimator.virtual_sensing.estimator import VirtualSensingConfig, leave_one_station_out
from rotor_estimator.virtual_sensing.loaders import load_npz_channels


def test_batch_virtual_sensing_rows_equal_the_leave_one_out_report(tmp_path, dask_cluster):
    """Two model-consistent NPZ recordings (three_probe_rig, 600 samples): each row's channel count equals
    leave_one_station_out on the same file, and its coverage mean/min and largest displacement error equal
    it to 1e-12 relative: the Dask worker runs the same code in another process, whose BLAS may split a sum
    over other threads (a 1-ulp difference in the largest error was seen in CI on a loaded machine)."""
    ss = build_state_space(load_rotor_description("three_probe_rig"))
    paths = []
    for seed in (1, 2):
        sim = simulate(ss, 600, seed=seed)
        path = tmp_path / f"vs{seed}.npz"
        np.savez(path, t=sim.t, **{c: sim.z[:, j] for j, c in enumerate(ss.channel_names)})
        paths.append(str(path))
    s = run_batch(BatchOptions("virtual-sensing"), paths, None, scheduler=dask_cluster.scheduler_address,
                  progress=False)
    for path, row in zip(paths, s.rows):
        assert row["status"] == "ok", row["error"]
        t, z, u = load_npz_channels(path, ss)
        rows = leave_one_station_out(ss, z, u, VirtualSensingConfig()).rows
        assert row["n_samples"] == 600 and row["channels"] == len(rows)
        np.testing.assert_allclose(row["coverage_mean"], np.mean([r.coverage_measured for r in rows]), rtol=1e-12)
        np.testing.assert_allclose(row["coverage_min"], np.min([r.coverage_measured for r in rows]), rtol=1e-12)
        np.testing.assert_allclose(row["rms_error_max_m"], max(r.rms_error for r in rows if r.unit == "m"),
                                   rtol=1e-12)
        assert row["channels_calibrated"] == sum(r.calibrated for r in rows)
