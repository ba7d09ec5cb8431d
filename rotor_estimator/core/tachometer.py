# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Shaft angle, speed and angular acceleration from once-per-revolution keyphasor pulses.

Each accepted pulse marks shaft angle 0 (mod 2*pi) at its stamp (integer ns). Pulse
``i`` gets a revolution index ``n_i`` (integers; skipped revolutions are inferred), and a
polynomial ``n(t)`` of order ``fit_order`` (2: constant angular acceleration) is fitted
by least squares to the last ``window_pulses`` pulses, so pulse-time jitter is averaged.
With ``u = (t - t_ref) * 1e-9`` seconds after the fit's reference pulse ``t_ref``::

    revs(u) = c0 + c1*u + c2*u**2        (revolutions since the reference pulse)
    angle_rad    = 2*pi * (revs - floor(revs))      wrapped to [0, 2*pi)
    speed_rad_s  = 2*pi * (c1 + 2*c2*u)
    accel_rad_s2 = 2*pi * 2*c2

The angle is *wrapped* to ``[0, 2*pi)``: the imbalance force only needs cos/sin of it, and
a wrapped angle stays exact over hours and across tracker resets.

Two ways to use the same fit and the same evaluation code:

* **Live** (:class:`ShaftAngleTracker`): a causal fit. ``query(t)`` uses the fit made at
  the newest accepted pulse with stamp ``<= t`` (a short history of fits is kept), i.e.
  it extrapolates up to about one revolution. Because the fit is chosen by stamp, the
  answer does not depend on whether a later pulse was already added: live and replay
  give identical numbers if every pulse is added before samples more than
  ``fit_history`` pulses newer are queried.
* **Offline** (:func:`shaft_states_from_pulses`): the same pulse screening, then for the
  interval between pulses ``j`` and ``j+1`` a fit *centered* on it (half the window on each
  side), so there is no extrapolation lag and jitter averages symmetrically.

