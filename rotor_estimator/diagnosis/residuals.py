# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Where the gap lies: a budget of the residual power by channel, band, whirl direction and time.

Bands: the synchronous orders 1X..8X are estimated by order tracking (least squares on
``cos(h theta), sin(h theta)`` of the measured shaft angle, so they follow speed changes);
what remains is split into fixed-frequency non-synchronous peaks of the periodogram and
the broadband rest. Each band's "excess" is its power minus what white noise of the
estimated level puts there (``sigma^2`` times the band's share of spectral lines).

Whirl direction (full spectrum): per probe plane the complex signal ``x + j y``; for
order ``h`` with phasors ``X, Y`` the forward part is ``|X + jY|/2`` and the backward
part ``|X - jY|/2`` (the convention of :func:`rotor_estimator.core.model.whirl_modes`).
"""
from __future__ import annotations

import numpy as np

CHANNELS = ("xp1", "yp1", "xp2", "yp2")
N_ORDERS = 8


#: Orders are tracked up to this share of the sampling rate (a decimated record's flat band,
#: :data:`.decimation.FLAT_FRACTION`): an order above it is filtered out of the record, and its columns would
#: alias onto a lower frequency and take a non-synchronous line there.
ORDER_BAND_FRACTION = 0.45


def _tracked_orders(fs: float, speed_rad_s: np.ndarray) -> int:
    """How many orders 1X.. stay below :data:`ORDER_BAND_FRACTION` of ``fs`` at the fastest speed (<= N_ORDERS)."""
    fastest_hz = float(np.max(speed_rad_s)) / (2 * np.pi) if speed_rad_s.size else 0.0
    if fastest_hz <= 0:
        return N_ORDERS
    return int(np.clip(np.floor(ORDER_BAND_FRACTION * fs / fastest_hz), 0, N_ORDERS))


def _orders(e: np.ndarray, angle: np.ndarray, n_orders: int = N_ORDERS) -> tuple[np.ndarray, np.ndarray]:
    """Phasors (N_ORDERS, 4) complex ``X_h`` with ``e ~ Re(sum X_h exp(j h theta))`` and the order fit (N, 4);
    the orders above ``n_orders`` are not fitted (their phasors zero)."""
    cols = [np.ones_like(angle)]
    for h in range(1, n_orders + 1):
        cols += [np.cos(h * angle), np.sin(h * angle)]
    basis = np.column_stack(cols)
    coef, *_ = np.linalg.lstsq(basis, e, rcond=None)
    ph = np.zeros((N_ORDERS, e.shape[1]), complex)
    for h in range(1, n_orders + 1):
        ph[h - 1] = coef[2 * h - 1] - 1j * coef[2 * h]
    return ph, basis @ coef


def _peaks(rest: np.ndarray, fs: float, speed_hz: float, n_peaks: int = 3) -> list[dict]:
    """Largest fixed-frequency lines of the order-removed residual (summed over channels)."""
    n = rest.shape[0]
    spec = (np.abs(np.fft.rfft(rest * np.hanning(n)[:, None], axis=0)) ** 2).sum(axis=1)
    f = np.fft.rfftfreq(n, 1 / fs)
    floor = np.median(spec[1:]) + 1e-300
    out, used = [], np.zeros(spec.size, bool)
    order = np.argsort(spec)[::-1]
    for k in order:
        if len(out) >= n_peaks or spec[k] < 30 * floor:
            break
        if k == 0 or used[k]:
            continue
        near_order = speed_hz > 0 and abs(f[k] / speed_hz - round(f[k] / speed_hz)) * speed_hz < 3 * fs / n
        lo, hi = max(k - 4, 1), min(k + 5, spec.size)
        used[lo:hi] = True
        if near_order:
            continue
        out.append({"frequency_hz": float(f[k]), "lines": (lo, hi)})
    return out


def nonsync_peak_frequencies_hz(t_s: np.ndarray, residual_m: np.ndarray, angle_rad: np.ndarray,
                                speed_rad_s: np.ndarray, n_peaks: int = 2) -> list[float]:
    """Frequencies (Hz) of the largest fixed-frequency lines of a residual (rows already selected) once its
    orders 1X..8X are removed: the ``nonsync_peaks`` of :func:`budget`, strongest first. An unmodelled mode
    rung by an impact or by the start from rest shows here (at the frequency of the whole system's mode)."""
    e = residual_m - residual_m.mean(axis=0)
    fs = 1.0 / float(np.median(np.diff(t_s)))
    _, fit = _orders(e, angle_rad, _tracked_orders(fs, speed_rad_s))
    speed_hz = float(np.mean(speed_rad_s)) / (2 * np.pi)
    return [p["frequency_hz"] for p in _peaks(e - fit, fs, speed_hz, n_peaks)]


def budget(t_s: np.ndarray, residual_m: np.ndarray, angle_rad: np.ndarray, speed_rad_s: np.ndarray,
           impact_force_n: np.ndarray, noise_std_m: np.ndarray) -> dict:
    """Residual budget of masked samples (rows already selected). Powers in m^2, shares of the total excess."""
    e = residual_m - residual_m.mean(axis=0)
    n = e.shape[0]
    fs = 1.0 / float(np.median(np.diff(t_s)))
    sigma2 = np.asarray(noise_std_m, dtype=float) ** 2
    total = np.mean(e ** 2, axis=0)                      # (4,)
    excess_ch = np.maximum(total - sigma2, 0.0)
    ph, fit = _orders(e, angle_rad, _tracked_orders(fs, speed_rad_s))
    rest = e - fit
    speed_hz = float(np.mean(speed_rad_s)) / (2 * np.pi)
    bands: dict[str, np.ndarray] = {}
    for h in range(N_ORDERS):
        bands[f"{h + 1}X"] = np.abs(ph[h]) ** 2 / 2
    peaks = _peaks(rest, fs, speed_hz)
    spec = np.abs(np.fft.rfft(rest, axis=0)) ** 2 / n ** 2 * 2  # one-sided power per line (m^2)
    noise_lines = spec.shape[0]
    peak_power = np.zeros(4)
    peak_info = []
    for p in peaks:
        lo, hi = p["lines"]
        pw = spec[lo:hi].sum(axis=0) - sigma2 * (hi - lo) / noise_lines
        peak_power += np.maximum(pw, 0)
        peak_info.append({"frequency_hz": round(p["frequency_hz"], 2), "power_m2": float(np.maximum(pw, 0).sum())})
    bands["nonsync_peaks"] = peak_power
    broadband = np.maximum(np.mean(rest ** 2, axis=0) - peak_power - sigma2, 0.0)
    bands["broadband"] = broadband
    band_total = sum(float(v.sum()) for v in bands.values()) + 1e-300
    band_rows = sorted(({"band": k, "share": float(v.sum() / band_total), "rms_m": float(np.sqrt(v.sum() / 4)),
                         "per_channel_rms_m": [float(np.sqrt(x)) for x in v]} for k, v in bands.items()),
                       key=lambda r: -r["share"])
    ch_total = float(excess_ch.sum()) + 1e-300
    ch_rows = sorted(({"channel": c, "rms_m": float(np.sqrt(total[i])), "excess_rms_m": float(np.sqrt(excess_ch[i])),
                       "share": float(excess_ch[i] / ch_total)} for i, c in enumerate(CHANNELS)),
                     key=lambda r: -r["share"])
    planes = {}
    for p, name in ((0, "plane1"), (1, "plane2")):
        x, y = ph[:, 2 * p], ph[:, 2 * p + 1]
        fwd, bwd = np.abs(x + 1j * y) / 2, np.abs(x - 1j * y) / 2
        z = rest[:, 2 * p] + 1j * rest[:, 2 * p + 1]
        zs = np.abs(np.fft.fft(z)) ** 2
        fz = np.fft.fftfreq(n, 1 / fs)
        planes[name] = {"orders": {f"{h + 1}X": {"forward_m": float(fwd[h]), "backward_m": float(bwd[h])}
                                   for h in range(3)},
                        "nonsync_forward_share": float(zs[fz > 0].sum() / max(zs[fz != 0].sum(), 1e-300))}
    time_rows = _time_budget(t_s, e, impact_force_n, speed_rad_s, sigma2)
    return {"total_rms_m": float(np.sqrt(total.mean())), "noise_std_m": [float(s) for s in np.sqrt(sigma2)],
            "gap_ratio": float(np.sqrt(total.mean() / max(sigma2.mean(), 1e-300))),
            "channels": ch_rows, "bands": band_rows, "dominant_channel": ch_rows[0]["channel"],
            "dominant_band": band_rows[0]["band"], "nonsync_peaks": peak_info, "whirl": planes, "time": time_rows}


def _time_budget(t_s, e, impact_force_n, speed_rad_s, sigma2) -> list[dict]:
    hit = np.flatnonzero(np.any(impact_force_n != 0, axis=1))
    seg = np.full(t_s.size, "steady", dtype=object)
    for k in hit:
        seg[(t_s >= t_s[k]) & (t_s < t_s[k] + 0.05)] = "after_impact_50ms"
    if hit.size:
        seg[t_s < t_s[hit[0]]] = "before_first_impact"
    rows = []
    if np.ptp(speed_rad_s) > 0.02 * max(np.mean(speed_rad_s), 1e-9):
        edges = np.quantile(speed_rad_s, [0, 0.25, 0.5, 0.75, 1.0])
        for i in range(4):
            m = (speed_rad_s >= edges[i]) & (speed_rad_s <= edges[i + 1])
            rows.append({"segment": f"speed_{edges[i] * 30 / np.pi:.0f}_{edges[i + 1] * 30 / np.pi:.0f}_rpm",
                         "samples": int(m.sum()), "rms_m": float(np.sqrt(np.mean(e[m] ** 2)))})
    for name in ("before_first_impact", "after_impact_50ms", "steady"):
        m = seg == name
        if m.sum():
            rms = float(np.sqrt(np.mean(e[m] ** 2)))
            rows.append({"segment": name, "samples": int(m.sum()), "rms_m": rms,
                         "ratio_to_noise": rms / float(np.sqrt(sigma2.mean()))})
    return rows


def innovation_consistency(nis: np.ndarray, innovation_m: np.ndarray, innovation_std_m: np.ndarray,
                           max_lag: int = 20) -> dict:
    """NIS mean against chi-square(4) and whiteness of the normalized innovations (Ljung-Box)."""
    from scipy.stats import chi2

    ok = np.isfinite(nis) & np.all(np.isfinite(innovation_m), axis=1)
    n = int(ok.sum())
    if n < 50:
        return {"samples": n, "consistent": False, "white": False, "note": "too few filter updates"}
    nis_mean = float(np.mean(nis[ok]))
    half = 1.96 * np.sqrt(8.0 / n)
    u = innovation_m[ok] / innovation_std_m[ok]
    u = u - u.mean(axis=0)
    q_stats, p_values, lag1 = [], [], []
    for c in range(4):
        x = u[:, c]
        d = float(x @ x)
        r = np.array([float(x[:-k] @ x[k:]) / d for k in range(1, max_lag + 1)])
        q = n * (n + 2) * np.sum(r ** 2 / (n - np.arange(1, max_lag + 1)))
        q_stats.append(float(q))
        p_values.append(float(chi2.sf(q, max_lag)))
        lag1.append(float(r[0]))
    return {"samples": n, "nis_mean": nis_mean, "nis_expected": 4.0,
            "nis_95_interval": [4.0 - half, 4.0 + half], "consistent": bool(abs(nis_mean - 4.0) <= max(half, 0.4)),
            "ljung_box_q": q_stats, "ljung_box_p": p_values, "lag1_autocorrelation": lag1,
            "white": bool(min(p_values) > 1e-3)}
