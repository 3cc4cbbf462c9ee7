"""Exact oracles for the internals that the end-to-end tests reach only statistically (a mutation
audit found these mutants alive): the PDMP's phi1/phi2 series and hitting time against
``decimal`` at 60 digits, the grid offsets and sizes against hand arithmetic, the noise chain's
stationary law against detailed balance in ``fractions``, the uniform mapping bit for bit, the
regeneration set against scipy's Gaussian density, and fixed-seed moment tests of the streams."""
import dataclasses
import math
import re
from decimal import Decimal, getcontext
from fractions import Fraction

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import stats

import dryfric_jax as dj
from dryfric_jax import rng
from dryfric_jax.combine import combine_estimates
from dryfric_jax.noise import check_delta, delta_max, grid_size, stationary_law, up_probability
from dryfric_jax.ou import OUStep
from dryfric_jax.pdmp import grid_offsets, hitting_time, make_pdmp_model, pdmp_grid_info, phi1, phi2
from dryfric_jax.regeneration import split_set

getcontext().prec = 60


def _dphi(z, order):
    """phi1 = (e^z - 1)/z or phi2 = (e^z - 1 - z)/z^2 of the float z, in 60-digit decimal."""
    z = Decimal(float(z))
    return float((z.exp() - 1) / z) if order == 1 else float((z.exp() - 1 - z) / (z * z))


def _zs(dtype):
    cut = 0.1 if dtype == np.float32 else 0.01
    near = cut * np.array([0.5, 0.9, 0.99, 0.999, 1.001, 1.01, 1.1, 2.0])
    z = np.concatenate([np.geomspace(1e-7, 0.5, 40), near, [0.3, 0.45]]).astype(dtype)
    return np.concatenate([z, -z])


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_phi1_and_phi2_are_correctly_rounded_to_a_few_ulp(dtype):
    """Relative error against 60-digit decimal, in units of eps.  Bounds: phi1 and the series of
    phi2 are a few roundings (measured max 2.8 ulp: 4); outside the series phi2 = (expm1(z) - z)/z^2
    loses the absolute rounding of expm1(z) - z, ~2 eps |z|, against z^2/2: 4 eps/|z| more (measured
    264 ulp at z = 0.01 in float64, 38 at 0.11 in float32).  A series coefficient 1/700 for 1/720
    (phi1) or 1/4000 for 1/5040 (phi2) is 17 and 46 ulp off at z = 0.0099; a float32 series cut at
    0.5, 14 ulp at 0.45."""
    eps = float(np.finfo(dtype).eps)
    cut = 0.1 if dtype == np.float32 else 0.01
    z = _zs(dtype)
    p1, p2 = np.asarray(phi1(jnp.asarray(z))), np.asarray(phi2(jnp.asarray(z)))
    assert p1.dtype == dtype and p2.dtype == dtype
    for zi, g1, g2 in zip(z.astype(float), p1.astype(float), p2.astype(float)):
        e1, e2 = _dphi(zi, 1), _dphi(zi, 2)
        assert abs(g1 - e1) <= 4 * eps * e1, (zi, g1, e1)
        bound2 = 4 * eps + (0.0 if abs(zi) < cut else 4 * eps / abs(zi))
        assert abs(g2 - e2) <= bound2 * e2, (zi, g2, e2)
    assert float(phi1(jnp.asarray(0.0, dtype))) == 1.0 and float(phi2(jnp.asarray(0.0, dtype))) == 0.5


