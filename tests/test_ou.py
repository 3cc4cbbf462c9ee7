"""Exact OU step: closed forms, Cholesky factor, sampled moments, and an independent fine-grid check."""
import re

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from dryfric_jax.ou import ou_moments, ou_moments_reference, ou_step

RATIOS = np.logspace(-8, 8, 49)


def _rel(a, b):
    return abs(a - b) / max(abs(b), 1e-300)


# and r near 1, between the grid's 0.46 and 1, where the series of the time-average's moments is cut (15 terms
# instead of 30 passed: 2e-10 off at r = 0.9)
@pytest.mark.parametrize("r", list(RATIOS) + [0.7, 0.9, 0.99, 0.999])
def test_moments_match_high_precision_closed_forms_float64(r):
    tau = 0.37
    got = [float(v) for v in ou_moments(jnp.float64(r * tau), tau)]
    ref = ou_moments_reference(r * tau, tau)
    for g, e in zip(got, ref):
        if e == 0.0:  # e^{-r} underflows for r = 1e8 in both
            assert g == 0.0
        else:
            assert _rel(g, e) < 1e-12


@pytest.mark.parametrize("r", RATIOS[::4])
def test_moments_float32(r):
    tau = 0.37
    got = [float(v) for v in ou_moments(jnp.float32(r * tau), jnp.float32(tau))]
    ref = ou_moments_reference(float(np.float32(r * tau)), float(np.float32(tau)))
    for g, e in zip(got, ref):
        assert np.isfinite(g)
        if abs(e) > 1e-30:
            assert _rel(g, e) < 5e-6


@pytest.mark.parametrize("r", RATIOS[::2])
@pytest.mark.parametrize("dtype,tol", [(jnp.float64, 1e-12), (jnp.float32, 5e-6)])
def test_cholesky_factor_is_exact(r, dtype, tol):
    """L L^T = Sigma entrywise, and L22^2 = det(Sigma)/Sigma11 from the 60-digit reference."""
    tau = 2.0
    s = ou_step(r * tau, tau, dtype)
    m1, m2, S11, S12, S22 = ou_moments_reference(r * tau, tau, digits=80)
    from decimal import Decimal, localcontext
    with localcontext() as c:
        c.prec = 80
        det = float(Decimal(S11) * Decimal(S22) - Decimal(S12) ** 2)
    L11, L21, L22 = (float(v) for v in (s.L11, s.L21, s.L22))
    assert all(np.isfinite([L11, L21, L22])) and L11 > 0 and L22 > 0
    assert _rel(L11**2, S11) < tol
    assert _rel(L11 * L21, S12) < tol
    assert _rel(L21**2 + L22**2, S22) < tol
    # the reference det is itself rounded from float64 Sigma entries; it keeps ~1e-16/(1-rho^2)
    rho2 = S12**2 / (S11 * S22)
    assert _rel(L22**2, det / S11) < max(tol, 4e-16 / (1 - rho2))


@pytest.mark.parametrize("r", [1e-6, 1e-2, 1.0, 1e2, 1e6])
def test_sampled_pair_moments(r, key):
    """Mean and covariance of 4e5 sampled pairs, tolerance 5 standard errors of each moment."""
    tau, x0 = 0.5, 0.8
    s = ou_step(r * tau, tau)
    n = 400_000
    z = jax.random.normal(key, (2, n))
    Xi, Xn = s.sample(x0, z[0], z[1])
    Y = np.stack([np.asarray(Xi), np.asarray(Xn)])
    m1, m2, S11, S12, S22 = (float(v) for v in ou_moments(jnp.float64(r * tau), tau))
    S = np.array([[S11, S12], [S12, S22]])
    mean = np.array([m1, m2]) * x0
    se_mean = np.sqrt(np.diag(S) / n)
    assert np.all(np.abs(Y.mean(1) - mean) < 5 * se_mean)
    C = np.cov(Y)
    for i in range(2):
        for j in range(2):
            se = np.sqrt((S[i, i] * S[j, j] + S[i, j] ** 2) / n)  # Gaussian sampling error of a covariance
            assert abs(C[i, j] - S[i, j]) < 5 * se


