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
0.45 of the new rate, where the diagnosis estimates the noise floor (:func:`.context.noise_std_from_spectrum`).
The first and last ``HALF_TAPS_PER_FACTOR * q`` samples, where the filter would run off the record, are dropped.
The impact force, held over each sample period (:class:`.core.recording.RigRecording`), is held over each new
period at its mean there, which keeps its impulse. The keyphasor stamps are kept as they are.
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
#: The diagnosis reads the noise floor above 10x the running speed (:func:`.context.build_context`): a factor is
#: allowed while that frequency stays in the flat band of the new rate.
NOISE_BAND_ORDER = 10.0
#: Samples a decimated record keeps at least (beyond the dropped edges).
MIN_KEPT_SAMPLES = 256


def half_band_taps(factor: int) -> np.ndarray:
    """The zero-phase low-pass FIR of :func:`decimated` for ``factor`` (unit DC gain)."""
    from scipy.signal import firwin

    half = HALF_TAPS_PER_FACTOR * factor
    return firwin(2 * half + 1, 1.0 / factor, window=("kaiser", KAISER_BETA))


def largest_factor(sample_rate_hz: float, max_speed_hz: float, limit: int = 8) -> int:
    """The largest factor (at most ``limit``) whose new rate keeps ``NOISE_BAND_ORDER`` x ``max_speed_hz`` in the
    flat band (``FLAT_FRACTION`` of the new rate): the rotor's harmonics and the noise band the diagnosis reads."""
    q = int(np.floor(FLAT_FRACTION * sample_rate_hz / (NOISE_BAND_ORDER * max(max_speed_hz, 1e-9))))
    return max(1, min(q, int(limit)))


def decimated(recording: RigRecording, factor: int) -> RigRecording:
    """``recording`` low-pass filtered and sampled every ``factor``-th sample (module docstring); ``factor`` 1
    returns it unchanged. Raises :class:`InputError` naming ``decimate`` for a factor that is not a positive
    integer, one that would put ten times the running speed above the filter's flat band, or a record too short
    for the filter's edges."""
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
    pulses_s = np.diff(recording.pulse_stamps_ns) * 1e-9
    if pulses_s.size:
        # the running speed near its highest (the 5th percentile of the revolution periods: a jittered pulse
        # does not set it)
        fastest_hz = float(1.0 / np.percentile(pulses_s[pulses_s > 0], 5)) if np.any(pulses_s > 0) else 0.0
        allowed = largest_factor(1.0 / period_s, fastest_hz, limit=factor)
        if allowed < factor:
            raise InputError(
                f"decimate: a factor of {factor} puts {NOISE_BAND_ORDER:g}x the running speed ({fastest_hz:.1f} Hz "
                f"from the keyphasor) above {FLAT_FRACTION:g} of the new rate ({1.0 / period_s / factor:.0f} Hz); "
                f"this record allows at most {allowed}")
    taps = half_band_taps(factor)
    probes = np.stack([np.convolve(recording.probes_m[:, i], taps, mode="valid") for i in range(4)], axis=1)
    keep = np.arange(0, probes.shape[0] - factor + 1, factor)  # probes[j] is the filtered sample half + j
    force = recording.impact_force_n[half:n - half]
    held = np.mean(np.stack([force[keep + j] for j in range(factor)]), axis=0)
    meta = {**recording.meta, "decimation": {"factor": factor, "filter_taps": int(taps.size),
                                             "dropped_edge_samples": half}}
    return RigRecording(recording.stamps_ns[half:n - half][keep], probes[keep], recording.pulse_stamps_ns, held,
                        meta=meta)
