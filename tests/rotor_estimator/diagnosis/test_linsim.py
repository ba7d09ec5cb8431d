# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""linsim: the start transient's columns against an independent matrix exponential; the radial bearing forces."""
import numpy as np
import pytest
from scipy.linalg import expm

from rotor_estimator.core.config import load_rig_file
from rotor_estimator.core.model import rotor_matrices
from rotor_estimator.diagnosis import models
from rotor_estimator.diagnosis.effects.bearing_cubic import RadialBearingCubic
from rotor_estimator.diagnosis.linsim import (SpeedSchedule, _bearing_force, free_response, simulate_linear,
                                              simulate_linear_many)


def _rigid(speed_rad_s: float, n: int):
    rig = load_rig_file().rig
    mats = rotor_matrices(rig)
    r = rig.true_coefficients.as_array()
    schedule = SpeedSchedule.from_speed(np.full(n, speed_rad_s))
    return mats, r, schedule


def test_free_response_is_c_expm_a_t_on_each_unit_initial_state():
    """At one speed, column i at sample k equals ``C expm(A k h) e_i`` (scipy's expm, no recursion), to 1e-9
    of the column's largest value: the exact discretization's powers, nothing lost in the recursion."""
    h = 1.0 / 20000.0
    mats, r, schedule = _rigid(2000.0, 600)
    a = models.rigid_state_matrix(mats, r, 2000.0)
    c = models.rigid_output(mats)[:4]
    cols = free_response(lambda w: models.rigid_state_matrix(mats, r, w), models.rigid_input(mats), c, h, schedule)
    assert cols.shape == (600, 4, 8)
    for k in (0, 1, 37, 599):
        ref = c @ expm(a * k * h)
        np.testing.assert_allclose(cols[k], ref, rtol=0, atol=1e-9 * np.abs(cols).max(axis=(0, 1)).max())


def test_free_response_decays_and_is_cut_to_zero_only_after_the_floor():
    """The rigid model is stable, so every column decays; the recursion stops once the transition matrix is
    below 1e-9 of its start, and the zeros after it are below that bound of each column's peak."""
    h = 1.0 / 20000.0
    mats, r, schedule = _rigid(1500.0, 20000)
    c = models.rigid_output(mats)[:4]
    cols = free_response(lambda w: models.rigid_state_matrix(mats, r, w), models.rigid_input(mats), c, h, schedule)
    peak = np.abs(cols).max(axis=(0, 1))
    tail = np.abs(cols[-2000:]).max(axis=(0, 1))
    assert np.all(tail <= 1e-6 * peak)
    assert np.all(peak > 0)


def test_radial_bearing_force_matches_the_effects_own_and_has_no_value_or_tangent_at_the_static_point():
    """The recursion's radial cubic (numba) equals the effect's vectorized one (the grid's first-order columns
    use it), and, being the force less its value and tangent at the static point, it and its derivative
    vanish there (central differences, against the size of the tangent it removed)."""
    rng = np.random.default_rng(7)
    static_um = np.array([3.0, -8.0])
    effect = RadialBearingCubic()
    z = rng.normal(size=(50, 4)) * 6e-6
    out = np.empty(4)
    for k in range(z.shape[0]):
        _bearing_force(z, k, 0, np.ones(4), np.tile(static_um * 1e-6, 2), np.zeros(4), 1, out)
        np.testing.assert_allclose(out, effect._force(z[k:k + 1], static_um)[0], rtol=1e-9, atol=1e-30)
    h = 1e-9
    tangent = float(np.sum((static_um * 1e-6) ** 2))
    for j in range(4):
        dz = np.zeros((2, 4))
        dz[0, j], dz[1, j] = h, -h
        f = effect._force(dz, static_um)
        assert np.all(np.abs(f[0] - f[1]) / (2 * h) < 1e-5 * tangent)
    assert np.all(np.abs(effect._force(np.zeros((1, 4)), static_um)) < 1e-12 * tangent * 1e-6)


