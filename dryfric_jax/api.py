"""Public entry points: ``estimate_diffusivity`` (long excursions) and ``bruteforce_diffusivity``.

Both take physical :class:`~dryfric_jax.params.Params`, simulate the nondimensional DI chain or the
PDMP (``method``) and return physical numbers (D in m^2/s, M0 in m/s, durations in s) with 95% CIs.
"""
from __future__ import annotations

import math
import numbers
import time
import warnings
from dataclasses import MISSING, asdict, dataclass, field, fields

import jax
import numpy as np

from ._version import __version__
from .bruteforce import simulate_bruteforce
from .di import make_di_model
from .estimators import (
    MAX_PATHS, MIN_PATHS, MIN_RELIABLE_N, MIN_RELIABLE_PATHS, WEAK_DAMPING_TAU_L, bruteforce_estimates,
    long_excursion_estimates, near_runaway_note, rounding_note,
)
from .excursions import BLOCK, MAX_LAYOUT
from .rounds import (_ABANDON, FINAL_DEADLINE, INTERRUPT_GRACE_S, after_run, noted_late, simulate_long_excursions,
                     work_per_excursion)
from .limits import MAX_WORK, refuse_known_work
from .live import fit_text, live_progress, status_line, terminal_columns  # noqa: F401  (re-exported)
from .outfiles import dumps
from .params import Params, check_positive, real_or_none, require_x64, rounded_bound
from .pdmp import make_pdmp_model, simulate_pdmp_bruteforce
from . import theory
from .plan import (  # noqa: F401  (default_h, h_max, check_h, METHODS are part of the API)
    DTYPES, MAX_COUNT, METHODS, Plan, check_count, check_h, check_layout, check_max_time, check_max_work,
    check_method, check_rtol, choose, default_h, h_max, plan_estimate, scalar, shown,
)

class DryfricWarning(UserWarning):
    """A result that should be read with care (too few excursions, truncated excursions)."""


#: brute force (DI): a horizon t that whole steps of h miss by more than this share is said
HORIZON_RTOL = 0.01
#: brute force: a horizon t under this many correlation times (:func:`correlation_time`) is warned about
#: (D_t's O(1/t) bias; Fig. 8's brute force agreed with the long excursions wherever t >= 100 tau0)
MIN_HORIZON = 100


def correlation_time(params: Params) -> float:
    r"""The velocity's correlation time scale that sets brute force's horizon bias, s:

    .. math::
        \tau_c = \max\big(\min(\tau_0/(1 - |\bar\gamma'|)^2,\ \tau_L),\ \tau\big)

    (the noise's memory, or the friction's and the damping's relaxation, whichever is longer;
    :math:`\tau_0/(1 - |\bar\gamma'|)^2` is the excursions' time scale against the bias, infinite
    for :math:`|\bar\gamma'| \ge 1`, where only the damping bounds it).  White noise, tau_L = inf: the bias
    coefficient b (:math:`D^t = D(1 - b/t)`) is 27/5 tau0 at gamma_bar' = 0, 22.1 at 0.5 and 575 at 0.9
    (:func:`~dryfric_jax.theory.horizon_bias`, exact), 4.8 to 5.75 of these :math:`\tau_c`."""
    g = abs(params.gamma_bar_nd)
    relax = params.tau0 / (1.0 - g) ** 2 if g < 1.0 else math.inf
    return max(min(relax, params.tau_L), params.tau)


#: brute force's D_t: its O(1/t) bias b/t, b in correlation times, from rest and after a burn-in of D_BURN_IN_TAU_C
#: tau_c: the largest exact white-noise, tau_L = inf values over gamma_bar' (theory.horizon_bias: 23/4 tau_c as
#: |gamma_bar'| -> 1, 27/5 at 0; 14/5 at 0), an upper estimate (measured ~1.3 tau_c with damping at Fig. 3's point)
D_BIAS_TAU_C, D_BIAS_BURNT_TAU_C, D_BURN_IN_TAU_C = 5.75, 2.8, 20.0
#: what colored noise adds to those coefficients, per unit of min(tau', 1): an audit (2026-12-07, DI, gamma_bar = 0,
#: tau_L = inf, 16384 paths x 12-40 seeds, paired against white noise) measured b = 5.70-5.86 tau_c at tau' = 0.1-0.2,
#: 5.93 +- 0.09 at 0.3 (above 5.75), 6.29 at 0.5, 6.94 at 1 from rest, and after the burn-in 2.7-2.9 tau_c up to
#: tau' = 0.5, 3.17 +- 0.18 at 0.7 and 3.18 +- 0.19 at 1 (above 2.8); from tau' = 0.5 without the burn-in
#: :func:`colored_start_note` quotes its own, larger bound
D_BIAS_COLORED, D_BIAS_BURNT_COLORED = 2.0, 1.0
#: the exact white-noise coefficients at gamma_bar = 0, in tau0 (:func:`short_horizon_note` quotes them)
_BIAS_REST_0, _BIAS_STAT_0 = theory.horizon_bias(1.0, 1.0), theory.horizon_bias(1.0, 1.0, stationary=True)
#: brute force's bias notes (:func:`d_bias_note`, :func:`m0_lag_note`) are said where the bias they estimate
#: exceeds this share of the CI half-width (a Gaussian 95% interval then covers ~0.93)
BIAS_SHARE_OF_CI = 0.2


def short_horizon_note(params: Params, t: float) -> str | None:
    r"""The warning for a brute-force horizon :math:`t < 100\,\tau_c` (:func:`correlation_time`),
    None for a longer one.  :math:`\hat D^t` estimates :math:`D^t = D - b/t + o(1/t)`, b > 0: with
    white noise and :math:`\tau_L = \infty`, :math:`D^t = D(1 - 5.4\,\tau_0/t) + o(1/t)` from rest at
    :math:`\bar\gamma = 0` (:func:`~dryfric_jax.theory.horizon_bias`, exact to exponentially small terms: the
    coefficient t(1 - D^t/D) is 5.35 at t = 20 tau0, 4.86 at 10; an audit measured -91% at t = 2 tau0,
    -27% at 20, -3.4% at 200, -1.5% at 1000, where the CIs covered the exact D in 0%, 6%, 84% and 92% of
    runs), about half of it from the start at V = 0, which a burn-in of ~20 tau0 removes (14/5 tau0 left); at
    :math:`\bar\gamma' = 0.9`, -97%, -53% and -3% measured at t = 100, 1000 and 10^4 tau0
    (:math:`\tau_c = 100\,\tau_0`, b = 575 tau0)."""
    tc = correlation_time(params)
    if t >= MIN_HORIZON * tc:
        return None
    return (f"t = {t:.4g} s is {t / tc:.3g} < {MIN_HORIZON} correlation times tau_c = max(min(tau0/(1 - "
            f"|gamma_bar'|)^2, tau_L), tau) = {tc:.3g} s: D_t is biased by O(tau_c/t), which its CI does not "
            f"include (low from a white-noise start, tau_L = inf: D_t = D (1 - {_BIAS_REST_0:g} tau0/t) from rest at "
            f"gamma_bar = 0, D (1 - {_BIAS_STAT_0:g} tau0/t) after a burn_in of {D_BURN_IN_TAU_C:g} tau0; -53% at "
            "t = 10 tau_c, gamma_bar' = 0.9); raise t, add burn_in, or use estimate_diffusivity, which has no horizon "
            "bias")


