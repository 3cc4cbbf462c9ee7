r"""Exact white-noise results, in the convention of *this* model (MODEL_NOTES section 2).

As :math:`\tau \to 0`, :math:`\sqrt\Gamma X \to \sqrt{2\Gamma}\,\xi`: the limit is
:math:`dV = (b(V) - \Delta\,\mathrm{sgn}\,V)\,dt + \sqrt{2\Gamma}\,dW` (Fokker-Planck diffusion
coefficient :math:`\Gamma`).  Literature formulas written for noise :math:`\sqrt{\Gamma_w}\xi` apply
with :math:`\Gamma_w = 2\Gamma`.  The paper prints several of them in the :math:`\Gamma_w = \Gamma`
form (its stationary density, its Hayakawa formula and Table 1): those are the values of this
model with :math:`\Gamma` halved, not of the model as written.

Everything is computed in nondimensional units (:math:`\Gamma = \Delta = 1`) and scaled back:
:math:`D = D'\,\Gamma^3/\Delta^4`, :math:`M_0 = M_0'\,\Gamma/\Delta`.
"""
from __future__ import annotations

import math
import warnings

import numpy as np
from scipy import integrate, special

from .limits import check_recurrent
from .params import Params, check_finite, check_params, check_positive


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
    r""":math:`\psi(v) = -v^2/(2\tau_L') - |v| + \bar\gamma' v` (nondimensional)."""
    v = np.asarray(v, np.float64)
    return -0.5 * itl * v * v - np.abs(v) + g * v


def _log_half_line_mass(beta, itl):
    r"""log of :math:`\int_0^\infty e^{-\mathrm{itl}\,v^2/2 - \beta v} dv`, stable for any sign and size
    of :math:`\beta` (erfcx for :math:`x \ge 0`; :math:`x^2 + \log\operatorname{erfc}(x)` below 0,
    where erfcx overflows: a strong bias :math:`|\bar\gamma'| \gg 1`)."""
    if itl == 0.0:
        return -math.log(beta)  # beta > 0: check_recurrent refuses |gamma_bar'| >= 1 here
    s = math.sqrt(itl)
    x = beta / (s * math.sqrt(2))
    log_erfcx = math.log(special.erfcx(x)) if x >= 0 else x * x + math.log(special.erfc(x))
    return 0.5 * math.log(math.pi / 2) - math.log(s) + log_erfcx


def _log_norm(itl, g):
    return float(np.logaddexp(_log_half_line_mass(1.0 - g, itl), _log_half_line_mass(1.0 + g, itl)))


def stationary_density(v, params: Params):
    r"""Exact white-noise stationary velocity density (physical units).

    .. math::
        p(v) \propto \exp\!\Big(-\frac{v^2}{2\Gamma\tau_L} - \frac{\Delta|v|}{\Gamma}
        + \frac{\bar\gamma v}{\Gamma}\Big)

    (MODEL_NOTES section 2; the paper prints the :math:`\Gamma_w = \Gamma` form without the 2s).
    """
    itl, g = _nd(params)
    vn = np.asarray(v, np.float64) / params.v0
    inf = np.isinf(vn)  # p(+-inf) = 0 (the exponent would be inf - inf there)
    p = np.where(inf, 0.0, np.exp(_log_p_unnorm(np.where(inf, 0.0, vn), itl, g) - _log_norm(itl, g)) / params.v0)
    return p[()]  # a scalar for a scalar v


def _scale(itl, g):
    """Width of p in nondimensional velocity: quadratures run in v/scale so that no piece of
    mass is missed however narrow (tau_L' -> 0) or wide (|gamma_bar'| -> 1) p is."""
    return 1.0 / max(math.sqrt(itl), min(abs(1.0 - g), abs(1.0 + g)))


def _quad(f, a, b, s, epsrel):
    """∫_a^b f(v) dv computed as s ∫ f(s w) dw."""
    if a >= b:
        return 0.0
    return s * integrate.quad(lambda w: f(s * w), a / s, b / s, epsabs=0, epsrel=epsrel, limit=200)[0]


