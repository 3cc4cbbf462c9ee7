r"""Exact white-noise results, in the convention of *this* model (MODEL_NOTES section 2).

As :math:`\tau \to 0`, :math:`\sqrt\Gamma X \to \sqrt{2\Gamma}\,\xi`: the limit is
:math:`dV = (b(V) - \Delta\,\mathrm{sgn}\,V)\,dt + \sqrt{2\Gamma}\,dW` (Fokker-Planck diffusion
coefficient :math:`\Gamma`).  Literature formulas written for noise :math:`\sqrt{\Gamma_w}\xi` apply
with :math:`\Gamma_w = 2\Gamma`.  The paper prints several of them in the :math:`\Gamma_w = \Gamma`
form (its stationary density, its Hayakawa formula and Table 1): those are the values of this
model with :math:`\Gamma` halved, not of the model as written.

Everything is computed in nondimensional units (:math:`\Gamma = \Delta = 1`) and scaled back:
:math:`D = D'\,\Gamma^3/\Delta^4`, :math:`M_0 = M_0'\,\Gamma/\Delta`; the closed forms (used for
:math:`\tau_L = \infty`) in physical units, with no intermediate overflow or underflow.  A result
outside float64's range is refused by name (``ValueError``), never returned as inf or 0.
"""
from __future__ import annotations

import contextlib
import math
import sys
import warnings

import numpy as np
from scipy import integrate, special

from .limits import check_recurrent
from .params import Params, check_finite, check_params, check_positive, refuse_traced


#: tau/tau0 above which the white-noise values are said not to be the params' (their tau is not used)
WHITE_TAU_ND = 1e-3


def _white_only(params: Params, name: str) -> None:
    """Warn (a ``DryfricWarning``) when ``params`` has a correlation time these tau -> 0 values ignore: given
    Fig. 3's params, exact_D returned the white-noise 0.0227 without a word, 8.5x the colored-noise D (a user
    audit).  At tau/tau0 <= :data:`WHITE_TAU_ND` the white-noise value is what the params mean; above it,
    pass a tau near 0 (``Params(Gamma, Delta, 1e-9, tau_L, gamma_bar)``) to ask for it without the warning."""
    if params.tau_nd > WHITE_TAU_ND * (1 + 1e-9):  # slack: from_nondim(1e-3, ...) may round a few ulp above
        from .api import DryfricWarning

        warnings.warn(f"theory.{name} is the white-noise (tau -> 0) value: tau = {params.tau:.3g} s (tau/tau0 = "
                      f"{params.tau_nd:.3g} > {WHITE_TAU_ND:g}) is not used, and colored noise changes it (D is 8.5x "
                      "lower at Fig. 3's point, tau/tau0 = 1.47; estimate_diffusivity gives the colored-noise values)",
                      DryfricWarning, stacklevel=3)


# ---------------------------------------------------------------------------------------------
# stationary density and exact D, M0 for b(v) = -v/tau_L + gamma_bar
# ---------------------------------------------------------------------------------------------
def _nd(params: Params):
    check_params(params)
    nd = params.nondim()
    itl = 0.0 if math.isinf(nd.tau_L) else 1.0 / nd.tau_L
    check_recurrent(nd.tau_L, nd.gamma_bar)
    return itl, nd.gamma_bar


def _log_p_unnorm(v, itl, g):
    r""":math:`\psi(v) = -v^2/(2\tau_L') - |v| + \bar\gamma' v` (nondimensional), its linear part as
    :math:`(\bar\gamma' \mp 1) v`: the sum of the two large terms lost :math:`\epsilon |v|` (1e-8 at
    :math:`|v| \sim 10^8`, a wide law, :math:`|\bar\gamma'| \to 1`), noise that stalled the quadratures."""
    v = np.asarray(v, np.float64)
    return -0.5 * itl * v * v + np.where(v > 0, g - 1.0, g + 1.0) * v


def _log_half_line_mass(beta, itl):
    r"""log of :math:`\int_0^\infty e^{-\mathrm{itl}\,v^2/2 - \beta v} dv`, stable for any sign and size
    of :math:`\beta` (erfcx for :math:`x \ge 0`; :math:`x^2 + \log\operatorname{erfc}(x)` below 0,
    where erfcx overflows: a strong bias :math:`|\bar\gamma'| \gg 1`)."""
    if itl == 0.0:
        return -math.log(beta)  # beta > 0: check_recurrent refuses |gamma_bar'| >= 1 here
    s = math.sqrt(itl)
    return 0.5 * math.log(math.pi / 2) - math.log(s) + _log_erfcx(beta / (s * math.sqrt(2)))


def _log_erfcx(x):
    return math.log(special.erfcx(x)) if x >= 0 else x * x + math.log(special.erfc(x))


def _log_norm(itl, g):
    return float(np.logaddexp(_log_half_line_mass(1.0 - g, itl), _log_half_line_mass(1.0 + g, itl)))


def stationary_density(v, params: Params):
    r"""Exact white-noise stationary velocity density (physical units).

    .. math::
        p(v) \propto \exp\!\Big(-\frac{v^2}{2\Gamma\tau_L} - \frac{\Delta|v|}{\Gamma}
        + \frac{\bar\gamma v}{\Gamma}\Big)

    (MODEL_NOTES section 2; the paper prints the :math:`\Gamma_w = \Gamma` form, this exponent doubled:
    :math:`\Gamma` halved).
    ``params.tau`` is not used (a ``DryfricWarning`` where :math:`\tau/\tau_0 > 10^{-3}`).
    """
    itl, g = _nd(params)
    _white_only(params, "stationary_density")
    vn = _velocities(v) / params.v0
    inf = np.isinf(vn)  # p(+-inf) = 0 (the exponent would be inf - inf there)
    p = np.where(inf, 0.0, np.exp(_log_p_unnorm(np.where(inf, 0.0, vn), itl, g) - _log_norm(itl, g)) / params.v0)
    return p[()]  # a scalar for a scalar v