When ``valid`` is False every number in the state is 0.0 (a stopped shaft has speed 0).
Reasons: fewer than 2 pulses in the current track, a time before the first pulse (or
older than the kept fit history), more than ``max_extrapolation_revs`` past the reference
pulse, no pulse for ``stop_timeout_s`` (machine stopped), or a fitted speed outside
``[min_speed_rad_s, max_speed_rad_s]``.
"""
from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from rotor_estimator.core.errors import ConfigError, InputError

__all__ = [
    "TachometerConfig",
    "ShaftState",
    "ShaftStates",
    "ShaftAngleTracker",
    "shaft_states_from_pulses",
    "PULSE_COUNTERS",
    "max_speed_for_rig",
]

TWO_PI = 2.0 * math.pi
DEFAULT_MAX_SPEED_RAD_S = TWO_PI * 1000.0  # 60000 rpm


def max_speed_for_rig(running_speed_rad_s: float) -> float:
    """The tracker's speed limit for a rig: twice its running speed (a pulse interval shorter than
    half a revolution at running speed is spurious), and never below 60000 rpm, so that rigs faster
    than that are tracked instead of having every pulse rejected as too fast."""
    return max(DEFAULT_MAX_SPEED_RAD_S, 2.0 * float(running_speed_rad_s))
_LOCK_PULSES = 3  # below this many pulses in a track, no skipped revolution is inferred

#: Counter names of :attr:`ShaftAngleTracker.counters`. ``pulses_in`` equals
#: ``accepted`` plus every ``rejected_*``; the other counters are informational.
PULSE_COUNTERS: tuple[str, ...] = (
    "pulses_in",              # add_pulse calls
    "accepted",               # pulses used (including those that start a new track)
    "rejected_duplicate",     # stamp equal to an accepted pulse of the current track
    "rejected_out_of_order",  # older than the newest accepted pulse, within the window
    "rejected_clock_jump",    # older than every pulse of the window (clock went backwards)
    "rejected_early",         # less than (1 - pulse_tolerance_revs) revolution after the last one
    "rejected_inconsistent",  # not within pulse_tolerance_revs of a whole revolution count
    "missed_pulses",          # revolutions inferred without a pulse (gap of 2, 3... periods)
    "resets",                 # track discarded: too many consecutive rejections, gap too long,
                              # or inconsistent pulses while locking on
    "stop_timeouts",          # track ended: no pulse for stop_timeout_s (machine stopped)
    "model_breaks",           # fit window restarted: a pulse far off the fit's prediction
)


@dataclass(frozen=True)
class TachometerConfig:
    """Keyphasor tracking parameters (validated at construction, raises ConfigError).

    * ``window_pulses``: pulses in the least-squares fit (>= 2; 8 default).
    * ``fit_order``: 1 (constant speed) or 2 (constant acceleration) polynomial n(t).
    * ``max_extrapolation_revs``: queries further than this many revolutions past the
      reference pulse are invalid (2.5 tolerates one missing pulse).
    * ``stop_timeout_s``: no pulse for this long means the machine stopped (s).
    * ``min_speed_rad_s`` / ``max_speed_rad_s``: valid speed range; an interval shorter than
      ``2*pi/max_speed_rad_s`` is a spurious pulse.
    * ``pulse_tolerance_revs``: how far (revolutions) a pulse may fall from a whole
      revolution count predicted by the fit before it is rejected.
    * ``max_missed_pulses``: the longest run of skipped revolutions inferred; a longer gap
      starts a new track.
    * ``max_consecutive_rejections``: this many rejected pulses in a row (duplicates not
      counted) start a new track at the last one (e.g. a sustained clock jump back).
    * ``fit_history``: fits kept so that stamps older than the newest pulse can be queried.
    * ``jitter_smoothing``: weight of each new window in the jitter RMS estimate (0..1].
    * ``break_threshold_sigma`` / ``break_floor_revs``: a pulse further than
      ``max(break_threshold_sigma * jitter, break_floor_revs)`` (revolutions) from the fit's
      prediction marks a change of acceleration: the window restarts from the last
      ``fit_order`` pulses (counted ``model_breaks``).
    """

    window_pulses: int = 8
    fit_order: int = 2
    max_extrapolation_revs: float = 2.5
    stop_timeout_s: float = 1.0
    min_speed_rad_s: float = 10.0
    max_speed_rad_s: float = DEFAULT_MAX_SPEED_RAD_S
    pulse_tolerance_revs: float = 0.25
    max_missed_pulses: int = 3
    max_consecutive_rejections: int = 4
    fit_history: int = 64
    jitter_smoothing: float = 0.05
    break_threshold_sigma: float = 15.0
    break_floor_revs: float = 2e-4

    def __post_init__(self) -> None:
        def integer(name: str, low: int, high: int) -> None:
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or not low <= v <= high:
                raise ConfigError(f"tachometer.{name}: must be an integer from {low} to {high}, got {v!r}")

        def number(name: str, low: float, high: float, unit: str, low_open: bool = True) -> None:
            v = getattr(self, name)
            ok = (not isinstance(v, bool) and isinstance(v, (int, float, np.floating, np.integer))
                  and math.isfinite(v) and (v > low if low_open else v >= low) and v <= high)
            if not ok:
                op = ">" if low_open else ">="
                raise ConfigError(f"tachometer.{name}: must be a finite number {op} {low:g} and <= {high:g} "
                                  f"{unit}, got {v!r}")

        integer("window_pulses", 2, 1000)
        integer("fit_order", 1, 2)
        if self.window_pulses < self.fit_order + 1:
            raise ConfigError(f"tachometer.window_pulses: must be >= fit_order + 1 = {self.fit_order + 1}, "
                              f"got {self.window_pulses}")
        number("max_extrapolation_revs", 0.0, 100.0, "rev")
        number("stop_timeout_s", 0.0, 3600.0, "s")
        number("min_speed_rad_s", 0.0, 1e6, "rad/s", low_open=False)
        number("max_speed_rad_s", 0.0, 1e7, "rad/s")
        if not self.max_speed_rad_s > self.min_speed_rad_s:
            raise ConfigError(f"tachometer.max_speed_rad_s: must be > min_speed_rad_s ({self.min_speed_rad_s:g}), "
                              f"got {self.max_speed_rad_s:g}")
        number("pulse_tolerance_revs", 0.0, 0.49, "rev")
        integer("max_missed_pulses", 0, 1000)
        integer("max_consecutive_rejections", 1, 1000)
        integer("fit_history", 1, 100_000)
        number("jitter_smoothing", 0.0, 1.0, "")
        number("break_threshold_sigma", 0.0, 1e6, "(dimensionless)")
        number("break_floor_revs", 0.0, 0.5, "rev", low_open=False)


class ShaftState(NamedTuple):
    """Shaft state at one stamp; all zeros when ``valid`` is False."""

    angle_rad: float      # wrapped to [0, 2*pi), 0 at the keyphasor mark
    speed_rad_s: float
    accel_rad_s2: float
    valid: bool


class ShaftStates(NamedTuple):
    """Shaft states at many stamps: arrays of shape (N,); zeros where ``valid`` is False."""

    angle_rad: np.ndarray
    speed_rad_s: np.ndarray
    accel_rad_s2: np.ndarray
    valid: np.ndarray


_INVALID = ShaftState(0.0, 0.0, 0.0, False)


# --------------------------------------------------------------------------- pure functions
def _fit_revolutions(u_s: np.ndarray, revs: np.ndarray, order: int) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares polynomial ``revs ~ c0 + c1 u + c2 u^2`` for a stack of windows.

    ``u_s`` and ``revs`` are (B, m). Returns coefficients (B, 3) (``c2 = 0`` for order 1)
    and the unbiased residual variance (B,) in rev^2 (NaN when m <= order + 1).
    Solved by QR on ``u`` scaled to [-1, 1] (well conditioned for any speed).
    """
    b, m = u_s.shape
    scale = np.max(np.abs(u_s), axis=1, keepdims=True)
    scale[scale == 0.0] = 1.0
    x = u_s / scale
    vander = np.stack([x ** k for k in range(order + 1)], axis=-1)        # (B, m, p)
    q, r = np.linalg.qr(vander)                                            # (B,m,p), (B,p,p)
    coef = np.linalg.solve(r, np.einsum("bmp,bm->bp", q, revs)[..., None])[..., 0]
    resid = revs - np.einsum("bmp,bp->bm", vander, coef)
    dof = m - (order + 1)
    var = np.sum(resid ** 2, axis=1) / dof if dof > 0 else np.full(b, np.nan)
    out = np.zeros((b, 3))
    out[:, : order + 1] = coef / scale ** np.arange(order + 1)
    return out, var


