r"""Brute force's horizon bias and lag, exact with white noise and :math:`\tau_L = \infty`
(``theory.horizon_bias``, ``theory.m0_lag``), against an independent computation of the moments of U(t).

The formulas come from Poisson equations solved by hand (and by a computer-algebra check, 2026-12-07).  The
test solves instead the equations of the first two moments of U(t) from the Fokker-Planck equation of the
nondimensional white-noise model :math:`dv = (r - \mathrm{sgn}\,v)\,dt + \sqrt2\,dW` (MODEL_NOTES section 2):

.. math::
    \partial_t f_k = L^* f_k + k\,v\,f_{k-1},\qquad
    f_0 = p(v, t),\ f_1 = E[U(t);\ V(t) \in dv],\ f_2 = E[U(t)^2;\ V(t) \in dv],

by finite volumes (centred face fluxes, no flux through the ends of a grid reaching 40 scale lengths of the
stationary law on each side) and Crank-Nicolson steps.  :math:`\sum f_1` and :math:`\sum f_2` give E U(t) and
Var U(t) at a horizon long against the velocity's memory (the rest is ~e^{-15}), so b = t - Var U/D and
L = t - E U/M0 with the closed-form D and M0.  The scheme is second order: two grids (dv = 0.08 and 0.04,
dt = dv/2) and Richardson's extrapolation :math:`b_R = b_{0.04} + (b_{0.04} - b_{0.08})/3`.  The formula must
lie within a tenth of the fine grid's own error estimate :math:`|b_{0.04} - b_{0.08}|/3` of :math:`b_R`
(measured: within 0.003 of it; a coefficient changed in its 3rd digit fails).
"""
import math

import numpy as np
import pytest
from scipy import integrate
from scipy.linalg import solve_banded

from dryfric_jax import theory
from dryfric_jax.api import D_BIAS_BURNT_TAU_C, D_BIAS_TAU_C, M0_LAG_TAU_C


def _moments_of_U(r, t, dv, start):
    """(E U(t), Var U(t)), nondimensional, from V(0) = 0 (``start="rest"``) or the stationary law."""
    dt = dv / 2
    n_lo, n_hi = (int(round(40.0 / (1.0 + s * r) / dv)) for s in (1, -1))  # e^{-40} of the mass beyond
    v = dv * np.arange(-n_lo, n_hi + 1)  # 0 is a cell centre, so the drift's jump falls on no face
    a = r - np.sign(0.5 * (v[1:] + v[:-1]))
    cl, cr = (a / 2 + 1 / dv) / dv, (a / 2 - 1 / dv) / dv  # (face flux)/dv = cl f_left + cr f_right
    diag, up, lo = np.zeros(v.size), np.zeros(v.size), np.zeros(v.size)
    diag[:-1] -= cl
    diag[1:] += cr
    up[1:] -= cr
    lo[:-1] += cl
    implicit = np.array([-dt / 2 * up, 1 - dt / 2 * diag, -dt / 2 * lo])

    def Lstar(f):
        out = diag * f
        out[:-1] += up[1:] * f[1:]
        out[1:] += lo[:-1] * f[:-1]
        return out

    if start == "rest":
        f0 = np.zeros(v.size)
        f0[n_lo] = 1 / dv
    else:  # the asymmetric Laplace law (MODEL_NOTES section 2), sampled at the cell centres
        f0 = np.exp(np.where(v > 0, -(1 - r) * v, (1 + r) * v))
        f0 /= f0.sum() * dv
    f1, f2 = np.zeros(v.size), np.zeros(v.size)
    for _ in range(int(round(t / dt))):
        n0 = solve_banded((1, 1), implicit, f0 + dt / 2 * Lstar(f0))
        n1 = solve_banded((1, 1), implicit, f1 + dt / 2 * (Lstar(f1) + v * (f0 + n0)))
        n2 = solve_banded((1, 1), implicit, f2 + dt / 2 * (Lstar(f2) + 2 * v * (f1 + n1)))
        f0, f1, f2 = n0, n1, n2
    mean = f1.sum() * dv
    return mean, f2.sum() * dv - mean**2


def _extrapolated(r, t, start):
    """Richardson's (b, L) from the two grids, and the fine grid's error estimates of both."""
    D, M0 = theory.D_constant_bias(1.0, 1.0, r), theory.M0_constant_bias(1.0, 1.0, r)
    (m1, v1), (m2, v2) = (_moments_of_U(r, t, dv, start) for dv in (0.08, 0.04))
    b1, b2 = t - v1 / D, t - v2 / D
    out = [b2 + (b2 - b1) / 3, abs(b2 - b1) / 3]
    if M0:
        L1, L2 = t - m1 / M0, t - m2 / M0
        out += [L2 + (L2 - L1) / 3, abs(L2 - L1) / 3]
    return out


#: r = gamma_bar/Delta and a horizon some 15 relaxation times 4/(1 - |r|)^2 long
CASES = [(0.0, 60.0), (0.5, 200.0), (-0.3, 120.0)]