def _mode_points(itl, g):
    r"""For :math:`|\bar\gamma'| > 1` with viscous damping, p is a bump of width
    :math:`\sqrt{\tau_L'}` at :math:`v^* = \operatorname{sgn}(\bar\gamma')(|\bar\gamma'| - 1)\tau_L'`,
    which may lie far from 0 on the quadrature's scale: break the integrals there too."""
    if itl == 0.0 or abs(g) <= 1.0:
        return ()
    v, sd = math.copysign((abs(g) - 1.0) / itl, g), 1.0 / math.sqrt(itl)
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
    return _moment_quad(itl, g, k)


def _moment_quad(itl, g, k):
    logZ = _log_norm(itl, g)
    s = _scale(itl, g)
    f = lambda v: v**k * math.exp(_log_p_unnorm(v, itl, g) - logZ)
    return sum(_quad(f, a, b, s, 1e-13) for a, b in _pieces(0.0, *_mode_points(itl, g)))


def _G(v, m, itl, g, s):
    r""":math:`G(v) = F(v)/p(v)` taken from the nearer tail, so that :math:`F^2/p = p\,G^2` is stable."""
    psi_v = float(_log_p_unnorm(v, itl, g))
    f = lambda u: (u - m) * math.exp(float(_log_p_unnorm(u, itl, g)) - psi_v)
    pieces = _pieces(0.0, *_mode_points(itl, g))
    if v > m:
        return -sum(_quad(f, max(a, v), b, s, 1e-12) for a, b in pieces if b > v)
    return sum(_quad(f, a, min(b, v), s, 1e-12) for a, b in pieces if a < v)


def exact_M0(params: Params) -> float:
    r"""White-noise mobility :math:`M_0 = \int v\,p(v)\,dv` (physical units)."""
    itl, g = _nd(params)
    return _velocity_moment_nd(itl, g, 1) * params.v0


def exact_mean_square_velocity(params: Params) -> float:
    r"""White-noise :math:`E[V^2] = \int v^2 p(v)\,dv` (physical units, m^2/s^2)."""
    itl, g = _nd(params)
    return _velocity_moment_nd(itl, g, 2) * params.v0 * params.v0


def exact_D(params: Params) -> float:
    r"""White-noise diffusivity by quadrature, any :math:`b(v) = -v/\tau_L + \bar\gamma`.

    .. math::
        D = \frac2\Gamma \int \frac{F(v)^2}{p(v)}\,dv, \qquad
        F(v) = \int_{-\infty}^{v} (u - m)\,p(u)\,du, \quad m = \int u\,p(u)\,du,

    exact for a 1-D velocity diffusion with Fokker-Planck diffusion coefficient :math:`\Gamma`
    (MODEL_NOTES section 2).  F is integrated from the nearer tail.
    """
    itl, g = _nd(params)
    with warnings.catch_warnings():  # inner quads near the kink report harmless round-off
        warnings.simplefilter("ignore", integrate.IntegrationWarning)
        return _exact_D_nd(itl, g) * params.D0


def _exact_D_nd(itl, g):
    lin = _linear_limit(itl, g)
    if lin is not None:
        return 2.0 * lin[1] * lin[1]
    m = _velocity_moment_nd(itl, g, 1)
    logZ = _log_norm(itl, g)
    s = _scale(itl, g)
    integrand = lambda v: math.exp(float(_log_p_unnorm(v, itl, g)) - logZ) * _G(v, m, itl, g, s) ** 2
    return 2.0 * sum(_quad(integrand, a, b, s, 1e-10) for a, b in _pieces(0.0, m, *_mode_points(itl, g)))


def _closed_form_args(Gamma, Delta=None, **kw):
    """Validate a closed form's arguments by name (``ValueError``, as Params does): they were
    taken as they came, so a NaN gave NaN and a zero a ZeroDivisionError."""
    check_positive("Gamma", Gamma)
    if Delta is not None:
        check_positive("Delta", Delta)
    for name, v in kw.items():
        (check_finite if name == "gamma_bar" else check_positive)(name, v)