def _scale(itl, g):
    """Width of p in nondimensional velocity (the wider of its two sides, :func:`_tail_scales`):
    the extent of the law (:mod:`dryfric_jax.chain_law` sizes its grid with it)."""
    return 1.0 / max(math.sqrt(itl), min(abs(1.0 - g), abs(1.0 + g)))


def _tail_scales(itl, g):
    r"""Decay lengths ``(left, right)`` of p's two tails (nondimensional): on the side where the
    friction wins, :math:`1/\max(\sqrt{\mathrm{itl}}, 1 \pm \bar\gamma')`; on a side where the bias
    beats it, the bump's width :math:`\sqrt{\tau_L'}` (:func:`_mode_points`).  The infinite pieces
    of the quadratures run on their own tail's scale: with the wider side's scale for both
    (:func:`_scale`), the narrow side of a lopsided law (:math:`|\bar\gamma'| \to 1`: widths
    :math:`1/(1 - |\bar\gamma'|)` and 1/2) was a spike, missed by 2.5e-7 of D at
    :math:`\bar\gamma' = 1 - 10^{-6}` (and, with the cancellation :func:`_log_p_unnorm` now avoids,
    the nested quadrature of :func:`exact_D` took 78 s at :math:`\tau_L' = 10^8, \bar\gamma' = 1 - 10^{-4}`)."""
    side = lambda rate: 1.0 / max(math.sqrt(itl), rate) if rate > 0 else 1.0 / math.sqrt(itl)  # noqa: E731
    return side(1.0 + g), side(1.0 - g)


