r"""Mutation audit of :mod:`dryfric_jax.theory` (white-noise exact results and their stable helpers).

Audited: the stationary density and its log-space normalisation (``_log_p_unnorm``, ``_log_half_line_mass``,
``_log_erfcx``, ``_log_norm``), exact M0 / E[V^2] / D (``_quad``, ``_tail_scales``, ``_mode_points``, ``_pieces``,
``_linear_limit`` and LINEAR_BARRIER, ``_mean_strong_damping``, ``_G``, ``_in_units``), the closed forms and their
range handling (``_closed_form_args``, ``_product``, ``_gaps``, ``_refuse_range``, ``_check_bias``), Touchette's
propagator, first moment (Table 1) and correlation (``_corr_asymptotic``, CORR_SERIES_FROM), input checks.

Counts: 119 one-line mutants; 89 killed by tests/test_theory.py, test_exact_audit.py, test_bad_input.py and the
Table 1 / Fig. 6 figure tests; 14 equivalent (e.g. the sign of G = F/p, which D squares; the t^0 term of the
correlation's series, whose coefficient is exactly 0; a power-of-2 rescaling in ``_gaps``; switch points moved
inside a range where both branches agree to <= 1e-14, measured; quad's limit 200 -> 50, never reached); 15 killed
only by this file; 1 alive (the moments' quadrature loosened to epsrel 1e-7: scipy still reaches ~1e-14).

Oracles (none is the package's output): the OU limit of a strong bias (M0' = v*, E[V^2]' = v*^2 + tau_L',
D' = 2 tau_L'^2, the Gaussian's peak), exact to double precision beyond a barrier of ~40; plain scipy quadrature of
the MODEL_NOTES section 2 density; a semi-analytic D (F/p in closed form through erfcx, derived by hand below, one
quadrature); C(t) in 160-digit decimal arithmetic (Taylor series of erfc, Machin's pi); hand arithmetic for the
closed forms, powers of two at float64's range ends and the refusals' orders of magnitude.
"""
import math
import sys
import warnings
from decimal import Decimal, localcontext

import numpy as np
import pytest
from scipy import integrate, special

from dryfric_jax import Params, theory

G_PHYS, DELTA_PHYS = 2.0, 0.5  # tau0 = 8, v0 = 4, D0 = 64: a wrong unit power shows


def _q(f, pts, epsrel=1e-13):
    """scipy quad of f over the real line broken at ``pts`` (round-off warnings at 1e-13 are expected)."""
    pts = sorted(set(pts))
    pieces = [(-np.inf, pts[0]), *zip(pts[:-1], pts[1:]), (pts[-1], np.inf)]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", integrate.IntegrationWarning)
        return sum(integrate.quad(f, a, b, epsabs=0, epsrel=epsrel, limit=400)[0] for a, b in pieces)


def _moments_nd(tl, g):
    """(M0', E[V^2]') of p(v) ~ exp(-v^2/(2 tl) - |v| + g v) by plain quadrature (MODEL_NOTES section 2,
    nondimensional), broken at 0 and at the bump v* = sgn(g)(|g| - 1) tl."""
    vs = math.copysign(abs(g) - 1.0, g) * tl if abs(g) > 1 else 0.0
    psi = lambda v: -v * v / (2 * tl) - abs(v) + g * v  # noqa: E731
    c = psi(vs)
    pts = [0.0, vs, vs - 8 * math.sqrt(tl), vs + 8 * math.sqrt(tl)]
    z = _q(lambda v: math.exp(psi(v) - c), pts)
    return (_q(lambda v: v * math.exp(psi(v) - c), pts) / z, _q(lambda v: v * v * math.exp(psi(v) - c), pts) / z)


# ------------------------------------------------------------------------------------------------------------
# the OU limit of a strong bias: its switch (LINEAR_BARRIER) and the quadrature just below it
# ------------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_a_low_barrier_is_not_the_ou_limit(sign):
    """Barrier B = (|g'| - 1)^2 tau_L'/2 = 12: the velocity still reaches 0 with probability ~e^-12, so M0 and
    E[V^2] differ from the OU values v*, v*^2 + tau_L' by ~4e-7 (relative) and must be the plain quadrature's.
    Kills LINEAR_BARRIER = 10 (the OU shortcut taken where the friction still acts)."""
    tl = 50.0
    g = sign * (1.0 + math.sqrt(2 * 12.0 / tl))
    p = Params.from_nondim(1e-3, tl, g, Gamma=G_PHYS, Delta=DELTA_PHYS)
    m, m2 = _moments_nd(tl, g)
    vs = math.copysign(abs(g) - 1.0, g) * tl
    assert abs(m / vs - 1) > 1e-7  # the oracle sees the friction
    assert theory.exact_M0(p) == pytest.approx(m * p.v0, rel=1e-11, abs=0)
    assert theory.exact_mean_square_velocity(p) == pytest.approx(m2 * p.v0**2, rel=1e-11, abs=0)