def test_contact_force_is_the_independent_generators_less_its_value_and_tangent_at_the_static_point():
    """The recursion's contact spring beyond a clearance (``radial == 2``) equals the independent generator's
    force law (:func:`.bench.independent_physics.nonlinear_bearing_force`, a second implementation) on
    ``s + z``, less its value at ``s`` and its tangent there (that module's central-difference
    :func:`bearing_tangent_stiffness`): for a shaft resting on the contact (``|s| > c``) and for one clear of
    it; and a clearance beyond every displacement leaves no force at all."""
    from rotor_estimator.bench.independent_physics import (BearingNonlinearity, bearing_tangent_stiffness,
                                                           nonlinear_bearing_force)

    rng = np.random.default_rng(11)
    kc = 4.0e6
    z = rng.normal(size=(40, 4)) * 8e-6
    out = np.empty(4)
    for static_um, clearance_um in (((6.0, -12.0), 10.0), ((3.0, -4.0), 9.0)):
        s = np.array(static_um) * 1e-6
        nl = BearingNonlinearity(clearance_m=clearance_um * 1e-6, contact_stiffness_n_per_m=kc)
        tangent = bearing_tangent_stiffness(nl, s)  # (2, 2) stiffness: minus the force's derivative
        for k in range(z.shape[0]):
            _bearing_force(z, k, 0, np.full(4, kc), np.tile(s, 2), np.full(4, clearance_um * 1e-6), 2, out)
            for j in (0, 2):
                d = z[k, j:j + 2]
                expected = nonlinear_bearing_force(nl, s + d) - nonlinear_bearing_force(nl, s) + tangent @ d
                np.testing.assert_allclose(out[j:j + 2], expected, rtol=1e-6, atol=1e-6 * kc * 1e-6)
        if np.hypot(*s) < clearance_um * 1e-6:
            assert np.all(tangent == 0.0)
        else:
            assert np.abs(tangent).max() > 0.1 * kc
    for k in range(z.shape[0]):
        _bearing_force(z, k, 0, np.full(4, kc), np.zeros(4), np.full(4, 1e-3), 2, out)
        assert np.all(out == 0.0)


def test_kept_first_revolution_phasors_equal_a_fresh_fit_and_cannot_be_altered_by_a_caller():
    """The steady start's phasors are kept per input: a kept value equals harmonic_phasors of the same samples
    to the bit, another input (one sample changed) gets its own, and a caller writing into the returned array
    does not change what the next caller gets."""
    from rotor_estimator.diagnosis.linsim import _first_revolutions_phasors, harmonic_phasors

    h, speed = 1e-4, 2 * np.pi * 100.0
    angle = speed * h * np.arange(400)
    u = np.stack([np.cos(angle + k) + 0.1 * np.cos(2 * angle) for k in range(4)], axis=1)
    rev = int(round(2 * (2 * np.pi / speed) / h))
    fresh = harmonic_phasors(u[:rev], angle[:rev])
    first = _first_revolutions_phasors(u, angle, speed, h)
    first[:] = 0.0
    again = _first_revolutions_phasors(u, angle, speed, h)
    assert np.array_equal(again, fresh)
    other = u.copy()
    other[3, 2] += 1e-9
    other_fresh = harmonic_phasors(other[:rev], angle[:rev])
    assert np.array_equal(_first_revolutions_phasors(other, angle, speed, h), other_fresh)
    assert not np.array_equal(_first_revolutions_phasors(other, angle, speed, h), fresh)


