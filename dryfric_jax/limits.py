r"""Validity ranges and work bounds, decided before any simulation.

Everything here is nondimensional (:math:`\tau_0, u_0`; MODEL_NOTES section 1) and pure Python, so
that a plan can be checked for thousands of parameter sets in a test.

Predicted excursion length
--------------------------
A long excursion needs the noise to carry a stuck particle from the release threshold
:math:`x_+ = 1 - \bar\gamma'` to :math:`x_- = -1 - \bar\gamma'` and back (section 2: a stuck
particle only leaves downwards once :math:`X < x_-`).  For :math:`\tau\,dX = -X\,dt + \sqrt2\,dW`
the mean first-passage time from :math:`a` down to :math:`b < a` is exact,

.. math::
    T(a \to b) = \tau\sqrt\pi \int_{u_b}^{u_a} \operatorname{erfcx}(u)\,du, \qquad u = y\sqrt{\tau/2},

(scale function and speed measure of the OU diffusion), and :math:`T(x_+\to x_-) + T(x_-\to x_+)`
is a lower bound on the mean duration of the continuous-time excursion.  For
:math:`\tau' (1+|\bar\gamma'|)^2 \gg 1` it grows like :math:`e^{\tau'(1+|\bar\gamma'|)^2/2}`: slow,
weak noise rarely reaches the far threshold.  Measured over Fig. 3's 40 points
(:math:`\tau' = 0.18`-14.7, N = 1e5), the PDMP's mean excursion lasts 1.01-1.6 times this sum and the
DI's (splitting regeneration) 2.2-6.4 times.  For fast noise the sum vanishes like
:math:`\tau'` while the velocity still needs its own time to stick and turn: the bound is floored at
:math:`\min(1, \tau_L')` (measured: the PDMP's excursions last 0.50-0.70 :math:`\tau_0` at
:math:`\tau' = 0.02`-0.18 and :math:`\tau_L' = 0.03`-0.1, 2.9 :math:`\tau_0` at :math:`\tau' = 0.05`,
:math:`\tau_L = \infty`; the DI's 2.0-8.6 :math:`\tau_0` at :math:`\tau = 10^{-5}` s).

Near the runaway bias (:math:`|\bar\gamma'| \to 1^-`) a moving particle decelerates only at the net
rate :math:`1 - |\bar\gamma'|` (plus the viscous :math:`v/\tau_L'`), and the excursions lengthen like
:math:`1/(1 - |\bar\gamma'|)`, which neither passage time sees: the prediction is also floored at
:math:`1/((1 - |\bar\gamma'|) + 0.5/\sqrt{\tau_L'})`.  Measured (a PDMP audit, then here;
:math:`\tau' = 1`, N = 2000, seed 0): undamped, the PDMP's excursions last 4.4-4.9 times it at
:math:`|\bar\gamma'| = 0.8`-0.98 (22-222 :math:`\tau_0`, where the passage sum predicted 9-12), the DI's
cycles 15-15.5 times; damped, the PDMP's 4.3, 4.3 and 1.4 times at :math:`(\tau_L', |\bar\gamma'|) =
(10, 0.95), (100, 0.95), (3, 0.9)`.  Faster noise comes closer to it (:math:`\tau_L = \infty`, N = 1000-3000,
a coarse :math:`\delta'` to keep the runs to minutes): the PDMP's excursions last 1.17 (CI 0.57-1.8), 1.28 and
1.33-1.6 times it at :math:`\tau' = 0.1` and :math:`|\bar\gamma'| = 0.98, 0.95, 0.9` (:math:`\delta' = 0.15`-0.3),
1.45 times at :math:`\tau' = 0.3`, 0.95, and 1.9-3.2 times at :math:`\tau' = 0.01` (:math:`\delta' = 0.5`-1; the finer
:math:`\delta'` the longer); the DI's cycles 10-12.6 times at :math:`\tau' = 0.01`-0.1.  The factor 1 keeps it a
lower estimate on every point measured, narrowly at :math:`\tau' = 0.1`, 0.98 (the fits at :math:`\tau' = 1` were
4.4 for the PDMP); before it, a PDMP run at :math:`\tau_L = \infty, |\bar\gamma'| = 0.99` did 320 times its
predicted work.

With :math:`|\bar\gamma'| \ge 1` the bias alone drives a moving particle: it relaxes to
:math:`v^* = (|\bar\gamma'| - 1)\tau_L'`, and must come back to rest against a Gaussian barrier
of :math:`z^2 = (|\bar\gamma'|-1)^2(\tau_L' + \tau')` (stationary variance
:math:`\tau_L'^2/(\tau_L'+\tau')` of the velocity filtered through the viscous relaxation), which
takes about :math:`\tau_L' e^{z^2/2}/\max(z,1)` (an order of magnitude, not a bound).  Without
viscous damping (:math:`\tau_L = \infty`) and :math:`|\bar\gamma| \ge \Delta` there is no
stationary state at all: :func:`check_recurrent` refuses it.

The larger of the two predictions, times the steps (DI, :math:`1/h'`) or the noise jumps (PDMP,
:math:`\Lambda'`: every jump is an event) per :math:`\tau_0`, times N, is the predicted work, a lower
estimate of the run's work; :func:`check_work` refuses a run predicted to exceed
``max_work`` (default :data:`MAX_WORK`) with a message naming the parameters and the numbers.
Where the prediction is too low, the per-excursion bound (:func:`max_steps_per_excursion`)
truncates and reports instead.  It is far too low for strong noise with stiff damping
(:math:`\tau', \tau_L' \ll 1`: the particle sticks only where the velocity crosses zero while the
force is inside the friction window; measured (DI, default h, N = 200, seed 0, 0.2.7), 0.25, 0.21 and
0.16 :math:`\tau_0` at Fig. 3's :math:`\tau, \tau_L` and :math:`\Gamma = 10^3, 10^4, 10^5`, 4.2, 11 and
26 times the prediction, which there is the runaway floor's :math:`0.5/\sqrt{\tau_L'}` term), and no
floor in :math:`\tau_L/\tau` alone held on the measured points (README "Predicted work").  For fast noise
(:math:`\tau' \ll 1`) the passage sum vanishes while the cycles last several to tens of :math:`\tau_0` (a stuck
particle is released only where the force lies inside the friction window), so the prediction is floored there
too: the DI's regeneration cycle at :func:`di_cycle_floor` (from h/tau), the PDMP's long excursion (and the
long-excursion count's, :func:`~dryfric_jax.durations.le_duration_floor`) at :func:`le_floor`.  On the points
measured the DI's cycles still last 1.5-8 times the prediction undamped (median 2.6, 12 before the floor) and up
to 40 times with stiff damping; 32 further damped points (2026-12-07, default h, N = 400, seed 0, :math:`\tau' =
10^{-5}`-1, :math:`\tau_L' = 10^{-4}`-0.3) gave 1.17-58 times (58 at :math:`\tau' = \tau_L' = 10^{-4}`: 1.14
:math:`\tau_0` against 0.0196).  A damping factor in :math:`\tau_L'/\tau'` alone, which fitted the points at
:math:`\tau' \ge 10^{-3}`, failed there (at :math:`\tau' = 10^{-5}, \tau_L' = 10^{-4}` the cycles last 0.79
:math:`\tau_0`, not the 2.9 it gave), so the factor stays the conservative :math:`\tau_L'/(1 + \tau_L')`.  Where
the prediction is low the run projects itself from its rounds and warns early (:func:`dryfric_jax.api.time_left`).

float32
-------
The OU coefficients are computed in float64 and rounded once, but :math:`1 - m_2 = 1 - e^{-h/\tau}`
is what sets the noise's correlation time, and float32 rounds :math:`m_2` near 1 by up to
:math:`3\cdot 10^{-8}`: the stationary variance of X is then off by :math:`\sim 3\cdot10^{-8}\tau/h`
(1.3% at :math:`h/\tau = 10^{-6}`).  Velocity increments of size :math:`h'` must also stay far
above float32's resolution of :math:`V = O(1)`.  float32 is therefore used only for
:math:`h/\tau \ge` :data:`FLOAT32_MIN_H_OVER_TAU` and :math:`h' \ge` :data:`FLOAT32_MIN_H_ND`, and
for :math:`\tau' \ge` :data:`FLOAT32_MIN_TAU_ND` (the noise's stationary SD :math:`1/\sqrt{\tau'}` and
the regeneration's squared distances :math:`\sim 16/\tau'` must stay far inside float32's range,
3.4e38); elsewhere the DI runs in float64 and the result says so (:func:`float32_unsafe_reason`).
"""
from __future__ import annotations

