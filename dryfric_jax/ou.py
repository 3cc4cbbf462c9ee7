r"""Exact step of the Ornstein-Uhlenbeck noise (paper section 6.2, MODEL_NOTES section 3.5).

For :math:`\tau\,dX = -X\,dt + \sqrt2\,dW` started at :math:`X_0 = x`, the pair
:math:`(\Xi, X_h) = (h^{-1}\int_0^h X_s\,ds,\ X_h)` is Gaussian with mean :math:`x\,m(h)` and
covariance :math:`\Sigma(h)`:

.. math::
    m(h) = \Big(\tfrac{\tau}{h}(1-e^{-h/\tau}),\ e^{-h/\tau}\Big), \qquad
    \Sigma(h) = \frac1\tau\begin{pmatrix} \hat g(r) & q(r) \\ q(r) & p(r)\end{pmatrix},\quad r = h/\tau,

with :math:`\hat g = (2r - 3 + 4e^{-r} - e^{-2r})/r^2`, :math:`q = (1-e^{-r})^2/r` and
:math:`p = 1 - e^{-2r}`.  The printed :math:`\hat g` cancels catastrophically for small r, so
it is evaluated by its Taylor series :math:`\hat g = \sum_{k\ge3} (-1)^k (4-2^k) r^{k-2}/k!` for
:math:`r < 1`.  The Cholesky factor is built from these pieces,

.. math::
    L_{11} = \sqrt{\hat g/\tau},\quad L_{21} = q/\sqrt{\tau\hat g},\quad
    L_{22} = \sqrt{(\hat g p - q^2)/(\tau \hat g)},

never from a numerical factorisation of a rounded matrix: the correlation of the pair tends
to 1 as :math:`r \to 0`, where :math:`\det\Sigma \sim r^2/(3\tau^2)` is all that is left.
All expressions stay accurate for :math:`r \in [10^{-8}, 10^{8}]` in float64 and float32, and
for larger r, where :math:`\hat g = (2 - 3/r)/r` exactly and :math:`r^2` would overflow.  Towards small r they
hold (to 3e-16 against 400-digit arithmetic at :math:`r = 10^{-12}`-:math:`10^{-100}`, float64) until
:math:`(1 - e^{-r})^2` underflows: :math:`L_{21} = L_{22} = 0` below :math:`r \approx 2\sqrt{\text{tiny}}` (the
factor is exact to rounding at 2, 3, 4 and 8 :math:`\sqrt{\text{tiny}}` and 0 at 1.5, in float64 and float32,
measured) and 0/0 = NaN where r itself is below the dtype's normal range.  So :func:`ou_step` and :func:`ou_moments`
refuse :math:`r <` :func:`min_ratio` (:math:`4\sqrt{\text{tiny}}` of the dtype they compute in: 6.0e-154 in float64,
4.3e-19 in float32), a ``ValueError`` naming h/tau (an audit: NaN from ``make_di_model`` at :math:`\tau = 10^{299}`
s, h = 1e-12 s), and :func:`ou_step` a factor that its cast to float32 rounds to 0.
"""
from __future__ import annotations

import math

import equinox as eqx
import jax
import jax.numpy as jnp

from .params import check_positive
from .plan import dtype_name

_N_SERIES = 30
# coefficients c_j of ghat(r) = sum_j c_j r^j, j = k - 2, k = 3 .. 3 + _N_SERIES - 1
_GHAT_COEFFS = [(-1) ** k * (4 - 2**k) / math.factorial(k) for k in range(3, 3 + _N_SERIES)]


_R_HUGE = 1e8  # beyond this r the exponentials of ghat vanish (e^{-1e8} = 0)


def min_ratio(dtype) -> float:
    """The least h/tau :func:`ou_step` and :func:`ou_moments` accept when they compute in ``dtype`` (module
    docstring): 4 sqrt(tiny), twice the least r where the factor is still exact to rounding (a margin of 1e4
    refused float32 steps that were exact: a review)."""
    return 4.0 * math.sqrt(float(jnp.finfo(dtype).tiny))


def check_ratio(h, tau, dtype) -> None:
    """``ValueError`` naming h/tau below :func:`min_ratio` of ``dtype``, the dtype the step is computed in, from the
    caller's ``h`` and ``tau`` as given (a float32 cast made tau = 1e39 "inf"); concrete values only (a tracer is
    checked where it was made)."""
    if isinstance(h, jax.core.Tracer) or isinstance(tau, jax.core.Tracer):
        return
    lo, h, tau = min_ratio(dtype), float(h), float(tau)
    if not h / tau >= lo:  # in Python floats: the array's own h/tau may underflow to 0
        raise ValueError(f"h/tau must be >= {lo:.2g} in {jnp.dtype(dtype).name} (got h = {h:.3g}, tau = {tau:.3g}: "
                         f"h/tau = {h / tau:.3g}): the OU step's covariance underflows below it")


def _ghat(r):
    r = jnp.asarray(r)
    small = r < 1.0
    rs = jnp.where(small, r, 0.5)
    acc = jnp.zeros_like(rs)
    for c in reversed(_GHAT_COEFFS):  # Horner
        acc = acc * rs + c
    series = acc * rs
    # r > 1e8: the exponentials are exactly 0 and r^2 may overflow (white noise, tau' -> 0)
    huge = r > _R_HUGE
    rb = jnp.where(small | huge, 2.0, r)
    direct = (2 * rb - 3 + 4 * jnp.exp(-rb) - jnp.exp(-2 * rb)) / rb**2
    rh = jnp.where(huge, r, 2.0)
    return jnp.where(small, series, jnp.where(huge, (2.0 - 3.0 / rh) / rh, direct))