def _evaluate(fit_t_ns: np.ndarray, fit_coef: np.ndarray, fit_ok: np.ndarray, stamps_ns: np.ndarray,
              config: TachometerConfig) -> ShaftStates:
    """Evaluate the fit table (sorted reference stamps, (F,3) coefficients) at stamps.

    Same arithmetic, in the same order, as :meth:`ShaftAngleTracker.query`.
    """
    stamps = np.asarray(stamps_ns)
    n = stamps.shape[0]
    if len(fit_t_ns) == 0 or n == 0:
        z = np.zeros(n)
        return ShaftStates(z, z.copy(), z.copy(), np.zeros(n, dtype=bool))
    idx = np.searchsorted(fit_t_ns, stamps, side="right") - 1
    has = idx >= 0
    idx[~has] = 0
    c0, c1, c2 = fit_coef[idx, 0], fit_coef[idx, 1], fit_coef[idx, 2]
    u = (stamps - fit_t_ns[idx]).astype(float) * 1e-9
    revs = c0 + u * (c1 + u * c2)
    speed = TWO_PI * (c1 + 2.0 * c2 * u)
    valid = (has & fit_ok[idx] & (u <= config.stop_timeout_s) & (revs <= config.max_extrapolation_revs)
             & (speed >= config.min_speed_rad_s) & (speed <= config.max_speed_rad_s))
    frac = revs - np.floor(revs)
    frac[frac >= 1.0] = 0.0
    angle = np.where(valid, TWO_PI * frac, 0.0)
    return ShaftStates(angle, np.where(valid, speed, 0.0), np.where(valid, TWO_PI * 2.0 * c2, 0.0), valid)


def _as_stamp(stamp_ns: object) -> int:
    if isinstance(stamp_ns, bool) or not isinstance(stamp_ns, (int, np.integer)):
        raise InputError(f"pulse stamp must be an integer number of nanoseconds, got {stamp_ns!r} "
                         f"({type(stamp_ns).__name__}); convert once at the boundary")
    return int(stamp_ns)


def _as_stamp_array(stamps_ns: np.ndarray, name: str) -> np.ndarray:
    arr = np.asarray(stamps_ns)
    if arr.ndim != 1 or not np.issubdtype(arr.dtype, np.integer):
        raise InputError(f"{name}: expected a 1-D integer array of nanosecond stamps, "
                         f"got dtype {arr.dtype} shape {arr.shape}")
    return arr.astype(np.int64, copy=False)


