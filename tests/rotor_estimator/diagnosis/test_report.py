# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""The diagnosis report's figures: what the ranking plot and the residual spectra show."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from rotor_estimator.diagnosis.report import ranking_bars, residual_spectra


def _fit(name: str, delta_bic: float) -> SimpleNamespace:
    return SimpleNamespace(name=name, delta_bic=delta_bic)


def test_ranking_keeps_negative_evidence_and_marks_the_verdict_and_its_tied_partner():
    """Evidence is plotted signed (an effect worse than its parameter cost stays negative, not clipped to a
    floor), best first, with the verdict, the tied single and the pairs told apart."""
    singles = [_fit("probe_runout", 420.0), _fit("tach_offset", 415.0), _fit("pedestal", -12.5),
               _fit("bearing_cubic", -300.0)]
    d = SimpleNamespace(verdict_set=["probe_runout", "tach_offset"],
                        ranking=SimpleNamespace(singles=singles, tied=[singles[1]]),
                        ranking_pairs=lambda n: [{"effects": ["probe_runout", "pedestal"], "delta_bic": 410.0}][:n])
    bars = ranking_bars(d)
    assert [b[1] for b in bars] == sorted((b[1] for b in bars), reverse=True)
    values = dict((b[0], b[1]) for b in bars)
    assert values["pedestal"] == -12.5 and values["bearing_cubic"] == -300.0
    roles = dict((b[0], b[2]) for b in bars)
    assert roles["tach_offset"] == "tied" and roles["probe_runout + pedestal"] == "pair"
    assert roles["probe_runout"] == "other"  # a set verdict: no single is "the" verdict


def test_white_residual_lies_on_the_noise_floor_and_orders_are_multiples_of_the_speed():
    """For a white residual of std sigma the Welch amplitude density is sigma sqrt(2 / fs): the drawn floor
    (median within 5 %); the order markers sit at k times the shaft frequency."""
    fs, n, sigma = 20000.0, 20000, np.array([1e-6, 2e-6, 0.5e-6, 1e-6])
    rng = np.random.default_rng(3)
    y = rng.standard_normal((n, 4)) * sigma
    ctx = SimpleNamespace(sample_rate_hz=fs, y_m=y, mask=np.ones(n, bool), mean_speed_rad_s=2 * np.pi * 300.0,
                          noise_std_m=sigma)
    d = SimpleNamespace(ctx=ctx, nominal_prediction_m=np.zeros_like(y), after_fit=None, verdict_set=[])
    spec = residual_spectra(d)
    asd = spec["asd_m_per_sqrt_hz"]["nominal"][1:-1]
    assert np.median(asd, axis=0) == pytest.approx(spec["noise_floor_m_per_sqrt_hz"], rel=0.05)
    assert spec["order_hz"]["3X"] == pytest.approx(900.0)
