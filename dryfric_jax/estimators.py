r"""Where the CI comes from: ratio estimators and their delta-method confidence intervals.

Long excursions (paper section 5.1 and appendix D, corrected).  The excursions are i.i.d.
regeneration cycles with displacement U and duration t.  The regenerative central limit
theorem (e.g. Asmussen, *Applied Probability and Queues*, VI.3) gives

.. math::
    M_0 = \frac{E[U]}{E[t]}, \qquad D = \frac{E[(U - M_0 t)^2]}{E[t]} .

**Erratum.** The paper's eq. (defD), :math:`D = \mathrm{Var}(U)/E[t]`, is right only when
:math:`M_0 = 0`: its proof counts a deterministic :math:`\lfloor t/E[t_1]\rfloor` cycles and drops
the fluctuation of the number of cycles, which carries :math:`M_0 t`.  The two differ by
:math:`(M_0^2\mathrm{Var}(t) - 2M_0\mathrm{Cov}(U, t))/E[t]` (+40% at :math:`b = 0.3\Delta`, white
noise; negligible at the Fig. 3 point, where :math:`M_0` is small).  :func:`psi_D_paper` keeps the
printed form for comparison.

With :math:`\boldsymbol X = (U, U^2, t, Ut, t^2)` and :math:`\hat{\boldsymbol S}_N` its sample mean,

.. math::
    \hat D_N = \Psi_D(\hat{\boldsymbol S}_N), \quad
    \Psi_D(\boldsymbol x) = \frac{x_2 - 2 x_1 x_4/x_3 + x_1^2 x_5/x_3^2}{x_3}, \qquad
    \hat M_0 = \Psi_M(\hat{\boldsymbol S}_N), \quad \Psi_M(\boldsymbol x) = \frac{x_1}{x_3},

and :math:`\sqrt N(\Psi(\hat{\boldsymbol S}_N) - \Psi(\boldsymbol S)) \to \mathcal N(0, \sigma^2)` with
:math:`\sigma^2 = \nabla\Psi^T \mathbf C \nabla\Psi` (delta method).  :math:`\nabla\Psi` comes from
``jax.grad``; :math:`\hat{\mathbf C}_N` from the sufficient statistics (all products of two
entries of :math:`\boldsymbol X`).  The CI is :math:`\hat D_N \pm q_{1-\alpha/2}\hat\sigma_N/\sqrt N`.

Brute force (section 5.2): :math:`\hat D^t_{N'} = \Phi(\hat{\boldsymbol R})` with
:math:`\boldsymbol Y = (U(t)/\sqrt t, U(t)^2/t)` and :math:`\Phi(\boldsymbol y) = y_2 - y_1^2`.

The delta-method CI under-covers for small N because U per excursion is heavy-tailed
(MODEL_NOTES section 4); :data:`MIN_RELIABLE_N` is the measured threshold below which callers warn.
"""
from __future__ import annotations

import functools
import math
from statistics import NormalDist

import jax
import jax.numpy as jnp
import numpy as np

from .params import brief, check_positive, real_or_none, shown

#: Below this many excursions the 95% delta-method CI for D is not trusted.  Measured coverage
#: (README "Confidence intervals", scripts/ci_calibration.py): with viscous damping (paper's tau_L) it
#: is 0.94-0.95 from N = 500 on; without (tau_L = inf) it climbs to a plateau of ~0.90 only from
#: N ~ 5e3 (0.90 +- 0.01 up to 1e5), because U per excursion then has a stretched-exponential tail.
MIN_RELIABLE_N = 10_000
#: tau_L' above which the velocity tail is exponential over the range that dominates Var(U): the
#: D CI then covers ~0.90 instead of 0.95 (measured at tau_L = inf, gamma_bar = 0 and 0.5 Delta; ~0.83 at
#: 0.9 Delta, README "Confidence intervals"; nominal at tau_L' = 0.2).
WEAK_DAMPING_TAU_L = 1.0
#: |gamma_bar'| from which, when the damping does not cut the drift time (tau_L' >= 1/(1 - |gamma_bar'|)^2,
#: tau_L = inf included), the D interval is far below 95% near the runaway bias: measured coverage (white
#: noise, tau_L = inf, scripts/ci_calibration.py) 0.83 at 0.9 Delta (N = 2e4), 0.78 at 0.95 Delta (2e4),
#: 0.50 and 0.24 at 0.99 Delta (1e4, 2e3); README "Confidence intervals"
NEAR_RUNAWAY = 0.9


