# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Anti-aliased decimation of a record before the diagnosis (``diagnose(..., decimate=q)``).

Every re-simulation of the diagnosis costs in proportion to the samples, and a record sampled at 20 kHz
carries the rotor's response (its harmonics up to 4X, its modes) far below its Nyquist frequency. Low-pass
filtering the probes and keeping every ``q``-th sample keeps that band and the noise in it: the white noise of
the kept band is white at the new rate, of variance ``sigma^2 / q``, so a fit's information on the parameters
(``sum (dy/dtheta)^2 / sigma^2``) is unchanged while the samples are ``q`` times fewer. Plain subsampling
without the filter would fold the whole band's noise in and lose a factor ``q`` of that information.

The filter is a zero-phase (symmetric, centred) Kaiser-windowed half-band FIR at the new Nyquist frequency,
``2 * HALF_TAPS_PER_FACTOR * q + 1`` taps: flat to 1e-5 up to 0.45 of the new sampling rate, below 1.3e-5 from
0.55 of it (what folds onto 0.45 and below), and -6 dB at the new Nyquist. So the white noise stays white up to
0.45 of the new rate. A factor keeps ``RESPONSE_ORDER`` x the running speed in that flat band (the fits model
the harmonics up to 4X). The diagnosis reads the noise floor above 10x the speed
(:func:`.context.noise_std_from_spectrum`): at the new rate while 10x the speed is at most 0.3 of it (the band
read there before decimation went beyond 2), else at the record's own rate, carried to the new one by the
filter's white-noise gain ``sqrt(sum h^2)`` (:func:`fit_rate_noise_std_m`).
The first and last ``HALF_TAPS_PER_FACTOR * q`` samples, where the filter would run off the record, are dropped
when they are steady and hold no impact (the rest of the record repeats them); otherwise (a start from rest, an
impact there) they are kept unfiltered on the same grid, every ``q``-th raw sample: their in-band signal is exact
and their noise variance ``q`` times the filtered samples' (:func:`edge_handling`). Such a record was kept at
the full rate before, at four times the cost.
The impact force, held over each sample period (:class:`.core.recording.RigRecording`), is held over the new
periods so that each raw sample's impulse and centroid are kept (:func:`held_impact_force`). The keyphasor
stamps are kept as they are.
"""
from __future__ import annotations

import numpy as np

from rotor_estimator.core.errors import InputError
from rotor_estimator.core.recording import RigRecording

#: Filter half-length per unit of the factor (taps on each side of the centre: 200 at q = 2).
HALF_TAPS_PER_FACTOR = 100
#: Kaiser window's beta: the stop band's 1e-5 at 0.55 of the new rate with the half-length above.
KAISER_BETA = 8.0
#: The highest frequency the diagnosis needs is below this fraction of the new sampling rate: the filter's
#: flat band (see the module docstring).
FLAT_FRACTION = 0.45
#: The diagnosis reads the noise floor above 10x the running speed (:func:`.context.build_context`).
NOISE_BAND_ORDER = 10.0
#: A factor is allowed while this multiple of the running speed stays in the flat band of the new rate: the fits
#: model the rotor's harmonics up to 4X (:func:`.linsim.harmonic_phasors`), one order of margin. The noise floor
#: is then read at the record's rate where the new rate's band above 10x the speed is too narrow
#: (:func:`fit_rate_noise_std_m`). 10 (the noise band itself) until the noise was carried.
RESPONSE_ORDER = 5.0
#: Where the decimated record's own band is read for the noise floor: from 10x the speed, while that is at most
#: this share of the new rate (the band 0.3-0.45 of it checked on white noise, README "Decimation").
FIT_RATE_NOISE_LOW_FRACTION = 0.3
#: Samples a decimated record keeps at least (beyond the dropped edges).
MIN_KEPT_SAMPLES = 256
#: The largest factor ``decimate="auto"`` picks: the one checked on the blind sets (README, "Decimation"; 2 until
#: the noise floor could be read at the record's rate).
AUTO_MAX_FACTOR = 4
#: ``decimate="auto"`` keeps the full rate when the filter's dropped edges would be more than this share of the
#: record (a short record loses more by its edges than it gains in time; own seed 2041's 0.25-0.28 s records,
#: 7-8 % dropped at a factor of 2, kept every benchmark figure).
AUTO_MAX_EDGE_FRACTION = 0.10
#: ``decimate="auto"`` keeps the full rate when an edge the filter drops differs from the record a revolution on
#: by more than this over the noise (:func:`edge_transient_ratio`): a transient there (a start from rest) carries
#: much of a record's information without an impact.
AUTO_MAX_EDGE_TRANSIENT_RATIO = 1.5


def half_band_taps(factor: int) -> np.ndarray:
    """The zero-phase low-pass FIR of :func:`decimated` for ``factor`` (unit DC gain)."""
    from scipy.signal import firwin

    half = HALF_TAPS_PER_FACTOR * factor
    return firwin(2 * half + 1, 1.0 / factor, window=("kaiser", KAISER_BETA))


def largest_factor(sample_rate_hz: float, max_speed_hz: float, limit: int = 8) -> int:
    """The largest factor (at most ``limit``) whose new rate keeps ``RESPONSE_ORDER`` x ``max_speed_hz`` in the
    flat band (``FLAT_FRACTION`` of the new rate): the rotor's harmonics the fits model."""
    q = int(np.floor(FLAT_FRACTION * sample_rate_hz / (RESPONSE_ORDER * max(max_speed_hz, 1e-9))))
    return max(1, min(q, int(limit)))