def test_hitting_time_is_the_closed_form():
    """T* = log(1 + kappa sigma)/kappa, sigma = -v/a, in 60-digit decimal (sigma itself at
    kappa = 0): to 4 eps.  log(1 + x) for log1p is 7e-8 off at kappa = 1e-9 sigma; taking the
    inviscid sigma for kappa < 1e-6 is kappa sigma/2 = 8e-9 off at kappa = 1e-8."""
    cases = [(v, a, k) for k in (0.0, 1e-300, 1e-12, 1e-8, 1e-3, 0.7, 40.0)
             for v, a in ((0.5, -0.3), (-1.7, 2.9), (3.0, -1e-3))]
    vs, as_, ks = (jnp.asarray(c, jnp.float64) for c in zip(*cases))
    got = np.asarray(hitting_time(vs, as_, ks))
    for T, (v, a, kappa) in zip(got, cases):
        sigma, k = -Decimal(v) / Decimal(a), Decimal(kappa)
        x = k * sigma  # log(1 + x)/kappa, by its series where 1 + x is 1 even at 60 digits
        exact = float(sigma if kappa == 0 else sigma * (1 - x / 2) if x < Decimal("1e-40") else (1 + x).ln() / k)
        assert abs(T - exact) <= 4 * np.finfo(float).eps * exact, (v, a, kappa, T, exact)
    # the mode, not the sign of v, decides: v = 0 against the force is an immediate stop
    assert np.all(np.asarray(hitting_time(vs * 0, as_, ks, -jnp.sign(as_))) == 0.0)


def test_grid_offsets_snap_only_within_the_stated_tolerance():
    """1 - gamma_bar 1e-7 grid steps above x_4 = 1 is off the grid (k_+ = 4, r_+ = -1e-7 delta),
    1e-11 steps is on it (r = 0); likewise k_- for -1 - gamma_bar.  A tolerance of 1e-3 steps
    snapped the first."""
    d = 0.25
    for off, on in ((1e-7, False), (1e-11, True)):
        gb = -off * d  # (1 - gb)/d = 4 + off, (-1 - gb)/d = -4 + off
        kp, km, r_p, r_m = grid_offsets(d, gb)
        if on:
            assert (kp, km, r_p, r_m) == (4, -4, 0.0, 0.0)
        else:
            assert (kp, km) == (4, -3)
            assert r_p == pytest.approx(-off * d, rel=1e-6) and r_p < 0
            assert r_m == pytest.approx(d * (1 - off), rel=1e-12)


def test_grid_size_is_ceil_of_the_reach_plus_one():
    """N = ceil(L_req / delta) + 1 by hand: L_req = 8/sqrt(tau) = 8 at tau = 1; 8/0.125 = 64 is
    exact (N = 65), 8/0.15 = 53.3 (N = 55); at tau = 100, gamma_bar = -3 the thresholds set
    L_req = 4 (N = ceil(4/0.003) + 1 = 1335)."""
    assert grid_size(0.125, 1.0) == 65
    assert grid_size(0.15, 1.0) == 55
    assert grid_size(0.003, 100.0, -3.0) == 1335
    assert grid_size(2.0**-26, 1.0) == 2**29 + 1  # a grid of 2^30 + 3 points is still counted, not refused
    dm = 4 / (8 + math.sqrt(80))  # tau = 1: delta_max = 4/(tau L + sqrt((tau L)^2 + 16 tau)), L = 8
    check_delta(0.99 * dm * 2.5, 1.0, scale=2.5)  # a delta in units of 1/2.5 of the nondim one
    # the range's top 2.5 dm = 0.590170 rounded down (into the range) to 4 digits
    with pytest.raises(ValueError, match=r"^delta must be in \(0, 0\.5901\)"):
        check_delta(1.01 * dm * 2.5, 1.0, scale=2.5)
    N, d, tau = 10, 0.2, 1.0
    k = np.arange(-N, N + 1)
    expect = [0.0 if j == N else 1.0 if j == -N else 0.5 - tau * d * d * j / 4 for j in k]
    np.testing.assert_allclose(up_probability(k, N, d, tau), expect, rtol=1e-15, atol=0)