def ou_moments(h, tau):
    r"""Mean vector and covariance of (time-average of X over a step, X at the end of the step).

    Args:
        h: step length (> 0).
        tau: OU correlation time (> 0).

    Returns:
        ``(m1, m2, S11, S12, S22)`` with :math:`m = (m_1, m_2)` and
        :math:`\Sigma = [[S_{11}, S_{12}], [S_{12}, S_{22}]]` (paper section 6.2), computed in the
        dtype of the inputs (float64 for Python numbers and integers).
    """
    check_positive("h", h)  # concrete values only, as in ou_step (0 or -1 gave NaN or a negative variance)
    check_positive("tau", tau)
    ct = jnp.result_type(h, float)  # the dtype it computes in
    check_ratio(h, tau, ct)
    h = jnp.asarray(h, ct)  # an integer h made tau an integer: tau = 0.5 became 0
    tau = jnp.asarray(tau, dtype=h.dtype)
    r = h / tau
    em1 = jnp.expm1(-r)  # e^{-r} - 1, accurate for small r
    m1 = -em1 / r
    m2 = jnp.exp(-r)
    S11 = _ghat(r) / tau
    S12 = em1 * em1 / r / tau
    S22 = -jnp.expm1(-2 * r) / tau
    return m1, m2, S11, S12, S22


class OUStep(eqx.Module):
    r"""Constants of the exact OU step for one (tau, h), Cholesky factor included.

    One step from :math:`X_0 = x` with standard normals :math:`z_1, z_2`:

    .. math::
        \Xi = x m_1 + L_{11} z_1, \qquad X_h = x m_2 + L_{21} z_1 + L_{22} z_2 .
    """

    m1: jnp.ndarray
    m2: jnp.ndarray
    L11: jnp.ndarray
    L21: jnp.ndarray
    L22: jnp.ndarray

    def sample(self, x, z1, z2):
        """Return ``(Xi, X_next)`` given the current ``x`` and two standard normals."""
        return x * self.m1 + self.L11 * z1, x * self.m2 + self.L21 * z1 + self.L22 * z2

    def stationary_sd(self):
        r"""Standard deviation of the stationary law of the discrete X chain,
        :math:`\sqrt{(L_{21}^2 + L_{22}^2)/(1 - m_2^2)}`, computed in float64 and returned in the step's dtype (in
        float32 throughout it was 8% off at h/tau = 1e-7): :math:`1/\sqrt{\tau'}` for a float64 step, that of the
        rounded chain for a float32 one (inf where :math:`m_2` rounds to 1)."""
        c = [jnp.asarray(a, jnp.float64) for a in (self.L21, self.L22, self.m2)]
        return jnp.sqrt((c[0] ** 2 + c[1] ** 2) / (1.0 - c[2] ** 2)).astype(self.m2.dtype)

    def astype(self, dtype) -> "OUStep":
        return OUStep(*(jnp.asarray(c, dtype) for c in (self.m1, self.m2, self.L11, self.L21, self.L22)))


def ou_step(h, tau, dtype=None) -> OUStep:
    r"""Build :class:`OUStep` for step ``h`` and correlation time ``tau``.

    The factor is assembled from the stable closed forms (module docstring), in float64 when
    the inputs are Python numbers, and cast to ``dtype`` at the end.
    """
    check_positive("h", h)  # concrete values only; a tracer is checked where it was made
    check_positive("tau", tau)
    dtype = jnp.result_type(float) if dtype is None else dtype_name(dtype)  # float16 was accepted, "foo" a TypeError
    ct = jnp.result_type(h, float)  # the dtype it computes in
    check_ratio(h, tau, ct)
    h = jnp.asarray(h, ct)
    tau = jnp.asarray(tau, h.dtype)
    r = h / tau
    em1 = jnp.expm1(-r)
    g = _ghat(r)
    q = em1 * em1 / r
    p = -jnp.expm1(-2 * r)
    det = jnp.maximum(g * p - q * q, 0.0)  # = tau^2 det(Sigma) >= 0
    sqt = jnp.sqrt(tau)
    L11 = jnp.sqrt(g) / sqt
    L21 = q / jnp.sqrt(g) / sqt
    L22 = jnp.sqrt(det / g) / sqt
    step = OUStep(-em1 / r, jnp.exp(-r), L11, L21, L22)
    out = step.astype(dtype)
    if not isinstance(L22, jax.core.Tracer):  # the factor computed in float64, then cast: float32 may round it to 0
        lost = [f for f in ("L11", "L21", "L22") if getattr(out, f) == 0 < getattr(step, f)]
        if lost:  # the noise would not move X (ou_step(1e-100, 1, dtype='float32') gave L = 0: a review)
            raise ValueError(f"h/tau = {float(r):.3g} is too small for dtype {jnp.dtype(dtype).name}: the OU step's "
                             f"factor ({', '.join(lost)}) rounds to 0 in it; use float64")
    return out


def ou_moments_reference(h: float, tau: float, digits: int = 60):
    """Printed closed forms of m and Sigma evaluated in ``digits``-digit decimal arithmetic.

    An independent reference for tests (no series, no expm1): the cancellation is beaten by
    brute precision instead.
    """
    from decimal import Decimal, localcontext

    with localcontext() as ctx:
        ctx.prec = digits
        h_, t_ = Decimal(repr(float(h))), Decimal(repr(float(tau)))
        r = h_ / t_
        e1, e2 = (-r).exp(), (-2 * r).exp()
        m1 = t_ / h_ * (1 - e1)
        S11 = t_ / h_**2 * (2 * r - 3 + 4 * e1 - e2)
        S12 = (1 - e1) ** 2 / h_
        S22 = (1 - e2) / t_
        return tuple(float(v) for v in (m1, e1, S11, S12, S22))