import math
import sys

import numpy as np
from scipy import integrate, special

from .params import brief, rounded_bound

#: default cap on the lane-steps (DI) or events (PDMP) of one run: on a 2-core CPU ~15-25 min of DI
#: lane-steps (7e7-1.2e8 per second, float64, 0.2.5) or ~30-50 min of PDMP events (3.5e7-5.6e7 per
#: second; RESULTS.md, the times of Fig. 3), a few minutes on a GPU.  ``max_work`` / ``--max-work`` raises it.
MAX_WORK = 1e11
#: per-excursion bound in units of the excursion's time scale (see max_steps_per_excursion)
MAX_TIME_REL = 1.0e4
#: float32 only where its rounding of the OU decay 1 - e^{-h/tau} is below 3e-4 (relative) ...
FLOAT32_MIN_H_OVER_TAU = 1e-4
#: ... and where a step's velocity increment h' is > 100 float32 ulps of V = O(1)
FLOAT32_MIN_H_ND = 1e-5
#: ... and where X's stationary SD 1/sqrt(tau') is at most 1e15 (float32 overflows near 3.4e38)
FLOAT32_MIN_TAU_ND = 1e-30
#: the PDMP (no step h to bound it) in float32 only for tau_L' >= this: its velocities are of order
#: tau_L' and its 1/tau_L' overflows float32 below 2.9e-39 (measured: NaN at tau_L' = 3e-40, D 155x
#: too small at 1e-36; float32 and float64 agree to 1e-8 at 1e-30, same seed)
FLOAT32_MIN_TAU_L_ND = 1e-25
#: where the speeds sit in a few binades far from 1 (:func:`speed_scale`'s V_s > 2: a runaway, |gamma_bar'| > 1, near
#: tau_L'(|gamma_bar'| - 1), or |gamma_bar'| near 1 with a large tau_L'), float32 rounds each step's friction h' onto
#: V's grid alike, step after step, by up to ~2^-24 V_s/h' of it, against the net force F: float32 only where that
#: share, 2^-24 V_s/(h' F), is at most this (the PDMP: h' its mean time between events).  Audits (2026-12-07): M0_t
#: +0.23% (8 CIs) at tau_L' = 500, gamma_bar' = 11, h' = 0.01 (20.48 ulps of V ~ 5000 taken as 20); +0.27% at
#: tau_L' = 1000, 1.1, h' = 0.0109; +0.96% at 1e4, 0.999, 0.0109; the PDMP 1.1% low at 2000, 29 (its velocity noise
#: rounded away).  Where the speeds spread over binades near 1 (V_s <= 2) the roundings average out: h' >= 1e-5 there
FLOAT32_MAX_DRIFT_ROUNDING = 1e-3
#: no simulation below this tau_L': D ~ tau_L'^2 and the excursion sums behind the CI (U^4 ~
#: tau_L'^4) underflow float64 (measured, PDMP: CI 0 at tau_L' = 1e-80, D = 0 +- 0 at 1e-300; D/tau_L'^2
#: unchanged to 1e-14 from 1e-30 to 1e-70, same seed)
MIN_TAU_L_ND = 1e-60