#: tau_L' from which a run near the runaway bias whose drift the damping does stop (tau_L' (1 - |gamma_bar'|)^2 < 1)
#: gets a warning too.  Measured (white noise, N = 1e4 unless said; against theory.exact_D): 0.90 +- 0.04 and
#: 0.88 +- 0.04 coverage at (tau_L', |gamma_bar'|) = (1e3, 0.99) and (200, 0.95), 60 runs each, like the weak-damping
#: note's ~0.90; a hard-cases audit saw 2 of 6 runs cover at (5e3, 0.99) with N = 2000, and 0 of 6 at (1e5, 0.999),
#: misses of 4-68 half-widths, one run with N = 2e4 still 5 half-widths low.  The threshold lies between, a judgement
DAMPED_RUNAWAY_TAU_L = 3e3


def near_runaway_note(tau_L: float, gamma_bar: float) -> str | None:
    """The warning for a run near the runaway bias (nondimensional ``tau_L``, ``gamma_bar``), else None."""
    g = abs(gamma_bar)
    if not NEAR_RUNAWAY <= g < 1.0:
        return None
    if tau_L * (1.0 - g) ** 2 < 1.0:  # the damping stops the drift
        if tau_L < DAMPED_RUNAWAY_TAU_L:
            return None
        return (f"|gamma_bar|/Delta = {brief(g)}, near the runaway bias (|gamma_bar| = Delta), with damping so weak "
                f"(tau_L/tau0 = {tau_L:.3g}) that it sets the excursions' length: the D interval may cover far less "
                "than 95% (measured: 2 of 6 runs covered at tau_L/tau0 = 5e3, 0.99 Delta, N = 2e3; 0 of 6 at 1e5, "
                "0.999 Delta, misses of 4-68 half-widths, all low, and 5 half-widths low at N = 2e4); where "
                "tau << tau0 'dryfric theory' (theory.exact_D) gives the exact D")
    return (f"|gamma_bar|/Delta = {brief(g)}, near the runaway bias (|gamma_bar| = Delta) with no damping to stop "
            "the drift: the D interval covers far less than 95% (measured at tau_L = inf: 0.83 at 0.9 Delta, "
            "0.78 at 0.95 Delta with N = 2e4; 0.50 at 0.99 Delta with N = 1e4, 0.24 with N = 2e3), its misses are "
            "low and may be by many half-widths" + (
                "; beyond 0.99 Delta, where no coverage was measured, D and M0 may be low by orders of magnitude "
                "(at 0.999999 Delta, white noise, 428 excursions: D 2.8e6 +- 1.6e6 against the exact 4e24, M0 36 "
                "against 1e6, in units of Delta, Gamma)" if g > 0.99 else "")
            + "; where tau << tau0 'dryfric theory' (theory.exact_D) gives the exact D")


#: N' below which the brute-force CI of D^t under-covers: the delta-method CI of a variance needs
#: many paths.  Measured on Gaussian U(t) (its law at t >> the correlation time; heavier tails
#: cover less), 2e4 replicates each: 0.44 at N' = 3, 0.74 at 10, 0.87 at 30, 0.92 at 100, 0.935 at
#: 200, 0.947 at 500 (8000 replicates).  At N' = 2 the two centred U^2 are equal and the CI is 0.
MIN_RELIABLE_PATHS = 500
#: the fewest paths brute force takes (API, CLI, :func:`bruteforce_estimates`): 2 give a CI of 0
MIN_PATHS = 3
#: the most paths brute force takes: it keeps every path's U(t) and computes its CI from them, ~50 bytes a path in
#: memory at the peak (3.6 GB here); 1e9 paths passed the work bound and grew towards ~50 GB (an audit)
MAX_PATHS = 2**26


