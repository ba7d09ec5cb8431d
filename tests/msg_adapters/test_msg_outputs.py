# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Output adapters (JointState, DiagnosticArray): exact round trips, decoding by name."""
from __future__ import annotations

import numpy as np
import pytest

import msg_adapters as ma
from rotor_estimator.core.config import COEFFICIENT_NAMES_WITH_UNITS
from rotor_estimator.core.errors import InputError

T_NS = 1_700_000_123_000_000_001


def test_coefficients_round_trip_is_exact_with_documented_names(factory, wire):
    x = np.array([1.2e7, -3e5, 4e5, 1.1e7, 1.5e3, 10.0, -10.0, 1.4e3])
    s = np.abs(x) * 0.01
    msg = wire(ma.coefficients_to_msg(factory, T_NS, x, s))
    assert list(msg.name) == list(COEFFICIENT_NAMES_WITH_UNITS) and len(msg.effort) == 0
    got = ma.coefficients_from_msg(msg)
    assert got.stamp_ns == T_NS and np.array_equal(got.estimate, x) and np.array_equal(got.std, s)


def test_covariance_round_trip_is_exact_and_row_major(factory, wire):
    p = np.arange(64.0).reshape(8, 8)
    msg = wire(ma.covariance_to_msg(factory, T_NS, p))
    assert msg.name[1] == "cov(kxx_N_per_m,kxy_N_per_m)" and msg.position[1] == p[0, 1]
    got = ma.covariance_from_msg(msg)
    assert got.stamp_ns == T_NS and np.array_equal(got.covariance, p)


def test_innovation_nis_and_shaft_round_trips_are_exact(factory, wire):
    y, s = np.array([1e-6, -2e-6, 3e-7, 0.0]), np.array([1e-6] * 4)
    inn = ma.innovation_from_msg(wire(ma.innovation_to_msg(factory, T_NS, y, s)))
    assert np.array_equal(inn.innovation_m, y) and np.array_equal(inn.std_m, s)
    assert ma.nis_from_msg(wire(ma.nis_to_msg(factory, T_NS, 3.5, 4.1, 4.0))) == ma.Nis(T_NS, 3.5, 4.1, 4.0)
    assert ma.shaft_from_msg(wire(ma.shaft_to_msg(factory, T_NS, 314.159, 1.5))) == ma.Shaft(T_NS, 314.159, 1.5)


def test_diagnostics_round_trip_keeps_level_strings_and_values(factory, wire):
    recs = (ma.DiagnosticRecord("rotor_estimator: filter", 1, "NIS high", "rig1", {"nis": "12.5", "dof": "4"}),
            ma.DiagnosticRecord("rotor_estimator: input", 0, "ok"))
    got = ma.diagnostics_from_msg(wire(ma.diagnostics_to_msg(factory, T_NS, recs)))
    assert got == ma.Diagnostics(T_NS, recs)


def test_joint_state_is_decoded_by_name_not_position(factory):
    x = np.arange(8.0)
    msg = ma.coefficients_to_msg(factory, T_NS, x, x + 100)
    order = [7, 3, 0, 5, 1, 6, 2, 4]
    shuffled = factory.new("sensor_msgs/msg/JointState", header=msg.header, name=[msg.name[i] for i in order],
                           position=factory.float64_seq(x[order]), velocity=factory.float64_seq(x[order] + 100),
                           effort=factory.float64_seq(np.empty(0)))
    got = ma.coefficients_from_msg(shuffled)
    assert np.array_equal(got.estimate, x) and np.array_equal(got.std, x + 100)


def test_joint_state_without_velocity_gives_nan_std(factory):
    msg = ma.coefficients_to_msg(factory, T_NS, np.ones(8), np.ones(8))
    msg.velocity = factory.float64_seq(np.empty(0))
    assert np.isnan(ma.coefficients_from_msg(msg).std).all()


def test_joint_state_missing_a_name_raises_input_error(factory):
    msg = ma.shaft_to_msg(factory, T_NS, 1.0, 2.0)
    with pytest.raises(InputError, match="lacks names"):
        ma.coefficients_from_msg(msg)


def test_output_decoders_reject_other_message_types(factory):
    with pytest.raises(InputError, match="expected .*sensor_msgs/msg/JointState, got sensor_msgs/msg/TimeReference"):
        ma.shaft_from_msg(ma.pulse_to_msg(factory, T_NS))
    with pytest.raises(InputError, match="DiagnosticArray"):
        ma.diagnostics_from_msg(ma.shaft_to_msg(factory, T_NS, 1.0, 2.0))


def test_encoders_reject_wrong_sizes(factory):
    with pytest.raises(InputError, match="8 values"):
        ma.coefficients_to_msg(factory, T_NS, np.zeros(7), np.zeros(7))
    with pytest.raises(InputError, match=r"\(8, 8\)"):
        ma.covariance_to_msg(factory, T_NS, np.eye(4))


def test_output_topic_names_resolve_in_node_namespace():
    assert ma.output_topic(ma.COVARIANCE_TOPIC) == "/rotor_estimator/coefficients/covariance"
    assert ma.output_topic(ma.DIAGNOSTICS_TOPIC) == "/diagnostics"


def test_identifiability_round_trip_keeps_nan_estimates_and_status_codes(factory, wire):
    est = np.array([5e5, 4e5, np.nan, 6e5, 1100.0, np.nan, -40.0, 1200.0])
    std = np.array([2e4, 1e4, 9e5, 1e4, 8.0, 400.0, 8.0, 10.0])
    status = ("determined", "determined", "not determined", "determined", "determined", "not determined",
              "weakly determined", "determined")
    out = ma.identifiability_from_msg(wire(ma.identifiability_to_msg(factory, 42, est, std, status)))
    assert out.stamp_ns == 42 and out.status == status
    assert np.array_equal(out.estimate, est, equal_nan=True) and np.array_equal(out.predicted_std, std)


def test_identifiability_rejects_unknown_status(factory):
    with pytest.raises(InputError, match="status must be one of"):
        ma.identifiability_to_msg(factory, 0, np.zeros(8), np.ones(8), ["sure"] * 8)