def test_many_inputs_in_one_pass_equal_each_inputs_own_simulation_bit_for_bit():
    """``simulate_linear_many`` interleaves K recursions for speed only: on a three-block speed schedule, with
    a harmonic input (steady start), a chirp and an all-zero one, each column equals ``simulate_linear`` of
    its input exactly (the same sums in the same order)."""
    h = 1.0 / 20000.0
    rig = load_rig_file().rig
    mats = rotor_matrices(rig)
    r = rig.true_coefficients.as_array()
    n = 1500
    speed = np.repeat([1500.0, 1520.0, 1540.0], n // 3)
    schedule = SpeedSchedule.from_speed(speed, block=n // 3)
    assert schedule.speeds_rad_s.size == 3
    angle = np.cumsum(speed) * h
    t = np.arange(n) * h
    rng = np.random.default_rng(2)
    inputs = [np.column_stack([np.cos(angle), np.sin(angle), 0.3 * np.cos(angle + 1), np.zeros(n)]),
              np.sin(2 * np.pi * (100 + 4000 * t) * t)[:, None] * rng.normal(size=4),
              np.zeros((n, 4))]

    def build_a(w):
        return models.rigid_state_matrix(mats, r, w)

    b, c = models.rigid_input(mats), models.rigid_output(mats)
    together = simulate_linear_many(build_a, b, c, h, schedule, angle, inputs)
    assert together.shape == (n, c.shape[0], 3)
    for i, u in enumerate(inputs):
        alone, _ = simulate_linear(build_a, b, c, h, schedule, angle, u)
        assert np.array_equal(together[:, :, i], alone)
    assert np.any(together[:, :, 0]) and not np.any(together[:, :, 2])


def test_a_harmonic_force_drives_the_recursion_at_its_exact_steady_state_amplitude():
    """A force at 2X of a fast rotor (theta = 0.5 rad a sample: 800 Hz at 10 kHz) started at its exact periodic
    steady state (``steady_state``, the frequency response, no discretization) stays on it: the recursion's
    output after 40 ms agrees with the steady state's to 0.2 % of its amplitude. A plain first-order hold of the
    sampled force carries it at sinc^2(0.25) = 0.979 of its amplitude: 2 % off (fails without the pre-emphasis)."""
    from rotor_estimator.diagnosis.linsim import foh_compensated, steady_state

    h = 1.0 / 10000.0
    n = 1200
    w = 2 * np.pi * 400.0
    mats, r, schedule = _rigid(w, n)
    a = models.rigid_state_matrix(mats, r, w)
    b = models.rigid_input(mats)
    c = models.rigid_output(mats)[:4]
    angle = w * h * np.arange(n)
    phasors = np.zeros((3, b.shape[1]), dtype=complex)
    phasors[2, 0], phasors[2, 1] = 100.0, -100.0j      # a forward 2X force on the first input pair
    u = np.real(phasors[2][None, :] * np.exp(2j * angle)[:, None])
    y, _ = simulate_linear(lambda s: models.rigid_state_matrix(mats, r, s), b, c, h, schedule, angle, u)
    exact = np.stack([c @ steady_state(a, b, phasors, w, float(t)) for t in angle[400:]])
    amplitude = np.abs(exact).max()
    assert np.abs(y[400:] - exact).max() < 2e-3 * amplitude
    x = 0.5 * 2 * w * h
    gain = np.abs(np.fft.rfft(foh_compensated(u)[:, 0])).max() / np.abs(np.fft.rfft(u[:, 0])).max()
    s2 = np.sin(x) ** 2
    assert abs(gain * (np.sin(x) / x) ** 2 - 1.0) < 1e-4
    assert abs(gain - (1.0 + s2 / 3.0 + 8.0 * s2 ** 2 / 45.0 + 4.0 * s2 ** 3 / 35.0)) < 1e-4


@pytest.mark.parametrize("theta,tolerance", [(0.25, 1e-6), (1.0, 5e-4), (2.0, 0.04)])
def test_the_pre_emphasis_undoes_the_first_order_holds_sinc_squared_up_to_fast_harmonics(theta, tolerance):
    """A sampled sinusoid of ``theta`` rad per sample (2X of a 400 Hz rotor at 5 kHz: 1.0; its 4X: 2.0), linearly
    interpolated between its pre-emphasized samples, keeps its amplitude: the pre-emphasis's gain times
    ``sinc^2(theta / 2)`` is 1 within ``tolerance`` (the series' next terms, ``128 s^8 / 1575 + ...``: 0.99997 at
    1.0, 0.967 at 2.0), where the second difference alone gave 0.99996, 0.990 and 0.875 (each outside its
    tolerance). The gain is a pure gain (no phase); the first three samples, where a difference runs off the
    record, keep more than 0.6 of it (0.65, 0.86, 0.96 at 2.0)."""
    from rotor_estimator.diagnosis.linsim import foh_compensated

    k = np.arange(2000)
    u = np.stack([np.cos(theta * k), np.sin(theta * k)], axis=1)
    out = foh_compensated(u)
    x = theta / 2
    sinc2 = (np.sin(x) / x) ** 2
    gain = out[500:1500, 0] @ u[500:1500, 0] / (u[500:1500, 0] @ u[500:1500, 0])
    assert abs(gain * sinc2 - 1.0) < tolerance
    assert np.allclose(out[500:1500], gain * u[500:1500], atol=1e-9 * gain)  # the same phase: a pure gain
    assert np.all(np.hypot(out[:3, 0], out[:3, 1]) / gain > 0.6)


def test_the_compiled_recursions_equal_a_plain_loop_of_their_equations_on_several_speed_blocks():
    """``_propagate`` (the FOH/ZOH recursion ``q+ = Phi q + G1 (u_s + u_z) + G2 du_s``) and ``_propagate_cubic``
    (the same with the bearing force first-order held by a Heun step) agree, to rounding, with a plain NumPy loop
    written from their docstrings' equations: 28 states (the flexible shaft's size), three speed blocks, a step
    input, and each of the cubic's three force laws. Their loops run transposed for speed; the equations stay."""
    from rotor_estimator.diagnosis.linsim import _propagate, _propagate_cubic

    rng = np.random.default_rng(5)
    n_samples, n, m = 600, 28, 4
    phi = rng.normal(size=(3, n, n)) * 0.25 / np.sqrt(n)
    g1, g2 = rng.normal(size=(3, n, m)), rng.normal(size=(3, n, m))
    block = np.repeat(np.arange(3), n_samples // 3).astype(np.int64)
    us, uz = rng.normal(size=(n_samples, m)), np.zeros((n_samples, m))
    uz[100:103] = rng.normal(size=(3, m))
    q0, c_out = rng.normal(size=n), rng.normal(size=(6, n))
    out, states = _propagate(phi, g1, g2, block, us, uz, q0, c_out)
    q = q0.copy()
    for k in range(n_samples - 1):
        b = block[k]
        q = phi[b] @ q + g1[b] @ (us[k] + uz[k]) + g2[b] @ (us[k + 1] - us[k])
        assert np.allclose(states[k + 1], q, rtol=1e-12, atol=1e-12 * np.abs(q).max())
    assert np.allclose(out, states @ c_out.T, rtol=1e-12, atol=1e-12 * np.abs(out).max())

    k3 = np.abs(rng.normal(size=m)) * 0.05
    static = rng.normal(size=m) * 0.2
    clearance = np.abs(rng.normal(size=m)) * 0.1
    small = dict(phi=0.9 * phi, g1=0.1 * g1, g2=0.1 * g2, us=0.1 * us, uz=0.1 * uz, q0=0.1 * q0)
    for radial in (0, 1, 2):
        out_c, states_c = _propagate_cubic(small["phi"], small["g1"], small["g2"], block, small["us"], small["uz"],
                                           small["q0"], c_out, k3, 2, static, clearance, radial, 1)
        assert np.all(np.isfinite(states_c)) and np.any(states_c[-1])
        q = small["q0"].copy()
        f_k, f_1 = np.empty(m), np.empty(m)
        for k in range(n_samples - 1):
            b = block[k]
            _bearing_force(q.reshape(1, n), 0, 2, k3, static, clearance, radial, f_k)
            pred = small["phi"][b] @ q + small["g1"][b] @ (small["us"][k] + small["uz"][k] + f_k) \
                + small["g2"][b] @ (small["us"][k + 1] - small["us"][k])
            _bearing_force(pred.reshape(1, n), 0, 2, k3, static, clearance, radial, f_1)
            q = pred + small["g2"][b] @ (f_1 - f_k)
            assert np.allclose(states_c[k + 1], q, rtol=1e-11, atol=1e-11 * np.abs(q).max())
        assert np.allclose(out_c, states_c @ c_out.T, rtol=1e-12, atol=1e-12 * np.abs(out_c).max())


@pytest.mark.parametrize("block_samples", [256, 100, 7])
def test_the_chunked_free_response_equals_the_plain_recursion_across_speed_blocks(block_samples):
    """``_free_response`` (chunks of ``C Phi^j`` times the chunk's first state, the state carried by
    ``Phi^CHUNK``) equals, to 1e-12 of the peak, the plain loop ``out[k] = C s[k]``, ``s[k+1] = Phi_b[k] s[k]``:
    12 states, 10 initial states of them, four speed blocks of ``block_samples`` (256: whole chunks; 100 and 7:
    chunks cut short by a block's end), a record that ends inside a chunk."""
    from rotor_estimator.diagnosis.linsim import _free_response

    rng = np.random.default_rng(11)
    n_samples, n, q = 1003, 12, 10
    phi = np.stack([expm(0.01 * (rng.normal(size=(n, n)) - 3.0 * np.eye(n))) for _ in range(4)])
    block = np.minimum(np.arange(n_samples) // block_samples, 3).astype(np.int64)
    c_out = rng.normal(size=(4, n))
    s0 = np.ascontiguousarray(np.eye(n)[:, :q])
    out = _free_response(phi, block, c_out, s0, n_samples, 0.0)
    s = s0.copy()
    ref = np.empty_like(out)
    for k in range(n_samples):
        ref[k] = c_out @ s
        s = phi[block[k]] @ s
    np.testing.assert_allclose(out, ref, rtol=0, atol=1e-12 * np.abs(ref).max())


def _written_out_substeps(us, uz, block, substeps):
    """The inputs on a grid ``substeps`` times finer: the smooth (first-order held) input linearly interpolated,
    which is the path its hold follows, the step input and the speed block held; ``(N - 1) * substeps + 1``
    samples, sample ``k`` of the coarse grid at ``k * substeps``."""
    n = us.shape[0]
    frac = np.arange(substeps) / substeps
    between = us[:-1, None, :] * (1.0 - frac)[None, :, None] + us[1:, None, :] * frac[None, :, None]
    fine_us = np.vstack([between.reshape(-1, us.shape[1]), us[-1:]])
    fine_uz = np.vstack([np.repeat(uz[:-1], substeps, axis=0), uz[-1:]])
    fine_block = np.concatenate([np.repeat(block[:-1], substeps), block[-1:]])
    assert fine_us.shape[0] == (n - 1) * substeps + 1
    return np.ascontiguousarray(fine_us), np.ascontiguousarray(fine_uz), np.ascontiguousarray(fine_block)


@pytest.mark.parametrize("radial", [0, 1, 2])
def test_the_substeps_run_inside_the_recursion_equal_the_recursion_over_inputs_written_out_on_the_finer_grid(radial):
    """``_propagate_cubic`` with 4 substeps per sample (the smooth input on its straight line, the step input and
    the block held, states kept at the samples) equals, bit for bit at every sample, the same recursion with one
    substep over the inputs written out on the 4x finer grid: two speed blocks, a step input, each force law."""
    from rotor_estimator.diagnosis.linsim import _propagate_cubic

    rng = np.random.default_rng(8)
    n_samples, n, m, substeps = 300, 8, 4, 4
    phi = 0.9 * rng.normal(size=(2, n, n)) * 0.25 / np.sqrt(n)
    g1, g2 = 0.1 * rng.normal(size=(2, n, m)), 0.1 * rng.normal(size=(2, n, m))
    block = np.repeat(np.arange(2), n_samples // 2).astype(np.int64)
    us, uz = 0.1 * rng.normal(size=(n_samples, m)), np.zeros((n_samples, m))
    uz[40:42] = 0.1 * rng.normal(size=(2, m))
    q0, c_out = 0.1 * rng.normal(size=n), rng.normal(size=(6, n))
    k3, static = np.abs(rng.normal(size=m)) * 0.05, rng.normal(size=m) * 0.2
    clearance = np.abs(rng.normal(size=m)) * 0.1
    inside = _propagate_cubic(phi, g1, g2, block, us, uz, q0, c_out, k3, 2, static, clearance, radial, substeps)
    fine_us, fine_uz, fine_block = _written_out_substeps(us, uz, block, substeps)
    fine = _propagate_cubic(phi, g1, g2, fine_block, fine_us, fine_uz, q0, c_out, k3, 2, static, clearance, radial, 1)
    assert np.all(np.isfinite(inside[1])) and np.any(inside[1][-1])
    assert np.array_equal(inside[0], fine[0][::substeps]) and np.array_equal(inside[1], fine[1][::substeps])


@pytest.mark.parametrize("form", ["contact", "cubic"])
def test_a_nonlinear_bearing_at_a_coarse_rate_is_simulated_in_substeps_as_at_the_fine_rate(form):
    """A clearance contact (5 um clearance, a 48 um orbit) and a strong cubic (78 um orbit), each with a hammer
    impulse held over the same 200 us, simulated at 5 kHz agree with the 20 kHz simulation at its every 4th
    sample within 0.2 % of the peak: the nonlinear force is held over 50 us substeps. Held over the 200 us sample
    period itself (``max_step_s=None``) the contact was 3.5 % off and the cubic diverged."""
    from rotor_estimator.core.model import impact_force, imbalance_force
    from rotor_estimator.diagnosis.linsim import simulate_cubic

    rig = load_rig_file().rig
    mats, r, w = rotor_matrices(rig), rig.true_coefficients.as_array(), 2 * np.pi * 300.0

    def simulate(h_s, n, max_step_s):
        angle = w * h_s * np.arange(n)
        u_smooth = 20.0 * imbalance_force(mats, angle, np.full(n, w), np.zeros(n))  # a larger orbit
        force = np.zeros((n, 2))
        per = int(round(2e-4 / h_s))
        force[1000 * per:1001 * per, 0] = 300.0 * 1.5e-4 / 2e-4  # the same 200 us hold at both rates
        extra = {"static_m": np.zeros(4), "clearance_m": np.full(4, 5e-6)} if form == "contact" else {}
        k3 = np.full(4, 2e7 if form == "contact" else 3e15)
        y, _ = simulate_cubic(lambda s: models.rigid_state_matrix(mats, r, s), models.rigid_input(mats),
                              models.rigid_output(mats), h_s, SpeedSchedule.from_speed(np.full(n, w)), angle,
                              u_smooth, impact_force(mats, force), k3, 4, max_step_s=max_step_s, **extra)
        return y[:, :4]

    fine = simulate(5e-5, 8000, None)[::4]
    coarse = simulate(2e-4, 2000, 5e-5)
    assert np.max(np.abs(coarse - fine)) < 2e-3 * np.max(np.abs(fine))
    with np.errstate(all="ignore"):
        held = simulate(2e-4, 2000, None)
    assert not np.max(np.abs(held - fine)) < 0.02 * np.max(np.abs(fine))  # 3.5 % off, or diverged (nan)
