# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Effect forms of the independent benchmark, their measurement chain and the true gap.

Each :class:`Form` is one physical form of a library effect family, drawn in a shape other than
the library's (fixed-direction 2X forces, a common foundation mass, whole-sample delays, ...). Its
``apply(strength, shape, model, measurement)`` returns the changed true model and measurement; the
strength is a physical quantity (N, kg m, rad, samples, ...) capped at a realistic value.

The true gap of a record is ``sqrt(1 + (a / noise_std)^2)`` where ``a`` is the RMS (all four
channels, samples after :data:`WARMUP_S`, each channel's mean removed: DC is a nuisance) of the
noise-free record with the effect minus the noise-free record the same true model without the
effect makes from the recorded inputs (keyphasor pulses, force channel). It is computed against the
generating model only; nothing here calls the diagnosis.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Callable

import numpy as np

from rotor_estimator.bench.independent_physics import (BearingNonlinearity, Foundation,
                                                       HarmonicForce, Matrices, TrueModel, integrate)

#: Leading part of a record left out of the gap, s (the diagnosis's own warm-up window is as long).
WARMUP_S = 0.010
CHANNELS = ("xp1", "yp1", "xp2", "yp2")


@dataclass(frozen=True)
class Measurement:
    """How the probes, keyphasor and force channel read the true motion.

    ``delays_s`` per channel; ``gains`` and ``misorientation_rad`` per probe; ``runout`` entries
    ``(channel, harmonic, amplitude_m, phase_rad)`` fixed in the true shaft angle; the keyphasor
    fires at shaft angle ``tach_offset_rad + 2 pi n`` with Gaussian time jitter; the recorded
    force is ``force_scale`` times the applied one."""

    dc_offsets_m: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0)
    delays_s: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0)
    gains: tuple[float, ...] = (1.0, 1.0, 1.0, 1.0)
    misorientation_rad: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0)
    runout: tuple[tuple[int, int, float, float], ...] = ()
    tach_offset_rad: float = 0.0
    pulse_jitter_s: float = 0.0
    jitter_seed: int = 0
    force_scale: float = 1.0


@dataclass
class Record:
    """A noise-free record on the sample grid: probes (N, 4), keyphasor pulse times (s), recorded force (N, 2)."""

    t_s: np.ndarray
    probes_m: np.ndarray
    pulses_s: np.ndarray
    force_n: np.ndarray


def sample_times(duration_s: float, sample_rate_hz: float) -> np.ndarray:
    return np.arange(int(round(duration_s * sample_rate_hz))) / sample_rate_hz


def pulse_times(speed_rad_s: float, t_end_s: float, offset_rad: float, jitter_s: float, seed: int) -> np.ndarray:
    """Times where the true angle ``Omega t`` reaches ``offset + 2 pi n`` (one pulse beyond each end), jittered."""
    rev = 2 * math.pi
    n = np.arange(-2, math.ceil((speed_rad_s * t_end_s - offset_rad) / rev) + 2)
    t = (rev * n + offset_rad) / speed_rad_s
    t = t[(t > -rev / speed_rad_s) & (t < t_end_s + rev / speed_rad_s)]
    if jitter_s > 0:
        t = t + np.random.default_rng(seed).normal(size=t.size) * jitter_s
    return np.sort(t)


def angle_from_pulses(pulses_s: np.ndarray) -> Callable[[float], float]:
    """Shaft angle as a reader of the keyphasor infers it: 2 pi per pulse interval, linear between pulses."""
    angles = 2 * math.pi * np.arange(pulses_s.size)
    slope0 = 2 * math.pi / (pulses_s[1] - pulses_s[0])
    slope1 = 2 * math.pi / (pulses_s[-1] - pulses_s[-2])

    def angle(t: float) -> float:
        if t < pulses_s[0]:
            return float((t - pulses_s[0]) * slope0)
        if t > pulses_s[-1]:
            return float(angles[-1] + (t - pulses_s[-1]) * slope1)
        return float(np.interp(t, pulses_s, angles))

    return angle


