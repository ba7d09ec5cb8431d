# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Coupled flexible-shaft effect: equivalent beam, rigid limit, FE cross-check, self-recovery."""
from __future__ import annotations

import math
import warnings
from dataclasses import replace

import numpy as np
import pytest

from rotor_estimator.core.config import Imbalance, load_rig_file
from rotor_estimator.diagnosis.context import build_context
from rotor_estimator.bench.effect_sim import EffectScenario, HiddenEffects, simulate_with_effects
from rotor_estimator.diagnosis.effects.flexible_shaft import (DECOUPLED_OFFSET, FlexibleShaft, decoupled_column,
                                                      equivalent_beam, flexible_response, plane_matrices,
                                                      reduce_shaft, rig_stations, shaft_model,
                                                      VARIANT_SWITCH)
from rotor_estimator.diagnosis.ranking import fit_effect, nominal_solution, refine
from rotor_estimator.core.model import rotor_matrices
from rotor_estimator.core.recording import RigRecording
from rotor_estimator.core.simulator import Impact

warnings.filterwarnings("ignore", category=RuntimeWarning)


@pytest.fixture(scope="module")
def rig_file():
    return load_rig_file()


@pytest.fixture(scope="module")
def control(rig_file):
    """A short noisy record of the nominal rig (no hidden effect) and its fitting context."""
    rig = rig_file.rig
    scenario = EffectScenario(speed_rad_s=rig.speed_rad_s, duration_s=0.15, lead_in_s=0.15,
                              impacts=(Impact(0.04, 50e-6, 300.0, -515.0), Impact(0.10, 50e-6, -400.0, 200.0)),
                              noise_std_m=1e-6, coefficients=rig.true_coefficients.as_array())
    sim = simulate_with_effects(rig, scenario, HiddenEffects(), seed=11)
    return sim, build_context(sim.recording, rig, rig_file.estimator)


def _rigs(rig_file):
    """The seed rig, a slender-shaft rig (stations inside a heavy center) and a rig with its mass far out."""
    from rotor_estimator.bench.ross_cases import rig_from_geometry

    seed = rig_file.rig
    ross = rig_from_geometry(0.022, 1500.0, 1e-6)
    spread = replace(seed, transverse_inertia_kg_m2=0.06)  # I_t > m L^2 / 12 over the stations: no disk
    return seed, ross, spread


def test_equivalent_beam_matches_rig_mass_center_and_inertia(rig_file):
    for rig in _rigs(rig_file):
        beam = equivalent_beam(rig)
        m_mat, _ = plane_matrices(beam)
        translation = np.zeros(m_mat.shape[0])
        translation[0::2] = 1.0
        lever = np.zeros(m_mat.shape[0])
        lever[0::2], lever[1::2] = beam.nodes_m, 1.0  # rigid rotation about the mass center (slope 1)
        assert translation @ m_mat @ translation == pytest.approx(rig.shaft_mass_kg, rel=1e-12)
        assert abs(translation @ m_mat @ lever) < 1e-12 * rig.shaft_mass_kg      # mass center at 0
        assert lever @ m_mat @ lever == pytest.approx(rig.transverse_inertia_kg_m2, rel=1e-12)
        assert beam.mass_kg == pytest.approx(rig.shaft_mass_kg, rel=1e-12)
        assert beam.disk_mass_kg >= 0.0 and beam.mass_per_length_kg_m > 0.0
        stations = rig_stations(rig)
        assert beam.nodes_m[0] <= stations.min() + 1e-12 and stations.max() - 1e-12 <= beam.nodes_m[-1]
        red = reduce_shaft(rig)
        # the beam on the rigid shapes is Eq. 3's mass matrix in bearing coordinates
        np.testing.assert_allclose(red.mass_rigid, rotor_matrices(rig).mass_matrix[np.ix_([0, 2], [0, 2])],
                                   rtol=1e-10)
    assert equivalent_beam(_rigs(rig_file)[2]).disk_mass_kg == 0.0


def test_rigid_limit_equals_the_nominal_model(control):
    _, ctx = control
    red = reduce_shaft(ctx.rig)
    scale = float(np.max(np.abs(ctx.y_nom_m)))
    out = flexible_response(ctx, red, ctx.coefficients, math.inf, 0.02)
    np.testing.assert_allclose(out[:, :4], ctx.y_nom_m, rtol=0, atol=1e-10 * scale)
    np.testing.assert_allclose(out[:, 4:], ctx.v_nom_m_s, rtol=0, atol=1e-10 * float(np.max(np.abs(ctx.v_nom_m_s))))
    # finite but stiff: the offset vanishes as the shaft stiffens (about like 1 / EI)
    eff = FlexibleShaft()
    off = [float(np.max(np.abs(eff.basis(ctx, np.array([np.log10(f), -2.0]))[0]))) / scale for f in (1e3, 1e4, 1e5)]
    assert off[0] > 30 * off[1] > 30 * 30 * off[2]
    assert off[2] < 1e-5