@pytest.mark.parametrize("N,d,tau", [(10, Fraction(1, 5), Fraction(1)), (7, Fraction(1, 10), Fraction(30))])
def test_stationary_law_is_detailed_balance(N, d, tau):
    """pi_(k+1) (1 - alpha_(k+1)) = pi_k alpha_k solved in exact rationals, alpha_k = 1/2 -
    tau delta^2 k/4 (reflecting ends), against the float law to 1e-13 (about 60 roundings)."""
    alpha = lambda k: Fraction(0) if k == N else Fraction(1) if k == -N else Fraction(1, 2) - tau * d * d * k / 4
    w = [Fraction(1)]
    for k in range(-N, N):
        w.append(w[-1] * alpha(k) / (1 - alpha(k + 1)))
    pi = [x / sum(w) for x in w]
    x, got = stationary_law(N, float(d), float(tau))
    np.testing.assert_allclose(x, [float(k * d) for k in range(-N, N + 1)], rtol=1e-15, atol=0)
    np.testing.assert_allclose(got, [float(p) for p in pi], rtol=1e-13, atol=0)


def test_pdmp_grid_info_in_physical_units():
    """delta' = delta sqrt(Gamma)/Delta, L_X = N delta (physical), Lambda' = 2/(tau' delta')^2, at
    Gamma = 4, Delta = 0.5 (so delta' = 4 delta), checked by hand against the nondim tau'."""
    p = dj.Params(Gamma=4.0, Delta=0.5, tau=0.3, gamma_bar=0.1)
    tau_nd = p.nondim().tau
    delta = 0.25 * 0.9 * 0.2361 / math.sqrt(tau_nd)  # delta' = 0.9 delta_max (L_req = 8/sqrt(tau'))
    g = pdmp_grid_info(p, delta)
    assert g["delta_nd"] == pytest.approx(4 * delta, rel=1e-15)
    assert g["L_X"] == pytest.approx(g["N"] * delta, rel=1e-15)
    assert g["N"] == math.ceil(8 / math.sqrt(tau_nd) / (4 * delta)) + 1
    assert g["rate_nd"] == pytest.approx(2 / (tau_nd * 4 * delta) ** 2, rel=1e-14)
    tL = tau_nd * 8 / math.sqrt(tau_nd)  # the refusal states the range in physical units: delta_max' / 4
    dm_phys = 4 / (tL + math.sqrt(tL * tL + 16 * tau_nd)) / 4
    with pytest.raises(ValueError, match=rf"^delta must be in \(0, [^)]+\) .*\(got {delta / 0.9 * 1.1}\)") as e:
        pdmp_grid_info(p, delta / 0.9 * 1.1)
    top = float(re.match(r"delta must be in \(0, ([^)]+)\)", str(e.value)).group(1))
    assert dm_phys * (1 - 1e-3) <= top <= dm_phys  # 4 digits, rounded into the range
    m = make_pdmp_model(p, delta)
    assert float(m.c_alpha) == pytest.approx(tau_nd * (4 * delta) ** 2 / 4, rel=1e-15)


def test_a_refusals_stated_range_is_accepted_to_its_ends():
    """DEFECT (fixed: params.rounded_bound): a refusal printed its bounds to 4 digits rounded to nearest, so an
    upper bound could be printed above the true one and a lower one below it: "h must be in [..., 0.01235] s"
    refused h = 0.01235, and "delta must be in (0, 0.05873)" refused 0.058726.  Now a bound is rounded into the
    range.  Over 300 seeded parameter points: both ends of the stated h range are accepted, as is the largest
    float below the stated top of delta's open range (the old code failed at 300 of the points for h, at one end
    or the other, and at 154 for delta)."""
    from dryfric_jax.plan import check_h

    rs = np.random.default_rng(11)
    for _ in range(300):
        G, D = 10 ** rs.uniform(-3, 3), 10 ** rs.uniform(-2, 2)
        tau_nd, gb = 10 ** rs.uniform(-2, 3), rs.uniform(-0.99, 0.99)
        p = dj.Params(G, D, tau_nd * G / D**2, 10 ** rs.uniform(-1, 2) * G / D**2, gb * D)
        with pytest.raises(ValueError) as e:
            check_h(p, 1e300)
        lo, hi = map(float, re.match(r"h must be in \[([^,]+), ([^\]]+)\] s", str(e.value)).groups())
        assert check_h(p, lo) == lo and check_h(p, hi) == hi, str(e.value)
        with pytest.raises(ValueError) as e:
            pdmp_grid_info(p, 1e300)
        top = float(re.match(r"delta must be in \(0, ([^)]+)\)", str(e.value)).group(1))
        pdmp_grid_info(p, float(np.nextafter(top, 0)))