def measure(traj, mats: Matrices, model: TrueModel, meas: Measurement, t: np.ndarray) -> np.ndarray:
    """Probe readings (N, 4) at sample times ``t`` (each channel sampled ``delays_s`` late)."""
    out = np.zeros((t.size, 4))
    for tau in sorted(set(meas.delays_s)):
        ts = t - tau
        p = traj.states(ts)[:, :mats.n] @ mats.probe_map.T
        theta = model.speed_rad_s * ts
        for c in (c for c in range(4) if meas.delays_s[c] == tau):
            x, y, b = p[:, c - c % 2], p[:, c - c % 2 + 1], meas.misorientation_rad[c]
            v = (x * math.cos(b) + y * math.sin(b)) if c % 2 == 0 else (-x * math.sin(b) + y * math.cos(b))
            v = v * meas.gains[c]
            for ch, h, amp, ph in meas.runout:
                if ch == c:
                    v = v + amp * np.cos(h * theta + ph)
            out[:, c] = v + meas.dc_offsets_m[c]
    return out


def simulate_record(model: TrueModel, meas: Measurement, duration_s: float, *, steady: bool,
                    lead_s: float = 0.0, traj_cache: dict | None = None) -> Record:
    """Noise-free record of ``model`` seen through ``meas`` (a steady record integrates ``lead_s`` before t = 0)."""
    fs = model.geometry.sample_rate_hz
    t = sample_times(duration_s, fs)
    key = id(model)
    if traj_cache is not None and key in traj_cache:
        traj, mats = traj_cache[key][1:]
    else:
        t0 = -lead_s if steady else 0.0
        traj, mats = integrate(model, t0, duration_s + 1.0 / fs, steady=steady)
        if traj_cache is not None:
            traj_cache[key] = (model, traj, mats)  # the model is kept so its id stays unique
    probes = measure(traj, mats, model, meas, t)
    pulses = pulse_times(model.speed_rad_s, duration_s, meas.tach_offset_rad, meas.pulse_jitter_s, meas.jitter_seed)
    force = np.zeros((t.size, 2))
    for p in model.impacts:
        force += p.sample_means(t, 1.0 / fs)
    return Record(t, probes, pulses, force * meas.force_scale)


def reference_model(base: TrueModel, meas: Measurement, rec: Record) -> TrueModel:
    """The effect-free true model driven by the inputs as recorded: the shaft angle the pulses give and the
    recorded force (when the keyphasor or the force channel is the effect)."""
    model = base
    if meas.tach_offset_rad or meas.pulse_jitter_s:
        model = replace(model, angle_of_time=angle_from_pulses(rec.pulses_s))
    if meas.force_scale != 1.0:
        model = replace(model, impacts=tuple(replace(p, force_x_n=p.force_x_n * meas.force_scale,
                                                     force_y_n=p.force_y_n * meas.force_scale)
                                             for p in base.impacts))
    return model


def gap_of(a_m: np.ndarray, b_m: np.ndarray, t_s: np.ndarray, noise_std_m: float) -> float:
    """``sqrt(1 + (rms / noise)^2)`` of ``a - b`` after :data:`WARMUP_S`, each channel's mean removed."""
    d = (a_m - b_m)[t_s >= WARMUP_S]
    d = d - d.mean(axis=0)
    return math.sqrt(1.0 + float(np.mean(d ** 2)) / noise_std_m ** 2)


# --------------------------------------------------------------------------- forms
@dataclass(frozen=True)
class Form:
    """One physical form of an effect family: ``draw(rng, ctx)`` fixes the shape, ``apply`` sets the strength.

    ``ctx`` carries the case's base model, noise and effect-free orbit (``orbit_radius_m``, ``rms_m``).
    ``discrete``: candidate strengths (the gap picks among them) instead of a continuous calibration."""

    family: str
    form: str
    unit: str
    start: Callable[[dict, dict], float]
    cap: Callable[[dict, dict], float]
    draw: Callable[[np.random.Generator, dict], dict]
    apply: Callable[[float, dict, TrueModel, Measurement], tuple[TrueModel, Measurement, dict]]
    measurement_only: bool = False
    discrete: tuple[float, ...] = ()
    needs_impact: bool = False


