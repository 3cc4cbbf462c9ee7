"""White-noise theory: quadrature against closed forms, Touchette's formulas against their own identities.

Expected numbers come from MODEL_NOTES section 2 (closed forms, Table 1 values), not from this code.
"""
import math

import numpy as np
import pytest
from scipy import integrate

from dryfric_jax import Params, theory


def test_quadrature_pure_dry_friction():
    for G, D in [(1.0, 1.0), (5.0, 3.84), (1e-3, 3.84), (1e3, 3.84)]:
        p = Params(G, D, 1e-6)
        assert theory.exact_D(p) == pytest.approx(10 * G**3 / D**4, rel=1e-8)
        assert abs(theory.exact_M0(p)) < 1e-12 * G / D


@pytest.mark.parametrize("gbar_rel", [-0.7, 0.05, 0.3, 0.5, 0.9, 0.99])
def test_quadrature_constant_bias(gbar_rel):
    G, Dl = 5.0, 3.84
    g = gbar_rel * Dl
    p = Params(G, Dl, 1e-6, math.inf, g)
    exact_D = 2 * G**3 * (5 * Dl**4 + 22 * Dl**2 * g**2 + 5 * g**4) / (Dl**2 - g**2) ** 4
    exact_M = 2 * G * g / (Dl**2 - g**2)
    assert theory.D_constant_bias(G, Dl, g) == pytest.approx(exact_D, rel=1e-14)
    assert theory.exact_D(p) == pytest.approx(exact_D, rel=1e-7)
    assert theory.exact_M0(p) == pytest.approx(exact_M, rel=1e-9)
    # asymmetric Laplace p(v) ~ exp(-(Delta |v| - g v)/Gamma), scales A, B on the two sides:
    # E[V^2] = 2 (A^3 + B^3) / (A + B)
    A, B = G / (Dl - g), G / (Dl + g)
    assert theory.exact_mean_square_velocity(p) == pytest.approx(2 * (A**3 + B**3) / (A + B), rel=1e-9)


def test_quadrature_viscous_limit():
    """Delta -> 0 with b = -v/tau_L: D -> 2 tau_L^2 Gamma (MODEL_NOTES section 2)."""
    G, tL = 1.0, 1.0
    vals = [theory.exact_D(Params(G, d, 1e-6, tL)) for d in (1e-3, 1e-4)]
    assert vals[-1] == pytest.approx(2 * tL**2 * G, rel=1e-3)
    assert abs(vals[-1] - 2) < abs(vals[0] - 2)  # converging


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_strong_bias_reaches_the_linear_ou_limit(sign):
    """|gamma_bar| >> Delta with viscous damping: the velocity stays near
    v* = (|gamma_bar| - Delta) tau_L and never reaches 0 (the barrier psi(v*) - psi(0) =
    (|gamma_bar'| - 1)^2 tau_L'/2 is large), so V is an OU process: D = 2 tau_L^2 Gamma
    (MODEL_NOTES section 2, the Delta -> 0 limit) and M0 = sgn(gamma_bar) v*, up to O(e^-barrier).
    The quadrature (barrier 40-700) must reach these independent values; beyond the float64
    barrier the closed form is used.  Before, the normalisation overflowed (erfcx of a large
    negative number) and exact_M0 returned 0.0 at gamma_bar = 1000 m/s^2."""
    G, Dl, tL = 5.0, 3.84, 0.067
    tL_nd = tL / (G / Dl**2)
    for g_rel in (20.0, 60.0, 85.0, 150.0, 1e4):  # barrier 36, 344, 697 (quadrature); 2190, 1e7
        p = Params(G, Dl, 0.5, tL, sign * g_rel * Dl)
        barrier = (g_rel - 1.0) ** 2 * tL_nd / 2
        assert theory.exact_D(p) == pytest.approx(2 * tL**2 * G, rel=1e-9), (g_rel, barrier)
        assert theory.exact_M0(p) == pytest.approx(sign * (g_rel - 1.0) * Dl * tL, rel=1e-9), (g_rel, barrier)
        v = (g_rel - 1.0) * Dl * tL
        assert theory.exact_mean_square_velocity(p) == pytest.approx(v * v + G * tL, rel=1e-9), g_rel


def test_no_stationary_state_is_refused():
    with pytest.raises(ValueError, match="gamma_bar"):
        theory.exact_D(Params(1.0, 1.0, 1e-3, math.inf, 1.0))


def test_stationary_density_normalised_and_has_the_model_convention():
    p = Params(5.0, 3.84, 1e-5, 0.067, 0.342)
    f = lambda v: theory.stationary_density(v, p)
    mass = integrate.quad(f, -np.inf, 0)[0] + integrate.quad(f, 0, np.inf)[0]
    assert mass == pytest.approx(1.0, rel=1e-10)
    # log-density slope on v > 0 away from 0: -v/(Gamma tau_L) - (Delta - gamma_bar)/Gamma
    v1, v2 = 0.01, 0.02
    slope = (np.log(f(v2)) - np.log(f(v1))) / (v2 - v1)
    assert slope == pytest.approx(-(v1 + v2) / 2 / (5.0 * 0.067) - (3.84 - 0.342) / 5.0, rel=1e-10)


@pytest.mark.parametrize("t,v0", [(0.05, 1.0), (0.5, 1.0), (2.5, 1.0), (1.0, -2.0), (10.0, 0.3)])
def test_propagator_normalised_and_mean_matches_first_moment(t, v0):
    f = lambda v: theory.propagator(v, t, v0)
    pts = sorted({0.0, v0})
    mass = sum(integrate.quad(f, a, b, epsabs=1e-13, limit=200)[0]
               for a, b in [(-np.inf, pts[0]), *zip(pts[:-1], pts[1:]), (pts[-1], np.inf)])
    mean = sum(integrate.quad(lambda v: v * f(v), a, b, epsabs=1e-13, limit=200)[0]
               for a, b in [(-np.inf, pts[0]), *zip(pts[:-1], pts[1:]), (pts[-1], np.inf)])
    assert mass == pytest.approx(1.0, abs=1e-9)
    assert mean == pytest.approx(float(theory.first_moment(t, v0)), abs=1e-8)