def test_a_delta_within_ulps_of_its_bound_is_refused_in_physical_units():
    """DEFECT (fixed in pdmp.pdmp_grid_info): the physical delta was checked as delta / (Delta/sqrt(Gamma))
    but used as delta' = delta * (sqrt(Gamma)/Delta), which can round an ulp higher; a delta accepted by the
    first check was then refused by grid_size's check of delta', whose message gave the nondimensional range
    and value ("delta must be in (0, 0.003214) ... (got 0.0032138...)" for a delta of 0.0871 s^-1/2).  Here
    (2000 seeded parameter points, the bound and the 5 floats below it) 254 of the old code's 2258 refusals
    named the wrong range.  Now every delta is accepted with its grid or refused with the physical range
    delta_max' Delta / sqrt(Gamma) (noise.delta_max, checked against its closed form in
    test_grid_size_is_ceil_of_the_reach_plus_one; 4 significant digits) and the delta as given."""
    rs = np.random.default_rng(7)
    refused = 0
    for _ in range(2000):
        G, D = 10 ** rs.uniform(-2, 2), 10 ** rs.uniform(-1, 1)
        tau_nd, gb = 10 ** rs.uniform(-2, 3), rs.uniform(-0.99, 0.99)
        p = dj.Params(G, D, tau_nd * G / D**2, math.inf, gb * D)
        nd = p.nondim()
        dm = delta_max(nd.tau, nd.gamma_bar) * D / math.sqrt(G)
        x = dm
        for _ in range(6):
            try:
                g = pdmp_grid_info(p, x)
                assert g["N"] >= 2 and nd.tau * g["delta_nd"] ** 2 * g["N"] < 2 * (1 + 1e-12)
            except ValueError as e:
                refused += 1
                got = re.escape(repr(x))
                m = re.match(rf"delta must be in \(0, ([^)]+)\) for these parameters \(got {got}\)", str(e))
                assert m, str(e)
                # the stated range is the bound to 4 digits rounded into it, and excludes x (before: rounded
                # to nearest, "(0, 0.05873)" refusing 0.058726)
                top = float(m.group(1))
                assert dm * (1 - 1e-3) <= top <= dm and x >= top, str(e)
            x = float(np.nextafter(x, 0))
    assert refused > 100  # the bound itself and rounding next to it are exercised