def _int_erfcx(lo: float, hi: float) -> float:
    r"""log of :math:`\int_{lo}^{hi}\operatorname{erfcx}(u)\,du` for lo < hi (no overflow)."""
    if lo >= hi:
        return -math.inf
    if lo < -6.0:
        # erfcx(u) = 2 e^{u^2} - erfcx(-u) for u < 0, and the e^{u^2} part integrates to Dawson's
        # F(x) = e^{x^2} dawsn(x): 2 (F(|lo|) - F(|m|)), m = min(hi, 0).  What is left out, the
        # integral of erfcx(-u) <= 0.1 below -6 and of erfcx <= 1 above 0, is below 1e-14 of it.
        # (e^{lo^2}/|lo| alone was 1% high at -6 and 64% high with hi = -6.65 near lo = -6.72.)
        m = min(hi, 0.0)
        r = math.exp(m * m - lo * lo) * special.dawsn(-m) / special.dawsn(-lo)
        return lo * lo + math.log(2.0 * special.dawsn(-lo)) + math.log1p(-r)
    val, _ = integrate.quad(special.erfcx, lo, hi, limit=200)
    return math.log(val)


def log_ou_passage_time(a: float, b: float, tau: float) -> float:
    r"""log of the mean first-passage time of :math:`\tau dX = -X dt + \sqrt2 dW` from a to b.

    :math:`T = \tau\sqrt\pi\int_{u_b}^{u_a}\operatorname{erfcx}(u)\,du`, :math:`u = y\sqrt{\tau/2}`
    (for b < a; upwards by the symmetry X -> -X).  Returns -inf when a is already beyond b.
    """
    if b > a:
        a, b = -a, -b
    s = math.sqrt(tau / 2.0)
    return math.log(tau * math.sqrt(math.pi)) + _int_erfcx(b * s, a * s)


def log_duration_scale(tau: float, tau_L: float, gamma_bar: float) -> float:
    r"""log of the predicted mean excursion duration (in :math:`\tau_0`), module docstring.

    The OU passage part (the sum of both passage times, floored at :math:`\min(1, \tau_L')`) is
    a lower bound; the bias part (:math:`|\bar\gamma'| \ge 1`) an order of
    magnitude.  Arguments are the nondimensional :math:`\tau', \tau_L', \bar\gamma'`.
    """
    passage, drift = _log_passage_and_drift(tau, tau_L, gamma_bar)
    log_t = max(passage, math.log(min(1.0, tau_L)))
    g = abs(gamma_bar)
    if drift is not None:  # the slow deceleration near the runaway bias (module docstring)
        log_t = max(log_t, drift)
    if g >= 1.0 and math.isfinite(tau_L):
        z = (g - 1.0) * math.sqrt(tau_L + tau)
        log_t = max(log_t, math.log(tau_L) + 0.5 * z * z - math.log(max(z, 1.0)))
    return log_t