# --------------------------------------------------------------------------- streaming tracker
class ShaftAngleTracker:
    """Streaming keyphasor tracker: ``add_pulse`` per pulse, ``query`` per probe sample.

    >>> trk = ShaftAngleTracker(TachometerConfig())
    >>> period_ns = 3_000_000                       # 20000 rpm
    >>> all(trk.add_pulse(k * period_ns) for k in range(10))
    True
    >>> s = trk.query(9 * period_ns + period_ns // 4)
    >>> s.valid, round(s.angle_rad, 9) == round(math.pi / 2, 9), round(s.speed_rad_s, 6)
    (True, True, 2094.395102)
    """

    def __init__(self, config: TachometerConfig | None = None) -> None:
        self.config = config if config is not None else TachometerConfig()
        self.counters: dict[str, int] = dict.fromkeys(PULSE_COUNTERS, 0)
        self._track_t: deque[int] = deque(maxlen=self.config.window_pulses)
        self._track_n: deque[int] = deque(maxlen=self.config.window_pulses)
        self._track_len = 0                   # pulses in the current track (not capped)
        self._consecutive_rejections = 0
        self._jitter_var_s2 = math.nan
        # fit history, sorted by reference stamp: stamp, (c0, c1, c2), fit usable
        self._h_t: list[int] = []
        self._h_c: list[tuple[float, float, float]] = []
        self._h_ok: list[bool] = []
        self._arrays: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        # (stamp, n, track, model break before this pulse), kept for the offline function
        self._log: list[tuple[int, int, int, int]] | None = None
        self._track_id = -1

    # ----------------------------------------------------------------- properties
    @property
    def jitter_rms_s(self) -> float:
        """Smoothed RMS of pulse-time residuals about the fit (s); NaN until known.

        Includes any speed variation the polynomial cannot follow."""
        return math.sqrt(self._jitter_var_s2) if self._jitter_var_s2 == self._jitter_var_s2 else math.nan

    @property
    def last_pulse_ns(self) -> int | None:
        """Stamp of the newest accepted pulse, or None."""
        return self._track_t[-1] if self._track_t else None

    # ----------------------------------------------------------------- pulses
    def add_pulse(self, stamp_ns: int) -> bool:
        """Screen one pulse (int ns); True if accepted. Every call increments exactly one of
        ``accepted`` / ``rejected_*`` in :attr:`counters`."""
        stamp = _as_stamp(stamp_ns)
        cfg, c = self.config, self.counters
        c["pulses_in"] += 1
        if not self._track_t:
            return self._start_track(stamp)
        last = self._track_t[-1]
        if stamp <= last:
            if stamp in self._track_t:
                c["rejected_duplicate"] += 1
                return False
            kind = "rejected_out_of_order" if stamp > self._track_t[0] else "rejected_clock_jump"
            return self._reject(kind, stamp)
        if (stamp - last) * 1e-9 > cfg.stop_timeout_s:
            c["stop_timeouts"] += 1
            return self._start_track(stamp)
        if self._track_len == 1:
            if TWO_PI / ((stamp - last) * 1e-9) > cfg.max_speed_rad_s:
                return self._reject("rejected_early", stamp)
            return self._accept(stamp, 1)
        c0, c1, c2 = self._h_c[-1]
        u = (stamp - last) * 1e-9
        revs = c0 + u * (c1 + u * c2)
        k = int(math.floor(revs + 0.5))
        fit_error_revs = abs(revs - k)
        if abs(revs - k) > cfg.pulse_tolerance_revs or revs < 1.0 - cfg.pulse_tolerance_revs:
            # The fit may lag a sudden change of acceleration (drive switched on/off); judge
            # the pulse by the last interval's speed instead before rejecting it.
            t_prev, n_prev = self._track_t[-2], self._track_n[-2]
            revs = (stamp - last) / (last - t_prev) * (self._track_n[-1] - n_prev)
            k = int(math.floor(revs + 0.5))
        if revs < 1.0 - cfg.pulse_tolerance_revs:
            kind = "rejected_early"
        elif abs(revs - k) > cfg.pulse_tolerance_revs:
            kind = "rejected_inconsistent"
        elif k > 1 and self._track_len < _LOCK_PULSES:
            kind = "rejected_inconsistent"       # no skipped-revolution inference while locking on
        elif k - 1 > cfg.max_missed_pulses:
            c["resets"] += 1
            return self._start_track(stamp)
        else:
            c["missed_pulses"] += k - 1
            if self._is_model_break(fit_error_revs, k, c1):
                c["model_breaks"] += 1
                keep = self.config.fit_order          # + the new pulse = fit_order + 1 points
                while len(self._track_t) > keep:
                    self._track_t.popleft(), self._track_n.popleft()
                return self._accept(stamp, k, model_break=True)
            return self._accept(stamp, k)
        if kind == "rejected_inconsistent" and self._track_len < _LOCK_PULSES:
            # Locking on: the first pulse of the track may have been spurious. Restart
            # from the newest accepted pulse and judge this one against it.
            c["resets"] += 1
            c["accepted"] -= 1                    # re-counted by _start_track below
            self._start_track(last)
            c["pulses_in"] -= 1                   # this call is still one pulse
            return self.add_pulse(stamp)
        return self._reject(kind, stamp)

    def _reject(self, kind: str, stamp: int) -> bool:
        self._consecutive_rejections += 1
        if self._consecutive_rejections >= self.config.max_consecutive_rejections:
            self.counters["resets"] += 1
            return self._start_track(stamp)
        self.counters[kind] += 1
        return False

    def _start_track(self, stamp: int) -> bool:
        """Begin a new track at ``stamp`` (revolution 0); the fit is unusable until pulse 2."""
        self._track_t.clear()
        self._track_n.clear()
        self._track_t.append(stamp)
        self._track_n.append(0)
        self._track_len = 1
        self._track_id += 1
        self._consecutive_rejections = 0
        self.counters["accepted"] += 1
        self._prune_history_from(stamp)
        self._push_fit(stamp, (0.0, 0.0, 0.0), False)
        if self._log is not None:
            self._log.append((stamp, 0, self._track_id, 0))
        return True

    def _is_model_break(self, fit_error_revs: float, k: int, c1_rev_s: float) -> bool:
        """The new pulse missed the fit's prediction by more than ``break_threshold_sigma``
        times the jitter (in revolutions; at least ``break_floor_revs``): the acceleration
        changed, so the window restarts (a polynomial cannot follow a step in acceleration)."""
        cfg = self.config
        if len(self._track_t) <= cfg.fit_order + 1:
            return False
        sigma_revs = self.jitter_rms_s * c1_rev_s
        if sigma_revs != sigma_revs:
            sigma_revs = 0.0
        return fit_error_revs > max(cfg.break_threshold_sigma * sigma_revs * k, cfg.break_floor_revs)

    def _accept(self, stamp: int, k: int, model_break: bool = False) -> bool:
        n = self._track_n[-1] + k
        self._track_t.append(stamp)
        self._track_n.append(n)
        self._track_len += 1
        self._consecutive_rejections = 0
        self.counters["accepted"] += 1
        m = len(self._track_t)
        order = min(self.config.fit_order, m - 1)
        u = np.fromiter(((t - stamp) * 1e-9 for t in self._track_t), float, m)[None, :]
        y = np.fromiter((j - n for j in self._track_n), float, m)[None, :]
        coef, var = _fit_revolutions(u, y, order)
        c0, c1, c2 = (float(v) for v in coef[0])
        self._push_fit(stamp, (c0, c1, c2), True)
        if var[0] == var[0] and c1 > 0.0:
            var_s2 = float(var[0]) / (c1 * c1)
            a = self.config.jitter_smoothing
            self._jitter_var_s2 = var_s2 if self._jitter_var_s2 != self._jitter_var_s2 else (
                (1.0 - a) * self._jitter_var_s2 + a * var_s2)
        if self._log is not None:
            self._log.append((stamp, n, self._track_id, int(model_break)))
        return True

    def _push_fit(self, stamp: int, coef: tuple[float, float, float], ok: bool) -> None:
        self._h_t.append(stamp)
        self._h_c.append(coef)
        self._h_ok.append(ok)
        if len(self._h_t) > self.config.fit_history:
            del self._h_t[0], self._h_c[0], self._h_ok[0]
        self._arrays = None

    def _prune_history_from(self, stamp: int) -> None:
        """Drop fits (and logged pulses) at or after ``stamp``: after a backward clock jump
        they belong to the abandoned timeline."""
        while self._h_t and self._h_t[-1] >= stamp:
            self._h_t.pop(), self._h_c.pop(), self._h_ok.pop()
        if self._log is not None:
            while self._log and self._log[-1][0] >= stamp:
                self._log.pop()
        self._arrays = None

    # ----------------------------------------------------------------- queries
    def query(self, stamp_ns: int) -> ShaftState:
        """Shaft state at ``stamp_ns`` from the newest fit with reference stamp <= it. O(1)."""
        t = int(stamp_ns)
        h_t = self._h_t
        i = len(h_t) - 1
        while i >= 0 and h_t[i] > t:
            i -= 1
        if i < 0 or not self._h_ok[i]:
            return _INVALID
        cfg = self.config
        c0, c1, c2 = self._h_c[i]
        u = float(t - h_t[i]) * 1e-9
        revs = c0 + u * (c1 + u * c2)
        speed = TWO_PI * (c1 + 2.0 * c2 * u)
        if (u > cfg.stop_timeout_s or revs > cfg.max_extrapolation_revs
                or speed < cfg.min_speed_rad_s or speed > cfg.max_speed_rad_s):
            return _INVALID
        frac = revs - math.floor(revs)
        if frac >= 1.0:
            frac = 0.0
        return ShaftState(TWO_PI * frac, speed, TWO_PI * 2.0 * c2, True)

    def query_many(self, stamps_ns: np.ndarray) -> ShaftStates:
        """Vectorized :meth:`query`: bit-identical results for a 1-D int array of stamps."""
        stamps = _as_stamp_array(stamps_ns, "stamps_ns")
        if self._arrays is None:
            self._arrays = (np.asarray(self._h_t, dtype=np.int64),
                            np.asarray(self._h_c, dtype=float).reshape(-1, 3),
                            np.asarray(self._h_ok, dtype=bool))
        return _evaluate(*self._arrays, stamps, self.config)