def test_draw_lanes_keeps_the_waiting_time_uniform_above_zero(monkeypatch):
    """All-zero hash bits are the smallest uniform: draw_lanes must give minval = tiny there, as
    draw does (-log 0 would be an infinite waiting time); minval 0 passed every bit-for-bit test."""
    p = dj.Params.from_nondim(0.5, 1.0, 0.2)
    zeros = lambda kd, block, n, dtype, start=0, materialise=True: tuple(  # noqa: E731
        jnp.zeros((block, kd.shape[0]), rng._uint(dtype)) for _ in range(n))
    monkeypatch.setattr(rng, "_bits", zeros)
    for dtype in (jnp.float32, jnp.float64):
        m = make_pdmp_model(p, 0.3, dtype)
        u1, u2 = m.draw_lanes(jax.random.split(jax.random.key(0), 3), 4)
        assert np.all(np.asarray(u1) == np.finfo(dtype).tiny) and np.all(np.asarray(u2) > 0)


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_unit_and_normal_bit_mapping(dtype):
    """The top mantissa bits give f = (bits >> (w - nmant)) 2^-nmant exactly, [lo, hi) scales it;
    the extreme bits give finite normals: radius sqrt(-2 ln u) at the first and last cell midpoints
    u = 2^-(m+1) (bits 0) and 1 - 2^-(m+1) (all ones), on the angle's axes (m = nmant, or 32 for a float64
    pair's 32-bit words)."""
    ut, nm = rng._uint(dtype), np.finfo(dtype).nmant
    w = 8 * np.dtype(dtype).itemsize
    top = (1 << w) - 1
    ints = [0, 1, 1 << (w - nm), (1 << (w - 1)) + 12345, top, 0x5DEECE66D % (1 << w)]
    bits = jnp.asarray(np.array(ints, dtype=ut))
    f = [Fraction(b >> (w - nm), 1 << nm) for b in ints]
    np.testing.assert_array_equal(np.asarray(rng._unit(bits, dtype, 0.0, 1.0)), np.array([float(x) for x in f], dtype))
    lo, hi = 0.25, 3.0  # (f (hi - lo) + lo) in dtype, with f exact: two roundings at most
    got = np.asarray(rng._unit(bits, dtype, lo, hi)).astype(float)
    ref = np.array([float(x * Fraction(hi - lo) + Fraction(lo)) for x in f])
    assert np.all(np.abs(got - ref) <= 2 * np.finfo(dtype).eps * ref) and np.all((got >= lo) & (got < hi))
    # u from bits 0 / all ones: the first and last cells' midpoints, t from bits 0: angle 0.  A float64 pair's
    # bits are one hash's two 32-bit words, all 32 bits read (rng module docstring)
    if dtype == np.float64:
        ut, w, nm = np.uint32, 32, 32
        bits = jnp.asarray(np.array([0, 1, 2, 3, (1 << 32) - 1], dtype=ut))
        f = [Fraction(0), None, None, None, Fraction((1 << 32) - 1, 1 << 32)]
    z1, z2 = (np.asarray(a).astype(float) for a in rng._normal(bits[np.array([0, 4])], bits[np.array([0, 0])], dtype))
    u = np.array([float(f[0]), float(f[4])]) + 2.0 ** -(nm + 1)  # the cells' midpoints, exact
    assert np.all(np.isfinite(z1)) and np.allclose(z1, np.sqrt(-2 * np.log(u)), rtol=1e-6 if dtype == np.float32 else 1e-13)
    assert np.all(z2 == 0)
    # t from the quarter-turn bits: the radius moves to the sine, exactly
    quarter = jnp.asarray(np.array([1 << (w - 2)] * 2, dtype=ut))
    c, s_ = (np.asarray(a).astype(float) for a in rng._normal(bits[np.array([0, 4])], quarter, dtype))
    assert np.all(c == 0) and np.all(s_ == z1)


def test_streams_have_the_right_moments_and_no_cross_correlation():
    """Fixed seed, 64 lanes x 256 rows x 2 columns: normals have mean 0 (se 1/sqrt n), variance
    1 (se sqrt(2/n)), kurtosis 3 (se sqrt(96/n)); uniforms on [0.25, 3) have mean 1.625 (se
    2.75/sqrt(12 n)) and lie in range; lanes, columns and rows (lag 1) are uncorrelated (se
    1/sqrt n).  Bounds are 5 se (two-sided p = 6e-7 per check)."""
    keys = jax.random.split(jax.random.key(424242), 64)
    zs = [np.asarray(c, float) for c in rng.normals(keys, 256, 2, jnp.float64)]
    us = [np.asarray(c, float) for c in rng.uniforms(keys, 256, 2, jnp.float64, 0.25, 3.0)]
    for z in zs:
        n = z.size
        assert abs(z.mean()) < 5 / math.sqrt(n) and abs(z.var() - 1) < 5 * math.sqrt(2 / n)
        assert abs(stats.kurtosis(z.ravel(), fisher=False) - 3) < 5 * math.sqrt(96 / n)
    for u in us:
        assert u.min() >= 0.25 and u.max() < 3.0
        assert abs(u.mean() - 1.625) < 5 * 2.75 / math.sqrt(12 * u.size)
    se = 5 / math.sqrt(zs[0].size)
    corr = lambda a, b: np.corrcoef(a.ravel(), b.ravel())[0, 1]  # noqa: E731
    assert abs(corr(zs[0], zs[1])) < se  # columns
    assert abs(corr(zs[0][:, :-1], zs[0][:, 1:])) < se  # neighbouring lanes
    assert abs(corr(zs[0][:-1], zs[0][1:])) < se  # consecutive rows