def _add_forces(model: TrueModel, forces) -> TrueModel:
    return replace(model, forces=model.forces + tuple(forces))


def _mis_draw(fixed: bool):
    def draw(rng, ctx):
        sh = {"ratio2": float(rng.uniform(0.3, 1.2)), "phase": rng.uniform(0, 2 * np.pi, 2).tolist(),
              "direction": rng.uniform(0, np.pi, 2).tolist(), "preload_n": (rng.normal(size=(2, 2)) * 30).tolist()}
        if not fixed:
            sh["backward_ratio"] = rng.uniform(0.2, 1.5, 2).tolist()
            sh["backward_phase"] = rng.uniform(0, 2 * np.pi, 2).tolist()
        return sh
    return draw


def _mis_apply(fixed: bool):
    def apply(s, sh, model, meas):
        stations = model.geometry.bearing_positions_m
        forces, params = [], {"preload_n": sh["preload_n"], "bearing_force_2x_n": []}
        for b in range(2):
            amp = s * (1.0 if b == 0 else sh["ratio2"]) * np.exp(1j * sh["phase"][b])
            if fixed:   # a line force along a fixed direction: f = d A cos(2 theta + phase)
                fx, fy = amp * math.cos(sh["direction"][b]), amp * math.sin(sh["direction"][b])
            else:       # fx + i fy = F+ e^{2i theta} + F- e^{-2i theta}
                fb = abs(amp) * sh["backward_ratio"][b] * np.exp(1j * sh["backward_phase"][b])
                fx, fy = amp + np.conj(fb), -1j * amp + 1j * np.conj(fb)
            forces.append(HarmonicForce(stations[b], 2, complex(fx), complex(fy)))
            forces.append(HarmonicForce(stations[b], 0, complex(sh["preload_n"][b][0]), complex(sh["preload_n"][b][1])))
            params["bearing_force_2x_n"].append([[fx.real, fx.imag], [fy.real, fy.imag]])
        return _add_forces(model, forces), meas, params
    return apply


def _coupling_draw(rng, ctx):
    z1, z2 = sorted(ctx["model"].geometry.bearing_positions_m)
    overhang = float(rng.uniform(0.02, 0.08))
    return {"station_m": z1 - overhang if rng.random() < 0.5 else z2 + overhang,
            "direction": float(rng.uniform(0, np.pi)), "ratio1": float(rng.uniform(0.2, 1.0)),
            "phase": rng.uniform(0, 2 * np.pi, 2).tolist(), "preload_n": (rng.normal(size=2) * 30).tolist()}


def _coupling_apply(s, sh, model, meas):
    """A parallel offset through a flexible coupling on the shaft's overhang, outside the bearings: its reaction
    along the offset's fixed direction at 1X and 2X (amplitudes ``ratio1 s`` and ``s``, N; each of both whirls)
    and a static preload. The label also states the force pair at the bearings that a rigid rotor cannot tell
    from it (the lever rule: the same force and moment)."""
    station, (z1, z2) = sh["station_m"], model.geometry.bearing_positions_m
    cos_d, sin_d = math.cos(sh["direction"]), math.sin(sh["direction"])
    forces = [HarmonicForce(station, 0, complex(sh["preload_n"][0]), complex(sh["preload_n"][1]))]
    params: dict = {"station_m": station, "direction_rad": sh["direction"], "preload_n": sh["preload_n"]}
    for h, amp in ((1, s * sh["ratio1"] * np.exp(1j * sh["phase"][0])), (2, s * np.exp(1j * sh["phase"][1]))):
        fx, fy = complex(amp * cos_d), complex(amp * sin_d)
        forces.append(HarmonicForce(station, h, fx, fy))
        params[f"bearing_force_{h}x_n"] = [[[w * fx.real, w * fx.imag], [w * fy.real, w * fy.imag]]
                                           for w in ((z2 - station) / (z2 - z1), (station - z1) / (z2 - z1))]
    return _add_forces(model, forces), meas, params