def _log_passage_and_drift(tau: float, tau_L: float, gamma_bar: float) -> tuple:
    r""":func:`log_duration_scale`'s two terms: the log of the OU passage part (both passage times) and of the slow
    deceleration near the runaway bias (None where :math:`|\bar\gamma'| \ge 1`)."""
    xp, xm = 1.0 - gamma_bar, -1.0 - gamma_bar
    passage = float(np.logaddexp(log_ou_passage_time(xp, xm, tau), log_ou_passage_time(xm, xp, tau)))
    g = abs(gamma_bar)
    return passage, (-math.log((1.0 - g) + 0.5 / math.sqrt(tau_L)) if g < 1.0 else None)


def log_predicted_duration(tau: float, tau_L: float, gamma_bar: float, min_duration: float = 0.0) -> float:
    r"""log of the predicted mean duration (in :math:`\tau_0`) that the work is predicted from:
    :func:`log_duration_scale`, or ``min_duration`` (:math:`\tau_0`) where that is longer (the long-excursion
    count's floor for fast noise, :func:`~dryfric_jax.durations.le_duration_floor`)."""
    log_t = log_duration_scale(tau, tau_L, gamma_bar)
    return max(log_t, math.log(min_duration)) if min_duration > 0.0 else log_t


#: :func:`le_floor`'s constant: below every C measured for the long-excursion count (0.40-15; 0.40 +- 0.11 the
#: least, :func:`~dryfric_jax.durations.le_duration_floor`), so that the floor stays a lower estimate
LE_FLOOR_C = 0.25
#: :func:`di_cycle_floor`: (least r = h/tau, largest r, floor in tau0 before the damping factor), largest first
DI_CYCLE_FLOORS = ((1e-2, 10.0, 8.0), (1e-3, math.inf, 3.0))


def le_floor(tau: float, tau_L: float) -> float:
    r"""A floor on the mean long excursion (threshold to threshold) for fast noise, in :math:`\tau_0`:
    :math:`C\,\min(1, \tau_L')/\sqrt{\tau'}`, :math:`C =` :data:`LE_FLOOR_C` (nondimensional arguments).  A stuck
    particle is released only where its velocity reaches 0 while the force lies inside the friction window, whose
    chance at such a moment falls with the noise's spread :math:`1/\sqrt{\tau'}`, so for :math:`\tau' \ll 1` the
    LEs grow like :math:`1/\sqrt{\tau'}` while :func:`log_duration_scale` stays at :math:`\min(1, \tau_L')`; the
    measurements are in :func:`~dryfric_jax.durations.le_duration_floor`.  It is the PDMP estimator's floor too
    (its cycles are these LEs) on fine grids: :func:`pdmp_cycle_floor`."""
    return LE_FLOOR_C * min(1.0, tau_L) / math.sqrt(tau)


#: :func:`pdmp_cycle_floor`: the PDMP's cycles are held to :func:`le_floor` only on grids this fine (nondimensional
#: delta', the friction window is 2 wide): on coarser ones a release needs the noise on one of the few grid levels
#: inside the window, and the cycles are shorter.  Measured (an audit, 2026-12-06; tau' = 1e-3, seeds 1-8,
#: N = 300-1000, in tau0 against le_floor's 7.91): 13.0 +- 3.7 and 10.8 +- 1.8 at delta' = 2 and 3, but 5.7 +- 0.85
#: at 5 and 1.6-3.2 at 7.09 (delta'_max 7.47), where the floor refused runs that then took a quarter of its
#: prediction; at tau' = 0.01, delta' = 2.24 1.05 times the floor.  At delta' = 1 (seed 11, N = 300-650, undamped and
#: tau_L' = 1): 2.22 and 1.39 times it at tau' = 0.01, 2.04 and 1.23 at 3e-3, 1.35 at 1e-3 (tau_L' = 1); at 0.5,
#: 2.61 (0.01, undamped; 2.22 at delta' = 1): finer grids lengthen the cycles.  So 0.5, with room; the default
#: delta' is at most 0.05.
PDMP_FLOOR_MAX_DELTA_ND = 0.5


def pdmp_cycle_floor(tau: float, tau_L: float, delta: float) -> float:
    r"""A floor on the PDMP estimator's mean cycle (a long excursion) for fast noise, in :math:`\tau_0`
    (nondimensional :math:`\tau', \tau_L', \delta'`): :func:`le_floor` for :math:`\delta' \le`
    :data:`PDMP_FLOOR_MAX_DELTA_ND`, none (0) on coarser grids, where a grid step of the order of the friction
    window's width changes the release itself."""
    return le_floor(tau, tau_L) if delta <= PDMP_FLOOR_MAX_DELTA_ND else 0.0