def d_bias_note(params: Params, t: float, burn_in: float, d_t: float, d_ci: float) -> str | None:
    r"""The warning for brute force's :math:`\hat D^t` whose O(1/t) bias may exceed a fifth of its CI half-width, None
    otherwise; for horizons past :data:`MIN_HORIZON` :math:`\tau_c`, shorter ones having :func:`short_horizon_note`
    (the caller asks this one only where that one was not said: it checks the horizon asked for, this the one
    simulated, whole steps of h, which may fall just under: t = 100 at h = 0.03 ran 99.99, and neither was said).
    :math:`D^t \approx D(1 - b/t)` with :math:`b \le` :data:`D_BIAS_TAU_C` :math:`\tau_c` from rest
    (:data:`D_BIAS_BURNT_TAU_C` after a burn-in of :data:`D_BURN_IN_TAU_C` :math:`\tau_c`), the largest exact
    values with white noise and :math:`\tau_L = \infty` (:func:`~dryfric_jax.theory.horizon_bias`), plus
    :data:`D_BIAS_COLORED` (:data:`D_BIAS_BURNT_COLORED`) :math:`\min(\tau', 1)\,\tau_c`, what colored noise added in
    an audit, quoted as a share of D (:math:`D_t/(1 - b/t)`: 6% more at 100 :math:`\tau_c`); less
    with damping (0-4 :math:`\tau_c` measured at colored, damped points, ~1.3 at Fig. 3's), so it is an upper
    estimate where this note is said: not with colored noise (tau' >= 0.5) started at the threshold
    (:func:`colored_start_note`, said instead; an audit measured 7.1 :math:`\tau_c` at tau' = 1 and 3 without
    damping).  The bias does not shrink with N' and the half-width does not depend on t: an audit (2026-12-07)
    found 10^4 paths at t = 100 :math:`\tau_0` (white noise, :math:`\tau_L = \infty`) covering the exact D in 28%
    of runs (D_t = 9.36 +- 0.37 against 10), silently.  Never where the CI is 0 (its own note)."""
    tc = correlation_time(params)
    burnt = burn_in >= D_BURN_IN_TAU_C * tc
    coef = (D_BIAS_BURNT_TAU_C if burnt else D_BIAS_TAU_C) + (
        D_BIAS_BURNT_COLORED if burnt else D_BIAS_COLORED) * min(params.tau_nd, 1.0)
    # b/t of D, not of D_t = D (1 - b/t): 6% more at t = 100 tau_c (an audit)
    bias = coef * tc / t * abs(d_t) / (1.0 - min(coef * tc / t, 0.5))
    if not d_ci > 0 or not bias > BIAS_SHARE_OF_CI * d_ci:
        return None
    return (f"D_t is biased low by O(tau_c/t) also at t = {t / tc:.3g} tau_c: by up to ~{coef:.3g} tau_c/t D ~ "
            f"{bias:.2g} m^2/s here (tau_c = {tc:.3g} s; "
            "the largest value with white noise and tau_L = inf, where b is known exactly, plus what colored noise "
            f"added in an audit; measured less with damping), against its CI half-width {d_ci:.2g}, which does not "
            "include it (it shrinks with more paths, the bias does not); "
            f"t >= {bias / (BIAS_SHARE_OF_CI * d_ci) * t:.3g} s brings it under a fifth of the half-width, or use "
            "estimate_diffusivity, which has no horizon bias")


#: brute force's paths start as the paper's Algorithm 2 does, at rest with the noise at its up-threshold x+ =
#: (Delta - gamma_bar)/sqrt(Gamma) (the PDMP's one grid level above it, sliding); from this tau' on that start is
#: said to bias D_t (:func:`colored_start_note`), by up to START_D_TAU_C tau_c/t |D_t| (the largest an audit
#: measured: b = -67 +- 12 tau_c at tau' = 10, gamma_bar = 0)
COLORED_START_TAU_ND, START_D_TAU_C = 0.5, 70.0
#: the offset c u0 that start gives E[U(t)] (:func:`m0_lag_note`), at every tau': c <= min(tau', 1) (|1 - gamma_bar'|
#: + START_GRID_LEVELS delta') (delta' the PDMP's grid step, 0 for the DI).  Measured (2026-12-07, gamma_bar = 0,
#: tau_L = inf, 2^18-2^20 paths at t = 20 tau_c): the DI 0.013 +- 0.012 at tau' = 0.03, 0.065 +- 0.011 at 0.1, 0.14 at
#: 0.2, 0.18-0.21 at 0.3, 0.31 at 0.5, 0.48-0.51 at 1, 0.68 at 3, 0.34 at 10 (less with damping: 0.03-0.09 at
#: tau_L' = 0.5); the PDMP 0.16 +- 0.02 at tau' = 0.1, delta' = 0.5, 0.35-0.41 at tau' = 0.45, delta' = 0.33
START_GRID_LEVELS = 3.0


def _start_nd(params: Params, delta_nd: float | None) -> float:
    """Where brute force's paths start the noise, nondimensional (x+' = 1 - gamma_bar'; the PDMP at x_{k+ + 1} =
    (k+ + 1) delta', its grid level above x+)."""
    if delta_nd is None:
        return 1.0 - params.gamma_bar_nd
    from .pdmp import grid_offsets

    return (grid_offsets(delta_nd, params.gamma_bar_nd)[0] + 1) * delta_nd


def start_offset(params: Params, delta_nd: float | None = None) -> float:
    r"""The bound :math:`c` on the offset :math:`c\,u_0` of brute force's :math:`E[U(t)]` from its start at rest
    with the noise at its threshold, in :math:`u_0`: :math:`\min(\tau', 1)(|1 - \bar\gamma'| + 3\delta')`
    (:data:`START_GRID_LEVELS`; ``delta_nd`` the PDMP's grid step :math:`\delta'`, None for the DI).  The start
    pushes every path alike for ~tau (an impulse ~ x+ tau); an upper estimate from measurements, ~1.5x the DI's at
    tau' <= 0.3 (0.65 tau' measured)."""
    return min(params.tau_nd, 1.0) * (abs(1.0 - params.gamma_bar_nd) + START_GRID_LEVELS * (delta_nd or 0.0))


def colored_start_note(params: Params, t: float, burn_in: float, d_t: float, d_ci: float, *,
                       delta_nd: float | None = None) -> str | None:
    r"""The warning for brute force's :math:`\hat D^t` where its start with colored noise may bias it beyond a fifth
    of its CI (``t``, ``burn_in`` s, ``d_t``, ``d_ci`` m^2/s: the run's; ``delta_nd`` the PDMP's grid step
    :math:`\delta'`, None for the DI), None where :math:`\tau' <` :data:`COLORED_START_TAU_ND`, ``burn_in`` >=
    :data:`D_BURN_IN_TAU_C` :math:`\tau_c`, or :data:`START_D_TAU_C` :math:`\tau_c/t\,|D_t|` is under a fifth of the
    CI.  The paths start at V = 0 with X at the up-threshold :math:`x_+` (the paper's Algorithm 2, section 5.2; the
    PDMP at :math:`x_{k_++1}`, sliding), :math:`|x_+'| \sqrt{\tau'}` of X's stationary SDs out: with white noise X
    forgets it at once, with colored noise it pushes every path alike for ~tau, which biases D_t by O(1/t) of either
    sign, beyond what :func:`d_bias_note` (not said with this one) quotes.  An audit (2026-12-07, tau_L = inf unless
    said, no burn-in): D_t 67% high at t = 100 tau_c (+6 SE; tau' = 10, gamma_bar' = 0), b = 7.1 tau_c > 5.75 at tau'
    = 1 and 3 (gamma_bar' = 0 and -0.5).  A burn-in of 20 tau_c removed it at every point audited.  Its offset of
    M0_t is :func:`m0_lag_note`'s, at every tau'."""
    tc = correlation_time(params)
    if params.tau_nd < COLORED_START_TAU_ND or burn_in >= D_BURN_IN_TAU_C * tc:
        return None
    d_bias = START_D_TAU_C * tc / t * abs(d_t)
    if not d_bias > BIAS_SHARE_OF_CI * d_ci:
        return None
    sds = abs(_start_nd(params, delta_nd)) * math.sqrt(params.tau_nd)
    where = "x+ = (Delta - gamma_bar)/sqrt(Gamma)" + ("" if delta_nd is None else ", the PDMP one grid level above it")
    return (f"the paths start at rest with the noise at its threshold {where} (the paper's Algorithm 2), {sds:.2g} of "
            f"its stationary SDs out: with colored noise (tau/tau0 = {params.tau_nd:.3g}) that start biases D_t by "
            f"O(tau_c/t) of either sign, here by up to ~{d_bias:.2g} m^2/s (the largest measured: {START_D_TAU_C:g} "
            f"tau_c/t |D_t|), against its CI half-width {d_ci:.2g}, which does not include it (an audit: D_t 67% high "
            f"at t = 100 tau_c, tau/tau0 = 10); add burn_in >= {D_BURN_IN_TAU_C:g} tau_c = {D_BURN_IN_TAU_C * tc:.3g} "
            "s, which removed it wherever audited, or use estimate_diffusivity, which has no such bias")


#: brute force's M0_t from rest: the lag of E[U(t)] behind M0 t, in correlation times (an audit, 2026-12-07: 2.9
#: tau_c at tau' = tau_L' = 3, gamma_bar' = -0.7; with white noise and tau_L = inf exactly (3 + gamma_bar'^2)/(1 +
#: |gamma_bar'|)^2 <= 3, theory.m0_lag), and the burn-in (in tau_c) after which it was gone
M0_LAG_TAU_C, M0_BURN_IN_TAU_C = 3.0, 20.0