def _foundation_apply(relative: bool):
    def apply(s, sh, model, meas):
        f_hz = 2000.0 / math.sqrt(s)
        k = sh["mass_kg"] * (2 * math.pi * f_hz) ** 2
        c = 2 * sh["damping_ratio"] * math.sqrt(k * sh["mass_kg"])
        fnd = Foundation(sh["mass_kg"], k, c, relative)
        return replace(model, foundation=fnd), meas, {"mass_kg": sh["mass_kg"], "stiffness_n_per_m": k,
                                                      "damping_n_s_per_m": c, "frequency_hz": f_hz,
                                                      "probes_relative": relative}
    return apply


def _skew_apply(channels_of: Callable[[dict], list[int]]):
    def apply(s, sh, model, meas):
        dt = 1.0 / model.geometry.sample_rate_hz
        delays = [s * dt if c in channels_of(sh) else 0.0 for c in range(4)]
        return model, replace(meas, delays_s=tuple(delays)), {"delay_samples": s, "channels":
                                                              [CHANNELS[c] for c in channels_of(sh)]}
    return apply


def _tach_apply(s, sh, model, meas):
    off = sh["sign"] * s
    return model, replace(meas, tach_offset_rad=off, pulse_jitter_s=sh["jitter_s"], jitter_seed=sh["seed"]), {
        "offset_rad": off, "jitter_s": sh["jitter_s"]}


def _gain_apply(s, sh, model, meas):
    g = list(meas.gains)
    g[sh["channel"]] = 1.0 + sh["sign"] * s
    return model, replace(meas, gains=tuple(g)), {"channel": CHANNELS[sh["channel"]], "gain": g[sh["channel"]]}


def _orient_apply(s, sh, model, meas):
    b = list(meas.misorientation_rad)
    b[sh["channel"]] = sh["sign"] * s
    return model, replace(meas, misorientation_rad=tuple(b)), {"channel": CHANNELS[sh["channel"]],
                                                               "angle_rad": b[sh["channel"]]}


def _runout_draw(rng, ctx):
    chans = sorted(rng.choice(4, size=int(rng.integers(1, 4)), replace=False).tolist())
    return {"terms": [(c, h, float(rng.uniform(0.3, 1.0) * (1.0 if h == 1 else rng.uniform(0.2, 1.0))),
                       float(rng.uniform(0, 2 * np.pi))) for c in chans for h in (1, 2, 3)]}


def _runout_apply(s, sh, model, meas):
    terms = tuple((c, h, s * a, ph) for c, h, a, ph in sh["terms"])
    return model, replace(meas, runout=meas.runout + terms), {"terms_channel_harmonic_m_rad": [list(x) for x in terms]}


def _unbalance_apply(s, sh, model, meas):
    f = s * model.speed_rad_s ** 2 * np.exp(1j * sh["phase"])
    return (_add_forces(model, [HarmonicForce(sh["plane_m"], 1, complex(f), complex(-1j * f))]), meas,
            {"plane_m": sh["plane_m"], "moment_kg_m": s, "phase_rad": sh["phase"]})


def _cubic_apply(s, sh, model, meas):
    return replace(model, nonlinearity=BearingNonlinearity(cubic_n_per_m3=sh["sign"] * s)), meas, {
        "cubic_n_per_m3": sh["sign"] * s}


def _contact_apply(s, sh, model, meas):
    nl = BearingNonlinearity(clearance_m=sh["clearance_m"], contact_stiffness_n_per_m=s)
    return replace(model, nonlinearity=nl), meas, {"clearance_m": sh["clearance_m"], "contact_stiffness_n_per_m": s}


def _hammer_apply(s, sh, model, meas):
    return model, replace(meas, force_scale=1.0 + sh["sign"] * s), {"recorded_over_applied": 1.0 + sh["sign"] * s}