def di_cycle_floor(tau: float, tau_L: float, h: float) -> float:
    r"""A floor on the DI estimator's mean regeneration cycle for fast noise, in :math:`\tau_0` (nondimensional
    :math:`\tau', \tau_L', h'`), from :math:`r = h/\tau`:

    .. math::
        \frac{\tau_L'}{1 + \tau_L'} \times \begin{cases} 8 & 10^{-2} \le r \le 10 \\
        3 & 10^{-3} \le r < 10^{-2} \text{ or } r > 10 \\ 0 & r < 10^{-3} \end{cases}

    and, where :math:`r \le 10^{-2}`, at least :func:`le_floor`.  A cycle spans at least one long excursion
    (:mod:`~dryfric_jax.regeneration`), and with the noise resolved (:math:`r \le 10^{-2}`) those last :func:`le_floor`
    or longer.  At coarser steps the cycles depend on r more
    than on :math:`\tau'`: the noise integrated over a step is what must fall inside the friction window.
    Measured (2026-12-06, ``estimate_diffusivity``, seed 0, N = 200-800, CIs +-5-15%; :math:`\tau_L = \infty`,
    :math:`\bar\gamma = 0` unless said), the mean cycle in :math:`\tau_0`:

    * white at the step, :math:`r \ge 100`: 4.45-5.2 (:math:`\tau' = 10^{-7}`-:math:`10^{-6}`, :math:`h' =
      10^{-4}`-:math:`10^{-2}`), 5.7 (:math:`\tau' = 10^{-4}`), 8.3 (:math:`10^{-3}`);
    * :math:`r = 3`-30: 12.7-14.9 (:math:`\tau' = 10^{-5}`-:math:`10^{-3}`, r = 3, 10), 21.1 (0.01, r = 10), 8.9
      (:math:`10^{-3}`, r = 30);
    * :math:`r = 0.1`-1: 21-25 (:math:`\tau' = 10^{-5}`-0.1, r = 1), 19.5-40.6 (:math:`\tau' = 0.01`-1, r = 0.1),
      22-28 (:math:`\tau' = 0.03`), 24.8 (0.3, r = 0.33);
    * :math:`r = 0.01`-0.03: 11.8, 13.5, 37.3, 23.2 (:math:`\tau' = 0.1, 0.3, 0.01, 1`);
    * finer, where the cycle tends to one LE as :math:`h \to 0`: 6.9, 8.6, 10.9, 15.2 (:math:`\tau' = 0.1, 0.3,
      0.05, 1`, :math:`r = 10^{-3}`-:math:`3\cdot10^{-3}`), 5.7, 4.7-6.4, 10.8, 25.2, 11.2 (:math:`\tau' = 0.1, 0.3,
      0.03, 0.01, 1`, :math:`h' = 10^{-5}`-:math:`10^{-4}`);
    * damped, against the same point undamped: 0.84, 0.66-0.68, 0.48, 0.28-0.32 and 0.11-0.14 times at
      :math:`\tau_L' = 3, 1, 0.3, 0.1, 0.01` (the factor :math:`\tau_L'/(1+\tau_L')` is 0.75, 0.5, 0.23, 0.09,
      0.01);
    * a bias lengthens them: 18.8 (:math:`\bar\gamma' = 0.5`) and 79 (-0.9) at :math:`\tau' = 10^{-3}`, r = 10;
      6.0 and 26 at :math:`\tau' = 10^{-6}`.

    On these 65 points the mean cycle is 1.48-40 times the prediction (the larger of this floor and
    :func:`log_duration_scale`), 1.48-8.4 undamped at :math:`\tau' \le 0.1` (median 2.6); before the floor it was
    1.9-117 times, and 2.6-39 (median 11.8) there.  An audit's 136 runs elsewhere (2026-12-06, tau' = 1e-9-3,
    h/tau = 1e-5-1e6) found no cycle whose CI lies below the floor; the least ratios 1.29 (tau' = 1e-9, h' = 1e-5:
    3.88 +- 0.44 against 3; white at the step the cycle levels off at ~3.9-4.1 as h -> 0) and 1.32 (tau' = 0.25,
    r = 0.01: 10.5 +- 0.55 against 8)."""
    r = h / tau
    step = next((f for lo, hi, f in DI_CYCLE_FLOORS if lo <= r <= hi), 0.0)
    damp = tau_L / (1.0 + tau_L) if math.isfinite(tau_L) else 1.0
    return max(step * damp, le_floor(tau, tau_L) if r <= 1e-2 else 0.0)


def check_recurrent(tau_L: float, gamma_bar: float) -> None:
    """Refuse :math:`\\tau_L = \\infty` with :math:`|\\bar\\gamma| \\ge \\Delta` (nondimensional
    arguments): the particle runs away, D and M0 do not exist."""
    if math.isinf(tau_L) and abs(gamma_bar) >= 1.0:
        raise ValueError(
            f"gamma_bar must satisfy |gamma_bar| < Delta when tau_L = inf (got gamma_bar/Delta = {gamma_bar:.4g}): "
            "without viscous damping the bias beats the friction, the particle runs away and has no stationary "
            "state")