def test_coupled_model_matches_the_fe_rotor_package():
    """Eigenvalues at speed vs :mod:`rotor_estimator.core.flexible` (Timoshenko FE, all DOFs), slender shaft + disk."""
    from rotor_estimator.core.config import RigConfig
    from rotor_estimator.core.flexible import assemble, rotor_from_mapping
    from rotor_estimator.core.flexible.modal import state_matrices

    length, d, rho, e = 0.4, 0.012, 7800.0, 2.1e11
    disk = {"station_axial_m": 0.2, "mass_kg": 1.2, "polar_inertia_kg_m2": 3.5e-3, "transverse_inertia_kg_m2": 1.75e-3}
    r = np.array([5e5, 2e5, -2e5, 6e5, 900.0, 20.0, -20.0, 1100.0])
    speed = 1200.0
    fe = assemble(rotor_from_mapping({
        "material": {"density_kg_m3": rho, "youngs_modulus_pa": e, "poisson_ratio": -0.99},  # G = 50 E: no shear
        "shaft": [{"length_m": length, "outer_diameter_m": d}], "disks": [disk],
        "bearings": [dict(station_axial_m=s, **dict(zip(
            ("kxx_N_per_m", "kxy_N_per_m", "kyx_N_per_m", "kyy_N_per_m",
             "cxx_N_s_per_m", "cxy_N_s_per_m", "cyx_N_s_per_m", "cyy_N_s_per_m"), r))) for s in (0.075, 0.325)],
        "operating": {"speed_rpm": 0.0, "sample_rate_hz": 20000.0}, "model": {"max_element_length_m": 0.0125}}))
    a_fe, _ = state_matrices(fe.M, fe.C, fe.K, fe.G, speed)
    # the rig file of that rotor (stations from its mass center at 0.2 m; imbalances at the shaft ends)
    mu = rho * math.pi * d * d / 4
    rig = RigConfig("fe", shaft_mass_kg=mu * length + disk["mass_kg"],
                    polar_inertia_kg_m2=mu * length * d * d / 8 + disk["polar_inertia_kg_m2"],
                    transverse_inertia_kg_m2=mu * length ** 3 / 12 + mu * length * d * d / 16
                    + disk["transverse_inertia_kg_m2"],
                    bearing1_position_m=-0.125, bearing2_position_m=0.125, probe1_position_m=-0.1,
                    probe2_position_m=0.1, impact_position_m=0.0,
                    imbalances=(Imbalance(1e-3, 0.01, 0.0, -0.2), Imbalance(1e-3, 0.01, 0.0, 0.2)),
                    speed_rad_s=speed, sample_rate_hz=20000.0, noise_std_m=1e-6)
    red = reduce_shaft(rig)
    assert red.beam.length_m == pytest.approx(length)
    ei = e * math.pi * d ** 4 / 64
    a = shaft_model(rig, red, r, ei, 0.0).state_matrix(speed)

    def lowest(mat, k=6):
        lam = np.linalg.eigvals(mat)
        lam = lam[lam.imag > 1.0]
        return lam[np.argsort(np.abs(lam))][:k]

    ours, ref = lowest(a), lowest(a_fe)
    assert abs(ref[-1]) / (2 * math.pi) < 2000.0  # the first bending pair is among them
    np.testing.assert_allclose(np.abs(ours), np.abs(ref), rtol=0.01)          # natural frequencies
    assert np.all(np.abs(ours.real - ref.real) < 0.01 * np.abs(ref))          # decay rates


@pytest.mark.slow
def test_recovers_its_own_bending_frequency(control, rig_file):
    sim, ctx0 = control
    red = reduce_shaft(ctx0.rig)
    f_true, zeta_true = 300.0, 0.02
    r_true = rig_file.rig.true_coefficients.as_array()
    clean = flexible_response(ctx0, red, r_true, FlexibleShaft.stiffness(red, f_true), zeta_true)[:, :4]
    noise = np.random.default_rng(5).standard_normal(clean.shape) * 1e-6
    rec = sim.recording
    data = RigRecording(rec.stamps_ns, clean + noise, rec.pulse_stamps_ns, rec.impact_force_n)
    ctx = build_context(data, rig_file.rig, rig_file.estimator)
    _, bic0, _ = nominal_solution(ctx)
    eff = FlexibleShaft()
    fit = fit_effect(ctx, eff, reference_bic=bic0)
    coupled_starts = tuple(p for p in eff.refine_starts(ctx) if p[0] < VARIANT_SWITCH)  # the decoupled ones: 2x time
    fit = refine(ctx, eff, fit, reference_bic=bic0, nl_starts=coupled_starts, max_nfev=25)
    assert fit.physical["coupled"] == 1.0
    assert fit.delta_bic > 30
    assert fit.physical["bending_frequency_hz"] == pytest.approx(f_true, rel=0.02)
    assert fit.physical["bending_damping_ratio"] == pytest.approx(zeta_true, rel=0.2)
    np.testing.assert_allclose(fit.coefficients[:4], r_true[:4], rtol=0.05, atol=0.02 * np.abs(r_true[:4]).max())
    assert np.sqrt(np.mean(fit.residual_rms_m ** 2)) < 1.05e-6


def test_decoupled_variant_is_the_pinned_mode_of_effect_sim(control):
    """``nl[0] >= DECOUPLED_OFFSET`` selects one pinned-pinned mode decoupled from Eq. 2 (unit modal mass)."""
    _, ctx = control
    off, cols = FlexibleShaft().basis(ctx, np.array([DECOUPLED_OFFSET + np.log10(400.0), np.log10(0.02)]))
    assert off is None and cols.shape == (ctx.t_s.size, 4, 1)
    np.testing.assert_allclose(cols[:, :, 0], decoupled_column(ctx, 400.0, 0.02), rtol=1e-9)
    off, cols = FlexibleShaft().basis(ctx, np.array([np.log10(400.0), np.log10(0.02)]))
    assert off.shape == (ctx.t_s.size, 4) and not np.any(cols)