def test_first_moment_table1_both_conventions():
    model = [0.950, 0.877, 0.773, 0.618, 0.428, 0.182]  # MODEL_NOTES section 2
    printed = [0.950, 0.875, 0.757, 0.568, 0.336, 0.090]  # the paper's Table 1 (Gamma_w = Gamma)
    got = [float(theory.first_moment(t, 1.0)) for t in theory.TABLE1_TIMES]
    got_printed = [float(theory.first_moment_unit_intensity(t, 1.0)) for t in theory.TABLE1_TIMES]
    assert np.allclose(got, model, atol=5e-4)
    assert np.allclose(got_printed, printed, atol=5e-4)


def test_first_moment_stable_for_large_v0():
    vals = theory.first_moment(np.array([0.01, 1.0, 100.0]), 800.0)
    assert np.all(np.isfinite(vals)) and vals[0] == pytest.approx(800.0 - 0.01, rel=1e-9)


def test_correlation_identities():
    assert float(theory.correlation(0.0)) == pytest.approx(2.0, rel=1e-14)
    total = integrate.quad(theory.correlation, 0, np.inf, epsabs=0, epsrel=1e-12, limit=200)[0]
    assert total == pytest.approx(5.0, rel=1e-10)  # D' = 2 * 5 = 10


def test_correlation_no_cancellation_in_the_tail():
    t = np.array([40.0, 100.0, 299.99, 300.01, 1e3, 2e3])  # e^{-t/4} underflows past ~2800
    c = theory.correlation(t)
    assert np.all(np.isfinite(c)) and np.all(c > 0)
    # both branches agree where both are accurate (erfcx form keeps ~eps t^4/768 relative)
    for tt in (150.0, 250.0, 290.0):
        x = np.sqrt(tt) / 2
        from scipy.special import erfcx
        direct = np.exp(-tt / 4) * ((tt**3 + 6 * tt**2 - 12 * tt + 24) / 12 * erfcx(x)
                                    - np.sqrt(tt) * (tt**2 + 4 * tt - 12) / (6 * np.sqrt(np.pi)))
        assert theory._corr_asymptotic(tt) == pytest.approx(direct, rel=1e-8)
    # leading behaviour C ~ 128 e^{-t/4}/(sqrt(pi) t^{3/2}), first correction -24/t
    lead = 128 * np.exp(-t[4:] / 4) / (np.sqrt(np.pi) * t[4:] ** 1.5)
    assert np.allclose(c[4:] / lead, 1 - 24 / t[4:], atol=1e-3)


@pytest.mark.parametrize("call,match", [
    (lambda: theory.propagator(0.5, 0.0, 1.0), "^t must be finite and > 0"),  # was a divide-by-zero
    (lambda: theory.propagator(0.5, -1.0, 1.0), "^t must be finite and > 0"),  # was a math domain error
    (lambda: theory.propagator(0.5, math.nan, 1.0), "^t must be finite and > 0"),  # was NaN
    (lambda: theory.first_moment([1.0, -1.0], 1.0), "^t must be finite and >= 0"),  # was NaN
    (lambda: theory.first_moment(1.0, math.inf), "^v0 must be a finite number"),
    (lambda: theory.correlation([0.5, math.nan]), "^t must be finite"),
])
def test_touchette_formulas_refuse_bad_times_by_name(call, match):
    with pytest.raises(ValueError, match=match):
        call()


def test_touchette_formulas_at_their_edges():
    """<v(0)> = v0 (the formula divides by sqrt t); C is even; p(+-inf) = 0 (was NaN: inf - inf)."""
    assert np.array_equal(theory.first_moment([0.0, 0.0], -1.5), [-1.5, -1.5])
    assert theory.first_moment(1e-12, 1.0) == pytest.approx(1.0, abs=1e-6)
    assert np.array_equal(theory.correlation([-2.0, 2.0]), theory.correlation([2.0, 2.0]))
    p = Params(5.0, 3.84, 1e-6, 0.067, 0.342)
    assert np.array_equal(theory.stationary_density([-np.inf, np.inf], p), [0.0, 0.0])


@pytest.mark.parametrize("call,name", [
    (lambda: theory.D_pure_dry(5.0, math.nan), "Delta"),  # was nan
    (lambda: theory.D_pure_dry(5.0, 0), "Delta"),  # was a ZeroDivisionError
    (lambda: theory.D_pure_dry("5", 3.84), "Gamma"),  # was a TypeError
    (lambda: theory.D_pure_dry(1e300, 1e-300), "D"),  # was an OverflowError
    (lambda: theory.D_constant_bias(1e200, 1.0, 0.5), "D"),
    (lambda: theory.D_constant_bias(5.0, 3.84, None), "gamma_bar"),
    (lambda: theory.M0_constant_bias(5.0, math.inf, 0.0), "Delta"),
    (lambda: theory.D_viscous_only(5.0, math.nan), "tau_L"),
    (lambda: theory.D_viscous_only(5.0, math.inf), "tau_L"),  # was inf
    (lambda: theory.D_viscous_only(5.0, 0), "tau_L"),  # was 0.0
])
def test_closed_forms_refuse_bad_arguments_by_name(call, name):
    with pytest.raises(ValueError, match=f"^{name} (must|overflows)"):
        call()