def tail_time_scale(tau: float, tau_L: float, gamma_bar: float, min_duration: float = 0.0) -> float:
    r"""Time scale of the excursion's tail (in :math:`\tau_0`): the largest of 1, :math:`\tau'`,
    the predicted duration (:func:`log_predicted_duration`, with ``min_duration``), and for
    :math:`|\bar\gamma'| < 1` the drift time :math:`\min(1/(1-|\bar\gamma'|)^2, \tau_L')` of a velocity
    excursion against a weak net friction."""
    g = abs(gamma_bar)
    drift = min(1.0 / (1.0 - g) ** 2, tau_L) if g < 1.0 else 1.0
    return max(1.0, tau, drift, math.exp(min(log_predicted_duration(tau, tau_L, gamma_bar, min_duration), 700.0)))


def max_steps_per_excursion(tau: float, tau_L: float, gamma_bar: float, steps_per_tau0: float,
                            cap: float = MAX_WORK, min_duration: float = 0.0) -> int:
    r"""Work bound of one excursion: :data:`MAX_TIME_REL` tail time scales (:func:`tail_time_scale`), in steps
    (events), at most ``cap``.  An excursion reaching it is closed, counted as truncated and reported."""
    want = MAX_TIME_REL * tail_time_scale(tau, tau_L, gamma_bar, min_duration) * steps_per_tau0
    want = math.ceil(want) if want < 2.0**62 else 2**62  # want may be inf (tau' or 1/h' huge)
    return int(max(64, min(want, cap, 2**62)))


def check_work(tau: float, tau_L: float, gamma_bar: float, steps_per_tau0: float, n_excursions: int,
               max_work: float = MAX_WORK, unit: str = "steps", min_duration: float = 0.0, lanes: int = 0) -> float:
    r"""Refuse (``ValueError``) a run whose predicted work exceeds ``max_work``; return the prediction.

    Predicted work = N x predicted duration (:func:`log_predicted_duration`: :func:`log_duration_scale`, or
    ``min_duration`` where that is longer) x ``steps_per_tau0``, N = max(``n_excursions``, ``lanes``): every lane
    finishes the excursion it is in, so a run closes about one per lane at least (the refusal then says to use fewer
    lanes).  Parameters whose excursions outlast float range are
    refused first, as :func:`check_duration_in_range` refuses them (the planner has done so already, before h or
    delta; this keeps the function safe on its own).
    """
    check_duration_in_range(tau, tau_L, gamma_bar)
    log_t = log_predicted_duration(tau, tau_L, gamma_bar, min_duration)
    by_lanes = lanes > n_excursions
    count = max(n_excursions, lanes)
    log_w = math.log(count) + log_t + math.log(steps_per_tau0)
    if log_w > math.log(max_work):
        # the reason: the largest of the three factors of the predicted work
        factors = {"n": math.log(count), "t": log_t, "steps": math.log(steps_per_tau0)}
        key = max(factors, key=factors.get)
        why = {"n": "many lanes (fewer lanes)" if by_lanes else "many excursions (lower N)",
               "steps": "each excursion needs many small steps (h or delta small against the excursion)",
               "t": _long_duration_reason(tau, tau_L, gamma_bar)}[key]
        # beyond float range no max_work (a finite number) allows the run: do not suggest raising it
        beyond = log_w > math.log(sys.float_info.max)
        head = f"max_work must be >= {_exp10(log_w)} {unit} for these parameters" + (
            ", beyond float range (no max_work allows them)" if beyond else f" (got {max_work:.3g})")
        # fewer lanes alone may not do: N excursions by themselves may be over max_work too (a review)
        n_alone = math.log(n_excursions) + log_t + math.log(steps_per_tau0) > math.log(max_work)
        less = ("use fewer lanes" + (" and lower N" if n_alone else "")) if by_lanes else "lower N"
        fix = (("Coarsen" if beyond else "Raise max_work (--max-work), coarsen")
               + f" h or delta, {less}, or use the white-noise theory when tau << tau0")
        many = (f"~{count} excursions (about one per lane: every lane finishes the excursion it is in, whatever "
                f"n_excursions = {n_excursions})" if by_lanes else f"{count} excursions")
        raise ValueError(
            f"{head}: {many} of predicted mean duration >= {_exp10(log_t)} tau0 at "
            f"{steps_per_tau0:.3g} {unit} per tau0 (tau' = {brief(tau, 3)}, tau_L' = {brief(tau_L, 3)}, "
            f"gamma_bar' = {brief(gamma_bar, 3)}); {why}.  {fix}")
    # accepted: log_w <= log(max_work) <= log(largest float), up to rounding, so exp cannot overflow
    return min(math.exp(min(log_w, math.log(max_work))), max_work)