def m0_lag_note(params: Params, t: float, burn_in: float, m0_t: float, m0_ci: float, *,
                delta_nd: float | None = None) -> str | None:
    r"""The warning for brute force's :math:`\hat M_0^t` where its start at rest with the noise at its threshold
    may bias it beyond a fifth of its CI half-width, None otherwise (``delta_nd``: the PDMP's grid step, None for
    the DI).  :math:`E[U(t)] \approx M_0 (t - L) + c\,u_0`, so :math:`M_0^t` is off by :math:`(c\,u_0 - M_0 L)/t`,
    which its CI, of order :math:`\sqrt{D/(t N')}`, does not include, and which more paths make larger against it:

    * the lag L, a few correlation times (:func:`correlation_time`), from V = 0: an audit (2026-12-07) measured
      :math:`L \approx 2.9\,\tau_c` (:math:`\tau' = \tau_L' = 3, \bar\gamma' = -0.7`, 4000 paths at t = 100
      :math:`\tau_c`: M0_t 2.5-3.3% toward 0, 4.8-6.3 SE, at 3 seeds; -2.6 to -4.2 SE at white-noise points); with
      white noise and :math:`\tau_L = \infty` exactly :math:`L = (3 + \bar\gamma'^2)/(1 + |\bar\gamma'|)^2\,\tau_c
      \le 3\,\tau_c` (:func:`~dryfric_jax.theory.m0_lag`).  Quoted as :data:`M0_LAG_TAU_C` :math:`\tau_c |M_0|/t`,
      with :math:`|M_0|` taken as :math:`|\hat M_0^t|` and at most that (t under 3 tau_c); not at
      :math:`\bar\gamma = 0`, where :math:`M_0 = 0` by symmetry (it fired there on noise: a hard-cases audit);
    * the offset :math:`c\,u_0` of X's start at the threshold, which colored noise remembers (:func:`start_offset`:
      :math:`c \le \min(\tau', 1)(|1 - \bar\gamma'| + 3\delta')`), quoted as :math:`c\,u_0/\max(t, \tau_c)`.  Audits
      (2026-12-07) found M0_t 3.9 CI from its exact 0 at tau' = 0.3, 262144 paths, t = 30 tau_c, unsaid (this note
      skipped gamma_bar = 0, and the colored start's note tau' < 0.5), and at tau' = 0.5, gamma_bar' = -0.5 a bias
      10x what the colored start's note, said instead of this one, quoted.

    Said where ``burn_in`` < :data:`M0_BURN_IN_TAU_C` :math:`\tau_c` (which removed both wherever audited) and their
    sum exceeds a fifth of the CI half-width."""
    tc = correlation_time(params)
    if burn_in >= M0_BURN_IN_TAU_C * tc:
        return None
    lag = 0.0 if params.gamma_bar == 0 else min(M0_LAG_TAU_C * tc / t, 1.0) * abs(m0_t)
    c = start_offset(params, delta_nd)
    offset = c * params.u0 / max(t, tc)
    if not lag + offset > BIAS_SHARE_OF_CI * m0_ci:
        return None
    return (f"M0_t is biased by O(tau_c/t): the paths start at rest with the noise at its threshold, so E[U(t)] ~ "
            f"M0 (t - L) + c u0, by up to ~{lag + offset:.2g} m/s here (tau_c = {tc:.3g} s): the lag "
            f"~min({M0_LAG_TAU_C:g} tau_c/t, 1) |M0| ~ {lag:.2g} m/s (measured: 2.5-3.3% low at t = 100 tau_c) "
            f"and the offset c u0/max(t, tau_c) ~ {offset:.2g} m/s (c <= {c:.2g}: min(tau/tau0, 1) (|1 - gamma_bar'| + "
            f"3 delta'), measured up to 0.68), against its CI half-width {m0_ci:.2g}, which does not include them; add "
            f"burn_in >= {M0_BURN_IN_TAU_C:g} tau_c = {M0_BURN_IN_TAU_C * tc:.3g} s, or use estimate_diffusivity, "
            "which has no such bias")


#: the notes of an estimate whose excursions were truncated, by cause (the CLI names the option
#: that helps from them): the final round's deadline (2 max_time) or the work bound max_steps
FINAL_CUT = "the final round, which finishes the excursions in flight, was cut"
CUT_NOTE = f"{FINAL_CUT} at"  # by max_time's deadline (the CLI's --max-time hint looks for it)
BOUND_NOTE = "hit the work bound"
#: with weak damping, a run that the precision target ended (README "Confidence intervals": an audit's 2000 + 1000
#: replicates against the exact chain law, white noise, tau_L = inf, b = 0, rtol 0.15 and 0.10 after 1000)
TARGET_STOP_NOTE = ("the run stopped when the rtol target was met, so N depends on the data; with weak damping that "
                    "favours samples lacking the rare long excursions (measured at tau_L = inf, b = 0: D 1.9% low, "
                    "CI coverage 0.90 at N ~ 8e3 (rtol 0.15); 0.9% low, 0.92 at N ~ 2e4 (rtol 0.1); at a fixed N "
                    "0.2% low, 0.93-0.94): a fixed n_excursions avoids it")


class NoEstimateError(RuntimeError):
    """A run ended without an estimate: fewer than 2 complete excursions within its work bounds
    (``max_work``, ``max_steps``, ``max_time``).  Without ``max_time`` it is deterministic: the same
    seed and settings end the same way, so a sweep records the point as failed and does not rerun it.
    ``stopped_by`` says what ended the rounds (``"max_time"``: a longer time limit may succeed)."""

    def __init__(self, message: str, stopped_by: str = "work_bound"):
        super().__init__(message)
        self.stopped_by = stopped_by


class ProjectionWarning(DryfricWarning):
    """Said while a run is going (max_work is projected to end it early): not in the result,
    which says what did happen."""


class FileWarning(DryfricWarning):
    """About a results file as it was read (a last line a kill cut short, skipped): said at once, as it is in no
    result."""


class SmallSampleWarning(DryfricWarning):
    """N (or n_paths) below the size where the delta-method CI is calibrated.  Its own category so that a
    sweep at small N can silence it alone, ``warnings.simplefilter("ignore", dj.SmallSampleWarning)``,
    and still see the warnings that matter more (truncated excursions, the float64 fallback, weak damping,
    the runaway bias).  Each point's N is in the text, so Python's once-per-text rule showed it at every
    point of a sweep."""


def category(note: str) -> type:
    """The warning class a result's note is issued with: :class:`SmallSampleWarning` for the small-N
    and small-n_paths notes, :class:`DryfricWarning` for every other."""
    return SmallSampleWarning if note.startswith(("n_excursions = ", "n_paths = ")) and " < " in note \
        and "under-covers" in note else DryfricWarning


def small_n_note(n: int) -> str:
    """The warning for N below :data:`MIN_RELIABLE_N` (estimates and pooled estimates)."""
    return (f"n_excursions = {n} < {MIN_RELIABLE_N}: the delta-method CI under-covers at this size "
            "(heavy-tailed excursions)")


#: seeds are integers in [0, MAX_SEED] (jax.random.key takes a signed 64-bit seed; the figures add
#: offsets below 2^20 to theirs)
MAX_SEED = 2**62
#: the largest seed of the figures, which add offsets below 2^20 (the CLI takes the same range)
MAX_FIGURE_SEED = MAX_SEED - 2**20


def check_seed(seed, hi: int = MAX_SEED, hi_text: str = "2^62") -> int:
    """``seed`` as an int (a numpy integer or a 0-d array too); ``ValueError`` naming it unless it
    is an integer in [0, ``hi``]."""
    seed = scalar(seed)
    if isinstance(seed, (bool, np.bool_)) or not isinstance(seed, numbers.Integral) or not 0 <= seed <= hi:
        raise ValueError(f"seed must be an integer in [0, {hi_text}] (got {shown(seed)})")
    return int(seed)


def check_progress(progress, name: str = "progress", live: bool = True) -> None:
    """``ValueError`` unless ``progress`` (the argument ``name``) is a callable or None, or where ``live``, True (a
    live status line, :func:`~dryfric_jax.live.live_progress`) or False (checked before the first round, not called
    there)."""
    if progress is None or callable(progress) or (live and isinstance(progress, bool)):
        return
    raise ValueError(f"{name} must be a callable, True (a live status line), False or None (got {shown(progress)})"
                     if live else f"{name} must be a callable or None (got {shown(progress)})")