def test_pair_law_against_fine_grid_ou(key):
    """Independent check of m(h), Sigma(h): exact OU on 400 sub-steps, Riemann (trapezoid) average."""
    tau, h, x0, sub, n = 1.0, 1.0, 1.3, 400, 50_000
    dt = h / sub
    a, sd = np.exp(-dt / tau), np.sqrt((1 - np.exp(-2 * dt / tau)) / tau)
    z = np.asarray(jax.random.normal(key, (sub, n)))
    x = np.full(n, x0)
    integral = np.zeros(n)
    for k in range(sub):
        xn = a * x + sd * z[k]
        integral += 0.5 * (x + xn) * dt
        x = xn
    Xi = integral / h
    m1, m2, S11, S12, S22 = (float(v) for v in ou_moments(jnp.float64(h), tau))
    # trapezoid bias is O(dt^2) ~ 6e-6, far below the 5-sigma statistical tolerance
    assert abs(Xi.mean() - x0 * m1) < 5 * np.sqrt(S11 / n)
    assert abs(x.mean() - x0 * m2) < 5 * np.sqrt(S22 / n)
    C = np.cov(np.stack([Xi, x]))
    S = np.array([[S11, S12], [S12, S22]])
    for i in range(2):
        for j in range(2):
            assert abs(C[i, j] - S[i, j]) < 5 * np.sqrt((S[i, i] * S[j, j] + S[i, j] ** 2) / n)


@pytest.mark.parametrize("r,tau", [(1e9, 0.37), (1e12, 1e-12), (1e100, 1e-100), (1e298, 1e-300)])
def test_white_noise_limit_beyond_r_1e8(r, tau):
    """r = h/tau > 1e8 (tau' -> 0, white noise): the exponentials vanish and Sigma is exactly
    (1/tau) [[(2 - 3/r)/r, 1/r], [1/r, 1]]; before, r^2 overflowed at r ~ 1e154 and the factor
    came out (0, inf, nan).  Checked against the 60-digit closed forms where Decimal reaches."""
    s = ou_step(r * tau, tau)
    L11, L21, L22 = (float(v) for v in (s.L11, s.L21, s.L22))
    assert all(np.isfinite([L11, L21, L22])) and L11 > 0 and L22 > 0
    S11, S12, S22 = L11 * L11, L11 * L21, L21 * L21 + L22 * L22
    for got, want in ((S11, (2 - 3 / r) / r / tau), (S12, 1 / r / tau), (S22, 1 / tau)):
        assert _rel(got, want) < 1e-14, (got, want)
    if r < 1e20:
        _, _, rS11, rS12, rS22 = ou_moments_reference(r * tau, tau)
        assert _rel(S11, rS11) < 1e-14 and _rel(S12, rS12) < 1e-14 and _rel(S22, rS22) < 1e-14
    m1, m2, *_ = (float(v) for v in ou_moments(jnp.float64(r * tau), tau))
    assert _rel(m1, 1 / r) < 1e-15 and m2 == 0.0


@pytest.mark.parametrize("h,tau,name", [(0.0, 1.0, "h"), (-1.0, 1.0, "h"), (1.0, float("nan"), "tau")])
def test_a_step_that_is_not_positive_is_refused(h, tau, name):
    """Before: a factor of NaNs (h = 0: 0/0 in m1 and the Cholesky terms)."""
    with pytest.raises(ValueError, match=f"^{name} must be finite and > 0"):
        ou_step(h, tau)


def test_ou_moments_and_step_refuse_bad_input_by_name():
    """ou_moments had no checks (h = 0: NaN; h = -1: a negative variance) and an integer h made tau
    an integer (tau = 0.5 became 0: S11 = nan); ou_step took dtype float16 and failed on 'foo' with
    a TypeError."""
    import numpy as np

    from dryfric_jax.ou import ou_moments, ou_step

    assert np.allclose(ou_moments(1, 0.5), ou_moments(1.0, 0.5), rtol=0, atol=0)
    for h, tau, name in ((0.0, 1.0, "h"), (-1.0, 1.0, "h"), (1.0, 0.0, "tau"), (1.0, float("nan"), "tau")):
        with pytest.raises(ValueError, match=f"^{name} must be finite and > 0"):
            ou_moments(h, tau)
    for dtype in ("foo", "float16", 5):
        with pytest.raises(ValueError, match=r"^dtype must be one of \['float32', 'float64'\]"):
            ou_step(0.1, 1.0, dtype=dtype)
    assert ou_step(0.1, 1.0, dtype=np.float32).m1.dtype == np.float32