def check_duration_in_range(tau: float, tau_L: float, gamma_bar: float) -> None:
    r"""Refuse (``ValueError``) parameters whose predicted mean excursion alone (:func:`log_duration_scale`) lasts
    past float range, > 1.8e308 :math:`\tau_0`: no method, h, delta, N or max_work makes such an estimate feasible.
    The PDMP's grid refusal said "use method 'di'" there, which the DI then refused too (an audit)."""
    log_t = log_predicted_duration(tau, tau_L, gamma_bar)
    if log_t > math.log(sys.float_info.max):
        raise ValueError(
            f"the parameters must give excursions of predicted mean duration < 1.8e308 tau0 (float range; got >= "
            f"{_exp10(log_t)} tau0 at tau' = {brief(tau, 3)}, tau_L' = {brief(tau_L, 3)}, "
            f"gamma_bar' = {brief(gamma_bar, 3)}); "
            f"{_long_duration_reason(tau, tau_L, gamma_bar)}.  No h, delta or N makes this run feasible" + (
                "; the white-noise theory ('dryfric theory') gives D when tau << tau0" if tau < 1.0 else ""))


def _long_duration_reason(tau: float, tau_L: float, gamma_bar: float) -> str:
    """Why :func:`log_duration_scale` predicts long excursions: its largest term.  "Slow weak noise" was said
    for every |gamma_bar'| < 1, also at tau' = 1e-6 near the runaway bias, where the drift sets the length (a
    hard-cases audit)."""
    passage, drift = _log_passage_and_drift(tau, tau_L, gamma_bar)
    if drift is None:
        return "the bias |gamma_bar| >= Delta keeps the particle moving"
    if drift > passage:
        return ("the bias |gamma_bar| close to Delta, with weak damping, keeps the particle drifting (near the "
                "runaway bias |gamma_bar| = Delta)")
    return "the noise rarely reaches the far threshold (slow weak noise: tau large against tau0)"


def refuse_known_work(work: float, max_work: float, unit: str, what: str, fix: str, hint: str = "") -> None:
    """Refuse (``ValueError``) a run whose work is known before it starts (paths, brute force: paths x steps)
    beyond ``max_work``: "max_work must be >= <work, rounded up> <unit> for <what> (got <max_work><hint>); <fix>".
    The estimator's work is predicted, not known: :func:`check_work`."""
    if work > max_work:
        raise ValueError(f"max_work must be >= {rounded_bound(work, lower=True, digits=3)} {unit} for {what} "
                         f"(got {max_work:.4g}{hint}); {fix}")


def _exp10(log_x: float) -> str:
    """``exp(log_x)`` as text, also far beyond float range ("2.5e1234", "10^(1.9e+300)"), rounded
    up: it states a lower bound ("max_work must be >= ...", a duration ">= ..."), and a max_work copied
    from the message must be accepted (rounded to nearest, 54 of 200 were refused again).  Where ``log_x`` itself
    overflowed (inf: a bias of 1e160 Delta), "10^(1.79e+308)", a lower bound still (it said "inf": an audit)."""
    e = log_x / math.log(10.0)
    if e <= 15:  # accepted as max_work where its log is >= log_x (check_work compares logs)
        s = f"{math.exp(log_x):.3g}"
        return s if math.log(float(s)) >= log_x else rounded_bound(math.exp(log_x), lower=True, digits=3)
    if not math.isfinite(e):
        return f"10^({rounded_bound(sys.float_info.max, lower=False, digits=3)})"
    if e >= 1e6:
        return f"10^({rounded_bound(e, lower=True, digits=3)})"
    m, k = math.ceil(10 ** (e - math.floor(e)) * 10) / 10, int(math.floor(e))
    if m >= 10:  # a mantissa of 9.95... rounds up: "1e16", not "10e15"
        m, k = 1.0, k + 1
    return f"{m:g}e{k}"


def check_simulable(tau_L: float, tau_L_s: float, tau0: float) -> None:
    r"""Refuse a simulation at :math:`\tau_L' <` :data:`MIN_TAU_L_ND` (``tau_L`` nondimensional,
    ``tau_L_s`` and ``tau0`` in seconds, for the message)."""
    if tau_L < MIN_TAU_L_ND:
        raise ValueError(
            f"tau_L must be >= {MIN_TAU_L_ND:g} tau0 = {rounded_bound(MIN_TAU_L_ND * tau0, lower=True, digits=3)} s "
            f"for a simulation (got tau_L = "
            f"{tau_L_s:.3g} s, tau_L/tau0 = {tau_L:.3g}): D ~ tau_L^2 there, and the excursion sums behind its CI "
            "(U^4 ~ (tau_L/tau0)^4) underflow float64, collapsing the CI to 0")


def speed_scale(tau_L: float, gamma_bar: float) -> tuple[float, float]:
    r"""``(V_s, F)``: the speeds' scale (in :math:`v_0`) and the net force against them (in :math:`\Delta`):
    :math:`V_s = \max(\tau_L'(|\bar\gamma'| - 1), \sqrt{\tau_L'})` in a runaway (:math:`|\bar\gamma'| > 1`,
    where the speed settles), else :math:`\min(1/(1 - |\bar\gamma'|), \sqrt{\tau_L'})` (the stationary law's
    width, inf at :math:`|\bar\gamma'| = 1` with :math:`\tau_L = \infty`); :math:`F = \min(1, \max(||\bar\gamma'| - 1|,
    1/\sqrt{\tau_L'}))`."""
    g = abs(gamma_bar)
    if g > 1.0:  # at least the width sqrt(tau_L') just above 1 (a review: 1 + 1e-4 kept float32 at +0.5%)
        vs = max(tau_L * (g - 1.0), math.sqrt(tau_L))
    else:
        vs = min(1.0 / (1.0 - g) if g < 1.0 else math.inf, math.sqrt(tau_L))
    return vs, min(1.0, max(abs(g - 1.0), 1.0 / math.sqrt(tau_L)))