def psi_D(x):
    r""":math:`\Psi_D(x) = (x_2 - 2x_1x_4/x_3 + x_1^2x_5/x_3^2)/x_3` for :math:`x = E(U, U^2, t, Ut, t^2)` (a vector
    of at least 5; ``ValueError`` otherwise: JAX clamps an index past the end, so a 2-vector gave a number; and,
    called on concrete numbers, for a non-finite entry or :math:`x_3 \le 0`)."""
    _check_vector(x, 5, "psi_D")
    m = x[0] / x[2]
    return (x[1] - 2 * m * x[3] + m * m * x[4]) / x[2]


def psi_D_paper(x):
    r"""The paper's printed :math:`(x_2 - x_1^2)/x_3`: biased unless :math:`M_0 = 0` (module docstring)."""
    return (x[1] - x[0] ** 2) / x[2]


def psi_M(x):
    r""":math:`\Psi_M(x) = x_1/x_3` (a vector of at least 3; ``ValueError`` otherwise, and on concrete numbers for a
    non-finite entry or :math:`x_3 \le 0`)."""
    _check_vector(x, 3, "psi_M")
    return x[0] / x[2]


def _check_vector(x, k: int, name: str) -> None:
    """``ValueError`` unless ``x`` is a vector of at least ``k`` entries (its shape is static, also under jit) and,
    where concrete (not under jit or grad), of finite real numbers with ``x[2]`` (a mean duration) > 0."""
    try:
        shape = jnp.shape(x)
    except (TypeError, ValueError):
        shape = None
    if shape is None or len(shape) != 1 or shape[0] < k:
        raise ValueError(f"x must be a vector of at least {k} numbers for {name} (got shape {shape})")
    if isinstance(x, jax.core.Tracer):  # under grad/jit: the values are checked where they are concrete
        return
    a = np.asarray(x)  # strings were a TypeError from the division, x_3 = 0 a NaN or inf (an audit)
    if a.dtype.kind not in "iuf" or not np.all(np.isfinite(a)) or not a[2] > 0:
        raise ValueError(f"x must hold finite real numbers with x_3 = E[t] > 0 for {name} (got {str(a.tolist())[:80]})")


def grad_psi_D_by_hand(x):
    """Hand-written gradient of :func:`psi_D` (checked against ``jax.grad`` in the tests)."""
    x1, x2, x3, x4, x5 = np.asarray(x, np.float64)
    m = x1 / x3
    num = x2 - 2 * m * x4 + m * m * x5
    dm1, dm3 = 1 / x3, -x1 / x3**2  # dm/dx1, dm/dx3
    dnum_dm = -2 * x4 + 2 * m * x5
    return np.array([dnum_dm * dm1 / x3, 1 / x3, dnum_dm * dm3 / x3 - num / x3**2, -2 * m / x3, m * m / x3])


def phi_bf(y):
    r""":math:`\Phi(y) = y_2 - y_1^2` (brute force, :math:`y = (U/\sqrt t, U^2/t)`)."""
    return y[1] - y[0] ** 2


def z_quantile(level: float) -> float:
    """:math:`q_{1-\\alpha/2}` of the standard normal for a two-sided ``level`` = 1 - alpha, in (0, 1)."""
    v = real_or_none(level)
    if v is None or not 0 < v < 1:
        # 0 gave a CI of 0, NaN a NaN one, < 0 a negative half-width, >= 1 NormalDist's error about its p
        raise ValueError(f"level must be a confidence level in (0, 1) (got {shown(level)})")
    return -NormalDist().inv_cdf((1 - v) / 2)  # the lower tail: 0.5 + level / 2 rounded to 1 near level = 1


#: degrees of freedom above which :func:`t_quantile` uses its series (the CDF's sum has df / 2 terms)
T_SERIES_DF = 200


