r"""Where uniform bits become normals: the Box-Muller transform, branch-free and vectorised, in
float64 and float32, for the engine's generator (:mod:`dryfric_jax.rng`).

A pair of independent standard normals from a pair of independent uniforms, :math:`u \in (0, 1)`
and :math:`t \in [0, 1)` (Box and Muller, *Ann. Math. Statist.* 29 (1958) 610),

.. math::
    (Z_1, Z_2) = \sqrt{-2\ln u}\,\big(\cos 2\pi t,\ \sin 2\pi t\big).

The logarithm is :func:`log` and the turn's cosine and sine :func:`cos_sin_turns`, both
polynomials and selects that XLA vectorises: XLA:CPU calls a scalar libm routine per element for
``jnp.log``, ``jnp.cos`` and ``jnp.sin`` in float64 (~7 ns a number on one core of the 2-core
test machine; the engine's float64 normals, hash included, ~4 ns each).  With one logarithm and
one square root per *two* normals and an angle whose range reduction is exact (:math:`4t` minus
its nearest integer), this is 1.9x (float64) and 1.3x (float32) the rate of the branch-free
inverse normal CDF (AS 241) that version 0.2.4 used, which evaluated three rational functions, a
logarithm and a square root per normal.

Accuracy (``tests/test_boxmuller.py``, against extended-precision references): :func:`log` within
4 ulp of ``numpy.log``; :func:`cos_sin_turns` within 2 ulp (relative, also near the zeros) in
float64 on 10^6 random and all quadrant-edge arguments, and in float32 at all 2^23 arguments the
generator gives (1.7 measured); a normal within 6 ulp of the formula evaluated in extended
precision (4 measured).
"""
from __future__ import annotations

import numpy as np
from jax import lax
import jax.numpy as jnp

# cos(pi r / 2) = C(r^2) and sin(pi r / 2) = r S(r^2) on |r| <= 1/2, lowest degree first (itemsize ->
# coefficients): weighted least squares iterated toward minimax (Lawson) at 200 Chebyshev nodes in
# r^2 in 50-digit arithmetic, relative error 3.6e-20 / 3.3e-18 (float64) and 5.6e-11 / 3.2e-9
# (float32) before rounding the coefficients (scripts/fit_turn_polynomials.py prints them)
_COS = {8: (1.0, -1.2337005501361697, 0.2536695079010466, -0.020863480763308004, 0.0009192602741467696,
            -2.5202036558201833e-05, 4.710603581106915e-07, -6.320557318337729e-09),
        4: (0.9999999999439372, -1.2337005395647422, 0.2536691825958039, -0.020859936026650417,
            0.0009033629738938657)}
_SIN = {8: (1.5707963267948966, -0.6459640975062443, 0.07969262624603957, -0.004681754132282417,
            0.00016044115029163752, -3.598641754399591e-06, 5.6337210057061285e-08),
        4: (1.5707963217083254, -0.6459634602321207, 0.07968003275723907, -0.004601657857472804)}
_LN2_HI, _LN2_LO = 6.93147180369123816490e-01, 1.90821492927058770002e-10  # ln 2 = HI + LO, HI exact in 32 bits
_LOG_TERMS = {8: 12, 4: 5}  # terms of the atanh series (itemsize -> terms): error < 2^-60 / 2^-30


def _float_dtype(x, fn: str):
    """``x``'s dtype, float32 or float64, else ``ValueError`` naming the function ``fn``."""
    dt = np.dtype(x.dtype)
    if dt not in (np.dtype(np.float32), np.dtype(np.float64)):
        raise ValueError(f"{fn}: dtype must be float32 or float64 (got {dt.name})")
    return dt


def _horner(coeffs, x):
    """:math:`\\sum_k c_k x^k` (``coeffs`` lowest degree first) in ``x``'s dtype."""
    dt = x.dtype
    p = jnp.full_like(x, np.array(coeffs[-1], dt))
    for c in coeffs[-2::-1]:
        p = p * x + np.array(c, dt)
    return p