def _drift_rounding_reason(step: float, what: str, tau_L: float, gamma_bar: float) -> str | None:
    vs, f = speed_scale(tau_L, gamma_bar)
    share = 2.0**-24 * vs / (step * f) if f > 0 else math.inf
    if vs > 2.0 and share > FLOAT32_MAX_DRIFT_ROUNDING:
        return (f"{what} = {step:.3g} tau0 against speeds ~{vs:.3g} v0 and a net force {f:.3g} Delta "
                f"(tau_L' = {tau_L:.3g}, gamma_bar' = {gamma_bar:.3g}): float32 rounds each step's friction onto "
                f"V's grid alike, by ~{share:.2g} of that force > {FLOAT32_MAX_DRIFT_ROUNDING:g} (M0_t 0.23-0.96% "
                "off where audited)")
    return None


def pdmp_float32_unsafe_reason(tau_L: float, rate: float | None = None, gamma_bar: float = 0.0) -> str | None:
    r"""Why float32 is not safe for the PDMP at this :math:`\tau_L'` and jump rate
    :math:`\Lambda' = 2/(\tau'\delta')^2` (None if it is).  The mean time between events,
    :math:`1/\Lambda'`, is held to the DI's bound on :math:`h'` (:data:`FLOAT32_MIN_H_ND`): a shorter one
    makes the velocity increments of order :math:`1/\Lambda'` round away.  Measured (a PDMP audit, float32
    against float64 arithmetic on the same float32 uniforms, :math:`\tau' = 1, \tau_L' = 10,
    \bar\gamma' = 3`, 4 paths of 10 :math:`\tau_0`): U off by 1.0% (every path low) at
    :math:`1/\Lambda' = 5\cdot10^{-7}`, 4e-5 at 1e-5, 2.7e-6 at 1e-4.  Where the speeds sit far from 1 it must also
    keep the friction's rounding under :data:`FLOAT32_MAX_DRIFT_ROUNDING` of the net force (:func:`speed_scale`)."""
    if tau_L < FLOAT32_MIN_TAU_L_ND:
        return (f"tau_L/tau0 = {tau_L:.3g} < {FLOAT32_MIN_TAU_L_ND:g}: the velocities, of order tau_L/tau0, "
                "near float32's smallest numbers")
    if rate is not None and 1.0 / rate < FLOAT32_MIN_H_ND:
        return (f"mean time between events (tau delta)^2/2 = {1.0 / rate:.3g} tau0 < {FLOAT32_MIN_H_ND:g} tau0: "
                "velocity increments near float32 resolution (U 1% low at 5e-7 tau0)")
    return None if rate is None else _drift_rounding_reason(1.0 / rate, "mean time between events (tau delta)^2/2",
                                                             tau_L, gamma_bar)


def _percent(x: float) -> str:
    """``x`` as a percentage to 2 significant digits, without an exponent: "0.045%", "3%", "30000%" (a ".1%"
    format said 0.0% near the float32 bound, a ".2g" one 3e+04%)."""
    p = 100 * x
    return f"{p:.2g}%" if p < 100 else f"{p:.0f}%"


def float32_unsafe_reason(h_over_tau: float, h_nd: float, tau_nd: float = 1.0, tau_L: float = math.inf,
                          gamma_bar: float = 0.0) -> str | None:
    r"""Why float32 is not safe for the DI at this step and :math:`\tau'` (None if it is); module
    docstring.  Where the speeds sit far from 1, h' must also keep the friction's rounding under
    :data:`FLOAT32_MAX_DRIFT_ROUNDING` of the net force (:func:`speed_scale`)."""
    if h_over_tau < FLOAT32_MIN_H_OVER_TAU:
        return (f"h/tau = {h_over_tau:.3g} < {FLOAT32_MIN_H_OVER_TAU:g}: float32 rounds the OU decay "
                f"1 - exp(-h/tau) by up to {_percent(3e-8 / h_over_tau)}")
    if h_nd < FLOAT32_MIN_H_ND:
        return f"h/tau0 = {h_nd:.3g} < {FLOAT32_MIN_H_ND:g}: velocity increments near float32 resolution"
    if tau_nd < FLOAT32_MIN_TAU_ND:
        return (f"tau/tau0 = {tau_nd:.3g} < {FLOAT32_MIN_TAU_ND:g}: the noise's stationary SD "
                f"{1 / math.sqrt(tau_nd):.3g} nears float32's range")
    return _drift_rounding_reason(h_nd, "h", tau_L, gamma_bar)