def _key(key):
    """``(key, seed)`` from a seed in [0, :data:`MAX_SEED`] (None: 0) or a ``jax.random`` key
    (``seed`` None); ``ValueError`` naming ``key`` for anything else, ``RuntimeError`` with JAX's 64-bit mode off
    (:func:`~dryfric_jax.params.require_x64`: every runner takes its key here)."""
    require_x64()
    if isinstance(key, jax.core.Tracer):  # vmap over keys compiled for 12 s, then a TracerArrayConversionError
        raise ValueError("key is a JAX tracer (under jax.jit, vmap or grad): the estimators run on the host, round "
                         "after round, and cannot be traced; call them in a Python loop over the keys or seeds")
    key = scalar(key)  # a 0-d numpy array: its seed
    if isinstance(key, numbers.Integral) and not isinstance(key, (bool, np.bool_)):
        seed = check_seed(key)
        return jax.random.key(seed), seed
    if key is None:
        return jax.random.key(0), 0
    typed = isinstance(key, jax.Array) and jax.dtypes.issubdtype(key.dtype, jax.dtypes.prng_key) and key.shape == ()
    raw = isinstance(key, (jax.Array, np.ndarray)) and key.dtype == np.uint32 and key.shape == (2,)  # PRNGKey
    if not (typed or raw):
        what = f"an array of shape {key.shape} and dtype {key.dtype}" if hasattr(key, "shape") else repr(key)
        raise ValueError(f"key must be a seed (an integer in [0, 2^62]) or one jax.random key (got {what})")
    return (jax.random.wrap_key_data(jax.numpy.asarray(key)) if raw else key), None


def key_id(key) -> str:
    """A ``jax.random`` key as text: its dtype and data words in hex.  Seed ``s`` runs on
    ``jax.random.key(s)``, so a key-made run and a seeded one draw the same stream exactly when
    ``key_id(key) == key_id(jax.random.key(s))`` (``'key<fry>:00000000:00000005'`` for seed 5):
    what :func:`~dryfric_jax.combine_estimates` compares to refuse a stream pooled twice."""
    data = np.asarray(jax.random.key_data(key)).ravel()
    return str(key.dtype) + "".join(f":{int(w):08x}" for w in data)


def _build(params: Params, plan: Plan):
    """The nondimensional chain of ``plan``, in its simulation dtype."""
    if plan.method == "di":
        return make_di_model(params, plan.h, DTYPES[plan.dtype])
    return make_pdmp_model(params, plan.delta, DTYPES[plan.dtype])


def _seeds_text(seeds: list, shown: int = 6) -> str:
    """A pool's seeds for its summary: all of a few, else the first ``shown`` and how many (3000 pooled sweep records
    printed one line of 34,515 characters: an audit; the JSON keeps them all)."""
    if len(seeds) <= shown:
        return f"seeds {seeds}"
    return f"seeds [{', '.join(map(str, seeds[:shown]))}, ...] ({len(seeds)} runs)"


def _fmt(x, ci):
    """``x ± ci  (relative %)``."""
    return f"{x:.6g} ± {ci:.2g}  ({100 * ci / abs(x):.1f}%)" if x else f"{x:.6g} ± {ci:.2g}"


def _resolution(r):
    return f"h = {r.h:.3g} s" if r.delta is None else f"PDMP delta = {r.delta:.3g} s^-1/2, L_X = {r.L_X:.3g}"


def duration_text(s: float) -> str:
    """Seconds as a short text: "45 s", "12.5 min", "3.2 h"."""
    return f"{s:.0f} s" if s < 90 else f"{s / 60:.1f} min" if s < 5400 else f"{s / 3600:.1f} h"


def progress_text(d: dict) -> str:
    """A short text of a run's ``progress`` dict, for status lines: an estimate's
    (:func:`estimate_diffusivity`) D so far with its relative CI, N and the target (N asked, or ``rtol``), or a
    long-excursion count's (:func:`~dryfric_jax.di_long_excursion_duration`, the dict with ``stopping``) mean so
    far and the count of those asked; then the projected time left, naming ``max_time`` or ``max_work`` when that
    limit ends the run first, or, once a count starts no excursion, those still in flight.  A dash before a
    number exists, never "nan"."""
    if "stopping" not in d:
        rel = d["D_ci"] / abs(d["D"]) if d["D"] == d["D"] and d["D"] else math.nan
        pct = 100 * rel  # 2.8%, 17%, 120% (not 1.2e+02%)
        now = f"D={d['D']:.4g}\u00b1{pct:.2g}%" if pct < 10 else f"D={d['D']:.4g}\u00b1{pct:.0f}%" if rel == rel \
            else "D=\u2013"
        goal = (f" (target {100 * d['rtol']:.2g}%)" if d["rtol"] else f" of {d['target']}"
                if d["n_excursions"] <= d["target"] else f" ({d['target']} asked)")  # the final report: 2094 of 2000
        now += f" N={d['n_excursions']}{goal}"
    else:
        mean = f"{d['mean_s']:.4g}s" if d["mean_s"] == d["mean_s"] else "\u2013"
        k, n = d["n_excursions"], d["target"]  # those in flight at the rule finish and count: not "117 of 100"
        now = f"LE={mean} so far, {k} " + (f"of {n}" if k <= n else f"({n} asked)")
        if d["stopping"]:
            return now + in_flight_text(d)
        if d["left_s"] is None and d["in_flight"]:  # no projection (yet, or the long ones left to finish)
            return now + f", {d['in_flight']} in flight"
    return now + left_text(d)


def _live_text(d: dict) -> tuple:
    """``progress=True``'s status line of an estimate's or a count's ``progress`` dict: (:func:`progress_text`, the
    time taken)."""
    return progress_text(d), f" [{duration_text(d['elapsed_s'])}]"


def left_text(d: dict, options: bool = False) -> str:
    """A status line's projected time left (a ``progress`` dict's ``left_s``; none: ""), naming the limit that
    ends the run first (``left_to``) when it is ``max_work`` or ``max_time``, spelled as the CLI's option
    (``--max-time``) where ``options``."""
    if d.get("left_s") is None:
        return ""
    to = d["left_to"]
    name = "--" + to.replace("_", "-") if options else to
    return f", ~{duration_text(d['left_s'])} left" + (f" (stops at {name})" if to in ("max_work", "max_time") else "")


def in_flight_text(d: dict) -> str:
    """A long-excursion count's status once it starts no excursion (``stopping``): those still in flight, or done."""
    return f", finishing the {d['in_flight']} in flight" if d["in_flight"] else ", done"


def time_left(elapsed: float, work: float, closed: int, in_flight: int, target: int, *, rtol=None,
              rel=None, max_work=None, max_time=None, rate=None):
    """Projected seconds left of a long-excursion run and the limit that ends it first
    (``"n_excursions"``, ``"target"`` (``rtol``), ``"max_work"`` or ``"max_time"``), from the rounds
    so far: ``work`` lane-steps (events) paid in ``elapsed`` seconds, ``closed`` excursions closed
    and ``in_flight`` running.  ``(None, None)`` before any excursion has started.

    The work per excursion, ``work / (closed + in_flight)``, counts each in-flight excursion as
    one: a lower estimate, as the engine's own round sizing, and available before the first
    excursion closes (at a huge Gamma that takes minutes).  With ``rtol`` the excursions
    needed follow from the CI's :math:`N^{-1/2}` scaling, :math:`N (rel/rtol)^2`, once ``rel``
    (the relative half-width so far) is known.  The final round's tail is not counted.  ``rate``
    (lane-steps per second) defaults to ``work / elapsed``; :func:`estimate_diffusivity` passes the
    rate of the rounds after the first, whose time holds the compilation (on a short run it made
    the projection ~8x too long).
    """
    if closed + in_flight < 1 or elapsed <= 0 or work <= 0:
        return None, None
    rate, per_exc = rate or work / elapsed, work_per_excursion(work, closed, in_flight)
    need, to = float(target), "n_excursions"
    if rtol is not None:
        if rel is None or not math.isfinite(rel):
            return None, None
        need, to = max(need, min(closed * _ratio(rel, rtol) ** 2, float(MAX_COUNT))), "target"
    left = max(need - closed - in_flight, 0.0) * per_exc / rate
    # a limit already passed ends the run now (0 s), not before a target it reaches now: the engine checks N first
    if max_work is not None and max(max_work - work, 0.0) / rate < left:
        left, to = max(max_work - work, 0.0) / rate, "max_work"
    if max_time is not None and max(max_time - elapsed, 0.0) < left:
        left, to = max(max_time - elapsed, 0.0), "max_time"
    return left, to