def log(x):
    r"""Natural logarithm of positive *normal* float32/float64 numbers (no zeros, subnormals,
    infinities or NaN: the caller's arguments are at least 2^-53), elementwise and vectorisable.

    With :math:`x = 2^e m`, :math:`m \in [1/\sqrt2, \sqrt2)` read from the bits and
    :math:`s = (m - 1)/(m + 1)`,

    .. math::
        \ln x = e \ln 2 + 2\,\operatorname{artanh} s = e\ln 2 + 2s \sum_{k \ge 0} \frac{s^{2k}}{2k+1},
        \qquad |s| \le 3 - 2\sqrt2 < 0.1716,

    the series cut where its next term is below the dtype's rounding.  Within 4 ulp of
    ``numpy.log`` (``tests/test_boxmuller.py``)."""
    x = jnp.asarray(x)
    dt = _float_dtype(x, "log")
    wide = dt.itemsize == 8
    ut, it = (np.uint64, np.int64) if wide else (np.uint32, np.int32)
    nm, bias = (52, 1023) if wide else (23, 127)
    b = lax.bitcast_convert_type(x, ut)
    e = (b >> ut(nm)).astype(it) - it(bias)
    m = lax.bitcast_convert_type((b & ut((1 << nm) - 1)) | ut(bias << nm), dt)  # [1, 2)
    big = m > np.array(np.sqrt(2.0), dt)
    m = jnp.where(big, m * np.array(0.5, dt), m)
    e = jnp.where(big, e + 1, e).astype(dt)
    f = m - np.array(1.0, dt)
    s = f / (np.array(2.0, dt) + f)
    series = _horner([1.0 / (2 * k + 1) for k in range(_LOG_TERMS[dt.itemsize])], s * s)
    return e * np.array(_LN2_HI, dt) + (np.array(2.0, dt) * s * series + e * np.array(_LN2_LO, dt))


def cos_sin_turns(t):
    r""":math:`(\cos 2\pi t, \sin 2\pi t)` for float32/float64 ``t`` with :math:`4t` exact (every
    :math:`t \in [0, 1)` of the generator: :math:`k 2^{-m}`), elementwise and vectorisable.

    With :math:`q` the integer nearest :math:`4t` and :math:`r = 4t - q \in [-1/2, 1/2]` (exact),
    :math:`2\pi t = (\pi/2)(q + r)`, and :math:`c = \cos(\pi r/2)`, :math:`s = \sin(\pi r/2)` by
    the polynomials :math:`C(r^2)`, :math:`r S(r^2)` (``_COS``, ``_SIN``) give, for
    :math:`q \bmod 4 = 0, 1, 2, 3`, :math:`(c, s), (-s, c), (-c, -s), (s, -c)`.  The reduction
    is exact, so the relative error is that of the polynomials, also near the zeros; ``s`` is
    exactly odd in ``r``, so :math:`t \to 1 - t` flips the sine's sign exactly."""
    t = jnp.asarray(t)
    dt = _float_dtype(t, "cos_sin_turns")
    t4 = t * np.array(4.0, dt)
    q = jnp.round(t4)
    r = t4 - q
    r2 = r * r
    c, s = _horner(_COS[dt.itemsize], r2), r * _horner(_SIN[dt.itemsize], r2)
    qi = q.astype(jnp.int32) & 3
    odd = (qi & 1) == 1
    cos, sin = jnp.where(odd, s, c), jnp.where(odd, c, s)
    return jnp.where((qi == 1) | (qi == 2), -cos, cos), jnp.where(qi >= 2, -sin, sin)


def pair(u, t):
    r"""Box-Muller: :math:`\sqrt{-2\ln u}\,(\cos 2\pi t, \sin 2\pi t)` (module docstring) for
    float32/float64 ``u`` in (0, 1), at least :math:`2^{-53}` (the logarithm's domain, see
    :func:`log`), and ``t`` as :func:`cos_sin_turns` takes it."""
    u, t = jnp.asarray(u), jnp.asarray(t)
    dt = _float_dtype(u, "pair")
    if _float_dtype(t, "pair") != dt:
        raise ValueError(f"pair: u and t must have one dtype (got {dt.name} and {np.dtype(t.dtype).name})")
    radius = jnp.sqrt(np.array(-2.0, dt) * log(u))
    cos, sin = cos_sin_turns(t)
    return radius * cos, radius * sin