# --------------------------------------------------------------------------- offline
def shaft_states_from_pulses(pulse_stamps_ns: np.ndarray, sample_stamps_ns: np.ndarray,
                             config: TachometerConfig | None = None) -> tuple[ShaftStates, dict[str, int]]:
    """Offline shaft states at ``sample_stamps_ns`` with a centered fit window.

    ``pulse_stamps_ns`` (in arrival order) go through the same screening as
    :meth:`ShaftAngleTracker.add_pulse` (same counters, returned second). Samples between
    accepted pulses ``j`` and ``j+1`` use a fit over ``window_pulses`` pulses of the same
    track centered on that interval (shifted inward at track ends); samples after a
    track's last pulse extrapolate its last fit with the live limits. At a pulse the fit
    changes, so the angle may step by about the fit's noise (no blending).
    """
    cfg = config if config is not None else TachometerConfig()
    pulses = _as_stamp_array(pulse_stamps_ns, "pulse_stamps_ns")
    samples = _as_stamp_array(sample_stamps_ns, "sample_stamps_ns")
    trk = ShaftAngleTracker(cfg)
    trk._log = []
    for p in pulses.tolist():
        trk.add_pulse(p)
    log = np.asarray(trk._log, dtype=np.int64).reshape(-1, 4)
    t, n, track, brk = log[:, 0], log[:, 1], log[:, 2], log[:, 3]
    count = len(t)
    coef = np.zeros((count, 3))
    ok = np.zeros(count, dtype=bool)
    if count:
        # Segments: a new track starts at its first pulse; after a model break between
        # pulses j-1 and j, windows for intervals from j-1 on start at j-1 and the windows
        # before it end at j-1 (a window never straddles a change of acceleration).
        new_track = np.r_[True, track[1:] != track[:-1]]
        seg_start = np.flatnonzero(new_track | np.r_[brk[1:] == 1, False])
        seg_next = np.r_[seg_start[1:], count]
        seg_last = np.where(new_track[np.minimum(seg_next, count - 1)] | (seg_next == count),
                            seg_next - 1, seg_next)                 # share the break pulse
        sizes = seg_next - seg_start
        first = np.repeat(seg_start, sizes)
        last = np.repeat(seg_last, sizes)
        j = np.arange(count)
        k = cfg.window_pulses
        lo = np.maximum(first, np.minimum(j - (k // 2) + 1, last - k + 1))
        hi = np.minimum(last, lo + k - 1)
        size = hi - lo + 1
        for m in np.unique(size):
            if m < 2:
                continue
            rows = np.flatnonzero(size == m)
            win = lo[rows, None] + np.arange(m)
            u = (t[win] - t[rows, None]).astype(float) * 1e-9
            y = (n[win] - n[rows, None]).astype(float)
            coef[rows], _ = _fit_revolutions(u, y, min(cfg.fit_order, int(m) - 1))
            ok[rows] = True
    return _evaluate(t, coef, ok, samples, cfg), dict(trk.counters)
