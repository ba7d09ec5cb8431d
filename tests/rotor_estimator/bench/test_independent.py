# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Independent blind generator: its physics against the package's simulator, energy, labelled gaps,
independence of its imports, and the blind-set layout."""
from __future__ import annotations

import ast
import json
import math
from pathlib import Path

import numpy as np
import pytest

from rotor_estimator.bench import independent, independent_effects, independent_physics
from rotor_estimator.bench.blind import load_recording
from rotor_estimator.bench.independent_physics import (HammerPulse, RotorGeometry, TrueModel, integrate,
                                                       mechanical_energy, unbalance)
from rotor_estimator.core.config import load_rig_file


def _model(rig, coefficients, **kw) -> TrueModel:
    forces = tuple(unbalance(u.axial_position_m, u.moment_kg_m, u.phase_rad, rig.speed_rad_s) for u in rig.imbalances)
    return TrueModel(RotorGeometry.from_rig(rig), tuple(coefficients), rig.speed_rad_s, forces, **kw)


def test_solve_ivp_simulator_agrees_with_the_package_simulator():
    """From rest, no noise, same coefficients, speed, unbalance and a 50 us impact: the mass-center solve_ivp
    simulator and the package's bearing-coordinate RK4 simulator give the same probe records within 1e-3 of
    the response RMS (measured: 6e-10), so their sign conventions, gyroscopics and probe maps agree."""
    from rotor_estimator.core.simulator import Impact, Scenario, simulate

    rig = load_rig_file().rig
    r = rig.true_coefficients.as_array() * np.array([1.1, 0.8, 1.2, 0.9, 1.1, 1.3, 0.7, 0.9])
    from rotor_estimator.core.config import BearingCoefficients

    sc = Scenario(duration_s=0.1, discard_initial_s=0.0, impacts=(Impact(0.04, 50e-6, 120.0, -515.0),),
                  noise_std_m=0.0, coefficients=BearingCoefficients.from_array(r))
    theirs = simulate(rig, sc, seed=0).probes_clean_m
    model = _model(rig, r, impacts=(HammerPulse(0.04, 50e-6, 120.0, -515.0, "rect"),), gravity_m_s2=0.0)
    traj, mats = integrate(model, 0.0, 0.1, steady=False)
    t = np.arange(theirs.shape[0]) / rig.sample_rate_hz
    mine = traj.states(t)[:, :mats.n] @ mats.probe_map.T
    rel = np.sqrt(np.mean((mine - theirs) ** 2)) / np.sqrt(np.mean(theirs ** 2))
    assert rel < 1e-3


def test_steady_start_is_periodic():
    """A steady record of the linear model starts on its periodic solution: one revolution later the probes
    repeat to 1e-6 of their amplitude (a record from rest does not: its transient is still there)."""
    rig = load_rig_file().rig
    model = _model(rig, rig.true_coefficients.as_array())
    period = 2 * math.pi / rig.speed_rad_s
    t = np.linspace(0.0, 0.01, 200)
    for steady, bound in ((True, 1e-6), (False, None)):
        traj, mats = integrate(model, 0.0, 0.03, steady=steady)
        y0 = traj.states(t)[:, :4] @ mats.probe_map.T
        y1 = traj.states(t + period)[:, :4] @ mats.probe_map.T
        err = np.max(np.abs(y1 - y0)) / np.max(np.abs(y0 - y0.mean(axis=0)))
        assert (err < bound) if bound else (err > 1e-2)


def test_free_undamped_motion_conserves_energy_with_gyroscopics():
    """Zero damping, symmetric bearing stiffness, no forcing or gravity, spinning (gyroscopic coupling on):
    kinetic plus elastic energy stays constant to 1e-6 over 0.2 s; with damping it falls (the check can fail)."""
    rig = load_rig_file().rig
    y0 = np.array([20e-6, -10e-6, 1e-4, 2e-4, 0.01, 0.0, 0.05, -0.02])
    for damping, conserved in ((0.0, True), (300.0, False)):
        r = (5e5, 1e5, 1e5, 6e5, damping, 0.0, 0.0, damping)
        model = TrueModel(RotorGeometry.from_rig(rig), r, 2500.0, gravity_m_s2=0.0)
        traj, mats = integrate(model, 0.0, 0.2, steady=False, initial=y0)
        e = mechanical_energy(mats, traj.states(np.linspace(0, 0.2, 400)))
        drift = np.max(np.abs(e / e[0] - 1))
        assert (drift < 1e-6) if conserved else (e[-1] < 0.5 * e[0])


def _recomputed_gap(case) -> float:
    """``rms(recorded - DC - effect-free record) / noise_std`` of a case, rebuilt from its label and files:
    ``sqrt(gap^2 - 1 + (noise_rms / noise_std)^2)`` in expectation."""
    lab, rig = case.label, case.rig_file.rig
    rec = case.recording
    impacts = tuple(HammerPulse(a, d, fx, fy, shape) for a, d, fx, fy, shape in lab["impacts"])
    model = _model(rig, lab["true_coefficients"], impacts=impacts)
    if lab["effects"] == ["tach_offset"]:
        pulses = (rec.pulse_stamps_ns - rec.stamps_ns[0]) * 1e-9
        model = TrueModel(**{**model.__dict__, "angle_of_time": independent_effects.angle_from_pulses(pulses)})
    steady = lab["start"] == "steady"
    traj, mats = integrate(model, -1e-3 if steady else 0.0, rec.time_s()[-1] + 1e-3, steady=steady)
    ref = traj.states(rec.time_s())[:, :mats.n] @ mats.probe_map.T
    d = (rec.probes_m - ref)[rec.time_s() >= independent_effects.WARMUP_S]
    d = d - d.mean(axis=0)
    return float(np.sqrt(np.mean(d ** 2)) / lab["noise_std_m"])


@pytest.mark.parametrize("seed,form", list(enumerate(["control"] + list(independent.PLANNED_FORMS), start=4242)))
def test_each_form_changes_the_record_by_its_labelled_gap(seed, form, monkeypatch):
    """Each planned form (0.1 s records to keep it short; a seed of its own, so starts and conditions vary),
    rebuilt from its label and written record: the residual against the effect-free true model is the
    labelled true gap (within 6 %, the noise's own sampling spread included); a control's true gap is 1."""
    monkeypatch.setattr(independent, "DURATION_S", 0.1)
    spec = {"kind": "control", "impact": True} if form == "control" else {"kind": "single", "form": form}
    case = independent.make_case("t", spec, seed)
    lab = case.label
    expected = math.sqrt(lab["true_gap"] ** 2 - 1 + (lab["noise_rms_m"] / lab["noise_std_m"]) ** 2)
    assert _recomputed_gap(case) == pytest.approx(expected, rel=0.06)
    if form == "control":
        assert lab["true_gap"] == 1.0 and lab["effects"] == []
    else:
        assert lab["true_gap"] > 1.0 and lab["form"] == form and lab["effects"] == [form.split(":")[0]]


ALLOWED = {"rotor_estimator.core.config": None, "rotor_estimator.core.recording": {"RigRecording"},
           "rotor_estimator.bench.cases": {"BlindCase"},
           "rotor_estimator.bench.blind": {"store_case", "write_labels", "load_recording"},
           "rotor_estimator.bench.ross_cases": None, "rotor_estimator.bench": {"ross_cases"},
           "rotor_estimator.bench.independent_physics": None, "rotor_estimator.bench.independent_effects": None}
FORBIDDEN = ("rotor_estimator.core.model", "rotor_estimator.core.simulator", "rotor_estimator.core.forcing",
             "rotor_estimator.bench.effect_sim", "rotor_estimator.diagnosis")


def test_generator_imports_only_the_allowed_modules():
    """Every rotor_estimator import of the generator's three modules (at any depth of the file) is on the
    allow-list (config, recording, BlindCase, the blind-set file functions, ROSS cases, its own modules);
    none names the package's model, simulator, forcing, effect simulator or diagnosis."""
    seen = set()
    for mod in (independent, independent_effects, independent_physics):
        tree = ast.parse(Path(mod.__file__).read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                targets = [(a.name, None) for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                assert node.level == 0, "relative imports would hide the module name"
                targets = [(node.module or "", {a.name for a in node.names})]
            else:
                continue
            for name, names in targets:
                if not name.startswith("rotor_estimator"):
                    continue
                seen.add(name)
                assert not name.startswith(FORBIDDEN), f"{mod.__name__} imports {name}"
                assert name in ALLOWED, f"{mod.__name__} imports {name}, not on the allow-list"
                if ALLOWED[name] is not None:
                    assert names is not None and names <= ALLOWED[name], f"{mod.__name__}: {name} {names}"
    assert "rotor_estimator.core.config" in seen


def test_cases_and_labels_are_written_apart(tmp_path, monkeypatch):
    """A written set has cases/<id>/{recording.npz, rig.yaml} only, the labels in labels/labels.json with the
    scorer's keys, and no case's rig.yaml carries true coefficients."""
    monkeypatch.setattr(independent, "DURATION_S", 0.1)
    labels = independent.write_independent_set(tmp_path, 3, 11, use_ross=False)
    assert json.loads((tmp_path / "labels" / "labels.json").read_text()) == labels
    for cid, lab in labels.items():
        d = tmp_path / "cases" / cid
        assert sorted(p.name for p in d.iterdir()) == ["recording.npz", "rig.yaml"]
        assert "true_coefficients" not in (d / "rig.yaml").read_text()
        assert load_rig_file(d / "rig.yaml").rig.true_coefficients is None
        assert load_recording(d / "recording.npz").probes_m.shape == (2000, 4)
        for key in ("effects", "generator", "noise_std_m", "noise_rms_m", "speed_rpm", "true_coefficients", "form",
                    "true_gap", "effect_params"):
            assert key in lab
        assert lab["generator"] == "independent" and len(lab["true_coefficients"]) == 8


def test_bench_generate_writes_an_independent_set(tmp_path, monkeypatch, capsys):
    """`rotor-estimator bench generate --generator independent` writes the set and lists its forms."""
    from rotor_estimator.cli.main import main

    monkeypatch.setattr(independent, "DURATION_S", 0.1)
    assert main(["bench", "generate", "--generator", "independent", "--cases", "3", "--seed", "5", "--no-ross",
                 str(tmp_path)]) == 0
    labels = json.loads((tmp_path / "labels" / "labels.json").read_text())
    assert len(labels) == 3 and all(lab["generator"] == "independent" for lab in labels.values())
    assert "control:" in capsys.readouterr().out


def test_plan_mixes_controls_pairs_and_every_form():
    """A 40-case plan has ~15 % controls (half with an impact), ~10 % pairs, and singles over every planned
    own form and every ROSS form; the same seed gives the same plan."""
    p = independent.plan(40, 3)
    specs = [s for _, s, _ in p]
    controls = [s for s in specs if s["kind"] == "control"]
    assert len(p) == 40 and len(controls) == 6 and sum(s["impact"] for s in controls) == 3
    assert sum(s["kind"] == "pair" for s in specs) == 4
    singles = {s["form"] for s in specs if s["kind"] == "single"}
    assert singles == set(independent.PLANNED_FORMS) | set(independent.ROSS_FORMS)
    assert independent.plan(40, 3) == p and len({cid for cid, _, _ in p}) == 40


def test_tangent_coefficients_are_what_small_motion_about_the_static_equilibrium_follows():
    """A rotor on hardening bearings (radial cubic about the bearing centre) sags under gravity to the static
    equilibrium of :func:`static_equilibrium`; a small impact there moves it as the linear rotor on the
    tangent coefficients does (within 2 % of the response, the rest being the nonlinearity's higher orders),
    and not as the rotor on its linear coefficients ``K`` alone (over 20 % off: the check can fail)."""
    from rotor_estimator.bench.independent_physics import BearingNonlinearity, static_equilibrium, \
        tangent_coefficients

    rig = load_rig_file().rig
    r = rig.true_coefficients.as_array()
    pulse = (HammerPulse(0.002, 50e-6, 2.0, -1.5, "rect"),)
    geo = RotorGeometry.from_rig(rig)
    model = TrueModel(geo, tuple(r), rig.speed_rad_s, impacts=pulse,
                      nonlinearity=BearingNonlinearity(cubic_n_per_m3=2e14))
    tangent = tangent_coefficients(model)
    assert np.allclose(tangent[0], tangent[1])  # the rig's bearings carry equal static loads
    assert np.allclose(tangent[0, 4:], r[4:])   # damping is not changed by a stiffness law
    q0 = static_equilibrium(model)
    t = np.linspace(0.0, 0.03, 600)
    traj, mats = integrate(model, 0.0, 0.03, steady=False, initial=np.concatenate([q0, np.zeros(4)]))
    moved = traj.states(t)[:, :4] - q0
    assert np.max(np.abs(traj.states(t[:1])[:, :4] - q0)) < 1e-12  # at rest there before the impact
    for coefficients, close in ((tangent[0], True), (r, False)):
        linear = TrueModel(geo, tuple(coefficients), rig.speed_rad_s, impacts=pulse, gravity_m_s2=0.0)
        traj_l, _ = integrate(linear, 0.0, 0.03, steady=False)
        err = np.sqrt(np.mean((traj_l.states(t)[:, :4] - moved) ** 2)) / np.sqrt(np.mean(moved ** 2))
        assert (err < 0.02) if close else (err > 0.2)


def test_a_linear_true_model_has_its_own_coefficients_as_tangent():
    """Without a nonlinear bearing force the tangent at the static equilibrium is ``K`` at both bearings."""
    from rotor_estimator.bench.independent_physics import tangent_coefficients

    rig = load_rig_file().rig
    r = rig.true_coefficients.as_array()
    tangent = tangent_coefficients(_model(rig, r))
    assert np.array_equal(tangent, np.tile(r, (2, 1)))