@pytest.mark.parametrize("r,t", CASES)
@pytest.mark.parametrize("start", ["rest", "stationary"])
def test_the_horizon_bias_is_the_moment_equations(r, t, start):
    b, b_err, *lag = _extrapolated(r, t, start)
    exact = theory.horizon_bias(1.0, 1.0, r, stationary=start == "stationary")
    assert abs(b - exact) <= 0.1 * b_err, (b, exact, b_err)
    assert b_err < 1e-2 * exact  # the grids resolve it at all
    if lag:  # from the stationary law there is no lag (E U(t) = M0 t), from rest theory.m0_lag
        L, L_err = lag
        expected = theory.m0_lag(1.0, 1.0, r) if start == "rest" else 0.0
        assert abs(L - expected) <= 0.1 * L_err + 1e-6, (L, expected, L_err)


def test_the_dip_in_correlation_times_is_the_moment_equations():
    """From rest at r = 0.1 (where b/tau_c dips to 4.83 below its 5.4 at r = 0, and the notes' 4.8258 is quoted),
    the same check as above, over 15 relaxation times."""
    b, b_err, L, L_err = _extrapolated(0.1, 75.0, "rest")
    assert abs(b - theory.horizon_bias(1.0, 1.0, 0.1)) <= 0.1 * b_err, (b, b_err)
    assert abs(L - theory.m0_lag(1.0, 1.0, 0.1)) <= 0.1 * L_err + 1e-6, (L, L_err)
    assert b * 0.9**2 == pytest.approx(4.8258, rel=1e-3)  # in tau_c = tau0/(1 - 0.1)^2


def test_the_stationary_coefficient_at_zero_bias_is_touchettes_integral():
    r"""From the stationary law Var U(t) = 2 \int_0^t (t - s) C(s) ds, so b = 2 \int s C / D over Touchette's C
    (MODEL_NOTES section 2): the formula's 14/5 tau0 by quadrature."""
    C = lambda s: float(theory.correlation(s))
    first = integrate.quad(lambda s: s * C(s), 0, math.inf, limit=200)[0]
    assert 2.0 * first / theory.D_pure_dry(1.0, 1.0) == pytest.approx(theory.horizon_bias(1.0, 1.0, stationary=True),
                                                                       rel=1e-8)


def test_the_formulas_scale_with_tau0_and_are_even_in_gamma_bar():
    """b and L are tau0 = Gamma/Delta^2 times a function of gamma_bar/Delta, even in it."""
    for f in (lambda *a: theory.horizon_bias(*a), lambda *a: theory.horizon_bias(*a, stationary=True), theory.m0_lag):
        assert f(2.0, 3.0, 1.5) == pytest.approx(2.0 / 9.0 * f(1.0, 1.0, 0.5), rel=1e-14)
        assert f(2.0, 3.0, -1.5) == pytest.approx(f(2.0, 3.0, 1.5), rel=1e-15)  # a rounding: minus, plus swap
        assert f(1e200, 1e-50, 0.0) == pytest.approx(1e300 * f(1.0, 1.0, 0.0), rel=1e-14)  # no overflow inside


def test_the_notes_quote_the_largest_exact_coefficients():
    """api.d_bias_note's and api.m0_lag_note's coefficients, in correlation times tau0/(1 - |r|)^2, are the
    largest exact white-noise values over |r| < 1: 23/4 from rest (as |r| -> 1; 27/5 at r = 0 and 4.83 at 0.1),
    14/5 after a burn-in and a lag of 3 tau_c (both at r -> 0)."""
    r = np.concatenate([np.linspace(0.0, 0.999, 1000), 1.0 - np.logspace(-3, -7, 20)])
    per_tc = lambda f: np.array([f(1.0, 1.0, x) * (1.0 - x) ** 2 for x in r])
    rest, stat = per_tc(theory.horizon_bias), per_tc(lambda *a: theory.horizon_bias(*a, stationary=True))
    lag = per_tc(theory.m0_lag)
    assert rest.max() <= D_BIAS_TAU_C and rest.max() == pytest.approx(D_BIAS_TAU_C, rel=1e-6)
    # 27/5 by hand (theory.horizon_bias's docstring); 4.8258 the formula at r = 0.1, which the moment equations
    # check there (test_the_dip_in_correlation_times_is_the_moment_equations)
    assert rest[0] == pytest.approx(5.4, rel=1e-15) and rest[100] == pytest.approx(4.8258, rel=1e-4)
    assert stat.max() == pytest.approx(D_BIAS_BURNT_TAU_C, rel=1e-15) == stat[0]
    assert lag.max() == pytest.approx(M0_LAG_TAU_C, rel=1e-15) == lag[0]


@pytest.mark.parametrize("f", [theory.horizon_bias, theory.m0_lag])
@pytest.mark.parametrize("gamma_bar", [1.0, -2.0, math.nan])
def test_a_bias_outside_the_range_is_refused_by_name(f, gamma_bar):
    with pytest.raises(ValueError, match="gamma_bar"):
        f(1.0, 1.0, gamma_bar)