def _k_mean(ctx) -> float:
    r = ctx["model"].coefficients
    return 0.5 * (abs(r[0]) + abs(r[3]))


_sign = lambda rng: float(rng.choice([-1.0, 1.0]))  # noqa: E731
_plane_channels = lambda sh: [2 * sh["plane"], 2 * sh["plane"] + 1]  # noqa: E731

FORMS: tuple[Form, ...] = (
    Form("misalignment", "fixed_direction_2x+preload", "N", lambda c, s: 10.0, lambda c, s: 250.0,
         _mis_draw(True), _mis_apply(True)),
    Form("misalignment", "forward_backward_2x+preload", "N", lambda c, s: 10.0, lambda c, s: 250.0,
         _mis_draw(False), _mis_apply(False)),
    Form("misalignment", "coupling_offset_1x_2x+preload", "N", lambda c, s: 10.0, lambda c, s: 250.0,
         _coupling_draw, _coupling_apply),
    Form("pedestal", "common_foundation:relative_probes", "(2000 Hz / f)^2", lambda c, s: 25.0,
         lambda c, s: (2000.0 / 40.0) ** 2,
         lambda rng, c: {"mass_kg": float(rng.uniform(2.0, 15.0)), "damping_ratio": float(rng.uniform(0.02, 0.15))},
         _foundation_apply(True)),
    Form("pedestal", "common_foundation:absolute_probes", "(2000 Hz / f)^2", lambda c, s: 25.0,
         lambda c, s: (2000.0 / 40.0) ** 2,
         lambda rng, c: {"mass_kg": float(rng.uniform(2.0, 15.0)), "damping_ratio": float(rng.uniform(0.02, 0.15))},
         _foundation_apply(False)),
    Form("timing_skew", "whole_sample_delay:one_channel", "samples", lambda c, s: 1.0, lambda c, s: 5.0,
         lambda rng, c: {"channel": int(rng.integers(0, 4))}, _skew_apply(lambda sh: [sh["channel"]]),
         measurement_only=True, discrete=(1.0, 2.0, 3.0, 4.0, 5.0)),
    Form("timing_skew", "whole_sample_delay:one_plane", "samples", lambda c, s: 1.0, lambda c, s: 5.0,
         lambda rng, c: {"plane": int(rng.integers(0, 2))}, _skew_apply(_plane_channels),
         measurement_only=True, discrete=(1.0, 2.0, 3.0, 4.0, 5.0)),
    Form("timing_skew", "fractional_delay:one_channel", "samples", lambda c, s: 0.3, lambda c, s: 5.0,
         lambda rng, c: {"channel": int(rng.integers(0, 4))}, _skew_apply(lambda sh: [sh["channel"]]),
         measurement_only=True),
    Form("tach_offset", "keyphasor_offset+jitter", "rad", lambda c, s: 0.05, lambda c, s: math.pi,
         lambda rng, c: {"sign": _sign(rng), "jitter_s": float(rng.uniform(0.3e-6, 2e-6)),
                         "seed": int(rng.integers(1 << 30))}, _tach_apply),
    Form("probe_gain_orientation", "single_channel_gain", "relative", lambda c, s: 0.02,
         lambda c, s: 0.25 if s["sign"] > 0 else 0.2,
         lambda rng, c: {"channel": int(rng.integers(0, 4)), "sign": _sign(rng)}, _gain_apply, measurement_only=True),
    Form("probe_gain_orientation", "single_probe_misorientation", "rad", lambda c, s: 0.02, lambda c, s: 0.35,
         lambda rng, c: {"channel": int(rng.integers(0, 4)), "sign": _sign(rng)}, _orient_apply,
         measurement_only=True),
    Form("probe_runout", "harmonics_1x_3x:some_probes", "m", lambda c, s: 1e-6, lambda c, s: 20e-6,
         _runout_draw, _runout_apply, measurement_only=True),
    Form("residual_unbalance", "arbitrary_plane", "kg m", lambda c, s: 2e-6, lambda c, s: 5e-5,
         lambda rng, c: {"plane_m": float(rng.uniform(c["model"].geometry.bearing_positions_m[0] - 0.06,
                                                      c["model"].geometry.bearing_positions_m[1] + 0.06)),
                         "phase": float(rng.uniform(0, 2 * np.pi))}, _unbalance_apply),
    Form("bearing_cubic", "radial_cubic", "N/m^3",
         lambda c, s: 0.02 * _k_mean(c) / max(c["orbit_radius_m"], 1e-7) ** 2,
         lambda c, s: (1.0 if s["sign"] > 0 else 0.25) * _k_mean(c) / max(c["orbit_radius_m"], 1e-7) ** 2,
         lambda rng, c: {"sign": 1.0 if rng.random() < 0.75 else -1.0}, _cubic_apply),
    Form("bearing_cubic", "clearance_contact", "N/m", lambda c, s: 0.05 * _k_mean(c), lambda c, s: 30 * _k_mean(c),
         lambda rng, c: {"clearance_m": float(rng.uniform(0.55, 0.9) * c["orbit_radius_m"])}, _contact_apply),
    Form("hammer_force_scale", "recorded_force_scaled", "relative", lambda c, s: 0.05, lambda c, s: 0.5,
         lambda rng, c: {"sign": _sign(rng)}, _hammer_apply, needs_impact=True),
)