def _ratio(rel: float, rtol: float) -> float:
    """``rel / rtol``, at most 2^32: the excursions a precision target asks for, N (rel/rtol)^2, are
    capped at :data:`~dryfric_jax.plan.MAX_COUNT` (``rtol`` = 1e-160 overflowed: the work bound
    or ``max_time`` ends such a run, and its result says so)."""
    return rel / rtol if rel / rtol < 2.0**32 else 2.0**32  # also for inf and nan


def missing_fields(cls, d: dict) -> list[str]:
    """The fields of the result dataclass ``cls`` (:class:`EstimateResult`, :class:`BruteForceResult`)
    without a default that the dict ``d`` (a ``to_dict()`` read back from a file) lacks."""
    return [f.name for f in fields(cls) if f.default is MISSING and f.default_factory is MISSING and f.name not in d]


def _with_warnings(text, ws):
    return text + "".join(f"\nwarning: {w}" for w in ws)


class _Record:
    """What both results share: their fields as a dict and as strict JSON."""

    def to_dict(self) -> dict:
        """Every field, as Python values (tau_L = inf stays a float: ``json.dumps`` would write ``Infinity``;
        :meth:`to_json` writes strict JSON)."""
        return asdict(self)

    def to_json(self, **kw) -> str:
        """Strict JSON of :meth:`to_dict`, as the CLI writes it: a non-finite float (tau_L = inf) is the string
        ``"inf"``, which :func:`~dryfric_jax.combine_estimates` and ``json.load`` + ``outfiles.from_strict`` read
        back as the float; ``kw`` go to ``json.dumps`` (``indent=1``, say)."""
        return dumps(self.to_dict(), **kw)


@dataclass
class EstimateResult(_Record):
    """Long-excursion estimate (physical units; CIs are 95% half-widths).

    ``print(result)`` shows :meth:`summary` and the warnings; ``repr`` shows every field.

    Attributes:
        D, D_ci, M0, M0_ci: the diffusivity (m^2/s) and mobility (m/s) and their half-widths at ``ci_level``.
        mean_duration, mean_duration_ci: the mean cycle length (s).  For the PDMP it is the paper's long
            excursion (threshold to threshold); for the DI it is the regeneration cycle of
            :mod:`~dryfric_jax.regeneration`, which spans one or more of the paper's excursions (about 2-4 times
            longer at Fig. 3's parameters, and h-dependent).  D and M0 do not depend on the rule.
        n_excursions: N, the complete excursions behind the estimate; ``n_requested`` what was asked for.
        n_truncated: excursions that hit the work bound ``max_steps``, that the final round's deadline
            cut (``max_time``, or the grace after a Ctrl-C) or that a second Ctrl-C dropped in flight:
            excluded from the sums, so the estimate is biased low; a warning says so.
        stopped_by: what ended the rounds: ``"n_excursions"`` (N reached), ``"target"`` (``rtol`` met),
            ``"max_time"``, ``"work_bound"`` (``max_work``), ``"interrupted"`` (Ctrl-C, and SIGTERM
            under the ``dryfric`` command; the rounds already run are kept) or ``"combined"``
            (:func:`~dryfric_jax.combine_estimates`).
        method, method_reason, h, delta, L_X, dtype: the model and resolution simulated (``h`` for the DI
            in s, ``delta`` and ``L_X`` the PDMP's grid in s^-1/2) and why ``method="auto"`` chose it.
        seed, lanes, block, version: with the settings above they fix the random streams, so the same
            values give the same numbers to the last bit; ``seed`` is None for a ``jax.random`` key.
        wall_s, lane_steps_per_s, events_per_s: the call's wall time, compiling included on the first
            call of a shape (later calls reuse it), and its useful lane-steps (events) per second.
        work, predicted_work, max_work, max_steps, lane_utilization: lane-steps (events) paid, the
            planner's prediction, the bounds, and the share of paid slots that were useful.
        rtol, max_time: the precision target and time limit of the run (None when not given).
        warnings: every note the run issued (also issued as :class:`DryfricWarning`).
        sums: the excursions' sufficient statistics (nondimensional), which runs pool by adding.
        combined_from: the seeds a pooled result was made from (for runs made from a key, their ``key``).
        key: for a run made from a ``jax.random`` key (``seed`` None), the key (:func:`key_id`); else None.
        params: the physical parameters as a dict.
    """

    D: float
    D_ci: float
    M0: float
    M0_ci: float
    mean_duration: float
    n_excursions: int
    n_truncated: int
    method: str
    h: float | None
    dtype: str
    seed: int | None
    wall_s: float
    lane_steps_per_s: float
    params: dict
    mean_duration_ci: float = 0.0
    delta: float | None = None
    L_X: float | None = None
    events_per_s: float | None = None
    method_reason: str = ""
    max_steps: int = 0
    max_work: float = 0.0
    predicted_work: float = 0.0
    work: int = 0
    lane_utilization: float = 0.0
    ci_level: float = 0.95
    rtol: float | None = None
    stopped_by: str = "n_excursions"
    warnings: list = field(default_factory=list)
    # the sufficient statistics behind D and M0: totals over the complete excursions of
    # STAT_NAMES, nondimensional (U in u0, t in tau0); runs combine by adding them (combine.py)
    sums: dict = field(default_factory=dict)
    combined_from: list = field(default_factory=list)  # seeds (or keys) of the runs a combined result pools
    key: str | None = None  # a key-made run's key (key_id); None for a seed
    lanes: int = 0  # the engine's layout (with the seed, it fixes the random streams)
    block: int = 0
    # what reproduces the run with the seed and the fields above: the n_excursions asked for (N is
    # what closed), the time limit, and the package version ("" for results written before it)
    n_requested: int = 0
    max_time: float | None = None
    version: str = ""

    def summary(self) -> str:
        """D and M0 with their CIs, the mean duration, N, the resolution, seed and speed (what
        ``dryfric estimate`` prints)."""
        return (f"D  = {_fmt(self.D, self.D_ci)} m^2/s   ({100 * self.ci_level:g}% CI)\n"
                f"M0 = {_fmt(self.M0, self.M0_ci)} m/s\n"
                + f"mean excursion duration = {self.mean_duration:.4g} s"
                + ("\n" if self.method == "pdmp" else
                   " (DI: regeneration cycles, each >= 1 of the paper's excursions)\n")
                + f"N = {self.n_excursions} excursions, {self.n_truncated} truncated, {_resolution(self)}, "
                f"{self.dtype}, " + (_seeds_text(self.combined_from) if self.combined_from
                                    else f"seed {self.seed}" if self.key is None else f"key {self.key}")
                + f"\nwall {self.wall_s:.1f} s, {self.lane_steps_per_s:.3g} "
                f"{'lane-steps' if self.delta is None else 'events'}/s, stopped by: {self.stopped_by}")

    def __str__(self) -> str:
        return _with_warnings(self.summary(), self.warnings)


@dataclass
class BruteForceResult(_Record):
    """Fixed-horizon estimate (physical units; CIs are 95% half-widths); ``print`` shows
    :meth:`summary` and the warnings."""

    D_t: float
    D_t_ci: float
    M0_t: float
    M0_t_ci: float
    t: float
    n_paths: int
    method: str
    h: float | None
    dtype: str
    seed: int | None
    wall_s: float
    lane_steps_per_s: float
    params: dict
    burn_in: float = 0.0  # s, as simulated: for the DI a whole number of steps h, as t
    ci_level: float = 0.95
    delta: float | None = None
    L_X: float | None = None
    events_per_s: float | None = None
    n_unfinished: int = 0
    warnings: list = field(default_factory=list)
    # with the seed and the settings above, the block size K fixes the random streams (a block's numbers are
    # drawn at once; the chunk of paths run at once does not matter); 0 for results written before 0.2.6
    block: int = 0
    version: str = ""

    def summary(self) -> str:
        """D_t and M0_t with their CIs, the horizon, N' and the resolution (what ``dryfric
        bruteforce`` prints)."""
        return (f"D_t  = {_fmt(self.D_t, self.D_t_ci)} m^2/s   (t = {self.t:.4g} s, {100 * self.ci_level:g}% CI)\n"
                f"M0_t = {_fmt(self.M0_t, self.M0_t_ci)} m/s\nN' = {self.n_paths} paths, {_resolution(self)}, "
                f"wall {self.wall_s:.1f} s")

    def __str__(self) -> str:
        return _with_warnings(self.summary(), self.warnings)