@pytest.mark.parametrize("tl,g", [(1.0, 1.0 + math.sqrt(1460.0)), (1.0, -1.0 - math.sqrt(1460.0)), (5800.0, 1.5)])
def test_barrier_just_below_the_float64_switch(tl, g):
    """B = (|g'| - 1)^2 tau_L'/2 = 730 and 725, just below LINEAR_BARRIER = 745 (quadrature) and above 709.8,
    where erfcx(-sqrt B) overflows: p's normalisation must come from x^2 + log erfc(x).  The values are the OU
    limit to double precision (friction's share ~e^-725): M0' = v*, E[V^2]' = v*^2 + tau_L',
    D' = 2 tau_L'^2 (MODEL_NOTES, Delta -> 0), and the density at the bump's top is the Gaussian's
    1/sqrt(2 pi tau_L').  At g' = 1.5 the bump lies 38 widths from 0.
    Kills _log_erfcx taking erfcx down to x = -30 (inf there) and _mode_points skipping 1 < |g'| <= 2
    (the quadrature missed the bump: M0 = 0)."""
    p = Params.from_nondim(1e-3, tl, g, Gamma=G_PHYS, Delta=DELTA_PHYS)
    vs = math.copysign(abs(g) - 1.0, g) * tl
    assert theory.exact_M0(p) == pytest.approx(vs * p.v0, rel=1e-12, abs=0)
    assert theory.exact_mean_square_velocity(p) == pytest.approx((vs * vs + tl) * p.v0**2, rel=1e-12, abs=0)
    assert theory.stationary_density(vs * p.v0, p) * p.v0 == pytest.approx(1 / math.sqrt(2 * math.pi * tl), rel=1e-12)
    if tl == 1.0:  # (exact_D takes 7 s at tau_L' = 5800)
        assert theory.exact_D(p) == pytest.approx(2 * tl * tl * p.D0, rel=1e-10, abs=0)


# ------------------------------------------------------------------------------------------------------------
# refusals: the right word, the right size, the right edge of float64's range
# ------------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("call,msg", [
    # 10 Gamma^3/Delta^4 = 10 * 1e900 * 1e1200 = 1e2101
    (lambda: theory.D_pure_dry(1e300, 1e-300), "D overflows float64 for Gamma = 1e+300, Delta = 1e-300 "),
    (lambda: theory.D_pure_dry(1e300, 1e-300), "|D| ~ 1e2101)"),
    # 10 * 1e-600 = 1e-599
    (lambda: theory.D_pure_dry(1e-200, 1.0), "D underflows float64 for Gamma = 1e-200, Delta = 1.0 "),
    (lambda: theory.D_pure_dry(1e-200, 1.0), "|D| ~ 1e-599)"),
    # D' ~ 2 tau_L'^2 = 2e-400 (strong damping): the quadrature's 0.0 is an underflow, not an overflow
    (lambda: theory.exact_D(Params.from_nondim(1.0, 1e-200, 0.3)), "D underflows float64 for Gamma = 1.0, "),
    # M0 = 2 Gamma g/(Delta^2 - g^2) = 2e308/0.75
    (lambda: theory.M0_constant_bias(1e308, 1.0, 0.75), "M0 overflows float64 for Gamma = 1e+308, "),
])
def test_range_refusals_say_which_end_and_how_far(call, msg):
    """The refusal says "overflows" or "underflows" as the value (computed by hand in each comment) is above
    float64's largest or below its smallest normal number, and its decimal size.  The other tests match
    "(underflows|overflows)".  Kills _product's over=e < _MAX_EXP, _in_units' over=True and a size printed
    with the natural log."""
    with pytest.raises(ValueError) as e:
        call()
    assert msg in str(e.value), str(e.value)


def test_results_at_the_edges_of_float64_are_returned():
    """Exact powers of two: D = 2 tau_L^2 Gamma = 2^-1022 (the smallest normal number, not refused) and
    10 Gamma^3/Delta^4 = 10 * 2^1019 (below the largest).  Kills _product's range test _MIN_EXP < e."""
    assert theory.D_viscous_only(2.0**-1021, 0.5) == sys.float_info.min
    assert theory.D_pure_dry(2.0**340, 2.0**0.25) == pytest.approx(10 * 2.0**1019, rel=1e-15)
    with pytest.raises(ValueError, match="^D underflows"):
        theory.D_viscous_only(2.0**-1022, 0.5)  # 2^-1023: subnormal, refused