def _ou(m1, m2, L11, L21, L22):
    return OUStep(*(jnp.asarray(c, jnp.float64) for c in (m1, m2, L11, L21, L22)))


@pytest.mark.parametrize("tau", [0.05, 50.0])
def test_split_set_is_the_minorisation_of_the_gaussian_step(tau):
    """For a step with mean x m and covariance L L^T: a = L^-1 m (numpy solve), w = min(1/|a|,
    4/sqrt(tau)), C = [c - w, c + w], epsilon = 2 Phi(-w |a|), and log r = min over the ends of
    log phi(y - c_i m) - log phi(y - x m) (scipy's density), at points of C."""
    m = np.array([0.83, 0.61])
    L = np.array([[0.42, 0.0], [-0.17, 0.29]])
    s = split_set(_ou(m[0], m[1], L[0, 0], L[1, 0], L[1, 1]), 0.7, tau)
    a = np.linalg.solve(L, m)
    w = min(1 / np.linalg.norm(a), 4 / math.sqrt(tau))
    assert float(s.c1) == pytest.approx(0.7 - w, rel=1e-14) and float(s.c2) == pytest.approx(0.7 + w, rel=1e-14)
    assert float(s.epsilon) == pytest.approx(2 * stats.norm.cdf(-w * np.linalg.norm(a)), rel=1e-12)
    law = stats.multivariate_normal(cov=L @ L.T)
    for x, z in ((0.7 - 0.3 * w, (0.4, -1.1)), (0.7 + 0.8 * w, (-2.0, 0.5)), (0.7, (0.0, 0.0))):
        y = x * m + L @ np.array(z)
        ref = min(law.logpdf(y - c * m) for c in (0.7 - w, 0.7 + w)) - law.logpdf(y - x * m)
        assert float(s.log_coin(x, *z)) == pytest.approx(ref, rel=1e-10, abs=1e-12)


def test_uniform_per_key_honours_its_range():
    """rng.uniform with a range other than the engine's (tiny, 1): jax.random.uniform's numbers bit
    for bit and inside [0.25, 3) (a uniform that dropped minval/maxval passed with (tiny, 1))."""
    keys = jax.random.split(jax.random.key(3), 8)
    for dtype in (jnp.float32, jnp.float64):
        ref = jax.vmap(lambda k: jax.random.uniform(k, (), dtype, 0.25, 3.0))(keys)
        got = np.asarray(rng.uniform(keys, dtype, 0.25, 3.0))
        np.testing.assert_array_equal(got, np.asarray(ref))
        assert np.all((got >= 0.25) & (got < 3.0))


def _synthetic(seed, U, t, **kw):
    """An EstimateResult of the DI (units with D0, v0, tau0 all different from 1) with the excursions (U, t) and the
    given bookkeeping (D, M0 are not read by combine: they are recomputed from the sums)."""
    from dryfric_jax.estimators import sums_from_samples

    base = dict(D=1.0, D_ci=0.1, M0=0.0, M0_ci=0.1, mean_duration=1.0, n_excursions=len(U), n_truncated=0,
                method="di", h=1e-3, dtype="float64", seed=seed, wall_s=1.0, lane_steps_per_s=1.0,
                params=dj.Params(Gamma=4.0, Delta=0.5, tau=0.3, gamma_bar=0.1).as_dict(),
                sums=sums_from_samples(U, t, 0.5 * t),
                version="test")
    return dj.EstimateResult(**{**base, **kw})