def _t_central(t: float, df: int) -> float:
    r""":math:`P(|T| \le t)` for Student's T with integer ``df`` degrees of freedom, in closed form
    (Abramowitz & Stegun 26.7.3-4): with :math:`\theta = \arctan(t/\sqrt{\nu})` and :math:`c = \cos^2\theta`,
    :math:`\sin\theta\,(1 + \tfrac12 c + \tfrac{1\cdot3}{2\cdot4}c^2 + \dots)` (:math:`\nu - 2` over 2 terms past
    1) for even :math:`\nu`, :math:`\tfrac2\pi(\theta + \sin\theta\cos\theta\,(1 + \tfrac23 c + \tfrac{2\cdot4}{3\cdot5}
    c^2 + \dots))` (:math:`(\nu - 3)/2` terms past 1) for odd :math:`\nu > 1`, :math:`2\theta/\pi` at 1."""
    th = math.atan(t / math.sqrt(df))
    c, s = math.cos(th) ** 2, math.sin(th)
    term, total = 1.0, 1.0
    if df % 2 == 0:
        for k in range(1, df // 2):
            term *= (2 * k - 1) / (2 * k) * c
            total += term
        return s * total
    if df == 1:
        return 2 * th / math.pi
    for k in range(1, (df - 1) // 2):
        term *= (2 * k) / (2 * k + 1) * c
        total += term
    return 2 / math.pi * (th + s * math.cos(th) * total)


def t_quantile(level: float, df: int) -> float:
    r""":math:`t_{\nu,\,1-\alpha/2}`, the two-sided ``level`` = 1 - alpha quantile of Student's t with ``df``
    = :math:`\nu \ge 1` degrees of freedom: the CI of a mean of :math:`\nu + 1` i.i.d. values (normal ones:
    exactly), :math:`\bar d \pm t_{\nu}\,s/\sqrt{\nu + 1}`.  Up to :data:`T_SERIES_DF`, bisection on the
    closed-form CDF (:func:`_t_central`) to 1e-12 in t; above, the Cornish-Fisher series in :math:`1/\nu` about
    :func:`z_quantile` (Abramowitz & Stegun 26.7.5, four terms: error :math:`O(\nu^{-5})`).  Exact to ~1e-12
    at the levels a CI uses; :math:`P(|T| \le t)` loses digits as it nears 1 (an audit against mpmath: 3e-8
    relative at level 1 - 1e-9, 1e-4 at 1 - 1e-12), and :func:`z_quantile` at levels below ~1e-12."""
    z = z_quantile(level)
    v = float(level)
    if isinstance(df, (bool, np.bool_)) or not (isinstance(df, (int, np.integer)) or (
            isinstance(df, np.ndarray) and df.shape == () and np.issubdtype(df.dtype, np.integer))) or df < 1:
        raise ValueError(f"df must be an integer >= 1 (got {shown(df)})")
    df = int(df)
    if df > T_SERIES_DF:
        x = 1 / df  # int / int: no OverflowError for a df beyond float range (10**400 gave one)
        g = ((z**3 + z) / 4, (5 * z**5 + 16 * z**3 + 3 * z) / 96, (3 * z**7 + 19 * z**5 + 17 * z**3 - 15 * z) / 384,
             (79 * z**9 + 776 * z**7 + 1482 * z**5 - 1920 * z**3 - 945 * z) / 92160)
        return z + sum(gk * x ** (k + 1) for k, gk in enumerate(g))
    # z = 0 for a level below ~1e-16 (0.5 + level / 2 rounds to 0.5): doubling from it looped for ever (an audit)
    lo, hi = 0.0, max(z, 1.0)
    for _ in range(2100):  # 2^2100 passes any finite t
        if _t_central(hi, df) >= v:
            break
        lo, hi = hi, 2 * hi
    while hi - lo > 1e-12 * hi:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if _t_central(mid, df) < v else (lo, mid)
    return 0.5 * (lo + hi)


def delta_method(psi, mean, cov, n: int, level: float = 0.95):
    r"""Estimate :math:`\Psi(\hat S)` and the half-width of its asymptotic ``level`` CI.

    Args:
        psi: a scalar function of the mean vector (differentiated with ``jax.grad``).
        mean: sample mean :math:`\hat S_N`.
        cov: sample covariance :math:`\hat C_N` (divisor N, as in appendix D).
        n: sample size N.

    Returns:
        ``(estimate, half_width, sigma)`` with :math:`\hat\sigma_N^2 = \nabla\Psi^T \hat C_N \nabla\Psi`.
    """
    if isinstance(n, bool) or not isinstance(n, (int, np.integer, float, np.floating)) or not n >= 1 \
            or not math.isfinite(n) or n != math.floor(n):
        raise ValueError(f"n must be a sample size >= 1, a whole number (got {n!r}): n = 0 gave an infinite CI, n < 0 "
                         "NaN, inf a CI of 0")
    z_quantile(level)
    m, c = _real_array("mean", mean), _real_array("cov", cov)
    if m.ndim != 1 or m.size == 0 or c.shape != (m.size, m.size):
        raise ValueError(f"mean must be a vector of k >= 1 numbers and cov a k x k matrix (got shapes {m.shape} "
                         f"and {c.shape}; a mismatch was a TypeError from inside JAX)")
    scale = float(np.abs(c).max())
    if not np.allclose(c, c.T, rtol=1e-12, atol=1e-300) or np.linalg.eigvalsh(0.5 * (c + c.T)).min() < -1e-9 * scale:
        raise ValueError("cov must be a covariance matrix: symmetric and positive semidefinite (a negative definite "
                         "one gave a half-width of 0)")
    try:
        out = _delta_method(psi, m, c, n, level)
    except TypeError as e:  # psi itself: not a scalar, or not a function of one vector (a JAX TypeError)
        raise ValueError(f"psi must map a vector of {m.size} numbers to one number ({e})") from None
    if not all(math.isfinite(v) for v in out):
        raise ValueError(f"psi and its gradient must be finite at mean (got estimate {out[0]!r}, sigma {out[2]!r}): "
                         "e.g. a mean duration x_3 = 0 divides by 0")
    return out


def _delta_method(psi, mean, cov, n, level):
    """:func:`delta_method` on arguments the package built itself (not validated again)."""
    value, var = _value_and_variance(psi)(jnp.asarray(mean, jnp.float64), jnp.asarray(cov, jnp.float64))
    sigma = float(jnp.sqrt(var))
    return float(value), z_quantile(level) * sigma / math.sqrt(n), sigma  # float64 whatever n's type


def _real_array(name: str, x) -> np.ndarray:
    """``x`` as a float64 array of finite numbers, or ``ValueError`` naming ``name`` (a NaN mean gave a
    NaN or, where psi ignored the entry, a finite CI of a sample that held a NaN)."""
    try:
        a = np.asarray(x, np.float64)
    except (TypeError, ValueError):
        a = None
    if a is None or not np.isfinite(a).all():
        raise ValueError(f"{name} must hold finite real numbers (got {shown(x)})")
    return a


@functools.lru_cache(maxsize=16)
def _value_and_variance(psi):
    r""":math:`(\Psi(m), \max(\nabla\Psi^T C \nabla\Psi, 0))` compiled once per ``psi`` (and shape):
    traced op by op, ``jax.grad`` cost 12 ms per long-excursion estimate, and the replicate loops
    (coverage, Fig. 9's RMSEs) ran a thousand of them."""
    def f(mean, cov):
        value, g = jax.value_and_grad(psi)(mean)
        return value, jnp.maximum(g @ cov @ g, 0.0)
    return jax.jit(f)


#: names of the sums E[X_i X_j] for X = (U, U^2, t, Ut, t^2)
_PRODUCTS = (("U2", "U3", "Ut", "U2t", "Ut2"),
             ("U3", "U4", "U2t", "U3t", "U2t2"),
             ("Ut", "U2t", "t2", "Ut2", "t3"),
             ("U2t", "U3t", "Ut2", "U2t2", "Ut3"),
             ("Ut2", "U2t2", "t3", "Ut3", "t4"))


def moments_from_sums(T: dict):
    """Mean and covariance (divisor N) of X = (U, U^2, t, Ut, t^2) from the sums ``T``."""
    n = T["n"]
    S = np.array([T["U"], T["U2"], T["t"], T["Ut"], T["t2"]]) / n
    E2 = np.array([[T[k] for k in row] for row in _PRODUCTS]) / n
    return S, E2 - np.outer(S, S)


#: The D interval is flagged (:func:`rounding_note`) when rounding may move its variance by more than
#: this fraction (its half-width by about half as much).
ROUNDING_TOL = 1e-2


@functools.lru_cache(maxsize=1)
def _grad_psi_D():
    return jax.jit(jax.grad(psi_D))


def ci_rounding(T: dict) -> float:
    r"""An estimate of the relative rounding error of the D interval's variance, from the sums ``T``.

    :math:`\hat\sigma^2 = \nabla\Psi^T \mathbf C \nabla\Psi` is formed from raw moments,
    :math:`\mathbf C = E[\boldsymbol X \boldsymbol X^T] - \boldsymbol S \boldsymbol S^T`.  When the drift of an
    excursion, :math:`M_0 t`, dominates its spread (:math:`\kappa = M_0^2 E[t^2] / (D E[t]) \gg 1`), the
    terms cancel to a small fraction :math:`\sim 1/(20\kappa^2)` of their size and float64's rounding
    (:math:`\epsilon = 2.2\cdot 10^{-16}`) is amplified by the inverse of that fraction:

    .. math::
        \rho = \epsilon\,\frac{|\nabla\Psi|^T (|E[\boldsymbol X \boldsymbol X^T]| + |\boldsymbol S
        \boldsymbol S^T|)\,|\nabla\Psi|}{\hat\sigma^2}

    (``inf`` if :math:`\hat\sigma^2 \le 0`, where the half-width came out 0).  On synthetic excursions
    (t ~ Gamma(2), U = mu t + sqrt(t) Z, N = 1e5, seed 0) rho was 3-50x the actual error of sigma^2: 5e-6,
    4e-4, 5e-2 and 2.2 at mu = 100, 300, 1e3 and 3e3 (half-width off by 3e-7, 5e-5, 4e-4 and 29%; at mu = 1e4
    the variance came out negative).  The runs measured reach kappa = 1.6e4 (rho ~ 1e-6: gamma_bar = 3 Delta,
    tau_L = 1 s, white noise); the default max_work refuses the points beyond.
    """
    S, C = moments_from_sums(T)
    g = np.asarray(_grad_psi_D()(jnp.asarray(S, jnp.float64)))
    var = float(g @ C @ g)
    SS = np.outer(S, S)
    size = float(np.abs(g) @ (np.abs(C + SS) + np.abs(SS)) @ np.abs(g))  # C + SS = E[X X^T], the raw moments
    if not var > 0:
        return float("inf")
    return float(np.finfo(np.float64).eps) * size / var


#: how :func:`rounding_note`'s warning begins (a pool recomputes it for its own sums)
ROUNDING_NOTE = "the CI of D is not reliable"


def rounding_note(T: dict) -> str | None:
    """The warning for a D interval that rounding may have moved by more than ~``ROUNDING_TOL / 2``
    (:func:`ci_rounding`), else None.  Estimates and pooled estimates carry it."""
    rho = ci_rounding(T)
    if rho <= ROUNDING_TOL:
        return None
    what = ("its variance came out <= 0 by rounding, so the half-width is 0 and means nothing" if rho == float("inf")
            else f"rounding may move its half-width by up to ~{50 * rho:.2g}%")
    return (f"{ROUNDING_NOTE}: the drift of each excursion dominates its spread, and the delta method's "
            f"variance, a difference of moment sums, cancels: {what} (D and M0 themselves are not affected)")


def sums_from_samples(U, t, t_half=None) -> dict:
    """The sufficient statistics of per-excursion samples (tests, and any external sampler)."""
    U, t = np.asarray(U, np.float64), np.asarray(t, np.float64)
    th = np.zeros_like(t) if t_half is None else np.asarray(t_half, np.float64)
    return dict(n=float(U.size), U=U.sum(), U2=(U**2).sum(), U3=(U**3).sum(), U4=(U**4).sum(), t=t.sum(),
                t2=(t**2).sum(), t3=(t**3).sum(), t4=(t**4).sum(), Ut=(U * t).sum(), U2t=(U**2 * t).sum(),
                U3t=(U**3 * t).sum(), Ut2=(U * t**2).sum(), U2t2=(U**2 * t**2).sum(), Ut3=(U * t**3).sum(),
                t_half=th.sum())


def long_excursion_estimates(T: dict, level: float = 0.95) -> dict:
    """D, M0 (and mean durations) with CIs from the sums ``T`` of :class:`~dryfric_jax.rounds.ExcursionStats`.

    Units are those of the sums (nondimensional in the engine).
    """
    n = int(round(T["n"]))
    if n < 2:
        raise ValueError(f"need at least 2 complete excursions for a CI (got {n})")
    S, C = moments_from_sums(T)
    D, D_ci, _ = _delta_method(psi_D, S, C, n, level)
    M0, M0_ci, _ = _delta_method(psi_M, S, C, n, level)
    z = z_quantile(level)
    return dict(D=D, D_ci=D_ci, M0=M0, M0_ci=M0_ci, mean_duration=S[2],
                mean_duration_ci=z * np.sqrt(max(C[2, 2], 0.0) / n),
                mean_half_duration=T["t_half"] / n, n_excursions=n)


def bruteforce_estimates(U, t: float, level: float = 0.95) -> dict:
    r"""Brute-force :math:`D^t` and :math:`M_0^t = \overline{U(t)}/t` with delta-method CIs.

    Args:
        U: displacements :math:`U^{(k)}(t)` of N' independent paths.
        t: the horizon.
    """
    check_positive("t", t)  # t <= 0 gave NaN and inf estimates
    U = np.asarray(U, np.float64)
    n = U.size
    if n < MIN_PATHS:
        raise ValueError(f"n_paths must be >= {MIN_PATHS} (got {n}): with 2 paths the D_t CI is 0")
    # centred first (D^t does not change under a shift of U, nor does its delta-method variance): y2 - y1^2
    # and the gradient (-2 y1, 1) cancelled catastrophically when |mean U| >> sd U (a strong bias, a long t;
    # mean 1e6, sd 1e-3 gave D = 2.4e-4 for 1.0e-6), and D went below 0 by rounding (-1.5e-54 at t = 1e-12 s)
    Uc = U - U.mean()
    Y = np.stack([Uc / np.sqrt(t), Uc**2 / t])
    R = Y.mean(1)
    G = np.cov(Y, bias=True)
    D, D_ci, _ = _delta_method(phi_bf, R, G, n, level)
    D = max(D, 0.0)  # y2 >= y1^2 up to the rounding of y1 ~ 1e-16 sd
    z = z_quantile(level)
    return dict(D_t=D, D_t_ci=D_ci, M0_t=float(U.mean() / t), M0_t_ci=z * float(U.std() / t / np.sqrt(n)),
                n_paths=n, t=t)


def replicate_coverage(lane_sums: np.ndarray, names, lanes_per_replicate: int, D_true: float, M_true: float,
                       level: float = 0.95) -> dict:
    """Empirical coverage of the D and M0 CIs over independent replicates.

    Args:
        lane_sums: per-lane sufficient statistics (rows: lanes, columns: ``names``); lanes hold
            i.i.d. excursions, so consecutive groups of ``lanes_per_replicate`` lanes are
            independent replicates.
        D_true, M_true: exact values to cover.
    """
    reps = lane_sums.shape[0] // lanes_per_replicate
    hit_D = hit_M = 0
    widths, sizes = [], []
    for r in range(reps):
        block = lane_sums[r * lanes_per_replicate:(r + 1) * lanes_per_replicate]
        e = long_excursion_estimates(dict(zip(names, block.sum(0))), level)
        sizes.append(e["n_excursions"])
        hit_D += abs(e["D"] - D_true) <= e["D_ci"]
        hit_M += abs(e["M0"] - M_true) <= e["M0_ci"]
        widths.append(e["D_ci"] / abs(D_true))
    return dict(replicates=reps, coverage_D=hit_D / reps, coverage_M0=hit_M / reps,
                rel_half_width=float(np.mean(widths)), min_size=int(min(sizes)), mean_size=float(np.mean(sizes)))
