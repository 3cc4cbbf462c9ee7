r"""The jump noise of the PDMP: a birth-death chain on the grid :math:`S^\delta = \delta\mathbb Z\cap[-L_X, L_X]`.

Paper section 3.1 and appendix A, nondimensional units (MODEL_NOTES section 1:
:math:`\delta' = \delta\sqrt\Gamma/\Delta`, :math:`\tau' = \tau/\tau_0`; the product
:math:`\delta\sqrt\tau` is the same in both).  The state is the integer index k of
:math:`x_k = k\delta`, :math:`|k| \le N`.  Jumps come at rate :math:`\Lambda = 2/(\tau^2\delta^2)`;
from :math:`x_k` the chain goes up with probability

.. math::
    \alpha_k = \tfrac12\big(1 - \tfrac{\tau\delta x_k}{2}\big) = \tfrac12 - \tfrac{\tau\delta^2}{4}k,
    \qquad \alpha_N = 0,\ \alpha_{-N} = 1 \ \text{(reflecting ends)}.

Choice of :math:`L_X` (MODEL_NOTES erratum 3; the paper never gives it)
-----------------------------------------------------------------------
:math:`N = \lceil L_{req}/\delta\rceil + 1` with :math:`L_{req} = \max(8/\sqrt\tau,\ 1 + |\bar\gamma|)`:
the grid covers 8 standard deviations of :math:`\mathcal N(0, 1/\tau)` and both stick thresholds
:math:`-\bar\gamma \pm 1` with a point to spare.  The up-probabilities stay in [0, 1] only if
:math:`\tau\delta L_X < 2`; since :math:`L_X = N\delta < L_{req} + 2\delta`, this holds for every

.. math::
    0 < \delta < \delta_{max} = \frac{-\tau L_{req} + \sqrt{\tau^2 L_{req}^2 + 16\tau}}{4\tau}
    \quad (\approx 0.24/\sqrt\tau \text{ when the noise sets } L_{req}),

and :func:`check_delta` refuses any other :math:`\delta`.
"""
from __future__ import annotations

import math

import numpy as np

from .params import real_or_none, refuse_traced, rounded_bound, shown

COVER_SD = 8.0


def required_reach(tau: float, gamma_bar: float = 0.0) -> float:
    """L_req (nondimensional): 8 noise standard deviations, and both stick thresholds."""
    return max(COVER_SD / math.sqrt(tau), 1.0 + abs(gamma_bar))


def delta_max(tau: float, gamma_bar: float = 0.0) -> float:
    """Largest admissible nondimensional grid step (exclusive), module docstring."""
    L = required_reach(tau, gamma_bar)
    # (-a + sqrt(a^2 + 16 tau)) / (4 tau) with a = tau L, rationalised: no cancellation for
    # tau L^2 >> 1 and no underflow of tau^2 for tiny tau
    a = tau * L
    return 4.0 / (a + math.hypot(a, 4.0 * math.sqrt(tau)))


def least_delta(tau: float, gamma_bar: float = 0.0, scale: float = 1.0) -> str | None:
    """The smallest delta whose grid fits (at most 2^31 - 1 points), in units of ``scale``, as a refusal states it:
    rounded up, so that it is admissible; None where it would not stay below delta_max (no delta is admissible)."""
    shown_least = rounded_bound(required_reach(tau, gamma_bar) / (2**30 - 2) * scale, lower=True)
    return shown_least if float(shown_least) < delta_max(tau, gamma_bar) * scale else None


def check_delta(delta: float, tau: float, gamma_bar: float = 0.0, *, scale: float = 1.0) -> None:
    """ValueError naming delta and its admissible range (in units of ``scale``, e.g. physical); a JAX tracer is
    refused as one (it was told the range)."""
    refuse_traced("delta", delta, "the noise grid's check")
    dm = delta_max(tau, gamma_bar)
    v = real_or_none(delta)
    ok = v is not None and math.isfinite(v) and 0 < v / scale < dm
    if not ok:
        # the least delta whose grid fits (grid_size's bound), stated too: "(0, ...)" alone sent a user to a
        # 1e-9 that grid_size then refused (an audit)
        least = least_delta(tau, gamma_bar, scale)
        low = (f"; and delta >= {least} here, or the grid exceeds {2**31 - 1} points" if least is not None
               else f"; no delta is admissible here (its grid would exceed {2**31 - 1} points): use method 'di'")
        raise ValueError(
            f"delta must be in (0, {rounded_bound(dm * scale, lower=False)}) for these parameters "
            f"(got {shown(delta)}): the noise grid must "
            f"cover 8 standard deviations of N(0, 1/tau) and the stick thresholds while keeping "
            f"tau*delta*L_X < 2 (up-probabilities in [0, 1]){low}")


def grid_size(delta: float, tau: float, gamma_bar: float = 0.0, shown_as: str | None = None,
              scale: float | None = None) -> int:
    """N, the grid is x_k = k delta for |k| <= N (nondimensional delta, tau, gamma_bar); ``shown_as``: how
    a refusal names delta (default "delta' = ..."; :func:`dryfric_jax.pdmp.pdmp_grid_info` gives the
    caller's physical delta too, and ``scale``, delta / delta', for the smallest delta it states)."""
    check_delta(delta, tau, gamma_bar)
    reach = required_reach(tau, gamma_bar)
    n = reach / delta  # may be inf
    if not n <= 2**30 - 2:  # 2 ceil(n) + 3 <= 2**31 - 1 points
        shown_as = shown_as or f"delta' = {delta!r}"
        shown_least = least_delta(tau, gamma_bar, scale or 1.0)
        if shown_least is not None:
            name, unit = ("delta'", "") if scale is None else ("delta", " s^-1/2")
            fix = f"{name} must be >= {shown_least}{unit} here, or use method 'di'"
        else:
            fix = "no delta is admissible for these parameters: use method 'di'"
        raise ValueError(f"{shown_as} is too small: the noise grid would have {2.0 * n + 3:.3g} points "
                         f"(at most {2**31 - 1}); {fix}")
    N = math.ceil(n) + 1
    # tau delta L_X < 2 for every delta < delta_max, but only up to rounding: a delta an ulp below delta_max
    # with L_req/delta just above an integer has the product 2 - 2e-16, which float64 rounds to 2.0 (it met a
    # bare AssertionError here)
    assert tau * delta * N * delta < 2.0 * (1.0 + 1e-12)
    return N


def up_probability(k: np.ndarray, N: int, delta: float, tau: float) -> np.ndarray:
    """alpha_k with reflecting ends (alpha_N = 0, alpha_-N = 1)."""
    k = np.asarray(k, dtype=float)
    return np.where(k >= N, 0.0, np.where(k <= -N, 1.0, 0.5 - 0.25 * tau * delta * delta * k))


def stationary_law(N: int, delta: float, tau: float) -> tuple[np.ndarray, np.ndarray]:
    r"""Exact stationary law of the chain: detailed balance
    :math:`\pi_{k+1}(1-\alpha_{k+1}) = \pi_k\alpha_k` (product of alpha ratios), in log space.

    Returns:
        ``(x, pi)``: grid points and probabilities.  Since the jump rate does not depend on the
        state, this is also the time-weighted occupation.
    """
    k = np.arange(-N, N + 1)
    a = up_probability(k, N, delta, tau)
    log_ratio = np.log(a[:-1]) - np.log1p(-a[1:])
    logp = np.concatenate([[0.0], np.cumsum(log_ratio)])
    p = np.exp(logp - logp.max())
    return k * delta, p / p.sum()