def test_no_stationary_state_is_refused_by_the_density_too():
    """tau_L = inf with |gamma_bar| = Delta: the law is not normalisable.  stationary_density must refuse it by
    name like exact_D (it has no closed form to do it: without check_recurrent it failed with "math domain
    error").  Kills dropping check_recurrent from _nd."""
    p = Params(5.0, 3.84, 1e-3, math.inf, 3.84)
    with pytest.raises(ValueError, match="^gamma_bar must satisfy"):
        theory.stationary_density(0.1, p)


@pytest.mark.parametrize("tl", [0.5, 1.0])
def test_no_bias_means_zero_mobility_with_damping(tl):
    """g' = 0: p is even, so M0 = 0 (exactly, by the strong-damping formula's symmetry) and is returned, not
    refused as an underflow.  Kills exact_M0's positive=True."""
    assert theory.exact_M0(Params.from_nondim(1e-3, tl, 0.0, Gamma=G_PHYS, Delta=DELTA_PHYS)) == 0.0


# ------------------------------------------------------------------------------------------------------------
# exact D for finite tau_L against a semi-analytic oracle (one quadrature, F/p in closed form)
# ------------------------------------------------------------------------------------------------------------
def _J(beta, T):
    r""":math:`\int_0^\infty e^{-s^2/(2T) - \beta s} ds = \sqrt{\pi T/2}\,\operatorname{erfcx}(\beta\sqrt{T/2})`."""
    return math.sqrt(math.pi * T / 2) * special.erfcx(beta * math.sqrt(T / 2))


def _law_by_hand(T, g):
    r"""(M0', D') of :math:`p \propto e^{\psi}`, :math:`\psi = -v^2/(2T) - |v| + g v` (nondimensional), derived by
    hand.  On each side :math:`u = T(\beta_\pm - \psi'(u))` (:math:`\beta_\pm = g \mp 1`), so
    :math:`\int u e^{\psi}` integrates by parts:
    :math:`m = T((g - 1) J(1 - g) + (g + 1) J(1 + g))/Z`, :math:`Z = J(1 - g) + J(1 + g)`, and
    :math:`F/p = (T(g + 1) - m) K_-(v) - T` for v <= 0, :math:`-(T(g - 1) - m) K_+(v) - T` for v >= 0, with
    :math:`K_\mp(v) = \int e^{\psi(v \mp s) - \psi(v)} ds = J(1 \pm g \mp v/T)`.  Then
    :math:`D' = 2\int p (F/p)^2` (MODEL_NOTES section 2) by one scipy quad at epsrel 1e-13: no nested quadrature,
    no tail scaling, no log-space normalisation.  Agrees with exact_D to ~1e-15 at tau_L' <= 3."""
    Jp, Jm = _J(1 - g, T), _J(1 + g, T)
    Z = Jp + Jm
    m = T * ((g - 1) * Jp + (g + 1) * Jm) / Z

    def f_over_p(v):
        return (T * (g + 1) - m) * _J(1 + g - v / T, T) - T if v <= 0 else -(T * (g - 1) - m) * _J(1 - g + v / T, T) - T

    psi = lambda v: -v * v / (2 * T) - abs(v) + g * v  # noqa: E731
    return m, 2 * _q(lambda v: math.exp(psi(v)) / Z * f_over_p(v) ** 2, [0.0, m])


@pytest.mark.parametrize("tl,g", [(3.0, -0.7), (1.0, 0.3), (0.25, -0.8)])
def test_exact_D_to_1e13_against_the_semi_analytic_law(tl, g):
    """exact_D (physical units) against :func:`_law_by_hand` to 2e-13: the existing nested-quadrature oracles
    allow 1e-9.  Silently: scipy's IntegrationWarning on the kink's round-off is the package's to swallow.
    Kills loosening the inner quadrature of F/p to epsrel 1e-6 (4.5e-11 off at tau_L' = 3, g' = -0.7), the
    outer one to 1e-5 (1.6e-11), and _round_off_ignored letting the warning through."""
    p = Params.from_nondim(1e-3, tl, g, Gamma=G_PHYS, Delta=DELTA_PHYS)
    m, D = _law_by_hand(tl, g)
    with warnings.catch_warnings(record=True) as shown:  # (recorded: the package's own filter would override "error")
        warnings.simplefilter("always")
        got_m, got_D = theory.exact_M0(p), theory.exact_D(p)
    assert not shown, [str(w.message) for w in shown]
    assert got_m == pytest.approx(m * p.v0, rel=1e-13, abs=0)
    assert got_D == pytest.approx(D * p.D0, rel=2e-13, abs=0)