def _finite(name, value):
    if not math.isfinite(value):
        raise ValueError(f"{name} overflows for these parameters (Gamma, Delta out of floating-point range); "
                         "use other units")
    return value


def D_pure_dry(Gamma, Delta) -> float:
    r""":math:`b = 0`: :math:`D = 10\Gamma^3/\Delta^4` (:math:`= 5\Gamma_w^3/(4\Delta^4)`)."""
    _closed_form_args(Gamma, Delta)
    G, d = float(Gamma), float(Delta)
    return _finite("D", 10.0 * (G / d) ** 3 / d if G / d < 1e100 else math.inf)


def D_constant_bias(Gamma, Delta, gamma_bar) -> float:
    r""":math:`b = \bar\gamma`, :math:`|\bar\gamma| < \Delta`:
    :math:`D = 2\Gamma^3(5\Delta^4 + 22\Delta^2\bar\gamma^2 + 5\bar\gamma^4)/(\Delta^2 - \bar\gamma^2)^4`."""
    _closed_form_args(Gamma, Delta, gamma_bar=gamma_bar)
    _check_bias(Delta, gamma_bar)
    d2, g2 = Delta * Delta, gamma_bar * gamma_bar  # products: a float's ** raises on overflow
    gap2 = (d2 - g2) * (d2 - g2)
    return _finite("D", 2 * Gamma * Gamma * Gamma * (5 * d2 * d2 + 22 * d2 * g2 + 5 * g2 * g2) / (gap2 * gap2))


def M0_constant_bias(Gamma, Delta, gamma_bar) -> float:
    r""":math:`b = \bar\gamma`: :math:`M_0 = 2\Gamma\bar\gamma/(\Delta^2 - \bar\gamma^2)`."""
    _closed_form_args(Gamma, Delta, gamma_bar=gamma_bar)
    _check_bias(Delta, gamma_bar)
    return 2 * Gamma * gamma_bar / (Delta**2 - gamma_bar**2)


def D_viscous_only(Gamma, tau_L) -> float:
    r"""Limit :math:`\Delta \to 0`: :math:`D = 2\tau_L^2\Gamma` (the paper's :math:`\tau_L^2\Gamma` is the
    :math:`\Gamma_w = \Gamma` form)."""
    _closed_form_args(Gamma, tau_L=tau_L)
    return _finite("D", 2.0 * tau_L * tau_L * Gamma)


def _check_bias(Delta, gamma_bar):
    if not abs(gamma_bar) < Delta:
        raise ValueError(f"gamma_bar must satisfy |gamma_bar| < Delta (got {gamma_bar}, Delta = {Delta})")


# ---------------------------------------------------------------------------------------------
# Touchette (2010), pure dry friction, nondimensional: dv = -sgn(v) dt + sqrt(2) dW
# ---------------------------------------------------------------------------------------------
def _log_erfc(z):
    """log erfc(z) without underflow: erfc(z) = 2 Phi(-z sqrt 2)."""
    return math.log(2.0) + special.log_ndtr(-np.asarray(z, np.float64) * math.sqrt(2.0))


def _real_array(t):
    """``t`` as a float64 array; ``ValueError`` naming ``t`` unless it is a real number or an array
    of them (a string, a bool, None or a list of them was read as a number, or said "got nan")."""
    try:
        a = None if isinstance(t, (str, bytes)) else np.asarray(t)
    except Exception:  # noqa: BLE001  (a ragged list, say)
        a = None
    if a is None or a.dtype.kind not in "iuf":
        raise ValueError(f"t must be a real number or an array of real numbers (got {t!r:.80})")
    return a.astype(np.float64)


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
    v = np.asarray(v, np.float64)
    a, av = abs(v0), np.abs(v)
    st = math.sqrt(t)
    g = np.exp(-t / 4 - (av - a) / 2 - (v - v0) ** 2 / (4 * t)) / (2 * math.sqrt(math.pi) * st)
    return g + 0.25 * np.exp(-av + _log_erfc((av + a - t) / (2 * st)))