@contextlib.contextmanager
def _round_off_ignored():
    """The quadratures near the kink at v = 0 report harmless round-off (scipy's IntegrationWarning,
    printed raw on stderr): silenced in :func:`exact_D`, :func:`exact_M0` and
    :func:`exact_mean_square_velocity`."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", integrate.IntegrationWarning)
        yield


def _quad(f, a, b, tails, epsrel):
    """∫_a^b f(v) dv; an infinite piece computed as s ∫ f(s w) dw with s its tail's decay length
    (``tails``, :func:`_tail_scales`), so that no piece of mass is missed however narrow
    (tau_L' -> 0) or wide (|gamma_bar'| -> 1) that tail is.  (A finite piece needs no scale:
    quad's nodes are affine in [a, b].)"""
    if a >= b:
        return 0.0
    s = tails[0] if a == -math.inf else tails[1] if b == math.inf else 1.0
    return s * integrate.quad(lambda w: f(s * w), a / s, b / s, epsabs=0, epsrel=epsrel, limit=200)[0]


def _mode_points(itl, g):
    r"""For :math:`|\bar\gamma'| > 1` with viscous damping, p is a bump of width
    :math:`\sqrt{\tau_L'}` at :math:`v^* = \operatorname{sgn}(\bar\gamma')(|\bar\gamma'| - 1)\tau_L'`,
    which may lie far from 0 on the quadrature's scale: break the integrals there too, unless it
    reaches 0 (:math:`|v^*| \le 8\sqrt{\tau_L'}`), where they are broken already (there the extra
    points made D jump by 2e-5 across :math:`|\bar\gamma'| = 1` at :math:`\tau_L' = 10^9`)."""
    if itl == 0.0 or abs(g) <= 1.0:
        return ()
    v, sd = math.copysign((abs(g) - 1.0) / itl, g), 1.0 / math.sqrt(itl)
    if abs(v) <= 8.0 * sd:  # the bump reaches 0, where the integrals are broken already
        return ()
    return v - 8.0 * sd, v, v + 8.0 * sd


def _pieces(*points):
    brk = sorted(set(points))
    return [(-np.inf, brk[0])] + list(zip(brk[:-1], brk[1:])) + [(brk[-1], np.inf)]


#: beyond this barrier :math:`\psi(v^*) - \psi(0)` the velocity reaches 0 with probability
#: :math:`< e^{-745}` (below float64's smallest number): the friction never acts
LINEAR_BARRIER = 745.0


def _linear_limit(itl, g):
    r"""``(mean, variance)`` of :math:`N(v^*, \tau_L')` when the bias holds the velocity away from 0
    beyond float64's reach, :math:`(|\bar\gamma'| - 1)^2\tau_L'/2 >` :data:`LINEAR_BARRIER`: the
    particle then never sticks and V is the OU process :math:`dV = (-V/\tau_L' + \bar\gamma' \mp 1)\,dt
    + \sqrt2\,dW`, so :math:`M_0' = v^*` and :math:`D' = 2\tau_L'^2` (:func:`D_viscous_only`) to double
    precision.  None otherwise (quadrature)."""
    if itl == 0.0 or abs(g) <= 1.0 or (abs(g) - 1.0) * (abs(g) - 1.0) / (2.0 * itl) <= LINEAR_BARRIER:
        return None
    return math.copysign((abs(g) - 1.0) / itl, g), 1.0 / itl


def _velocity_moment_nd(itl, g, k=1):
    lin = _linear_limit(itl, g)
    if lin is not None and k in (1, 2):
        mean, var = lin
        return mean if k == 1 else mean * mean + var
    if k == 1 and itl >= 1.0:
        return _mean_strong_damping_numerator(itl, g) / itl
    if k == 1 and abs(g) <= 1.0:
        return _mean_weak_damping(itl, g)
    return _moment_quad(itl, g, k)


def _mean_weak_damping(itl, g):
    r"""The mean for :math:`\tau_L' > 1, |\bar\gamma'| \le 1` as one integral over :math:`v > 0` of
    :math:`v\,(p(v) - p(-v)) = \operatorname{sgn}(\bar\gamma')\,v\,p(\operatorname{sgn}(\bar\gamma') v)\,
    (1 - e^{-2|\bar\gamma'| v})` (:math:`\psi(v) - \psi(-v) = 2\bar\gamma' v`), the bracket by
    ``expm1``: :math:`\int v\,p` over both half-lines subtracted two near-equal halves and lost
    :math:`\epsilon/|\bar\gamma'|` of M0 (1.1e-4 relative at :math:`\bar\gamma' = 10^{-12}`, and 0.0 at
    :math:`10^{-300}`, where M0' = 7.2e-301; a theory audit against mpmath)."""
    if g == 0.0:
        return 0.0
    sg, logZ = math.copysign(1.0, g), _log_norm(itl, g)
    def f(v):
        return v * math.exp(float(_log_p_unnorm(sg * v, itl, g)) - logZ) * -math.expm1(-2.0 * abs(g) * v)

    tail = _tail_scales(itl, g)[1 if g > 0 else 0]
    return sg * _quad(f, 0.0, math.inf, (tail, tail), 1e-13)


def _mean_strong_damping_numerator(itl, g):
    r"""The mean for :math:`\tau_L' \le 1` from :math:`\int \psi'(v)\,p(v)\,dv = 0`, returned as
    :math:`m/\tau_L' = \bar\gamma' - E[\mathrm{sgn}\,V]` (:func:`exact_M0` scales it by
    :math:`\tau_L'\Gamma/\Delta` in one product: M0' itself left float64's normal range at
    :math:`\tau_L' = 10^{-300}` and came back 0.0 or with 1e-5 of it lost):
    :math:`m = \tau_L'(\bar\gamma' - E[\mathrm{sgn}\,V])`, with :math:`P(V<0) - P(V>0) =
    \tanh((\log J(1 + \bar\gamma') - \log J(1 - \bar\gamma'))/2)` from the half-line masses
    :math:`J` (:func:`_log_half_line_mass`; their common terms cancel exactly and are left out).
    The quadrature of :math:`\int v\,p` cancels there: a mean :math:`\approx \tau_L'\bar\gamma'`
    against a width :math:`\sqrt{\tau_L'}` (it returned 0.0 at :math:`\tau_L' = 10^{-100}` and was
    100 times off at :math:`10^{-24}`).  For :math:`|\bar\gamma'| < 1/2` the difference of the two
    logs is taken as :math:`\int_{(1-\bar\gamma')x}^{(1+\bar\gamma')x} (\log\operatorname{erfcx})'(y)\,dy`,
    :math:`(\log\operatorname{erfcx})'(y) = 2y - 2/(\sqrt\pi\operatorname{erfcx}(y))`: as a difference it
    lost :math:`\epsilon/|\bar\gamma'|` of M0 (2e-4 relative at :math:`\bar\gamma' = 10^{-12}`)."""
    x = 1.0 / math.sqrt(2.0 * itl)
    if abs(g) < 0.5:  # a smooth integrand on [x/2, 3x/2]
        dlog = lambda y: 2.0 * y - 2.0 / (math.sqrt(math.pi) * special.erfcx(y))  # noqa: E731
        # y = x (1 + g s), s in [-1, 1]: the endpoints (1 -+ g) x as numbers would lose eps/|g| of the width
        d = g * x * integrate.quad(lambda s: dlog(x + g * x * s), -1.0, 1.0, epsabs=0, epsrel=2e-14)[0]
    else:
        d = _log_erfcx((1.0 + g) * x) - _log_erfcx((1.0 - g) * x)
    return g + math.tanh(0.5 * d)


def _moment_quad(itl, g, k):
    logZ = _log_norm(itl, g)
    tails = _tail_scales(itl, g)
    f = lambda v: v**k * math.exp(_log_p_unnorm(v, itl, g) - logZ)
    return sum(_quad(f, a, b, tails, 1e-13) for a, b in _pieces(0.0, *_mode_points(itl, g)))


def _G(v, m, itl, g, tails):
    r""":math:`G(v) = F(v)/p(v)` taken from the nearer tail, so that :math:`F^2/p = p\,G^2` is stable."""
    psi_v = float(_log_p_unnorm(v, itl, g))
    f = lambda u: (u - m) * math.exp(float(_log_p_unnorm(u, itl, g)) - psi_v)
    pieces = _pieces(0.0, *_mode_points(itl, g))
    if v > m:
        return -sum(_quad(f, max(a, v), b, tails, 1e-12) for a, b in pieces if b > v)
    return sum(_quad(f, a, min(b, v), tails, 1e-12) for a, b in pieces if a < v)


def _phys_args(params: Params) -> dict:
    return {k: getattr(params, k) for k in ("Gamma", "Delta", "tau_L", "gamma_bar")}


def _in_units(name, value_nd, unit, params: Params, *, positive: bool):
    r"""A quadrature's nondimensional ``value_nd`` times its unit :math:`\Gamma^{a}\Delta^{b}`
    (``unit = (a, b)``), refused by name (:func:`_product`) where it leaves float64's range: an
    overflow was returned as inf, and a ``positive`` quantity (D, E[V^2]) that underflowed as 0."""
    if value_nd == 0.0 and not positive:
        return 0.0
    if not math.isfinite(value_nd) or value_nd == 0.0:
        _refuse_range(name, _phys_args(params), over=value_nd != 0.0)
    return _product(name, _phys_args(params), [(abs(value_nd), 1), (float(params.Gamma), unit[0]),
                                               (float(params.Delta), unit[1])], sign=value_nd)


def exact_M0(params: Params) -> float:
    r"""White-noise mobility :math:`M_0 = \int v\,p(v)\,dv` (physical units); the closed form
    :func:`M0_constant_bias` for :math:`\tau_L = \infty`.  ``params.tau`` is not used (a ``DryfricWarning``
    where :math:`\tau/\tau_0 > 10^{-3}`)."""
    itl, g = _nd(params)
    _white_only(params, "exact_M0")
    if itl == 0.0:
        return M0_constant_bias(params.Gamma, params.Delta, params.gamma_bar)
    if itl >= 1.0 and _linear_limit(itl, g) is None:  # M0 = (m/tau_L') tau_L' Gamma/Delta, one product
        num = _mean_strong_damping_numerator(itl, g)
        if num == 0.0:
            return 0.0
        return _product("M0", _phys_args(params), [(abs(num), 1), (itl, -1), (float(params.Gamma), 1),
                                                   (float(params.Delta), -1)], sign=num)
    with _round_off_ignored():
        return _in_units("M0", _velocity_moment_nd(itl, g, 1), (1, -1), params, positive=False)


def exact_mean_square_velocity(params: Params) -> float:
    r"""White-noise :math:`E[V^2] = \int v^2 p(v)\,dv` (physical units, m^2/s^2); for
    :math:`\tau_L = \infty` the closed form of the asymmetric Laplace law,
    :math:`2\Gamma^2(\Delta^2 + 3\bar\gamma^2)/(\Delta^2 - \bar\gamma^2)^2`.  ``params.tau`` is not used (a
    ``DryfricWarning`` where :math:`\tau/\tau_0 > 10^{-3}`)."""
    itl, g = _nd(params)
    _white_only(params, "exact_mean_square_velocity")
    if itl == 0.0:
        return _mean_square_constant_bias(params.Gamma, params.Delta, params.gamma_bar)
    with _round_off_ignored():
        return _in_units("E[V^2]", _velocity_moment_nd(itl, g, 2), (2, -2), params, positive=True)


def exact_D(params: Params) -> float:
    r"""White-noise diffusivity by quadrature, any :math:`b(v) = -v/\tau_L + \bar\gamma`.

    .. math::
        D = \frac2\Gamma \int \frac{F(v)^2}{p(v)}\,dv, \qquad
        F(v) = \int_{-\infty}^{v} (u - m)\,p(u)\,du, \quad m = \int u\,p(u)\,du,

    exact for a 1-D velocity diffusion with Fokker-Planck diffusion coefficient :math:`\Gamma`
    (MODEL_NOTES section 2).  F is integrated from the nearer tail.  For :math:`\tau_L = \infty`
    the closed form :func:`D_constant_bias` (the quadrature agrees with it to 1e-14, but it is
    exact and instantaneous however close :math:`|\bar\gamma|` is to :math:`\Delta`).
    ``ValueError`` naming D where it leaves float64's range.  ``params.tau`` is not used (a
    ``DryfricWarning`` where :math:`\tau/\tau_0 > 10^{-3}`).
    """
    itl, g = _nd(params)
    _white_only(params, "exact_D")
    if itl == 0.0:
        return D_constant_bias(params.Gamma, params.Delta, params.gamma_bar)
    viscous = _viscous_D_factor(itl, g)
    if viscous is not None:  # D = 2 tau_L'^2 c Gamma^3/Delta^4 in one product (D' itself may leave the range)
        return _product("D", _phys_args(params), [(2.0 * viscous, 1), (itl, -2), (float(params.Gamma), 3),
                                                  (float(params.Delta), -4)])
    with _round_off_ignored():
        try:
            D_nd = _exact_D_nd(itl, g)
        except OverflowError:  # G(v)^2 past 1.8e308 (|gamma_bar'| = 1, tau_L' >= 1e160): D' = 3.4 tau_L'^2
            raise ValueError(f"D overflows float64 in nondimensional units (D' = D Delta^4/Gamma^3 at tau_L' = "
                             f"{1.0 / itl:.3g}, gamma_bar' = {g:.6g} is past 1.8e308, whatever the units; the "
                             "quadrature cannot hold it)") from None
        return _in_units("D", D_nd, (3, -4), params, positive=True)


#: :math:`\tau_L'` at and below which :func:`exact_D` takes the strong-damping asymptote
#: :math:`D' = 2\tau_L'^2(1 - 2\sqrt{2\tau_L'/\pi})` (where :math:`|\bar\gamma'|\sqrt{\tau_L'} \le 10^{-5}`):
#: the quadrature agrees with it to 4e-15 from 1e-20 to 1e-45 at :math:`\bar\gamma'` = 0 to 1e5, and the
#: next term is :math:`O(\tau_L')`
VISCOUS_TAU_L_ND = 1e-30


def _viscous_D_factor(itl, g):
    r""":math:`c` in :math:`D' = 2\tau_L'^2 c`, or None for the quadrature: c = 1 in the linear limit
    (:func:`_linear_limit`: the friction never acts), :math:`c = 1 - 2\sqrt{2\tau_L'/\pi}` at
    :math:`\tau_L' \le` :data:`VISCOUS_TAU_L_ND` (the friction's effect on D is :math:`O(\sqrt{\tau_L'})`,
    found by a theory audit with mpmath and matched by the quadrature).  :func:`exact_D` multiplies
    by :math:`\tau_L'^2\Gamma^3/\Delta^4` in one product: D' alone left float64's range (D' = 2e-320 at
    :math:`\tau_L' = 10^{-160}` lost 1e-5 of D; D' = 2e400 at :math:`\tau_L' = 10^{200}` refused a D of 2e300)."""
    if _linear_limit(itl, g) is not None:
        return 1.0
    tl = 1.0 / itl
    if tl <= VISCOUS_TAU_L_ND and abs(g) * math.sqrt(tl) <= 1e-5:
        return 1.0 - 2.0 * math.sqrt(2.0 * tl / math.pi)
    return None


def _exact_D_nd(itl, g):
    """D' by quadrature (:func:`exact_D` takes the linear limit and strong damping in closed form,
    :func:`_viscous_D_factor`, before it gets here)."""
    m = _velocity_moment_nd(itl, g, 1)
    logZ = _log_norm(itl, g)
    tails = _tail_scales(itl, g)
    integrand = lambda v: math.exp(float(_log_p_unnorm(v, itl, g)) - logZ) * _G(v, m, itl, g, tails) ** 2
    return 2.0 * sum(_quad(integrand, a, b, tails, 1e-10) for a, b in _pieces(0.0, m, *_mode_points(itl, g)))


# ---------------------------------------------------------------------------------------------
# closed forms (MODEL_NOTES section 2), physical units
# ---------------------------------------------------------------------------------------------
def _closed_form_args(Gamma, Delta=None, **kw) -> dict:
    """Validate a closed form's arguments by name (``ValueError``, as Params does): they were
    taken as they came, so a NaN gave NaN and a zero a ZeroDivisionError.  Returns them by name
    as Python floats: a numpy float32 argument made the formula compute in float32 (D = 2e60
    refused as an overflow, an M0 of 1e-40 returned as 0.0).  A tracer is refused by name (a
    ConcretizationTypeError from inside JAX before)."""
    for name, v in {"Gamma": Gamma, "Delta": Delta, **kw}.items():
        refuse_traced(name, v, "the closed form")
    check_positive("Gamma", Gamma)
    if Delta is not None:
        check_positive("Delta", Delta)
    for name, v in kw.items():
        (check_finite if name == "gamma_bar" else check_positive)(name, v)
    args = {"Gamma": Gamma, "Delta": Delta, **kw}
    return {k: float(v) for k, v in args.items() if v is not None}


#: binary exponents (``math.frexp``) of float64's normal numbers: 2.2e-308 ... 1.8e308
_MIN_EXP, _MAX_EXP = sys.float_info.min_exp, sys.float_info.max_exp


def _refuse_range(name, args: dict, *, over: bool, exp2=None):
    size = "" if exp2 is None else f", |{name}| ~ 1e{exp2 * math.log10(2.0):.0f}"
    given = ", ".join(f"{k} = {v!r}" for k, v in args.items())
    raise ValueError(f"{name} {'overflows' if over else 'underflows'} float64 for {given} (it holds "
                     f"{sys.float_info.min:.3g} to {sys.float_info.max:.3g}{size}): "
                     "express the parameters in other units")


def _product(name, args: dict, factors, sign=1.0) -> float:
    r""":math:`\pm\prod_i x_i^{k_i}` for positive finite ``x_i`` (floats, or ``(m, e)`` pairs meaning
    :math:`m\,2^e`) and small integer powers, with mantissas and binary exponents kept apart
    (one rounding per factor): no intermediate product overflows or underflows (``Delta**2`` of
    1e200 raised OverflowError, ``2 * Gamma`` of 1e308 gave inf, ``Delta**2`` of 1e-200 gave 0).
    ``ValueError`` naming ``name`` and ``args`` if the result itself leaves float64's normal
    range, instead of inf or a 0 (or a subnormal without its digits)."""
    m, e = 1.0, 0
    for x, k in factors:
        x, ex = x if isinstance(x, tuple) else (x, 0)
        fm, fe = math.frexp(x)  # fm in [0.5, 1): fm**k cannot leave the range for |k| <= 4
        m, me = math.frexp(m * fm**k)
        e += me + k * (fe + ex)
    if not _MIN_EXP <= e <= _MAX_EXP:
        _refuse_range(name, args, over=e > _MAX_EXP, exp2=e)
    return math.copysign(math.ldexp(m, e), sign)


def _gaps(Delta, gamma_bar):
    r""":math:`\Delta - \bar\gamma` and :math:`\Delta + \bar\gamma` as ``(m, e)`` pairs (:func:`_product`),
    both scaled exactly by Delta's power of 2: neither overflows (Delta near 1.8e308), and
    :math:`\Delta^2 - \bar\gamma^2 = (\Delta - \bar\gamma)(\Delta + \bar\gamma)` loses nothing to
    cancellation as :math:`|\bar\gamma| \to \Delta`."""
    e = math.frexp(Delta)[1]
    d, g = math.ldexp(Delta, -e), math.ldexp(gamma_bar, -e)  # exact (g may lose digits below d's ulp)
    return (d - g, e), (d + g, e)


def D_pure_dry(Gamma, Delta) -> float:
    r""":math:`b = 0`: :math:`D = 10\Gamma^3/\Delta^4` (:math:`= 5\Gamma_w^3/(4\Delta^4)`)."""
    a = _closed_form_args(Gamma, Delta)
    return _product("D", a, [(10.0, 1), (a["Gamma"], 3), (a["Delta"], -4)])


def D_constant_bias(Gamma, Delta, gamma_bar) -> float:
    r""":math:`b = \bar\gamma`, :math:`|\bar\gamma| < \Delta`:
    :math:`D = 2\Gamma^3(5\Delta^4 + 22\Delta^2\bar\gamma^2 + 5\bar\gamma^4)/(\Delta^2 - \bar\gamma^2)^4`,
    computed as :math:`2\Gamma^3\Delta^4(5 + 22 r^2 + 5 r^4)/((\Delta - \bar\gamma)(\Delta + \bar\gamma))^4`,
    :math:`r = \bar\gamma/\Delta`."""
    a = _closed_form_args(Gamma, Delta, gamma_bar=gamma_bar)
    G, d, gb = a["Gamma"], a["Delta"], a["gamma_bar"]
    _check_bias(d, gb)
    r2 = (gb / d) ** 2
    minus, plus = _gaps(d, gb)
    return _product("D", a, [(2.0, 1), (G, 3), (d, 4), (5.0 + 22.0 * r2 + 5.0 * r2 * r2, 1), (minus, -4), (plus, -4)])


def M0_constant_bias(Gamma, Delta, gamma_bar) -> float:
    r""":math:`b = \bar\gamma`: :math:`M_0 = 2\Gamma\bar\gamma/(\Delta^2 - \bar\gamma^2)`, computed with
    :math:`\Delta^2 - \bar\gamma^2 = (\Delta - \bar\gamma)(\Delta + \bar\gamma)`."""
    a = _closed_form_args(Gamma, Delta, gamma_bar=gamma_bar)
    G, d, gb = a["Gamma"], a["Delta"], a["gamma_bar"]
    _check_bias(d, gb)
    if gb == 0.0:
        return 0.0
    minus, plus = _gaps(d, gb)
    return _product("M0", a, [(2.0, 1), (G, 1), (abs(gb), 1), (minus, -1), (plus, -1)], sign=gb)


def _mean_square_constant_bias(Gamma, Delta, gamma_bar) -> float:
    r""":math:`b = \bar\gamma`: :math:`E[V^2] = 2\Gamma^2(\Delta^2 + 3\bar\gamma^2)/(\Delta^2 - \bar\gamma^2)^2`
    (asymmetric Laplace law with scales :math:`\Gamma/(\Delta \mp \bar\gamma)`)."""
    a = _closed_form_args(Gamma, Delta, gamma_bar=gamma_bar)
    G, d, gb = a["Gamma"], a["Delta"], a["gamma_bar"]
    _check_bias(d, gb)
    minus, plus = _gaps(d, gb)
    return _product("E[V^2]", a, [(2.0, 1), (G, 2), (d, 2), (1.0 + 3.0 * (gb / d) ** 2, 1), (minus, -2), (plus, -2)])


def D_viscous_only(Gamma, tau_L) -> float:
    r"""Limit :math:`\Delta \to 0`: :math:`D = 2\tau_L^2\Gamma` (the paper's :math:`\tau_L^2\Gamma` is the
    :math:`\Gamma_w = \Gamma` form)."""
    a = _closed_form_args(Gamma, tau_L=tau_L)
    return _product("D", a, [(2.0, 1), (a["tau_L"], 2), (a["Gamma"], 1)])


def _horizon_args(Gamma, Delta, gamma_bar):
    r"""Validated ``(a, r^2, ((\Delta - \bar\gamma)(\Delta + \bar\gamma))`` as :func:`_gaps` pairs ``)``."""
    a = _closed_form_args(Gamma, Delta, gamma_bar=gamma_bar)
    _check_bias(a["Delta"], a["gamma_bar"])
    return a, (a["gamma_bar"] / a["Delta"]) ** 2, _gaps(a["Delta"], a["gamma_bar"])


def horizon_bias(Gamma, Delta, gamma_bar=0.0, *, stationary: bool = False) -> float:
    r"""Brute force's horizon bias b (s), exact for white noise with the constant drift :math:`b(v) = \bar\gamma`
    (:math:`\tau_L = \infty`, :math:`|\bar\gamma| < \Delta`): :math:`\operatorname{Var} U(t) = D\,(t - b) + o(1)`, so
    the brute-force :math:`D^t = \operatorname{Var} U(t)/t = D\,(1 - b/t) + o(1/t)` (paper section 5.2), for paths
    from rest (V(0) = 0, as ``bruteforce_diffusivity`` starts them) or, with ``stationary``, from the stationary law
    (a long burn-in):

    .. math::
        b_\text{rest} = \tau_0\,\frac{27 + 345 r^2 + 333 r^4 + 31 r^6}{(1 - r^2)^2\,(5 + 22 r^2 + 5 r^4)},\qquad
        b_\text{stat} = \tau_0\,\frac{2\,(1 + r^2)(7 + 66 r^2 + 7 r^4)}{(1 - r^2)^2\,(5 + 22 r^2 + 5 r^4)},

    :math:`r = \bar\gamma/\Delta`, :math:`\tau_0 = \Gamma/\Delta^2`: 27/5 and 14/5 :math:`\tau_0` at r = 0.  In
    correlation times :math:`\tau_c = \tau_0/(1 - |r|)^2` (``api.correlation_time``) :math:`b_\text{rest}` is
    5.4 at r = 0, 4.83 at |r| = 0.1 and rises to 23/4 as :math:`|r| \to 1`; :math:`b_\text{stat}` is at most 14/5.

    Derivation (nondimensional, generator :math:`L = (r - \mathrm{sgn}\,v)\,\partial_v + \partial_v^2`, stationary
    law :math:`\pi`, :math:`m = \pi(v)`, :math:`\tilde v = v - m`): the Poisson equations
    :math:`-L\psi = \tilde v`, :math:`-L\psi_2 = \psi`, :math:`-L\chi = \tilde v\psi - D/2`, each solution
    centred under :math:`\pi`, have polynomial solutions on each half line, C^1 at 0 (at r = 0:
    :math:`\psi = v + v|v|/2`, :math:`\psi_2 = 2v + v|v| + v^3/6`, :math:`\chi = 5v^2/2 + 5|v|^3/6 + v^4/8 - 13`).
    Writing :math:`U(t) - mt = \int_0^t \tilde v`,
    :math:`\operatorname{Var}_0 U(t) = Dt + 2\chi(0) - 2\pi(\tilde v\psi_2) - \psi(0)^2 + o(1)` and
    :math:`\operatorname{Var}_\pi U(t) = Dt - 2\pi(\tilde v\psi_2) + o(1)`, with :math:`D = 2\pi(\tilde v\psi)`
    (the closed form :func:`D_constant_bias`) and :math:`\pi(\tilde v\psi_2) = \int_0^\infty s\,C(s)\,ds`
    (14 at r = 0).  The o(1) decays with the velocity's memory (:math:`e^{-t/(4\tau_0)}` times a power of t at
    r = 0).  Checked against a finite-volume solution of the equations of the moments of U
    (``tests/test_horizon_bias.py``); colored noise and damping change b (measured ~1.3 :math:`\tau_c` at Fig. 3's
    point)."""
    a, r2, (minus, plus) = _horizon_args(Gamma, Delta, gamma_bar)
    if stationary:
        num = 2.0 * (1.0 + r2) * (7.0 + 66.0 * r2 + 7.0 * r2 * r2)
    else:
        num = 27.0 + 345.0 * r2 + 333.0 * r2 * r2 + 31.0 * r2**3
    return _product("b", a, [(a["Gamma"], 1), (a["Delta"], 2), (num / (5.0 + 22.0 * r2 + 5.0 * r2 * r2), 1),
                             (minus, -2), (plus, -2)])


def m0_lag(Gamma, Delta, gamma_bar) -> float:
    r"""Brute force's lag L (s) from rest, exact for white noise with the constant drift :math:`b(v) = \bar\gamma`
    (:math:`\tau_L = \infty`, :math:`|\bar\gamma| < \Delta`): :math:`E[U(t)] = M_0\,(t - L) + o(1)` for paths
    from V(0) = 0, so :math:`M_0^t = M_0(1 - L/t) + o(1/t)`:

    .. math::
        L = \tau_0\,\frac{3 + r^2}{(1 - r^2)^2},

    :math:`r = \bar\gamma/\Delta`: 3 :math:`\tau_0` as r -> 0 (where :math:`M_0 = 0`, and there is no lag) and
    :math:`(3 + r^2)/(1 + |r|)^2` correlation times (:func:`horizon_bias`), from 3 down to 1.  From
    :math:`E_0[U(t)] - M_0 t \to \psi(0) = -2r(3 + r^2)/(1 - r^2)^3` (nondimensional, :func:`horizon_bias`'s
    :math:`\psi`).  Colored noise and damping change it (measured 2.9 :math:`\tau_c` at
    :math:`\tau' = \tau_L' = 3`, :math:`\bar\gamma' = -0.7`; white noise at that :math:`\bar\gamma'` gives 1.2)."""
    a, r2, (minus, plus) = _horizon_args(Gamma, Delta, gamma_bar)
    return _product("L", a, [(a["Gamma"], 1), (a["Delta"], 2), (3.0 + r2, 1), (minus, -2), (plus, -2)])


def _check_bias(Delta, gamma_bar):
    if not abs(gamma_bar) < Delta:
        raise ValueError(f"gamma_bar must satisfy |gamma_bar| < Delta (got {gamma_bar}, Delta = {Delta})")


# ---------------------------------------------------------------------------------------------
# Touchette (2010), pure dry friction, nondimensional: dv = -sgn(v) dt + sqrt(2) dW
# ---------------------------------------------------------------------------------------------
def _log_erfc(z):
    """log erfc(z) without underflow: erfc(z) = 2 Phi(-z sqrt 2)."""
    return math.log(2.0) + special.log_ndtr(-np.asarray(z, np.float64) * math.sqrt(2.0))


def _real_array(t, name: str = "t"):
    """``t`` as a float64 array; ``ValueError`` naming ``name`` unless it is a real number or an
    array of them (a string, a bool, None or a list of them was read as a number, or said "got nan")."""
    try:
        a = None if isinstance(t, (str, bytes)) else np.asarray(t)
    except Exception:  # noqa: BLE001  (a ragged list, say)
        a = None
    if a is None or a.dtype.kind not in "iuf":
        raise ValueError(f"{name} must be a real number or an array of real numbers (got {t!r:.80})")
    return a.astype(np.float64)


def _velocities(v):
    """``v`` as a float64 array (:func:`_real_array`); ``ValueError`` naming ``v`` for a NaN (+-inf
    is a velocity whose density is 0)."""
    v = _real_array(v, "v")
    if np.any(np.isnan(v)):
        raise ValueError("v must be real numbers or +-inf, not NaN (got nan)")
    return v


def _times(t, *, zero_ok: bool):
    """``t`` as a float64 array; ``ValueError`` naming ``t`` unless every entry is finite and > 0
    (``>= 0`` with ``zero_ok``)."""
    t = _real_array(t)
    bad = ~np.isfinite(t) | ((t < 0) if zero_ok else (t <= 0))
    if np.any(bad):
        raise ValueError(f"t must be finite and {'>= 0' if zero_ok else '> 0'} (got {float(t[bad].flat[0])!r})")
    return t


def propagator(v, t, v0):
    r"""Transient density :math:`p(v, t \mid v_0)` (nondimensional, Touchette eq. 2.10 with
    :math:`\Gamma_w = 2`):

    .. math::
        \frac{e^{-t/4}}{2\sqrt{\pi t}} e^{-(|v|-|v_0|)/2} e^{-(v-v_0)^2/(4t)}
        + \frac{e^{-|v|}}{4}\operatorname{erfc}\Big(\frac{|v|+|v_0|-t}{2\sqrt t}\Big).
    """
    check_positive("t", t)
    check_finite("v0", v0)
    v = _velocities(v)
    t, v0 = float(t), float(v0)
    a, av = abs(v0), np.abs(v)
    st = math.sqrt(t)
    g = np.exp(-t / 4 - (av - a) / 2 - (v - v0) ** 2 / (4 * t)) / (2 * math.sqrt(math.pi) * st)
    return g + 0.25 * np.exp(-av + _log_erfc((av + a - t) / (2 * st)))


def first_moment(t, v0):
    r""":math:`\langle v(t)\rangle` from :math:`v_0` (Touchette eq. 2.11 with :math:`\Gamma_w = 2`), :math:`a = |v_0|`;
    nondimensional, as :func:`propagator`: ``t`` in :math:`\tau_0` and ``v0`` (and the result) in :math:`v_0` units
    (``Params.tau0``, ``Params.v0``), not seconds and m/s:

    .. math::
        \frac{\mathrm{sgn}(v_0)}2\Big[(a-t)\operatorname{erfc}\frac{t-a}{2\sqrt t}
        + e^{a}(a+t)\operatorname{erfc}\frac{a+t}{2\sqrt t}\Big],

    evaluated with :math:`w = (t-a)/(2\sqrt t)`, :math:`z = (t+a)/(2\sqrt t)` and :math:`a - z^2 = -w^2`
    as :math:`\frac{\mathrm{sgn}(v_0)}2[(a-t)\operatorname{erfc}(w) + (a+t)\,e^{-w^2}\operatorname{erfcx}(z)]`:
    :math:`e^{a}\operatorname{erfc}(z)` overflows as written, and in logs (``log_ndtr``) the sum
    :math:`a + \log\operatorname{erfc}(z)` lost :math:`\epsilon a` to cancellation.  Each half is taken before
    the sums, so that no intermediate overflows (``(a - t) erfc`` near 2e308 gave inf at
    :math:`v_0 = 10^{308}`, ``a + t`` nan): valid for every finite :math:`v_0` and :math:`t \ge 0`
    (:math:`|\langle v\rangle| \le |v_0| + \sqrt{t/\pi}`); :math:`v_0` itself at t = 0.
    """
    check_finite("v0", v0)
    t = _times(t, zero_ok=True)
    a = abs(float(v0))
    tp = np.where(t > 0, t, 1.0)
    st2 = 2.0 * np.sqrt(tp)
    with np.errstate(over="ignore"):  # w, z, w^2 -> inf as t -> 0 or a -> 1e308: erfc, erfcx, exp take it
        w, z = (tp - a) / st2, tp / st2 + a / st2  # z not as (t + a)/(2 sqrt t): t + a may overflow
        half1 = (a - tp) * (0.5 * special.erfc(w))
        half2 = (0.5 * a + 0.5 * tp) * (np.exp(-w * w) * special.erfcx(z))
    return np.where(t > 0, math.copysign(1.0, v0) * (half1 + half2), float(v0))[()]  # a scalar for a scalar t


def _corr_asymptotic(t, n_terms=34):
    # C(t) = e^{-t/4}/(6 sqrt(pi t)) * sum_k c_k t^-k, c_k = s_{k+3} + 6 s_{k+2} - 12 s_{k+1} + 24 s_k,
    # s_n = (-2)^n (2n-1)!!  (erfcx asymptotic series; the t^3 .. t^0 terms cancel exactly)
    s = [1.0]
    for n in range(1, n_terms + 4):
        s.append(s[-1] * (-2.0) * (2 * n - 1))
    acc = sum((s[k + 3] + 6 * s[k + 2] - 12 * s[k + 1] + 24 * s[k]) * t ** (-k) for k in range(1, n_terms))
    return np.exp(-t / 4) / (6 * np.sqrt(np.pi * t)) * acc


#: where :func:`correlation` switches from the erfcx form to the asymptotic series
CORR_SERIES_FROM = 160.0


def correlation(t):
    r"""Stationary velocity correlation :math:`C(t) = \langle v(0) v(t)\rangle` (nondimensional):

    .. math::
        C(t) = \frac{t^3+6t^2-12t+24}{12}\operatorname{erfc}\frac{\sqrt t}2
        - \frac{\sqrt t\,(t^2+4t-12)}{6\sqrt\pi} e^{-t/4},

    :math:`C(0) = 2`, :math:`\int_0^\infty C = 5` (so :math:`D' = 10`).  The two terms cancel for
    large t, so the common factor :math:`e^{-t/4}` is taken out through ``erfcx`` and, beyond
    ``CORR_SERIES_FROM`` = 160, the cancelled asymptotic series (33 terms, k = 1..33) is used.  Relative error
    against a 60-digit evaluation: ~eps t^4/768 below the cut (the terms still cancel: 5.2e-10 at t = 160),
    <= 4e-12 beyond it (1e-14 from t = 200); a cut at 300 with 14 terms left 5e-9 at t = 300.
    """
    a = _real_array(t)
    if not np.isfinite(a).all():  # checked before |t|: -inf was reported as "got inf" (an audit)
        raise ValueError(f"t must be finite (C(-t) = C(t)) (got {float(a[~np.isfinite(a)].flat[0])!r})")
    t = _times(np.abs(a), zero_ok=True)  # C(-t) = C(t)
    small = t <= CORR_SERIES_FROM
    ts = np.where(small, t, 1.0)
    x = np.sqrt(ts) / 2
    direct = np.exp(-ts / 4) * ((ts**3 + 6 * ts**2 - 12 * ts + 24) / 12 * special.erfcx(x)
                                - np.sqrt(ts) * (ts**2 + 4 * ts - 12) / (6 * np.sqrt(np.pi)))
    tl = np.where(small, 2 * CORR_SERIES_FROM, t)
    return np.where(small, direct, _corr_asymptotic(tl))


#: Table 1 times t'.
TABLE1_TIMES = (0.05, 0.125, 0.25, 0.5, 1.0, 2.5)


def first_moment_unit_intensity(t, v0):
    r"""The paper's printed Table 1 convention (:math:`\Gamma_w = \Gamma`, i.e. this model with
    :math:`\Gamma` halved), in the paper's units: the halved model has :math:`\tau_0/2` and
    :math:`v_0/2`, so the value is :math:`\tfrac12\langle v\rangle(2t;\ 2v_0)`.  ``t`` and ``v0`` must be
    finite with ``t >= 0`` and both at most half of float64's largest number in size (8.99e307), since they are
    doubled: beyond it they were refused as "got inf", a value never passed (an audit)."""
    check_finite("v0", v0)
    t = _times(t, zero_ok=True)
    half_max = sys.float_info.max / 2.0
    if abs(float(v0)) > half_max:
        raise ValueError(f"v0 must satisfy |v0| <= {half_max:.3g} (it is doubled; got {float(v0)!r})")
    if np.any(t > half_max):
        raise ValueError(f"t must be <= {half_max:.3g} (it is doubled; got {float(t[t > half_max].flat[0])!r})")
    return 0.5 * first_moment(2.0 * t, 2.0 * v0)