def test_an_integer_step_is_a_float_step():
    """ou_step(1, 0.5) is ou_step(1.0, 0.5) (an integer h must not make the arithmetic integer)."""
    a, b = ou_step(1, 0.5), ou_step(1.0, 0.5)
    for f in ("m1", "m2", "L11", "L21", "L22"):
        assert float(getattr(a, f)) == float(getattr(b, f)), f


@pytest.mark.parametrize("r", [1e-12, 1e-60, 1e-120, 2e-150])
def test_tiny_steps_keep_the_leading_order_factor(r):
    """Towards r = h/tau -> 0 the factor tends to its leading order, m = (1, 1), L11 = sqrt(2r/3), L21 =
    sqrt(3r/2), L22 = sqrt(r/2) (over sqrt(tau); corrections O(r)), down to min_ratio, and the split set built
    from it is finite (below ~1e-154 L21 and L22 were 0 and the split set NaN)."""
    from dryfric_jax.regeneration import split_set

    tau = 1e3
    s = ou_step(r * tau, tau)
    want = dict(m1=1.0, m2=1.0, L11=np.sqrt(2 * r / 3 / tau), L21=np.sqrt(1.5 * r / tau), L22=np.sqrt(r / 2 / tau))
    for f, w in want.items():
        assert _rel(float(getattr(s, f)), w) < 1e-11, f
    c = split_set(s, 1.0, tau)
    assert all(np.isfinite(float(getattr(c, f))) for f in c.__dataclass_fields__)


def test_a_step_below_min_ratio_is_refused_by_name():
    """h/tau below the dtype's normal range gave 0/0 = NaN in m1 and the factor, silently (an audit: ou_step(1e-310,
    1), ou_moments(0.01, 1e308), float32 ou_moments(1e-20, 1e20), make_di_model at tau = 1e299 s, h = 1e-12 s).  The
    bound is the dtype the step is computed in, from the caller's values, 4 sqrt(tiny); a margin of 1e4 refused
    exact float32 steps, a float32 cast named tau = 1e39 "inf", and a float64 factor cast to float32 came out 0 (a
    review)."""
    import dryfric_jax as dj
    from dryfric_jax.ou import min_ratio

    assert min_ratio(np.float64) == pytest.approx(5.97e-154, rel=1e-2)
    assert min_ratio(np.float32) == pytest.approx(4.34e-19, rel=1e-2)
    msg = r"^h/tau must be >= 6e-154 in float64 \(got h = {}, tau = {}: h/tau = {}\)"
    for call, args in ((ou_step, (1e-310, 1.0)), (ou_moments, (0.01, 1e308)), (ou_step, (1e-6, 1e150))):
        h, tau = args
        with pytest.raises(ValueError, match=msg.format(*(re.escape(f"{x:.3g}") for x in (h, tau, h / tau)))):
            call(*args)
    with pytest.raises(ValueError, match=r"^h/tau must be >= 4\.3e-19 in float32 \(got h = 1e-20, tau = 1e\+20"):
        ou_moments(np.float32(1e-20), np.float32(1e20))
    with pytest.raises(ValueError, match=r"^h/tau must be >= 4\.3e-19 in float32 \(got h = 0\.001, tau = 1e\+39"):
        ou_moments(np.float32(1e-3), 1e39)
    with pytest.raises(ValueError, match=r"^h/tau must be >= 6e-154 in float64 \(got h = 1e-12, tau = 1e\+152"):
        dj.make_di_model(dj.Params(1.0, 1.0, 1e152, 1.0, 0.0), 1e-12)
    for h in (1e-12, None):  # no allowed h would do: said so, also of the default h
        with pytest.raises(ValueError, match=r"^tau = 1e\+299 s is too long for any step h <= 0\.1 s"):
            dj.make_di_model(dj.Params(1.0, 1.0, 1e299, 1.0, 0.0), h)
    with pytest.raises(ValueError, match=r"^h/tau = 1e-100 is too small for dtype float32: the OU step's factor "
                                         r"\(L11, L21, L22\) rounds to 0 in it; use float64"):
        ou_step(1e-100, 1.0, dtype="float32")
    # just above the bounds the factor is exact (the leading order, corrections O(r))
    for h, dt in ((1e-153, None), (np.float32(5e-19), None), (1e-17, "float32")):
        s = ou_step(h, np.float32(1.0) if isinstance(h, np.float32) else 1.0, dtype=dt)
        assert _rel(float(s.L22), np.sqrt(float(h) / 2)) < 2e-7