def noise_read_at_record_rate(sample_rate_hz: float, factor: int, max_speed_hz: float) -> bool:
    """Whether the noise floor of a record decimated by ``factor`` is read at the record's own rate: where
    ``NOISE_BAND_ORDER`` x the speed is above ``FIT_RATE_NOISE_LOW_FRACTION`` of the new rate, the new rate's
    band from there to its flat band's edge is narrower than the one checked, or empty."""
    return factor > 1 and NOISE_BAND_ORDER * max_speed_hz > FIT_RATE_NOISE_LOW_FRACTION * sample_rate_hz / factor


def filter_noise_gain(factor: int) -> float:
    """``sqrt(sum h^2)`` of :func:`half_band_taps`: the std of white noise after the filter over its std before
    (about ``1 / sqrt(factor)``: the kept band's share)."""
    taps = half_band_taps(int(factor))
    return float(np.sqrt(np.sum(taps ** 2)))


def fit_rate_noise_std_m(recording: RigRecording, factor: int) -> np.ndarray | None:
    """(4,) white-noise std per channel (m) of ``recording`` once decimated by ``factor``, where the decimated
    record's own band cannot show it (:func:`noise_read_at_record_rate`), else ``None`` (the diagnosis reads it
    there). Read from the record at its own rate above 10x its fastest speed (the periodogram's median, as the
    diagnosis reads it, :func:`.context.noise_std_from_spectrum`) times :func:`filter_noise_gain`. Rows with a
    non-finite probe sample are left out; ``None`` too without keyphasor pulses (no factor above 1 is picked then)."""
    from rotor_estimator.diagnosis.context import noise_band_low_hz, noise_std_from_spectrum

    fastest_hz = _fastest_speed_hz(recording)
    rate_hz = 1.0 / (float(np.median(np.diff(recording.stamps_ns))) * 1e-9)
    if fastest_hz is None or not noise_read_at_record_rate(rate_hz, factor, fastest_hz):
        return None
    y = recording.probes_m[np.all(np.isfinite(recording.probes_m), axis=1)]
    sigma = noise_std_from_spectrum(y - y.mean(axis=0), rate_hz, noise_band_low_hz(rate_hz, 2 * np.pi * fastest_hz))
    return sigma * filter_noise_gain(factor)


def automatic_factor(recording: RigRecording) -> tuple[int, str]:
    """The factor ``decimate="auto"`` (the diagnosis's default) picks, and why: the largest of at most
    ``AUTO_MAX_FACTOR`` that keeps ``RESPONSE_ORDER`` x the running speed (from the keyphasor) in the flat band,
    while the filter's edges are at most ``AUTO_MAX_EDGE_FRACTION`` of the record (a short record keeps its
    rate). An impact or a transient in the edges does not stop it: :func:`decimated` keeps such edges unfiltered
    (:func:`edge_handling`). 1 for a record without keyphasor pulses (its band cannot be checked)."""
    n = len(recording)
    fastest_hz = _fastest_speed_hz(recording)
    if fastest_hz is None:
        return 1, "no keyphasor pulses to check the band against"
    period_s = float(np.median(np.diff(recording.stamps_ns))) * 1e-9
    q = largest_factor(1.0 / period_s, fastest_hz, limit=AUTO_MAX_FACTOR)
    top_hz = RESPONSE_ORDER * fastest_hz
    why = f"{RESPONSE_ORDER:g}x the speed ({top_hz:.0f} Hz) needs the full rate"
    for factor in range(q, 1, -1):
        half = HALF_TAPS_PER_FACTOR * factor
        if 2 * half > AUTO_MAX_EDGE_FRACTION * n:
            why = (f"a factor of {factor} would filter only {n - 2 * half} of the {n} samples (the filter's edges: "
                   f"{half} at each end)")
        else:
            return factor, (f"{RESPONSE_ORDER:g}x the speed ({top_hz:.0f} Hz) stays below {FLAT_FRACTION:g} of the "
                            f"new rate")
    return 1, why