def compose(model: TrueModel, meas: Measurement, parts) -> tuple[TrueModel, Measurement, list[dict]]:
    """Apply ``(form, strength, shape)`` parts in turn; returns the model, measurement and each part's parameters."""
    params = []
    for form, s, sh in parts:
        model, meas, p = form.apply(s, sh, model, meas)
        params.append(p)
    return model, meas, params


def true_gap(base: TrueModel, meas0: Measurement, parts, duration_s: float, noise_std_m: float, *, steady: bool,
             lead_s: float, cache: dict) -> tuple[float, Record]:
    """The gap of ``parts`` against ``base`` (see the module docstring) and the noise-free record with them."""
    model, meas, _ = compose(base, meas0, parts)
    rec = simulate_record(model, meas, duration_s, steady=steady, lead_s=lead_s,
                          traj_cache=cache if model is base else None)
    ref_model = reference_model(base, meas, rec)
    ref = simulate_record(ref_model, meas0, duration_s, steady=steady, lead_s=lead_s,
                          traj_cache=cache if ref_model is base else None)
    return gap_of(rec.probes_m, ref.probes_m, rec.t_s, noise_std_m), rec


def calibrate(gap_at: Callable[[float], float], form: Form, ctx: dict, shape: dict, target: float,
              iterations: int = 7) -> tuple[float, float]:
    """Strength whose true gap is nearest ``target`` (secant in log-log, within the form's cap), and its gap."""
    cap = form.cap(ctx, shape)
    if form.discrete:
        tried = [(s, gap_at(s)) for s in form.discrete if s <= cap]
        inside = [x for x in tried if 1.2 <= x[1] <= 16.0] or tried
        return min(inside, key=lambda x: abs(math.log(x[1] / target)))
    want = math.sqrt(target ** 2 - 1)
    s, slope, prev, best = min(form.start(ctx, shape), cap), 1.0, None, None
    for _ in range(iterations):
        g = gap_at(s)
        if best is None or abs(math.log(g / target)) < abs(math.log(best[1] / target)):
            best = (s, g)
        if abs(math.log(g / target)) < 0.03:
            break
        a = math.sqrt(max(g * g - 1, 0.0))
        if a <= 1e-9:
            s_new = s * 10
        else:
            if prev is not None and prev[1] > 1e-9 and abs(math.log(s / prev[0])) > 1e-9:
                slope = float(np.clip(math.log(a / prev[1]) / math.log(s / prev[0]), 0.3, 4.0))
            prev = (s, a)
            s_new = s * (want / a) ** (1 / slope)
        s_new = min(s_new, cap)
        if s_new == s:
            break
        s = s_new
    assert best is not None
    return best