def test_closed_forms_compute_in_float64_from_float32_arguments():
    """numpy float32 arguments are the float64 numbers they hold: D and E[V^2] of the constant bias by MODEL_NOTES'
    formulas in float64 (the float32 values widened by hand), to 1e-14.  Computing r^2 = (gamma_bar/Delta)^2 in
    float32 left ~1e-9.  Kills _closed_form_args returning its arguments without float()."""
    f32 = np.float32
    G, Dl, g = (float(f32(x)) for x in (5.0, 3.84, 0.342))
    gap = (Dl - g) * (Dl + g)
    assert theory.D_constant_bias(f32(5.0), f32(3.84), f32(0.342)) == pytest.approx(
        2 * G**3 * (5 * Dl**4 + 22 * Dl**2 * g**2 + 5 * g**4) / gap**4, rel=1e-14, abs=0)
    p = Params(G, Dl, 1e-3, math.inf, g)
    assert theory.exact_mean_square_velocity(p) == pytest.approx(2 * G**2 * (Dl**2 + 3 * g**2) / gap**2, rel=1e-14)
    assert theory._mean_square_constant_bias(f32(5.0), f32(3.84), f32(0.342)) == pytest.approx(
        2 * G**2 * (Dl**2 + 3 * g**2) / gap**2, rel=1e-14, abs=0)


# ------------------------------------------------------------------------------------------------------------
# Touchette's stationary correlation between t = 100 and the series cut
# ------------------------------------------------------------------------------------------------------------
def _correlation_by_taylor(t, prec=160):
    r"""C(t) of MODEL_NOTES section 2 in ``prec``-digit decimal arithmetic with
    :math:`\operatorname{erfc}(x) = 1 - \frac{2}{\sqrt\pi}\sum_n \frac{(-1)^n x^{2n+1}}{n!(2n+1)}` (Taylor series;
    at :math:`x = \sqrt t/2 \le 6` its terms reach ~e^36 and erfc ~1e-17: ~60 of the digits are lost, ~100 kept)
    and :math:`\pi` from Machin's formula: independent of scipy and of the continued fraction of test_theory."""
    with localcontext() as ctx:
        ctx.prec = prec

        def atan_inv(n):  # arctan(1/n)
            x, s, k, p = Decimal(1) / n, Decimal(0), 0, Decimal(1) / n
            while p > Decimal(10) ** (-prec - 5):
                s += (-1) ** k * p / (2 * k + 1)
                k, p = k + 1, p * x * x
            return s

        pi = 16 * atan_inv(5) - 4 * atan_inv(239)
        t = Decimal(repr(t))
        x = t.sqrt() / 2
        term, n, s = x, 0, Decimal(0)  # term = (-1)^n x^(2n+1)/n!
        while abs(term) > Decimal(10) ** (-prec + 10) or n < 10:
            s += term / (2 * n + 1)
            n += 1
            term = -term * x * x / n
        erfc = 1 - 2 / pi.sqrt() * s
        gauss = t.sqrt() * (t**2 + 4 * t - 12) / (6 * pi.sqrt()) * (-t / 4).exp()
        return float((t**3 + 6 * t**2 - 12 * t + 24) / 12 * erfc - gauss)


def test_correlation_below_the_series_cut():
    """C(t) at t = 100 ... 159 (test_theory checks 40 and 150 only) against :func:`_correlation_by_taylor`, to
    the erfcx form's own accuracy ~4 eps t^4/768 (8e-11 at t = 125).  The 34-term asymptotic series is 4e-8 off
    at t = 120, 3e-9 at 130.  Kills CORR_SERIES_FROM = 120."""
    for tt in (100.0, 121.0, 125.0, 135.0, 145.0, 159.0):
        rel = max(1e-12, 4 * np.finfo(float).eps * tt**4 / 768)
        assert float(theory.correlation(tt)) == pytest.approx(_correlation_by_taylor(tt), rel=rel, abs=0), tt


def test_first_moment_at_t0_is_v0_silently():
    """<v(0)> = v0 exactly, for v0 = 0 too, and without a numpy warning (under -W error a divide-by-zero at t = 0
    would be an exception).  Kills first_moment dividing by sqrt(t) at t = 0 (tp = where(t >= 0, ...))."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert np.array_equal(theory.first_moment([0.0, 0.0], 2.5), [2.5, 2.5])
        assert theory.first_moment(0.0, 0.0) == 0.0
        assert theory.first_moment_unit_intensity(0.0, -1.5) == -1.5