def first_moment(t, v0):
    r""":math:`\langle v(t)\rangle` from :math:`v_0` (Touchette eq. 2.11 with :math:`\Gamma_w = 2`), :math:`a = |v_0|`:

    .. math::
        \frac{\mathrm{sgn}(v_0)}2\Big[(a-t)\operatorname{erfc}\frac{t-a}{2\sqrt t}
        + e^{a}(a+t)\operatorname{erfc}\frac{a+t}{2\sqrt t}\Big],

    with :math:`e^{a}\operatorname{erfc}(\cdot)` evaluated in logs (it overflows otherwise);
    :math:`v_0` itself at t = 0.
    """
    check_finite("v0", v0)
    t = _times(t, zero_ok=True)
    a = abs(v0)
    tp = np.where(t > 0, t, 1.0)
    st = np.sqrt(tp)
    term1 = (a - tp) * special.erfc((tp - a) / (2 * st))
    term2 = (a + tp) * np.exp(a + _log_erfc((a + tp) / (2 * st)))
    return np.where(t > 0, 0.5 * math.copysign(1.0, v0) * (term1 + term2), float(v0))[()]  # a scalar for a scalar t


def _corr_asymptotic(t, n_terms=14):
    # C(t) = e^{-t/4}/(6 sqrt(pi t)) * sum_k c_k t^-k, c_k = s_{k+3} + 6 s_{k+2} - 12 s_{k+1} + 24 s_k,
    # s_n = (-2)^n (2n-1)!!  (erfcx asymptotic series; the t^3 .. t^0 terms cancel exactly)
    s = [1.0]
    for n in range(1, n_terms + 4):
        s.append(s[-1] * (-2.0) * (2 * n - 1))
    acc = sum((s[k + 3] + 6 * s[k + 2] - 12 * s[k + 1] + 24 * s[k]) * t ** (-k) for k in range(1, n_terms))
    return np.exp(-t / 4) / (6 * np.sqrt(np.pi * t)) * acc


def correlation(t):
    r"""Stationary velocity correlation :math:`C(t) = \langle v(0) v(t)\rangle` (nondimensional):

    .. math::
        C(t) = \frac{t^3+6t^2-12t+24}{12}\operatorname{erfc}\frac{\sqrt t}2
        - \frac{\sqrt t\,(t^2+4t-12)}{6\sqrt\pi} e^{-t/4},

    :math:`C(0) = 2`, :math:`\int_0^\infty C = 5` (so :math:`D' = 10`).  The two terms cancel for
    large t, so the common factor :math:`e^{-t/4}` is taken out through ``erfcx`` and, beyond
    t = 300, the cancelled asymptotic series is used.
    """
    t = _times(np.abs(_real_array(t)), zero_ok=True)  # C(-t) = C(t)
    small = t <= 300.0
    ts = np.where(small, t, 1.0)
    x = np.sqrt(ts) / 2
    direct = np.exp(-ts / 4) * ((ts**3 + 6 * ts**2 - 12 * ts + 24) / 12 * special.erfcx(x)
                                - np.sqrt(ts) * (ts**2 + 4 * ts - 12) / (6 * np.sqrt(np.pi)))
    tl = np.where(small, 400.0, t)
    return np.where(small, direct, _corr_asymptotic(tl))


#: Table 1 times t'.
TABLE1_TIMES = (0.05, 0.125, 0.25, 0.5, 1.0, 2.5)


def first_moment_unit_intensity(t, v0):
    r"""The paper's printed Table 1 convention (:math:`\Gamma_w = \Gamma`, i.e. this model with
    :math:`\Gamma` halved), in the paper's units: the halved model has :math:`\tau_0/2` and
    :math:`v_0/2`, so the value is :math:`\tfrac12\langle v\rangle(2t;\ 2v_0)`."""
    check_finite("v0", v0)
    return 0.5 * first_moment(2.0 * _real_array(t), 2.0 * v0)
