r"""Where a uniform becomes a normal: the inverse normal CDF :math:`\Phi^{-1}`, branch-free, in
float64 and float32, for the engine's generator (:mod:`dryfric_jax.rng`).

:math:`\Phi^{-1}` is Wichura's rational approximation (algorithm AS 241, *Appl. Statist.* 37
(1988) 477-484): with :math:`q = u - 1/2`,

.. math::
    \Phi^{-1}(u) = q\,\frac{A(r)}{B(r)},\quad r = 0.180625 - q^2 \qquad (|q| \le 0.425),

and otherwise, with :math:`s = \sqrt{-\ln\min(u, 1-u)}`,

.. math::
    \Phi^{-1}(u) = \operatorname{sign}(q)\,\frac{C(s - 1.6)}{D(s - 1.6)} \ (s \le 5), \qquad
    \operatorname{sign}(q)\,\frac{E(s - 5)}{F(s - 5)} \ (s > 5),

A ... F polynomials of degree 7 (PPND16, float64, relative error ~1e-16) or, in float32, of
degree 3 and 2 (PPND7, ~1e-7; :math:`s \le \sqrt{24 \ln 2} < 5` for every float32 argument this
module is given, so the third branch is not needed).  Every branch is evaluated and one is
selected (one division), so XLA vectorises it; the logarithm is :func:`log`, because XLA:CPU
calls a scalar libm routine per element for ``jnp.log`` in float64 (measured on one core of the
2-core test machine: ``jnp.log`` alone ~7 ns per float64 number, this whole transform ~6 ns, its
:func:`log` under 2 ns).

Accuracy, tested against ``scipy.special.ndtri`` (``tests/test_icdf.py``): float64 within 8 ulp
on 10^6 random arguments and at every branch edge down to 2^-53; float32 within 6 float32 ulp
(about 4e-7 relative) at every one of the 2^23 arguments the generator can produce.  XLA's
float32 ``erf_inv``, which ``jax.random.normal`` uses, is 90 ulp off near u = 1 on the same grid.
"""
from __future__ import annotations

import numpy as np
from jax import lax
import jax.numpy as jnp

# AS 241 PPND16 (float64)
_A16 = (3.3871328727963666080e0, 1.3314166789178437745e2, 1.9715909503065514427e3, 1.3731693765509461125e4,
        4.5921953931549871457e4, 6.7265770927008700853e4, 3.3430575583588128105e4, 2.5090809287301226727e3)
_B16 = (1.0, 4.2313330701600911252e1, 6.8718700749205790830e2, 5.3941960214247511077e3,
        2.1213794301586595867e4, 3.9307895800092710610e4, 2.8729085735721942674e4, 5.2264952788528545610e3)
_C16 = (1.42343711074968357734e0, 4.63033784615654529590e0, 5.76949722146069140550e0, 3.64784832476320460504e0,
        1.27045825245236838258e0, 2.41780725177450611770e-1, 2.27238449892691845833e-2, 7.74545014278341407640e-4)
_D16 = (1.0, 2.05319162663775882187e0, 1.67638483018380384940e0, 6.89767334985100004550e-1,
        1.48103976427480074590e-1, 1.51986665636164571966e-2, 5.47593808499534494600e-4, 1.05075007164441684324e-9)
_E16 = (6.65790464350110377720e0, 5.46378491116411436990e0, 1.78482653991729133580e0, 2.96560571828504891230e-1,
        2.65321895265761230930e-2, 1.24266094738807843860e-3, 2.71155556874348757815e-5, 2.01033439929228813265e-7)
_F16 = (1.0, 5.99832206555887937690e-1, 1.36929880922735805310e-1, 1.48753612908506148525e-2,
        7.86869131145613259100e-4, 1.84631831751005468180e-5, 1.42151175831644588870e-7, 2.04426310338993978564e-15)
# AS 241 PPND7 (float32)
_A7 = (3.3871327179, 50.434271938, 159.29113202, 59.109374720)
_B7 = (1.0, 17.895169469, 78.757757664, 67.187563600)
_C7 = (1.4234372777, 2.7568153900, 1.3067284816, 0.17023821103)
_D7 = (1.0, 0.73700164250, 0.12021132975)

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


def _horner_either(c1, c2, first, x):
    """``_horner(c1, x)`` where ``first`` else ``_horner(c2, x)``, in one pass (coefficients selected)."""
    dt = x.dtype
    p = jnp.where(first, np.array(c1[-1], dt), np.array(c2[-1], dt))
    for a, b in zip(c1[-2::-1], c2[-2::-1]):
        p = p * x + jnp.where(first, np.array(a, dt), np.array(b, dt))
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
    ``numpy.log`` (``tests/test_icdf.py``)."""
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


def ndtri(u):
    r""":math:`\Phi^{-1}(u)` for float32/float64 ``u`` in (0, 1) (module docstring), elementwise.

    Exactly antisymmetric, :math:`\Phi^{-1}(1 - u) = -\Phi^{-1}(u)`, wherever :math:`1 - u` is
    exact (every argument of the generator: :math:`u = (k + 1/2) 2^{-m}`).  Arguments must
    satisfy :math:`\min(u, 1-u) \ge 2^{-53}` (float64) or :math:`2^{-24}` (float32)."""
    u = jnp.asarray(u)
    dt = _float_dtype(u, "ndtri")
    wide = dt.itemsize == 8
    half = np.array(0.5, dt)
    q = u - half
    central = jnp.abs(q) <= np.array(0.425, dt)
    r = np.array(0.180625, dt) - q * q
    s = jnp.sqrt(-log(jnp.minimum(u, np.array(1.0, dt) - u)))
    if wide:
        near = s <= np.array(5.0, dt)
        x = s - jnp.where(near, np.array(1.6, dt), np.array(5.0, dt))
        tail_num, tail_den = _horner_either(_C16, _E16, near, x), _horner_either(_D16, _F16, near, x)
        num_c, den_c = q * _horner(_A16, r), _horner(_B16, r)
    else:
        x = s - np.array(1.6, dt)
        tail_num, tail_den = _horner(_C7, x), _horner(_D7, x)
        num_c, den_c = q * _horner(_A7, r), _horner(_B7, r)
    tail_num = jnp.where(q < 0, -tail_num, tail_num)
    return jnp.where(central, num_c, tail_num) / jnp.where(central, den_c, tail_den)
