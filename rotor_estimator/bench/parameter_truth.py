# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""True values of the diagnosis's reported effect parameters, from a benchmark label (for their coverage).

A label states each hidden effect in its generator's own physical form; the diagnosis reports the
parameters of the library's form (:meth:`.Effect.physical`). Only a parameter with a one-to-one
counterpart is scored, each mapping derived from the two generators' definitions (never from a fit):

* keyphasor offset: both put the pulse where the true angle is ``offset + 2 pi n`` -> ``offset_deg``;
* timing skew: both sample channel c at ``t - tau_c`` -> ``skew_<ch>_s`` (0 on undelayed channels);
* probe gain and misorientation: both read ``g (x cos b + y sin b)`` (x probe), ``g (-x sin b + y cos b)`` (y probe)
  -> ``gain_error_<ch> = g - 1``, ``angle_error_<ch>_deg = b``;
* residual unbalance: one rotating mass ``m r e^{i phase}`` at station z on a rigid rotor is the same force and
  moment as ``m r (z2 - z) / (z2 - z1)`` and ``m r (z - z1) / (z2 - z1)`` in the correction planes z1, z2 ->
  ``plane<i>_unbalance_g_mm`` and ``plane<i>_phase_deg``;
* radial cubic bearing ``f = -k3 |d|^2 d`` -> ``k3_N_per_m3`` of the radial form; per-axis cubics -> ``k3x/k3y``;
* foundation or pedestal: its uncoupled frequency ``sqrt(k / m) / 2 pi`` and damping ratio ``c / 2 sqrt(k m)``;
* a 2X force ``Re(F e^{2 i theta})`` per bearing axis -> ``force_2x_<bearing>_<axis>_amplitude_n = |F|``; a 1X
  force ``fx = Re(X e^{i theta})``, ``fy = Re(Y e^{i theta})`` -> its backward part
  ``force_1x_<bearing>_backward_n = |conj(X) + i conj(Y)| / 2`` (its forward part is an unbalance's);
* runout harmonics ``a_h cos(h theta + phase)`` on a channel -> ``<ch>_runout_peak_m = sqrt(2 sum a_h^2)``
  (the library's definition), on the channels that carry runout (an amplitude of zero has no two-sided interval);

Anything else (ROSS couplings and shafts, the bending mode (the library's coupled form is a pinned-pinned shaft
frequency, not the generator's modal one), clearance contact, keyphasor jitter, preloads) has no counterpart and
is counted as such, not scored.
"""
from __future__ import annotations

import math

import numpy as np

from rotor_estimator.diagnosis.effects.base import CHANNELS  # the library's parameter names are the targets
from rotor_estimator.diagnosis.effects.misalignment import BEARINGS


def lever_rule(moment_kg_m: complex, station_m: float, planes_m: tuple[float, float]) -> tuple[complex, complex]:
    """A rotating mass at ``station_m`` as two in the correction planes: the same force and moment (rigid rotor)."""
    z1, z2 = planes_m
    return moment_kg_m * (z2 - station_m) / (z2 - z1), moment_kg_m * (station_m - z1) / (z2 - z1)


def _unbalance(planes_kg_m: tuple[complex, complex]) -> dict[str, float]:
    out = {}
    for i, u in enumerate(planes_kg_m, start=1):
        out[f"plane{i}_unbalance_g_mm"] = abs(u) * 1e6
        out[f"plane{i}_phase_deg"] = math.degrees(math.atan2(u.imag, u.real))
    return out


def _oscillator(mass_kg: float, stiffness_n_per_m: float, damping_n_s_per_m: float) -> tuple[float, float]:
    """Uncoupled frequency (Hz) and damping ratio of a mass on a spring and damper."""
    return (math.sqrt(stiffness_n_per_m / mass_kg) / (2 * math.pi),
            damping_n_s_per_m / (2 * math.sqrt(stiffness_n_per_m * mass_kg)))


def _runout_peaks(amplitudes_by_channel: dict[int, list[float]]) -> dict[str, float]:
    return {f"{CHANNELS[c]}_runout_peak_m": math.sqrt(2 * sum(a * a for a in amps))
            for c, amps in amplitudes_by_channel.items() if any(amps)}


def independent_truth(effect: str, params: dict, planes_m: tuple[float, float],
                      sample_rate_hz: float) -> dict[str, float]:
    """Library-named true values of one effect of the independent generator (``{}``: no counterpart)."""
    if effect == "tach_offset":
        return {"offset_deg": math.degrees(params["offset_rad"])}
    if effect == "timing_skew":
        delay = params["delay_samples"] / sample_rate_hz
        return {f"skew_{ch}_s": delay if ch in params["channels"] else 0.0 for ch in CHANNELS}
    if effect == "probe_gain_orientation":
        gain = {ch: 0.0 for ch in CHANNELS}
        angle = {ch: 0.0 for ch in CHANNELS}
        if "gain" in params:
            gain[params["channel"]] = params["gain"] - 1.0
        if "angle_rad" in params:
            angle[params["channel"]] = math.degrees(params["angle_rad"])
        return {**{f"gain_error_{ch}": v for ch, v in gain.items()},
                **{f"angle_error_{ch}_deg": v for ch, v in angle.items()}}
    if effect == "residual_unbalance":
        u = params["moment_kg_m"] * complex(math.cos(params["phase_rad"]), math.sin(params["phase_rad"]))
        return _unbalance(lever_rule(u, params["plane_m"], planes_m))
    if effect == "bearing_cubic" and "cubic_n_per_m3" in params:
        return {"k3_N_per_m3": params["cubic_n_per_m3"]}
    if effect == "bearing_cubic" and "contact_stiffness_n_per_m" in params:
        return {"contact_stiffness_N_per_m": params["contact_stiffness_n_per_m"], "clearance_m": params["clearance_m"]}
    if effect == "pedestal" and "mass_kg" in params:
        f_hz, zeta = _oscillator(params["mass_kg"], params["stiffness_n_per_m"], params["damping_n_s_per_m"])
        return {"pedestal_frequency_hz": f_hz, "pedestal_damping_ratio": zeta}
    if effect == "misalignment" and "bearing_force_2x_n" in params:
        out = {}
        for b, ((xr, xi), (yr, yi)) in zip(BEARINGS, params["bearing_force_2x_n"]):
            out[f"force_2x_{b}_x_amplitude_n"] = math.hypot(xr, xi)
            out[f"force_2x_{b}_y_amplitude_n"] = math.hypot(yr, yi)
        for b, ((xr, xi), (yr, yi)) in zip(BEARINGS, params.get("bearing_force_1x_n", [])):
            out[f"force_1x_{b}_backward_n"] = abs(complex(xr, -xi) + 1j * complex(yr, -yi)) / 2
        return out
    if effect == "probe_runout" and "terms_channel_harmonic_m_rad" in params:
        amps: dict[int, list[float]] = {}
        for c, _h, a, _ph in params["terms_channel_harmonic_m_rad"]:
            amps.setdefault(int(c), []).append(float(a))
        return _runout_peaks(amps)
    return {}


def own_truth(effect: str, params: dict) -> dict[str, float]:
    """Library-named true values of one effect of the package's own generator (:class:`.HiddenEffects`)."""
    if effect == "tach_offset":
        return {"offset_deg": math.degrees(params["tach_offset_rad"])}
    if effect == "timing_skew":
        return {f"skew_{ch}_s": v for ch, v in zip(CHANNELS, [0.0, *params["skew_s"]])}
    if effect == "probe_gain_orientation":
        o = params["orientation_rad"]
        angles = [o[0], o[0], o[1], o[1]] if len(o) == 2 else list(o)
        return {**{f"gain_error_{ch}": float(g) for ch, g in zip(CHANNELS, params["gain"])},
                **{f"angle_error_{ch}_deg": math.degrees(a) for ch, a in zip(CHANNELS, angles)}}
    if effect == "residual_unbalance":
        u = params["residual_unbalance_kg_m"]
        return _unbalance((complex(u[0], u[1]), complex(u[2], u[3])))
    if effect == "bearing_cubic":
        k3x, k3y = params["cubic_n_per_m3"]
        return {"k3x_N_per_m3": k3x, "k3y_N_per_m3": k3y}
    if effect == "pedestal" and params.get("pedestal"):
        f_hz, zeta = _oscillator(*params["pedestal"])
        return {"pedestal_frequency_hz": f_hz, "pedestal_damping_ratio": zeta}
    if effect == "misalignment":  # the own generator's 2X force acts at bearing 1 only
        fx_c, fx_s, fy_c, fy_s = params["misalignment_n"]
        return {"force_2x_b1_x_amplitude_n": math.hypot(fx_c, fx_s),
                "force_2x_b1_y_amplitude_n": math.hypot(fy_c, fy_s)}
    if effect == "probe_runout" and len(params.get("runout_m", [])):
        r = np.asarray(params["runout_m"], dtype=float)  # (4, H, 2) cos/sin per channel and harmonic
        return _runout_peaks({c: list(np.hypot(r[c, :, 0], r[c, :, 1])) for c in range(r.shape[0])})
    return {}


def is_angle(name: str) -> bool:
    """Parameters compared modulo 360 degrees."""
    return name.endswith("_deg")


def covered(name: str, estimate: float, std: float, truth: float, z: float = 1.96) -> bool:
    """Whether ``truth`` lies within ``+-z std`` of ``estimate`` (angles on the circle)."""
    d = estimate - truth
    if is_angle(name):
        d = (d + 180.0) % 360.0 - 180.0
    return bool(abs(d) <= z * std)