def test_combine_pools_every_field_by_its_own_rule():
    """Two synthetic runs: D, M0 and the mean duration are the by-hand ratio estimators of the
    pooled excursions (M0 = sum U / sum t, D = sum (U - M0 t)^2 / sum t, times D0, v0, tau0); the
    counts and work add, wall time adds, the rate is steps/wall = (200 + 150)/5, utilisation is
    steps/slots = 350/(400 + 600), a setting the runs differ in is 0 and the seeds are listed."""
    g = np.random.default_rng(7)
    U1, t1, U2, t2 = g.normal(0.3, 1, 400), g.exponential(1, 400) + 0.1, g.normal(0.3, 1, 600), g.exponential(1, 600)
    a = _synthetic(1, U1, t1, wall_s=2.0, lane_steps_per_s=100.0, lane_utilization=0.5, work=300,
                   predicted_work=310.5, max_work=1000.0, n_truncated=1, n_requested=40, lanes=8, block=128)
    b = _synthetic(2, U2, t2, wall_s=3.0, lane_steps_per_s=50.0, lane_utilization=0.25, work=200,
                   predicted_work=190.25, max_work=2000.0, n_truncated=2, n_requested=60, lanes=8, block=64)
    c = combine_estimates([a, b])
    U, t = np.concatenate([U1, U2]), np.concatenate([t1, t2])
    p = dj.Params(**a.params)
    m0 = U.sum() / t.sum()
    assert c.M0 == pytest.approx(m0 * p.v0, rel=1e-12)
    assert c.D == pytest.approx(((U - m0 * t) ** 2).sum() / t.sum() * p.D0, rel=1e-12)
    assert c.mean_duration == pytest.approx(t.mean() * p.tau0, rel=1e-12) and c.n_excursions == 1000
    assert (c.wall_s, c.lane_steps_per_s, c.lane_utilization) == (5.0, 70.0, 0.35)
    assert (c.work, c.predicted_work, c.max_work, c.n_truncated, c.n_requested) == (500, 500.75, 3000.0, 3, 100)
    assert (c.lanes, c.block, c.combined_from, c.seed) == (8, 0, [1, 2], None)
    with pytest.raises(ValueError, match="lane_utilization"):
        combine_estimates([a, dataclasses.replace(b, lane_utilization=1.5)])
    with pytest.raises(ValueError, match="seeds must differ"):
        combine_estimates([a, dataclasses.replace(b, seed=1)])
    # a pool pools further under its runs' seeds, which still may not repeat
    d = _synthetic(3, U1[:50], t1[:50])
    assert combine_estimates([c, d]).combined_from == [1, 2, 3]
    with pytest.raises(ValueError, match=r"seed 2 used by results\[0\] and by results\[1\]"):
        combine_estimates([c, dataclasses.replace(d, seed=2)])


def test_keys_of_any_other_generator_take_jax_random():
    """unsafe_rbg keys (not only rbg) are not threefry: their draws are of jax.random's own bits (a
    check 'not rbg' hashed them as threefry, other numbers entirely).  (Their derived keys are not
    compared: unsafe_rbg's fold_in and split under vmap differ from one key at a time in JAX itself.)"""
    keys = jax.random.split(jax.random.key(9, impl="unsafe_rbg"), 4)
    ref = jax.vmap(lambda k: rng.normal(k, (3, 2), jnp.float64))(keys)
    got = rng.normals(keys, 3, 2, jnp.float64)
    for c in range(2):
        np.testing.assert_array_equal(np.asarray(got[c]), np.asarray(ref[:, :, c]).T)


def test_model_force_and_viscous_rate_by_hand():
    """a = x_k + gamma_bar' - y (the force at v = 0 in mode y = +-1) at off-grid thresholds, where
    r_+ != r_-, to rounding; inv_tau_L = 1/tau_L' (0 for tau_L = inf)."""
    p = dj.Params(Gamma=4.0, Delta=0.5, tau=0.3, tau_L=2.0, gamma_bar=0.13)
    nd = p.nondim()
    m = make_pdmp_model(p, 0.01)
    d = float(m.delta)
    assert float(m.r_p) != float(m.r_m)
    for k in (-7, 0, 3, int(m.kp) + 1, int(m.km) - 1):
        for y in (1, -1):
            a = float(m.force(jnp.int32(k), jnp.int32(y)))
            assert a == pytest.approx(k * d + nd.gamma_bar - y, abs=1e-12), (k, y)
    assert float(m.inv_tau_L) == pytest.approx(1 / nd.tau_L, rel=1e-15)
    assert float(make_pdmp_model(dj.Params(Gamma=4.0, Delta=0.5, tau=0.3), 0.01).inv_tau_L) == 0.0