def estimate_diffusivity(params: Params, key=0, *, method: str = "di", h: float | None = None,
                         delta: float | None = None, n_excursions: int = 20_000, dtype="float64",
                         lanes: int | None = None,
                         chunk_lanes: int | None = None, block: int | None = None, max_steps: int | None = None,
                         rtol: float | None = None, max_time: float | None = None, max_work: float = MAX_WORK,
                         progress=None) -> EstimateResult:
    r"""Estimate D and M0 from N i.i.d. long excursions (paper sections 4-6).

    Args:
        params: physical parameters.
        key: a ``jax.random`` key or an integer seed in [0, 2^62].
        method: ``"di"`` (differential inclusion with exact OU step, section 6), ``"pdmp"``
            (exact event-driven jump-noise model, section 3) or ``"auto"`` (the cheaper of the
            two by the cost model of :mod:`dryfric_jax.cost`; ``method_reason`` says why).
        h: DI step in seconds; default :func:`default_h` = 0.01 min(tau0, tau_L).
        delta: PDMP noise grid step in s^-1/2; default :func:`dryfric_jax.cost.default_delta`
            (delta' = min(0.05, 1/(16 sqrt(tau')), delta'_max/2)); admissible range in
            :mod:`dryfric_jax.noise`.
        n_excursions: N >= 2 excursions closed, truncated ones included (the run ends with slightly
            more: every lane finishes its in-flight excursion; ``stopped_by = "n_excursions"`` then,
            and the result's ``n_excursions`` counts the complete ones only, ``n_truncated`` the
            others); below :data:`MIN_RELIABLE_N` the CI under-covers and a
            :class:`DryfricWarning` is issued (also for weak viscous damping, see README).
        dtype: ``"float64"`` or ``"float32"`` for the simulation (statistics are float64).
        lanes, chunk_lanes, block: engine layout (do not change the estimate's law, only the
            random streams; recorded in the result): lanes in [1, 2^22] (default
            :func:`~dryfric_jax.excursions.lanes_for`, the power of two at or below max(N/32, min(512, N)),
            up to ``chunk_lanes``: N = 2000 gives 512 lanes; a new lane count compiles anew,
            default 4096 on a CPU and 2^18 on a GPU),
            block K in [1, 1024] (default :func:`~dryfric_jax.excursions.default_block`: 128,
            and 256 for the DI on a GPU), lanes * K <= 2^28 (:func:`~dryfric_jax.plan.check_layout`).
            On a GPU, ``dryfric bench --lanes ... --block ...`` measures which layout is fastest.
        max_steps: work bound per excursion; default
            :func:`~dryfric_jax.limits.max_steps_per_excursion` (1e4 tail time scales of the
            excursion, at most ``max(max_work / lanes, 64)``).  Excursions reaching it are truncated,
            excluded and reported (``n_truncated``, a warning).
        max_work: bound on the run's lane-steps (events); a run predicted to exceed it is refused
            with ``ValueError`` before any simulation
            (:func:`~dryfric_jax.limits.check_work`), and the rounds stop once it is spent
            (``stopped_by = "work_bound"``).  The final round then finishes the excursions in
            flight (dropping them would bias D low), each within ``max_steps <= max(max_work / lanes, 64)``,
            so a run's ``work`` can reach about twice ``max_work`` (measured: 1.66x).
        rtol: precision target: after the first ``n_excursions``, keep running rounds until
            the 95% half-width of D is at most ``rtol * |D|`` (a target out of reach, say 1e-160,
            runs until ``max_work`` or ``max_time`` ends it, and the result says so).  N then depends
            on the data: with weak damping D comes out ~1-2% low and the interval covers a few points
            less than at a fixed N (measured, README "Confidence intervals"; the result warns).
        max_time: stop after the round that passes this many seconds (``stopped_by`` says so); the
            final round, which finishes the excursions in flight, is cut at twice ``max_time``,
            and the excursions it cut are counted as truncated (excluded, warned).  Both act
            between calls: add up to one round and one call (~4 s each on 2 CPU cores).  The time includes
            compiling, seconds in a new process or at a new lane count (a sweep audit: a first point at
            max_time = 2 s stopped at 378 of 3000 excursions, the next ran all in 0.2 s).
        progress: ``True`` for a live status line (D so far, N, the time taken and the projected time left):
            an updated display in a Jupyter notebook, a self-overwriting line on a terminal's stderr, nothing
            elsewhere (:mod:`dryfric_jax.live`); or a callback ``progress(dict)`` after every round but the
            final one, which finishes the excursions in flight, and once after it with the final sums
            (``left_s`` None), with the keys
            ``n_excursions``, ``D`` and ``D_ci`` (so far, m^2/s), ``target`` (``n_excursions``
            asked for), ``rtol``, ``elapsed_s``, and the projection ``left_s`` (seconds, None
            until known) to the limit ``left_to`` that ends the run first (:func:`time_left`).  An exception
            it raises ends the run and goes on up, the rounds run so far lost (it is first called after the
            first round, so a faulty callback fails early).

    A Ctrl-C between rounds returns what the completed rounds reached (``stopped_by =
    "interrupted"``); nothing already simulated is lost.  Before 2 excursions have closed there is
    nothing to return, and the ``KeyboardInterrupt`` goes on up (with the reason "fewer than 2 complete
    excursions before the interrupt" once a round has run; a bare one during the first round, which
    includes compiling a new shape): callers (the CLI, sweeps, figures) treat it as any Ctrl-C.

    Returns:
        :class:`EstimateResult`: D, M0 with 95% CI half-widths, mean excursion duration (for the DI its
        regeneration cycle's, see :class:`EstimateResult`), counts.
    """
    require_x64()
    rtol, max_time = check_rtol(rtol), check_max_time(max_time)
    check_progress(progress)
    plan = plan_estimate(params, method=method, h=h, delta=delta, dtype=dtype, n_excursions=n_excursions,
                         max_work=max_work, max_steps=max_steps, lanes=lanes, chunk_lanes=chunk_lanes,
                         block=block)
    n_excursions, max_work = int(scalar(n_excursions)), plan.max_work  # validated: as Python numbers
    key, seed = _key(key)
    model, notes, h, grid, unit = _build(params, plan), list(plan.notes), plan.h, plan.grid, plan.unit

    def snapshot(st):
        if st.n_excursions < 2:
            return None
        return long_excursion_estimates(st.total())

    def more(st):  # precision target: excursions still wanted, from the CI's N^{-1/2} scaling
        e = snapshot(st)
        if e is None:
            return st.n_excursions + 2
        rel = e["D_ci"] / max(abs(e["D"]), 1e-300)
        return 0 if rel <= rtol else int(min(math.ceil(e["n_excursions"] * (_ratio(rel, rtol) ** 2 * 1.1 - 1)),
                                             MAX_COUNT))

    warned = []

    # the engine's rate: rounds after the first (which compiled the engine), less the time spent here
    # (the estimator compiles at its first snapshot): the projection was ~2-8x too long on short runs
    first, here = [], [0.0]

    def report(st, final=None):  # after every round: the projection, an early warning, the progress callback
        now = time.perf_counter()
        el, sim = now - t0, now - t0 - here[0]
        # final: the result's estimates, once it is formed (not computed again)
        e = final if final is not None else (snapshot(st) or {}) if progress is not None or rtol else {}
        closed = st.n_excursions + st.n_truncated
        rel = e["D_ci"] / abs(e["D"]) if e.get("D") else None
        if final is not None:  # the result's sums: nothing left to project
            left, to = None, None
        elif not first:  # no projection yet: the first round's rate is mostly compile time
            first.append((sim, st.slot_steps))
            left, to = None, None
        else:
            rate = (st.slot_steps - first[0][1]) / (sim - first[0][0]) if sim > first[0][0] else None
            left, to = time_left(el, st.slot_steps, closed, st.n_in_flight, n_excursions, rtol=rtol, rel=rel,
                                 max_work=max_work, max_time=max_time, rate=rate)
        if to == "max_work" and not warned:  # say so now, not only after the whole max_work
            warned.append(to)
            per_exc = work_per_excursion(st.slot_steps, closed, st.n_in_flight)
            warnings.warn(f"max_work = {max_work:.3g} {unit} is projected to end the run in "
                          f"~{duration_text(left)}, short of "
                          + (f"rtol = {rtol}" if rtol else f"{n_excursions} excursions")
                          + f": the rounds so far paid >= {per_exc:.3g} {unit} per excursion (predicted >= "
                          f"{plan.predicted_work / n_excursions:.3g}).  Lower n_excursions, raise max_work, or "
                          "coarsen h or delta", ProjectionWarning, stacklevel=4)
        if progress is not None:
            progress(dict(n_excursions=st.n_excursions, D=float(e.get("D", math.nan) * params.D0),
                          D_ci=float(e.get("D_ci", math.nan) * params.D0), target=n_excursions, rtol=rtol,
                          elapsed_s=el, left_s=left, left_to=to))
        here[0] += time.perf_counter() - now

    t0 = time.perf_counter()
    with live_progress(progress, _live_text) as progress:  # report() calls the callback this gives
        sim, stopped = simulate_long_excursions(model, key, n_excursions, lanes=plan.lanes, block=plan.block,
                                                max_steps=plan.max_steps, more=more if rtol else None,
                                                max_time=max_time, max_work=max_work, progress=report)
        # from here the run is over: a Ctrl-C or SIGTERM is held until its result is formed, then noted in it (it
        # threw the whole run away: an interrupt audit), except where a caller keeps finished runs only
        # (abandon_on_interrupt)
        with after_run() as late:
            wall = time.perf_counter() - t0
            # a lane the final round's deadline (max_time) or its block bound (never expected) stopped lost
            # its in-flight excursion: count it too
            # the final round's deadline: max_time's, or the grace after a Ctrl-C (the block bound never binds)
            cut = sim.n_unfinished > 0 and (max_time is not None or stopped == "interrupted")
            # a second Ctrl-C left the paused round's in-flight excursions unfinished: dropped, and counted as
            # truncated too (they were not, so 'dryfric combine' pooled such a run as unbiased, exit 0: a sweep audit)
            dropped = max(sim.n_in_flight - sim.n_unfinished, 0)
            n_truncated = sim.n_truncated + sim.n_unfinished + dropped
            if stopped == "interrupted":
                notes.append(f"interrupted: result of the {sim.n_excursions} excursions completed by then")
            if dropped:
                notes.append(f"{dropped} in-flight excursions dropped (a second interrupt) and counted as truncated: "
                             f"D is biased low by O(lanes/N) = O({dropped / max(sim.n_excursions, 1):.2g})")
            elif stopped in ("max_time", "work_bound") and (rtol or sim.n_excursions < n_excursions):
                # (not where the final round's in-flight excursions brought N to the count asked: "before the 300
                # excursions: result of 428" contradicted itself, a hard-cases audit)
                what = f"max_time reached ({max_time} s)" if stopped == "max_time" else \
                    f"work bound reached (max_work = {max_work:.3g} {unit}, predicted >= {plan.predicted_work:.3g})"
                notes.append(f"{what} before the " + (f"target rtol = {rtol}" if rtol else f"{n_excursions} excursions")
                             + f": result of {sim.n_excursions} excursions")
            if cut and stopped == "interrupted":
                notes.append(f"{FINAL_CUT} {INTERRUPT_GRACE_S:g} s after the interrupt"
                             + (f" (or at {FINAL_DEADLINE:g} x max_time)" if max_time is not None else "")
                             + f": {sim.n_unfinished} excursions still running are excluded and counted as "
                             "truncated: the estimate is biased low")
            elif cut:
                notes.append(f"{CUT_NOTE} {FINAL_DEADLINE:g} x "
                             f"max_time: {sim.n_unfinished} excursions still running are excluded and counted as "
                             "truncated: the estimate is biased low (the excursions are far longer than planned; raise "
                             "max_time)")
            hit_bound = n_truncated - (sim.n_unfinished if cut else 0) - dropped
            if hit_bound:
                notes.append(f"{hit_bound} of {n_truncated + sim.n_excursions} "
                             f"excursions {BOUND_NOTE} (max_steps = {plan.max_steps} {unit} per excursion) and are "
                             "excluded: the estimate is biased low")
            if sim.n_excursions < 2 and stopped == "interrupted":  # nothing to return: the Ctrl-C goes on up
                raise KeyboardInterrupt("fewer than 2 complete excursions before the interrupt")
            if sim.n_excursions < 2:
                cause = "within max_time (raise it)" if stopped == "max_time" else \
                    "within the work bounds (raise max_work / max_steps)"
                raise NoEstimateError(f"fewer than 2 complete excursions {cause}: " + "; ".join(notes),
                                      stopped_by=stopped)
            if sim.n_excursions < MIN_RELIABLE_N:
                notes.append(small_n_note(sim.n_excursions))
            if params.tau_L_nd > WEAK_DAMPING_TAU_L:
                notes.append(f"tau_L/tau0 = {params.tau_L_nd:.3g} > {WEAK_DAMPING_TAU_L:g} (weak or no viscous "
                             "damping): the 95% CI for D covers only ~90% (measured at tau_L = inf, gamma_bar = 0 and "
                             "0.5 Delta; ~83% at |gamma_bar| = 0.9 Delta), misses are on the low side")
                if stopped == "target":
                    notes.append(TARGET_STOP_NOTE)
            if runaway := near_runaway_note(params.tau_L_nd, params.gamma_bar_nd):
                notes.append(runaway)
            total = sim.total()
            if rounding := rounding_note(total):
                notes.append(rounding)
            e = long_excursion_estimates(total)
            r = EstimateResult(
                D=float(e["D"] * params.D0), D_ci=float(e["D_ci"] * params.D0), M0=float(e["M0"] * params.v0),
                M0_ci=float(e["M0_ci"] * params.v0),
                mean_duration=float(e["mean_duration"]) * params.tau0, n_excursions=sim.n_excursions,
                n_truncated=n_truncated, method=plan.method, h=h, dtype=plan.dtype, seed=seed, wall_s=wall,
                lane_steps_per_s=sim.useful_steps / wall, params=params.as_dict(),
                mean_duration_ci=float(e["mean_duration_ci"]) * params.tau0,
                lane_utilization=sim.useful_steps / max(sim.slot_steps, 1), rtol=rtol, stopped_by=stopped,
                warnings=notes, delta=grid and grid["delta"], L_X=grid and grid["L_X"],
                events_per_s=None if grid is None else sim.useful_steps / wall, method_reason=plan.reason,
                max_steps=plan.max_steps, max_work=plan.max_work, predicted_work=plan.predicted_work,
                work=int(sim.slot_steps), sums={k: float(v) for k, v in total.items()}, lanes=plan.lanes,
                block=plan.block, n_requested=n_excursions,
                max_time=None if max_time == math.inf else max_time, version=__version__,
                key=None if seed is not None else key_id(key))
        if progress is not None:  # once more, with the final sums: the last report is the result's N and D.  Not
            try:  # in the hold, which no Ctrl-C breaks (a slow callback), but a Ctrl-C in it keeps the result
                report(sim, final=e)
            except KeyboardInterrupt:
                if _ABANDON[0]:
                    raise
                late.append(True)
    for n in notes:  # once the status line is cleared (on a terminal they were written onto it)
        warnings.warn(n, category(n), stacklevel=2)
    return noted_late(r, "run") if late and r.stopped_by != "interrupted" else r