def edge_handling(recording: RigRecording, factor: int) -> tuple[str, str]:
    """What :func:`decimated` does with the first and last ``HALF_TAPS_PER_FACTOR * factor`` samples, where the
    zero-phase filter would run off the record, and why: ``"drop"`` them when they are steady (periodic to
    within ``AUTO_MAX_EDGE_TRANSIENT_RATIO`` x the noise, :func:`edge_transient_ratio`) and hold no impact (the
    record repeats what they say); else ``"keep"`` them unfiltered, every ``factor``-th sample on the same grid
    (an impact, a start from rest or a speed change there carries much of what a record says on the
    coefficients, and an edge that cannot be checked is kept). A kept edge's samples hold their in-band signal
    exactly and ``factor`` x the filtered samples' noise variance (plain subsampling folds the band above in)."""
    n = len(recording)
    half = HALF_TAPS_PER_FACTOR * int(factor)
    if np.any(recording.impact_force_n[:half] != 0.0) or np.any(recording.impact_force_n[n - half:] != 0.0):
        return "keep", "an impact in them"
    ratio = edge_transient_ratio(recording, half)
    if not np.isfinite(ratio):
        return "keep", "they cannot be checked for a transient (non-finite probe samples, or too few pulses)"
    if ratio > AUTO_MAX_EDGE_TRANSIENT_RATIO:
        return "keep", (f"a transient in them (they differ from the record a revolution on by {ratio:.1f}x the "
                        "noise: a start from rest, a speed change)")
    return "drop", f"steady (within {ratio:.1f}x the noise of the record a revolution on) and without an impact"


def edge_transient_ratio(recording: RigRecording, half: int) -> float:
    """How far the first and last ``half`` samples are from periodic: the larger over the two edges of the RMS of
    each edge minus the record a whole number of mean revolutions on (back, for the end edge), interpolated
    between samples, over the RMS that difference has on white noise alone (sqrt(2) x the noise floor read above
    0.3 of the rate, as the diagnosis reads it). About 1 for a steady record; a start from rest, a speed change or
    a decaying transient give more. ``inf`` without two keyphasor pulses or samples enough."""
    from scipy.interpolate import CubicSpline

    from rotor_estimator.diagnosis.context import noise_std_from_spectrum

    y = recording.probes_m
    n = len(recording)
    periods_ns = np.diff(recording.pulse_stamps_ns)
    if periods_ns.size == 0:
        return float("inf")
    step_ns = float(np.median(np.diff(recording.stamps_ns)))
    rev = float(np.median(periods_ns)) / step_ns          # samples per revolution
    lag = rev * np.ceil((half + 1) / rev)                  # whole revolutions, past the edge
    if n < 2 * half + lag + 8:
        return float("inf")

    def shifted(first: int, shift: float) -> np.ndarray:
        """y at samples first .. first + half - 1 moved by ``shift`` samples (cubic spline of the span)."""
        lo = int(np.floor(first + shift)) - 2
        span = y[lo:lo + half + 6]
        return CubicSpline(np.arange(lo, lo + span.shape[0]), span, axis=0)(np.arange(first, first + half) + shift)

    head = y[:half] - shifted(0, lag)
    tail = y[n - half:] - shifted(n - half, -lag)
    finite = np.all(np.isfinite(y), axis=1)
    if not (np.all(np.isfinite(head)) and np.all(np.isfinite(tail))) or finite.sum() < 64:
        return float("inf")
    rate_hz = 1e9 / step_ns
    sigma = noise_std_from_spectrum(y[finite] - y[finite].mean(axis=0), rate_hz, 0.3 * rate_hz)
    floor = np.sqrt(2.0 * np.mean(sigma ** 2))
    return float(max(np.sqrt(np.mean(head ** 2)), np.sqrt(np.mean(tail ** 2))) / max(floor, 1e-300))


def resolved_factor(recording: RigRecording, decimate: int | str) -> tuple[int, str]:
    """``decimate`` as a factor and why: ``"auto"`` through :func:`automatic_factor`, an integer as given (checked
    by :func:`decimated`)."""
    if isinstance(decimate, str):
        if decimate != "auto":
            raise InputError(f"decimate: 'auto' or a positive integer, got {decimate!r}")
        return automatic_factor(recording)
    return decimate, "as asked"


def _fastest_speed_hz(recording: RigRecording) -> float | None:
    """The running speed near its highest, Hz: from the 5th percentile of the revolution periods (a jittered
    pulse does not set it); None without two pulses."""
    periods_s = np.diff(recording.pulse_stamps_ns) * 1e-9
    periods_s = periods_s[periods_s > 0]
    return float(1.0 / np.percentile(periods_s, 5)) if periods_s.size else None


