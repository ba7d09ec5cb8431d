# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""`batch diagnose` rows hold the diagnosis summary of each recording (a 0.07 s record diagnoses in ~5 s)."""
import pytest

from rotor_estimator.batch.driver import run_batch
from rotor_estimator.batch.tasks import BatchOptions
from rotor_estimator.core.config import SEED_RIG_PATH
from rotor_estimator.diagnosis.api import diagnose


def test_batch_diagnose_row_equals_the_diagnosis_summary(short_bags, dask_cluster, seed_rig_file):
    """One short bag through `batch diagnose` on a cluster: verdict, second effect, top two, residual RMS
    before/after, noise and shrink ratio equal `diagnose(...).summary()` run here; the gap ratios are
    the RMS over the noise."""
    folder, recordings = short_bags
    path = next(p for p in recordings if p.endswith("run2"))
    s = run_batch(BatchOptions("diagnose", rig_path=str(SEED_RIG_PATH)), [path], None,
                  scheduler=dask_cluster.scheduler_address, progress=False)
    row = s.rows[0]
    assert row["status"] == "ok", row["error"]
    d = diagnose(recordings[path], seed_rig_file.rig, seed_rig_file.estimator, passes=2).summary()
    assert row["verdict"] == d["best_effect"] and row["second_effect"] == d["second_effect"]
    assert row["top_two"] == ";".join(d["top_two"])
    assert row["residual_rms_before_m"] == d["residual_rms_before"]
    assert row["residual_rms_after_m"] == d["residual_rms_after"]
    assert row["shrink_ratio"] == d["shrink_ratio"] and row["noise_std_m"] == d["noise_std_m"]
    assert row["gap_ratio_before"] == pytest.approx(d["residual_rms_before"] / d["noise_std_m"], rel=1e-12)
    assert row["samples_used"] == d["data"]["samples_used"]
    # the default (auto) keeps the full rate of a 0.1 s record: the filter's edges would be 29 % of it
    assert (row["decimate"], row["decimation_factor"]) == ("auto", 1) == ("auto", d["data"]["decimation"]["factor"])
    # the verdict's coefficients with their std, and the verdict set, as the summary has them
    assert row["verdict_set"] == ";".join(d["verdict_set"])
    assert row["kxx_n_per_m"] == d["coefficients_verdict"]["kxx_N_per_m"]
    assert row["cyy_std_n_s_per_m"] == d["coefficients_verdict_std"]["cyy_N_s_per_m"] > 0


def test_batch_diagnose_decimated_row_equals_the_decimated_diagnosis_and_a_table_keeps_one_factor(
        short_bags, dask_cluster, seed_rig_file, tmp_path):
    """`batch diagnose --decimate 2`: the row equals `diagnose(..., decimate=2).summary()` (verdict, residuals,
    samples used: fewer than the full rate's), its decimate column is what was asked and decimation_factor the
    factor used; resuming that table with another --decimate (the default, auto) is refused (its ok rows would mix
    two rates) unless forced; decimate on another command is refused."""
    from rotor_estimator.core.errors import InputError

    folder, recordings = short_bags
    path = next(p for p in recordings if p.endswith("run2"))
    table = tmp_path / "diagnosis.csv"
    s = run_batch(BatchOptions("diagnose", rig_path=str(SEED_RIG_PATH), decimate=2), [path], table,
                  scheduler=dask_cluster.scheduler_address, progress=False)
    row = s.rows[0]
    assert row["status"] == "ok", row["error"]
    d = diagnose(recordings[path], seed_rig_file.rig, seed_rig_file.estimator, passes=2, decimate=2).summary()
    assert row["decimate"] == "2" and row["decimation_factor"] == 2 == d["data"]["decimation"]["factor"]
    assert row["verdict"] == d["best_effect"]
    assert row["residual_rms_after_m"] == d["residual_rms_after"] and row["noise_std_m"] == d["noise_std_m"]
    assert row["samples_used"] == d["data"]["samples_used"] < len(recordings[path]) / 2
    with pytest.raises(InputError, match="with --decimate 2; a --decimate auto batch needs its own table"):
        run_batch(BatchOptions("diagnose", rig_path=str(SEED_RIG_PATH)), [path], table,
                  scheduler=dask_cluster.scheduler_address, progress=False)
    again = run_batch(BatchOptions("diagnose", rig_path=str(SEED_RIG_PATH), decimate=2), [path], table,
                      scheduler=dask_cluster.scheduler_address, progress=False)
    assert again.skipped == 1 and again.computed == 0
    with pytest.raises(InputError, match="decimate is an option of diagnose only"):
        BatchOptions("identify", decimate=2).validate()
    with pytest.raises(InputError, match="decimate must be auto or a positive integer"):
        BatchOptions("diagnose", rig_path=str(SEED_RIG_PATH), decimate=0).validate()