def bruteforce_diffusivity(params: Params, key=0, *, t: float, n_paths: int, method: str = "di",
                           h: float | None = None, delta: float | None = None, burn_in: float = 0.0,
                           dtype="float64", block: int = BLOCK, chunk_lanes: int = 4096,
                           max_events: int | None = None, max_work: float = MAX_WORK) -> BruteForceResult:
    r"""Brute-force :math:`\hat D^t_{N'}` and :math:`\hat M_0^t` on the horizon ``t`` (s).

    DI paths start at :math:`(x_\Delta, 0)`, PDMP paths at :math:`s_+ = (x_{k_++1}, 1, 0)`
    (Algorithm 2, corrected); ``burn_in`` seconds are simulated first and not counted.  The bias
    is O(1/t): pick t long against the velocity correlation time.  PDMP paths are bounded by
    ``max_events`` (default 10x the expected count + 1000); if any path reaches it the call raises
    ``RuntimeError`` naming how many, rather than return a biased number (so a returned result's
    ``n_unfinished`` is 0).  A run that
    needs more than ``max_work`` steps (events) is refused before it starts.

    A horizon under 100 correlation times (:func:`correlation_time`) is warned about
    (:func:`short_horizon_note`: D_t = D (1 - 5.4 tau0/t) from rest with white noise, tau_L = inf and
    gamma_bar = 0), so is a
    longer one where that bias may exceed a fifth of D_t's CI (:func:`d_bias_note`: many paths), so is
    an M0_t whose start (at rest, the noise at its threshold) may bias it by more than a fifth of its CI
    (:func:`m0_lag_note`: at any horizon and tau', without a burn-in of 20 tau_c); with colored noise (tau' >= 0.5)
    and no such burn-in the start's bias of D_t is said instead of the white-noise one where it may exceed a fifth
    of the CI (:func:`colored_start_note`), and so is a D_t CI of 0 (paths too short for the noise to spread
    them).  With the seed, ``block`` (steps whose numbers are drawn at once) fixes the numbers and is
    recorded; ``chunk_lanes`` (paths compiled and run at once) does not change the random numbers, and the
    results only to rounding (each chunk shape is compiled to its own code: 2.6e-16 relative in a path's U, measured).
    """
    require_x64()
    check_method(method, h, delta, auto=False)  # 'auto' refused, and 5 not told a list with 'auto' in it
    n_paths = check_count("n_paths", n_paths, MIN_PATHS, hi=MAX_PATHS,
                          why=" (with 2 paths the D_t CI is 0; every path's U is kept, ~50 bytes each in memory)")
    max_work = check_max_work(max_work)
    block = check_layout(None, block)[1]
    chunk_lanes = check_count("chunk_lanes", chunk_lanes, 1)
    if min(chunk_lanes, n_paths) * block > MAX_LAYOUT:  # 2^24 paths at once passed 8 GB and were killed (an audit)
        raise ValueError(f"min(chunk_lanes, n_paths) * block must be <= 2^28 (the paths run at once draw a block's "
                         f"normals at once, as the engine's lanes * block) (got chunk_lanes = {chunk_lanes}, n_paths = "
                         f"{n_paths}, block = {block})")
    if max_events is not None:
        max_events = check_count("max_events", max_events, 1, hi=MAX_COUNT)  # int64 counters
        if method == "di":  # it was taken and ignored
            raise ValueError("max_events must not be given with method 'di': it bounds the PDMP's events per "
                             "path (the DI runs exactly t/h steps)")
    plan = choose(params, method, h, delta, dtype)
    notes, method, h, grid, dname = plan.notes, plan.method, plan.h, plan.grid, plan.dtype
    check_positive("t", t)
    t, b = float(t), real_or_none(burn_in)
    if b is None or not (math.isfinite(b) and b >= 0):
        raise ValueError(f"burn_in must be a finite number >= 0 (got {burn_in!r})")
    burn_in = burn_asked = b  # burn_in becomes the one simulated, whole steps of h; the notes take the one asked for
    if h is not None and t < h:
        raise ValueError(f"t must be >= h = {rounded_bound(h, lower=True)} s (got {t!r})")
    # the work is known in advance: (t + burn_in) / h steps per path, or the expected events
    per_path = (t + burn_in) / params.tau0 * plan.per_tau0
    work = n_paths * per_path
    bound = per_path if h is not None else 10 * per_path  # the PDMP's default max_events is 10x the expected
    if not bound <= 2.0**62:  # the step and event counters are int64
        unit = "steps" if h is not None else "events (the bound max_events is 10x the expected count)"
        raise ValueError(f"t must keep t + burn_in below 2^62 {unit} per path (got t = {t:.4g} s, burn_in = "
                         f"{burn_in:.4g} s: {bound:.3g})")
    refuse_known_work(work, max_work, "steps" if h is not None else "events (expected)",
                      f"t = {t:.4g} s and n_paths = {n_paths}", "raise max_work (--max-work) or lower t or n_paths")
    if n_paths < MIN_RELIABLE_PATHS:
        notes = [*notes, f"n_paths = {n_paths} < {MIN_RELIABLE_PATHS}: the delta-method CI of D_t under-covers at "
                         "this size (0.74 at 10 paths, 0.92 at 100 for Gaussian U(t))"]
    short = short_horizon_note(params, t)
    if short:
        notes = [*notes, short]
    if h is not None:  # the DI runs whole steps; a horizon they miss by more than HORIZON_RTOL is said
        n_steps = round(t / h)
        if abs(n_steps * h - t) > HORIZON_RTOL * t:
            notes = [*notes, f"t = {t:.4g} s is {t / h:.3g} steps of h = {h:.4g} s: the horizon simulated is "
                             f"t = {n_steps * h:.4g} s = {n_steps} h (the result's t)"]
    model = _build(params, plan)
    for n in notes:
        warnings.warn(n, category(n), stacklevel=2)
    key, seed = _key(key)
    t0 = time.perf_counter()
    unfinished = 0
    if method == "di":
        # whole steps: t and burn_in are recorded as simulated (a burn-in under h/2 is none at all)
        burn_steps = round(burn_in / h)
        U, t_nd = simulate_bruteforce(model, key, int(n_paths), n_steps, burn_in_steps=burn_steps,
                                      block=block, chunk_lanes=chunk_lanes)
        burn_in = burn_steps * h
        steps = n_paths * (t_nd + burn_in / params.tau0) / float(model.h)
    else:
        t_nd, b_nd = t / params.tau0, burn_in / params.tau0
        if max_events is None:
            max_events = int(10 * plan.per_tau0 * (t_nd + b_nd)) + 1000
        U, steps, unfinished = simulate_pdmp_bruteforce(model, key, int(n_paths), t_nd, burn_in=b_nd,
                                                        max_events=max_events, block=block, chunk_lanes=chunk_lanes)
        if unfinished:
            raise RuntimeError(f"{unfinished} of {n_paths} PDMP paths hit max_events = {max_events} before t; "
                               "raise max_events")
    wall = time.perf_counter() - t0
    e = bruteforce_estimates(U, t_nd)
    if not e["D_t_ci"] > 0:  # issued after the run: the paths' spread is known only now
        zero = (f"the D_t CI is 0 (D_t = {e['D_t'] * params.D0:.3g} m^2/s): the {n_paths} paths' U(t) are equal to "
                "rounding, so the result has no error bar; t is too short for the noise to spread the paths")
        warnings.warn(zero, DryfricWarning, stacklevel=2)
        notes = [*notes, zero]
    t_s = t_nd * params.tau0
    d_t, d_ci = float(e["D_t"] * params.D0), float(e["D_t_ci"] * params.D0)
    m0_t, m0_ci = float(e["M0_t"] * params.v0), float(e["M0_t_ci"] * params.v0)
    # the burn-in asked for: the notes' advice "burn_in >= 20 tau_c = 10 s" followed (10 s, simulated as 9.99975 s in
    # whole steps) kept them said, with the same advice (a review)
    dnd = grid and grid["delta_nd"]
    start = colored_start_note(params, t_s, burn_asked, d_t, d_ci, delta_nd=dnd)
    # the white-noise note on D_t, not where the colored start's note said it does not hold
    for note in (start, None if short or start else d_bias_note(params, t_s, burn_asked, d_t, d_ci),
                 m0_lag_note(params, t_s, burn_asked, m0_t, m0_ci, delta_nd=dnd)):
        if note:  # issued after the run, as the zero CI's: they need the estimates and their CIs
            warnings.warn(note, DryfricWarning, stacklevel=2)
            notes = [*notes, note]
    return BruteForceResult(
        D_t=float(e["D_t"] * params.D0), D_t_ci=float(e["D_t_ci"] * params.D0), M0_t=float(e["M0_t"] * params.v0),
        M0_t_ci=float(e["M0_t_ci"] * params.v0), t=t_nd * params.tau0, n_paths=int(n_paths), method=method, h=h,
        dtype=dname, seed=seed, wall_s=wall, lane_steps_per_s=steps / wall, params=params.as_dict(),
        burn_in=burn_in, delta=grid and grid["delta"], L_X=grid and grid["L_X"],
        events_per_s=None if grid is None else steps / wall, n_unfinished=unfinished, warnings=notes, block=block,
        version=__version__)