def held_impact_force(force_n: np.ndarray, index: np.ndarray, factor: int) -> np.ndarray:
    """(len(index), 2) impact force (N) held over the new periods ``[index[k], index[k] + factor)`` (raw
    samples; a uniform grid) that keeps each raw sample's impulse and its centroid: a raw sample held over
    ``[j, j + 1)`` has its centre at ``(j - index[k] + 0.5) / factor`` of the way through its new period ``k``;
    its impulse is split between that period and the neighbour on the side of its centre, in the proportions
    that put the pair's centroid where the raw sample's is (linear interpolation between the periods' centres).
    So the impulse and its first moment are kept (at the record's first and last periods, where there is no
    neighbour, the impulse alone). Held at its mean over each period instead, a hammer pulse of 150 us in a
    200 us period (decimated by 4 from 20 kHz) was moved by up to 75 us: the response after it came out 1.8-2.8 %
    of its peak off the filtered full-rate response, against 0.4-0.7 % so (test). A raw sample outside the grid
    (a dropped edge holds no impact: :func:`edge_handling`) goes to the nearest period."""
    force = np.asarray(force_n, dtype=float)
    held = np.zeros((index.size, force.shape[1]))
    rows = np.flatnonzero(np.any(force != 0.0, axis=1))
    if rows.size == 0:
        return held
    k = np.clip(np.searchsorted(index, rows, side="right") - 1, 0, index.size - 1)
    alpha = np.clip((rows - index[k] + 0.5) / factor - 0.5, -0.5, 0.5)  # the centre's offset, in periods
    other = np.clip(k + np.sign(alpha).astype(int), 0, index.size - 1)
    share = np.where(other == k, 0.0, np.abs(alpha))
    per_period = force[rows] / factor  # the raw sample's impulse as a force held over one new period
    np.add.at(held, k, (1.0 - share)[:, None] * per_period)
    np.add.at(held, other, share[:, None] * per_period)
    return held


def decimated(recording: RigRecording, factor: int) -> RigRecording:
    """``recording`` low-pass filtered and sampled every ``factor``-th sample (module docstring); ``factor`` 1
    returns it unchanged. Raises :class:`InputError` naming ``decimate`` for a factor that is not a positive
    integer, one that would put ``RESPONSE_ORDER`` x the running speed above the filter's flat band, or a record
    too short for the filter's edges."""
    if isinstance(factor, bool) or not isinstance(factor, (int, np.integer)) or factor < 1:
        raise InputError(f"decimate: the factor must be a positive integer, got {factor!r}")
    factor = int(factor)
    if factor == 1:
        return recording
    n = len(recording)
    half = HALF_TAPS_PER_FACTOR * factor
    if n < 2 * half + factor * MIN_KEPT_SAMPLES:
        raise InputError(f"decimate: a factor of {factor} needs at least {2 * half + factor * MIN_KEPT_SAMPLES} "
                         f"samples (the filter's {half} at each end are dropped), the record has {n}")
    period_s = float(np.median(np.diff(recording.stamps_ns))) * 1e-9
    fastest_hz = _fastest_speed_hz(recording)
    if fastest_hz is not None:
        allowed = largest_factor(1.0 / period_s, fastest_hz, limit=factor)
        if allowed < factor:
            raise InputError(
                f"decimate: a factor of {factor} puts {RESPONSE_ORDER:g}x the running speed ({fastest_hz:.1f} Hz "
                f"from the keyphasor) above {FLAT_FRACTION:g} of the new rate ({1.0 / period_s / factor:.0f} Hz); "
                f"this record allows at most {allowed}")
    taps = half_band_taps(factor)
    filtered = np.stack([np.convolve(recording.probes_m[:, i], taps, mode="valid") for i in range(4)], axis=1)
    # filtered[j] is the filtered sample half + j: the kept grid is every factor-th sample from half
    inner = half + np.arange(0, filtered.shape[0] - factor + 1, factor)
    edges, edges_why = edge_handling(recording, factor)
    if edges == "keep":
        head = np.arange(half - factor, -1, -factor)[::-1]
        tail = np.arange(inner[-1] + factor, n, factor)
        index = np.concatenate([head, inner, tail])
        probes = np.concatenate([recording.probes_m[head], filtered[inner - half], recording.probes_m[tail]])
    else:
        index, probes = inner, filtered[inner - half]
    held = held_impact_force(recording.impact_force_n, index, factor)
    meta = {**recording.meta, "decimation": {
        "factor": factor, "filter_taps": int(taps.size), "edge_samples": half,
        "edges": "kept unfiltered" if edges == "keep" else "dropped", "edges_why": edges_why,
        "dropped_edge_samples": 0 if edges == "keep" else half}}
    return RigRecording(recording.stamps_ns[index], np.ascontiguousarray(probes), recording.pulse_stamps_ns, held,
                        meta=meta)
