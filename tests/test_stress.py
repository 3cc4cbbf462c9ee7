"""Stress matrix: extreme parameters end in a finite, checked estimate or a clear refusal / report.

Axes (physical units, Delta = 3.84): tau 1e-8 .. 1e3 s, Gamma 1e-3 .. 1e3, h/tau 1e-6 .. 1e6,
tau_L in {1e-4, 0.067, inf} s, gamma_bar/Delta in {0, 0.5, 0.99, 1.5}, float32 and float64.

* the exact OU step on the whole (tau', h/tau, dtype) grid: Sigma(h) positive definite and equal
  to the high-precision reference, and sampled moments of the step correct;
* the planner (``plan_estimate``, pure Python) on the full product of the axes: every case is
  either a plan with finite, bounded work or a ValueError naming the parameter and its range;
* estimators actually run on a covering subset (small N, small ``max_work``): finite numbers with
  finite CIs, or a refusal, or truncated excursions that are counted and reported;
* accuracy on hard cases with exact answers: |gamma_bar| near and above Delta under white noise,
  float32 and float64 against the exact D and M0, tolerance the 95% CI.
"""
import itertools
import math
import re
import warnings
from decimal import Decimal, localcontext

import jax.numpy as jnp
import numpy as np
import pytest

import dryfric_jax as dj
from dryfric_jax.limits import FLOAT32_MIN_H_OVER_TAU, log_ou_passage_time
from dryfric_jax.noise import delta_max
from dryfric_jax.ou import ou_step
from dryfric_jax.plan import h_max, plan_estimate

DELTA = 3.84
TAUS = [1e-8, 1e-6, 1e-4, 1e-2, 1.0, 10.0, 1e3]
GAMMAS = [1e-3, 1e-1, 10.0, 1e3]
H_OVER_TAU = [1e-6, 1e-3, 1.0, 1e3, 1e6]
TAU_LS = [1e-4, 0.067, math.inf]
GB = [0.0, 0.5, 0.99, 1.5]
DTYPES = ["float32", "float64"]
PARAM_NAMES = ("Gamma", "Delta", "tau", "tau_L", "gamma_bar", "h", "delta", "max_work", "dtype")


def _quiet(f, *a, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", dj.DryfricWarning)
        return f(*a, **kw)


# ---------------------------------------------------------------------------------------------
# the OU step
# ---------------------------------------------------------------------------------------------
def _sigma_ref(h, tau):
    """Sigma(h) and det Sigma in 50-digit arithmetic from the printed closed forms."""
    with localcontext() as ctx:
        ctx.prec = 50
        h_, t_ = Decimal(repr(h)), Decimal(repr(tau))
        r = h_ / t_
        e1, e2 = (-r).exp(), (-2 * r).exp()
        S11 = t_ / h_**2 * (2 * r - 3 + 4 * e1 - e2)
        S12 = (1 - e1) ** 2 / h_
        S22 = (1 - e2) / t_
        return np.array([[float(S11), float(S12)], [float(S12), float(S22)]]), float(S11 * S22 - S12 * S12), \
            np.array([float(t_ / h_ * (1 - e1)), float(e1)])


TAU_ND = sorted({t * DELTA**2 / g for t in TAUS for g in GAMMAS})  # tau' = tau / tau0


@pytest.mark.parametrize("dtype", DTYPES)
def test_ou_step_matrix(dtype):
    rng = np.random.default_rng(7)
    n = 4000
    z = rng.standard_normal((2, n))
    tol = 1e-9 if dtype == "float64" else 2e-6
    for tau, k in itertools.product(TAU_ND, range(-6, 7)):
        h = 10.0**k * tau
        s = ou_step(h, tau, getattr(jnp, dtype))
        L = np.array([[float(s.L11), 0.0], [float(s.L21), float(s.L22)]])
        assert np.all(np.isfinite(L)) and L[0, 0] > 0 and L[1, 1] > 0, (tau, k, L)  # Sigma = L L^T is PD
        S, det, m = _sigma_ref(h, tau)
        got = L @ L.T
        assert np.allclose(got, S, rtol=tol, atol=0), (tau, k, got, S)
        assert (L[0, 0] * L[1, 1]) ** 2 == pytest.approx(det, rel=4 * tol), (tau, k)
        # sampled moments of one step from x = one stationary standard deviation
        x = 1 / math.sqrt(tau)
        Xi, Xh = (np.asarray(a, np.float64) for a in s.sample(jnp.asarray(x, dtype), jnp.asarray(z[0], dtype),
                                                               jnp.asarray(z[1], dtype)))
        y = np.stack([Xi, Xh]) - x * m[:, None]
        w = np.linalg.solve(np.linalg.cholesky(S), y)  # whitened with the reference: ~ N(0, I)
        assert np.all(np.abs(w.mean(1)) < 5 / math.sqrt(n)), (tau, k, w.mean(1))
        assert np.all(np.abs(np.cov(w) - np.eye(2)) < 7 / math.sqrt(n)), (tau, k, np.cov(w))


def test_float32_threshold_is_where_the_stationary_law_breaks():
    """The documented float32 limit h/tau >= 1e-4: below it the float32 step's own stationary
    variance of X, (L21^2 + L22^2)/(1 - m2^2), is visibly wrong; above it, it is not."""
    def var_err(r, dt):
        s = ou_step(r, 1.0, dt)
        m2, L21, L22 = (float(v) for v in (s.m2, s.L21, s.L22))
        return abs((L21**2 + L22**2) / (1 - m2**2) - 1.0)

    assert var_err(1e-6, jnp.float32) > 5e-3  # 1e-6: off by ~1%
    assert var_err(1e-6, jnp.float64) < 1e-8
    for r in (FLOAT32_MIN_H_OVER_TAU, 1e-3, 1e-1, 10.0):
        assert var_err(r, jnp.float32) < 1e-3, r
    # and the estimator refuses float32 there: it runs float64 and says so
    p = dj.Params(**dj.FIG3)
    plan = plan_estimate(p, h=1e-6 * p.tau, dtype="float32", n_excursions=100)
    assert plan.dtype == "float64" and "float32 is not safe" in plan.notes[0]


# ---------------------------------------------------------------------------------------------
# the planner on the full product of the axes
# ---------------------------------------------------------------------------------------------
def _cases():
    for G, tau, tl, gb, dt in itertools.product(GAMMAS, TAUS, TAU_LS, GB, DTYPES):
        p = dj.Params(G, DELTA, tau, tl, gb * DELTA)
        for r in H_OVER_TAU:
            yield p, dict(method="di", h=r * tau, dtype=dt)
        yield p, dict(method="pdmp", dtype=dt)
        yield p, dict(method="auto", dtype=dt)


def test_plan_matrix_every_case_is_planned_or_refused_by_name():
    outcomes = {}
    for p, kw in _cases():
        try:
            plan = plan_estimate(p, n_excursions=1000, **kw)
        except ValueError as e:
            msg = str(e)
            name = msg.split(" must ")[0]
            assert name in PARAM_NAMES + ("the parameters",) and " must " in msg and "\n" not in msg, msg
            if name == "the parameters":  # one excursion outlasts float range: refused before any h or delta
                assert msg.endswith(("No h, delta or N makes this run feasible", "when tau << tau0")), msg
            if name == "h":  # the range is stated
                m = re.match(r"h must be in \[([^,]+), ([^\]]+)\] s", msg)
                assert m and h_max(p) * (1 - 1e-3) <= float(m.group(2)) <= h_max(p), msg
            if math.isinf(p.tau_L) and abs(p.gamma_bar) >= p.Delta:
                assert name == "gamma_bar", msg  # no stationary state: refused first
            outcomes[name] = outcomes.get(name, 0) + 1
            continue
        outcomes["planned"] = outcomes.get("planned", 0) + 1
        assert not (math.isinf(p.tau_L) and abs(p.gamma_bar) >= p.Delta)
        assert math.isfinite(plan.per_tau0) and plan.per_tau0 > 0
        assert 0 < plan.predicted_work <= plan.max_work
        assert 64 <= plan.max_steps <= max(plan.max_work / plan.lanes, 64)
        if plan.method == "di":
            assert 0 < plan.h <= h_max(p) * (1 + 1e-12)
            if kw["dtype"] == "float32" and plan.h / p.tau < FLOAT32_MIN_H_OVER_TAU:
                assert plan.dtype == "float64" and plan.notes
        else:
            nd = p.nondim()
            assert 0 < plan.grid["delta_nd"] < delta_max(nd.tau, nd.gamma_bar)
            assert nd.tau * plan.grid["delta_nd"] * (plan.grid["N"] * plan.grid["delta_nd"]) < 2  # tau delta L_X < 2
    # not vacuous: every kind of outcome occurs, and a good share is planned
    assert {"planned", "h", "gamma_bar", "max_work", "the parameters"} <= set(outcomes), outcomes
    assert outcomes["planned"] > 0.15 * sum(outcomes.values()), outcomes


@pytest.mark.parametrize("tl,fastest", [(0.067, 0.067), (math.inf, 5.0 / 3.84**2), (1.0, 5.0 / 3.84**2)])
def test_default_h_and_its_bound_are_the_documented_fractions(tl, fastest):
    """README "Choosing h": default h = 0.01 min(tau0, tau_L), admissible 1e-12 min(tau0, tau_L) <= h <= 0.1 min(tau0, tau_L)
    (the bound itself included); tau0 = Gamma/Delta^2 written out here."""
    p = dj.Params(5.0, 3.84, 0.5, tl, 0.342)
    assert dj.default_h(p) == pytest.approx(0.01 * fastest, rel=1e-14)
    assert plan_estimate(p, n_excursions=100).h == pytest.approx(0.01 * fastest, rel=1e-14)
    hm = h_max(p)
    assert hm == pytest.approx(0.1 * fastest, rel=1e-14)
    assert plan_estimate(p, h=hm, n_excursions=100).h == hm
    with pytest.raises(ValueError, match=r"^h must be in \["):
        plan_estimate(p, h=hm * (1 + 1e-12), n_excursions=100)


def test_bias_equal_to_the_friction_without_damping_is_refused_before_planning():
    """tau_L = inf and |gamma_bar| = Delta exactly: no stationary state (the particle runs away), so
    the planner refuses by name (a check with > instead of >= planned the run)."""
    for gb in (3.84, -3.84):
        with pytest.raises(ValueError, match="^gamma_bar must satisfy"):
            plan_estimate(dj.Params(5.0, 3.84, 0.5, math.inf, gb), n_excursions=100)


@pytest.mark.parametrize("tl", [0.05, 0.5, 100.0, math.inf])
def test_predicted_duration_is_floored_at_min_1_tau_L_for_fast_noise(tl):
    """limits docstring: for fast noise (tau' = 1e-3, OU passage sum ~1e-4 tau0) the predicted
    duration is the floor min(1, tau_L') (a max(1, tau_L') predicted 100x the work at tau_L' = 100), or the
    deceleration floor 1/((1 - |gamma_bar'|) + 0.5/sqrt(tau_L')) where that is larger (here from tau_L' = 0.05)."""
    floor = max(min(1.0, tl), 1.0 / (0.7 + 0.5 / math.sqrt(tl)))
    assert math.exp(dj.limits.log_duration_scale(1e-3, tl, 0.3)) == pytest.approx(floor, rel=1e-12)


def test_predicted_duration_grows_near_the_runaway_bias():
    """limits docstring: near |gamma_bar'| = 1 a moving particle decelerates at the net rate 1 - |gamma_bar'|, so
    the prediction is floored at 1/((1 - |gamma_bar'|) + 0.5/sqrt(tau_L')): at tau_L = inf, 0.99 it is 100 tau0
    (the passage sum alone gave 11.5, and a PDMP audit's run did 320x its predicted work). Each measured
    mean duration (PDMP, seed 0 or 1, tau' = 1 with N = 2000, faster noise with N = 1000-3000 and a coarse delta')
    stays above the prediction: a lower estimate."""
    f = lambda tl, g, tau=1.0: math.exp(dj.limits.log_duration_scale(tau, tl, g))
    assert f(math.inf, 0.99) == pytest.approx(100.0, rel=1e-12) and f(math.inf, 0.0) < 6.0
    for tl, g, measured in ((math.inf, 0.8, 22.2), (math.inf, 0.9, 43.8), (math.inf, 0.98, 222.0), (10.0, 0.95, 20.7),
                            (100.0, 0.95, 41.3), (3.0, 0.9, 14.0), (1.0, 0.9, 11.8), (0.3, 0.95, 12.0)):
        assert f(tl, g) < measured, (tl, g)
    for tau, g, measured in ((0.1, 0.98, 58.7), (0.1, 0.95, 25.5), (0.1, 0.9, 13.3), (0.3, 0.95, 28.9), (0.01, 0.9, 26.0),
                             (0.01, 0.98, 94.2)):
        assert f(math.inf, g, tau) < measured, (tau, g)


@pytest.mark.parametrize("tau,a,b,rel", [(1.0, 0.0, -4.0, 1e-6), (2.0, 1.0, -3.0, 1e-6), (1.0, 0.0, -9.5, 1e-6),
                                         (1.0, -9.4, -9.5, 1e-4), (0.08, -28.0, -30.0, 1e-6)])  # 1e-4: a short [b, a]
def test_ou_passage_time_against_a_double_quadrature(tau, a, b, rel):
    r"""T(a -> b) = \int_b^a s(y) \int_y^\infty m(z) dz dy, scale density e^{tau y^2/2} and speed density
    tau^2 e^{-tau z^2/2} of tau dX = -X dt + sqrt2 dW, by a plain numpy trapezoid (no erfcx).  The
    far side below u = -6 (Dawson's function; e^{u^2}/|u| was 1% off there, and 64% with both ends
    below -6: the fourth case) is tested as tightly as the quadrature."""
    z = np.linspace(b, 12.0 / math.sqrt(tau), 400_001)
    w = np.exp(-0.5 * tau * (z * z - b * b))  # speed density / (tau^2 e^{-tau b^2/2})
    tail = np.concatenate([[0.0], np.cumsum(0.5 * (w[1:] + w[:-1]) * np.diff(z))])
    inner = tail[-1] - tail  # int_y^inf, same scale
    f = np.where(z <= a, np.exp(0.5 * tau * (z * z - b * b)) * inner, 0.0)  # s(y) e^{-tau b^2/2} x inner
    T = tau * tau * np.sum(0.5 * (f[1:] + f[:-1]) * np.diff(z))
    assert math.exp(log_ou_passage_time(a, b, tau)) == pytest.approx(T, rel=rel)


def test_predicted_duration_is_the_exact_ou_passage_time():
    """The work predictor's OU mean first-passage time against Monte Carlo of the exact OU
    chain, with Siegmund's correction 0.5826 sd for the discrete monitoring; tolerance 3 SE."""
    rng = np.random.default_rng(3)
    tau, a, b, dt, n = 1.0, 1.0, -1.0, 2.5e-4, 4000
    e = math.exp(-dt / tau)
    sd = math.sqrt((1 - e * e) / tau)
    x, t, alive = np.full(n, a), np.zeros(n), np.ones(n, bool)
    while alive.any():
        i = np.nonzero(alive)[0]
        x[i] = x[i] * e + sd * rng.standard_normal(i.size)
        t[i] += dt
        alive[i[x[i] <= b]] = False
    exact = math.exp(log_ou_passage_time(a, b - 0.5826 * sd, tau))
    assert abs(t.mean() - exact) < 3 * t.std() / math.sqrt(n), (t.mean(), exact)
    # the Arrhenius branch continues the quadrature branch
    lo, hi = log_ou_passage_time(0.0, -6.0 / math.sqrt(0.5) + 1e-9, 1.0), \
        log_ou_passage_time(0.0, -6.0 / math.sqrt(0.5) - 1e-9, 1.0)
    assert abs(lo - hi) < 1e-6


def test_fast_noise_floors_set_the_predicted_work_and_the_excursion_bound():
    """limits.di_cycle_floor / le_floor: for fast noise the predicted cycle is the floor, not the passage floor
    min(1, tau_L'); the predicted work, the refusal just above it and the per-excursion bound all use it."""
    from dryfric_jax.limits import di_cycle_floor, le_floor
    p = dj.Params.from_nondim(1e-3)  # default h' = 0.01: h/tau = 10
    plan = plan_estimate(p, n_excursions=1000)
    assert plan.min_duration == di_cycle_floor(1e-3, math.inf, 0.01) == 8.0
    need = 1000 * 8.0 * 100.0  # N x 8 tau0 x 1/h' steps
    assert plan.predicted_work == pytest.approx(need, rel=1e-12)
    assert abs(plan.max_steps - 1e4 * need / 1000) <= 1  # 10^4 cycles of 8 tau0 (was 10^4 tau0)
    with pytest.raises(ValueError,
                       match=r"^max_work must be >= 8e\+05 steps .* predicted mean duration >= 8 tau0 at 100 steps"):
        plan_estimate(p, n_excursions=1000, max_work=need * (1 - 1e-9))
    # the step function of r = h/tau, the damping factor, and the long-excursion floor where the noise is resolved
    assert [di_cycle_floor(0.1, math.inf, r * 0.1) for r in (1e5, 10.0, 1e-2, 5e-3, 9e-4)] == \
        [3.0, 8.0, 8.0, 3.0, le_floor(0.1, math.inf)]
    assert di_cycle_floor(1e-3, 1.0, 1e-3) == 4.0 and di_cycle_floor(1e-3, 0.1, 1e-2) == pytest.approx(8 / 11)
    assert di_cycle_floor(1e-6, math.inf, 1e-8) == le_floor(1e-6, math.inf) == 250.0
    # the PDMP's cycles are long excursions: le_floor
    q = dj.Params.from_nondim(0.03, 0.5)
    assert plan_estimate(q, method="pdmp", n_excursions=10).min_duration == le_floor(0.03, 0.5) == \
        pytest.approx(0.125 / math.sqrt(0.03), rel=1e-15)
    # on a coarse grid (delta' > 0.5) the PDMP is held to no floor (test below)
    c = dj.Params.from_nondim(1e-3, 1.0)  # Gamma = Delta = 1: delta = delta'
    assert plan_estimate(c, method="pdmp", delta=0.5, n_excursions=10).min_duration == le_floor(1e-3, 1.0)
    assert plan_estimate(c, method="pdmp", delta=0.51, n_excursions=10).min_duration == 0.0
    # slow noise: the passage time, far above either floor, is the prediction
    f = dj.Params(**dj.FIG3)
    plan = plan_estimate(f, n_excursions=10)
    assert plan.min_duration < math.exp(dj.limits.log_duration_scale(f.tau_nd, f.tau_L_nd, f.gamma_bar_nd))


def test_a_coarse_pdmp_grid_is_not_held_to_the_long_excursion_floor():
    """limits.PDMP_FLOOR_MAX_DELTA_ND (an audit): with a grid step near its largest (delta' = 7.09 of 7.47 at tau' =
    1e-3), a release needs the noise on one of the few grid levels inside the friction window and the cycles last
    ~2 tau0, a quarter of limits.le_floor's 7.9 (seed 1: 2.06 +- 0.25): held to it, such a run was refused at a
    max_work it then kept to.  The prediction there stays a lower estimate."""
    from dryfric_jax.limits import le_floor
    p = dj.Params.from_nondim(1e-3, 1.0)
    r = _quiet(dj.estimate_diffusivity, p, 1, method="pdmp", delta=7.09, n_excursions=300)
    assert (r.mean_duration + r.mean_duration_ci) / p.tau0 < le_floor(1e-3, 1.0)
    assert r.predicted_work <= r.work * r.lane_utilization


@pytest.mark.parametrize("tau,tl,h", [
    (0.1, math.inf, 1e-3),  # h/tau = 0.01: floor 8, measured 11.8 +- 1.2 (seed 0, N = 400)
    (0.1, 10.0, 1e-3),  # damped: floor 7.3, measured 10.4 +- 1.0
    (1e-6, math.inf, None),  # white at the step (h/tau = 1e4): floor 3, measured 4.45 +- 0.34
])
def test_the_di_cycle_floor_lies_below_the_cycles_where_it_is_tightest(tau, tl, h):
    """limits.di_cycle_floor must stay a lower estimate (else a feasible run is refused): on the three points of
    its table where it is tightest, the cycles' 95% CI lies above it (6.2-8.4 SE at seed 0), and the run's useful work
    above the predicted work."""
    p = dj.Params.from_nondim(tau, tl)
    r = _quiet(dj.estimate_diffusivity, p, 0, n_excursions=400, **({} if h is None else dict(h=h)))
    floor = dj.limits.di_cycle_floor(tau, tl, r.h / p.tau0)
    assert floor >= 3.0 * (1.0 if math.isinf(tl) else tl / (1 + tl))  # the floor acts here
    assert r.n_truncated == 0
    assert (r.mean_duration - r.mean_duration_ci) / p.tau0 > floor, (r.mean_duration / p.tau0, floor)
    assert r.predicted_work <= r.work * r.lane_utilization


@pytest.mark.parametrize("G,Delta,tau,tl,gb,method,n,tight", [
    (10.0, 3.84, 0.125, 0.067, 0.342, "pdmp", 2000, True),  # fast noise (tau' = 0.18), tau_L' = 0.1
    (10.0, 3.84, 0.125, 0.067, 0.342, "di", 2000, False),
    (1.0, 3.84, 0.25, 0.067, 0.342, "pdmp", 2000, True),  # tau' = 1.8
    (1.0, 3.84, 0.25, 0.067, 0.342, "di", 2000, False),
    (8.0, 3.84, 1e-5, 0.067, 0.342, "di", 2000, False),  # white limit: the deceleration floor acts (0.43 tau0)
    (1.0, 1.0, 0.05, 0.1, 0.089, "pdmp", 100, False),  # fast noise, the deceleration floor acts for the PDMP
])
def test_predicted_work_is_a_lower_estimate_of_the_measured_work(G, Delta, tau, tl, gb, method, n, tight):
    """``predicted_work`` (N x the OU passage-time bound, or the fast-noise floor where longer, x the steps or noise
    jumps per tau0)
    never exceeds the work the run did; for the PDMP, whose excursions are the noise's passage
    cycles, it is within a factor 2 where the passage times dominate.  (Before: the PDMP counted
    2 Lambda' events per tau0 and the duration had a floor of 1 tau0, 3x above the measured work
    at the first case.)"""
    p = dj.Params(G, Delta, tau, tl, gb)
    r = _quiet(dj.estimate_diffusivity, p, 5, method=method, n_excursions=n)
    useful = r.work * r.lane_utilization
    assert r.predicted_work <= useful, (r.predicted_work, useful)
    if tight:
        assert useful <= 2 * r.predicted_work, (r.predicted_work, useful)


# ---------------------------------------------------------------------------------------------
# estimators on a covering subset: every axis value is run or refused
# ---------------------------------------------------------------------------------------------
INF = math.inf
RUNS = [  # (Gamma, tau, h/tau or None (default h), tau_L, gamma_bar/Delta, dtype, method, expected)
    (1e3, 1e-8, 1e6, INF, 0.0, "float32", "di", "finite"),  # white noise, h/tau = 1e6
    (1e3, 1e-8, None, INF, 0.5, "float64", "di", "finite"),
    (5.0, 1e-300, None, 0.067, 0.0, "float32", "di", "finite"),  # tau' = 3e-300, h/tau = 7e296: float64
    (1e-3, 1e-6, None, 1e-4, 0.0, "float64", "di", "finite"),  # tiny Gamma
    (1e-3, 1e-4, 1e-3, 1e-4, 0.0, "float32", "di", "finite"),
    (1e-1, 1e-2, 1e-3, 0.067, 0.99, "float32", "di", "finite"),  # |gamma_bar| near Delta
    (10.0, 1.0, None, INF, 0.0, "float64", "pdmp", "finite"),
    (1e3, 10.0, None, 0.067, 0.0, "float64", "pdmp", "finite"),  # stiff: tau_L' = 1e-3
    (5.0, 0.5, None, 0.067, 1.5, "float32", "di", "finite"),  # bias above friction, damped
    (1e-1, 1e-4, None, INF, 0.99, "float64", "di", "finite"),  # weak net friction, long tails
    (1e3, 1.0, 1.0, 1e-4, 0.0, "float32", "pdmp", "h"),  # h given to the PDMP
    (10.0, 10.0, None, 0.067, 0.5, "float32", "pdmp", "max_work"),  # slow weak noise
    (1e3, 1e3, None, INF, 0.0, "float64", "pdmp", "max_work"),
    # fast noise, stiff damping: planned (lower estimate 6.7e6 events; the old floor of 1 tau0 said
    # 9e8, but excursions last 0.0075 tau0), the heavy tail truncates ~5% at max_work / lanes: reported
    (10.0, 1e-2, None, 1e-4, 1.5, "float64", "pdmp", "finite"),
    (1e-1, 1e-2, 1e3, 0.067, 1.5, "float64", "di", "h"),  # h >> tau0
    (10.0, 1.0, 1e-6, INF, 0.0, "float64", "di", "max_work"),  # h/tau = 1e-6: too many steps
    (1e-1, 1e-2, None, INF, 1.5, "float32", "di", "gamma_bar"),  # runaway: no stationary state
]


@pytest.mark.parametrize("G,tau,r,tl,gb,dtype,method,expected", RUNS)
def test_estimators_on_extreme_parameters(G, tau, r, tl, gb, dtype, method, expected):
    p = dj.Params(G, DELTA, tau, tl, gb * DELTA)
    kw = dict(h=r * tau) if r is not None else {}
    call = lambda: _quiet(dj.estimate_diffusivity, p, 1, method=method, dtype=dtype, n_excursions=200,
                          max_work=2e7, **kw)
    if expected != "finite":
        with pytest.raises(ValueError, match=rf"^{expected} must "):
            call()
        return
    res = call()
    nums = [res.D, res.D_ci, res.M0, res.M0_ci, res.mean_duration, res.mean_duration_ci]
    assert all(math.isfinite(v) for v in nums), nums
    assert res.D > 0 and res.D_ci > 0 and res.M0_ci > 0 and res.mean_duration > 0
    assert res.n_excursions >= 2
    if p.tau_nd < 1e-6:  # white noise: D and M0 are known (the step's bias, ~1e-2 here, is far inside CIs of 25-55%)
        # within 2.81 SE of the exact values (they were checked finite and > 0 only: a test audit; measured 0.07,
        # 0.43 and 1.73 SE).  At N = 200 the CIs are 25-55% of D: this catches gross errors (a factor 2 where the CI
        # is under ~35%, a wrong scale or sign), not percent-level ones, which test_di_exact checks
        from dryfric_jax import theory
        assert abs(res.D - theory.exact_D(p)) <= 2.81 / 1.96 * res.D_ci, (res.D, res.D_ci, theory.exact_D(p))
        assert abs(res.M0 - theory.exact_M0(p)) <= 2.81 / 1.96 * res.M0_ci, (res.M0, res.M0_ci, theory.exact_M0(p))
    # bounded work: the cap plus at most one excursion bound per lane in the final round
    assert res.work <= res.max_work + (res.max_steps + 64) * 2 * 256
    # truncation is never silent
    if res.n_truncated:
        assert any("hit the work bound" in w for w in res.warnings)
    if res.stopped_by == "work_bound":
        assert any("work bound reached" in w for w in res.warnings)


def test_work_bound_stops_the_rounds_and_says_so():
    """A run the predictor lets through (it is a lower estimate) but that costs more than
    max_work stops at the cap, finishes its in-flight excursions and reports it (256 lanes: the
    per-excursion cap max_work / lanes then stays above the longest excursion).  It warns as
    soon as the rounds project the cap to end the run, once, before the result."""
    p = dj.Params(**dj.FIG3)
    with warnings.catch_warnings(record=True) as ws:
        warnings.simplefilter("always", dj.DryfricWarning)
        res = dj.estimate_diffusivity(p, 2, n_excursions=3000, max_work=2e7, lanes=256)
    assert res.predicted_work <= 2e7 < res.work and res.stopped_by == "work_bound"
    assert 2 <= res.n_excursions < 3000 and res.n_truncated == 0
    assert any("work bound reached" in w for w in res.warnings)
    early = [i for i, w in enumerate(ws) if "is projected to end the run" in str(w.message)]
    late = [i for i, w in enumerate(ws) if "work bound reached" in str(w.message)]
    assert len(early) == 1 and early[0] < late[0], [str(w.message) for w in ws]
    assert ws[early[0]].filename == __file__  # points at the caller's line
    assert not any("projected" in w for w in res.warnings)  # transient: the result says what happened


# ---------------------------------------------------------------------------------------------
# exact answers on hard cases, float32 and float64
# ---------------------------------------------------------------------------------------------
@pytest.mark.slow
@pytest.mark.parametrize("gb", [0.99, 1.5])
@pytest.mark.parametrize("dtype", DTYPES)
def test_bias_near_and_above_friction_white_noise_exact(gb, dtype):
    """White noise (tau' = 1e-5), viscous damping, gamma_bar = 0.99 Delta and 1.5 Delta: D and M0
    against the exact values (MODEL_NOTES section 2), tolerance the 95% CI, both dtypes."""
    G = 5.0
    p = dj.Params(G, DELTA, 1e-5 * G / DELTA**2, 0.067, gb * DELTA)
    r = _quiet(dj.estimate_diffusivity, p, 5, n_excursions=20_000, dtype=dtype)
    assert r.dtype == dtype and r.n_truncated == 0
    assert r.D_ci < 0.05 * r.D
    assert abs(r.D - dj.theory.exact_D(p)) <= r.D_ci, (r.D, r.D_ci, dj.theory.exact_D(p))
    assert abs(r.M0 - dj.theory.exact_M0(p)) <= r.M0_ci, (r.M0, r.M0_ci, dj.theory.exact_M0(p))


# ---------------------------------------------------------------------------------------------
# magnitudes out to the ends of float64: a plan, a theory value, or a refusal by name
# ---------------------------------------------------------------------------------------------
MAGS = [1e-300, 1e-150, 1e-30, 1e-3, 1e3, 1e30, 1e150, 1e300]
BASE = dict(Gamma=5.0, Delta=3.84, tau=0.5, tau_L=0.067, gamma_bar=0.342)


def _extreme_cases():
    for name in BASE:
        for m in MAGS:
            for sgn in ((1, -1) if name == "gamma_bar" else (1,)):
                yield {**BASE, name: sgn * m}
    for a, b in itertools.combinations(["Gamma", "Delta", "tau", "tau_L"], 2):
        for ma, mb in itertools.product([1e-200, 1e200], repeat=2):
            yield {**BASE, a: ma, b: mb}


def _readable_refusal(e: ValueError, names=PARAM_NAMES + ("Gamma and Delta", "the parameters")):
    msg = str(e)
    assert msg.split(" must ")[0] in names or msg.startswith("delta = "), msg
    assert "\n" not in msg and len(msg) < 700, msg
    assert not re.search(r"\d{20}", msg) and "(0, -" not in msg and "nan" not in msg.replace("got nan", ""), msg


def test_extreme_magnitudes_are_planned_computed_or_refused_by_name():
    """Each parameter (and pairs) from 1e-300 to 1e300: the parameters are refused by name when a
    unit or a nondimensional number leaves [1e-300, 1e300], and otherwise every method is planned
    with finite numbers or refused by name in one readable line, and the white-noise theory is
    finite (D > 0) or, beyond float64's range, refused by name (it returned D = 0.0).  Before:
    ZeroDivisionError and OverflowError from the units, the delta range and the
    message formatting; "delta must be in (0, -1e+150)"; 300-digit exponents in a refusal;
    exact_M0 = 0.0 for gamma_bar = 1000."""
    counts, theory_done = {}, set()
    for c in _extreme_cases():
        try:
            p = dj.Params(**c)
        except ValueError as e:
            _readable_refusal(e)
            counts["params"] = counts.get("params", 0) + 1
            continue
        for method in ("di", "pdmp", "auto"):
            try:
                plan = plan_estimate(p, method=method, n_excursions=1000)
            except ValueError as e:
                _readable_refusal(e)
                counts["refused"] = counts.get("refused", 0) + 1
                continue
            counts["planned"] = counts.get("planned", 0) + 1
            step = plan.h if plan.method == "di" else plan.delta
            assert all(math.isfinite(v) and v > 0 for v in (plan.per_tau0, plan.predicted_work, step)), (c, plan)
            assert 64 <= plan.max_steps <= 2**62
        nd = (p.tau_L_nd, p.gamma_bar_nd)  # the white-noise theory depends on these alone
        if not (math.isinf(p.tau_L) and abs(p.gamma_bar) >= p.Delta) and nd not in theory_done:
            theory_done.add(nd)
            for name, f in (("M0", dj.theory.exact_M0), ("D", dj.theory.exact_D)):
                try:
                    v = f(p)
                except ValueError as e:  # a value beyond float64 (D ~ 2 tau_L^2 Gamma = 1e-600) is refused by name
                    assert re.match(rf"{name} (underflows|overflows) float64 for ", str(e)), (c, str(e))
                    assert "\n" not in str(e) and len(str(e)) < 700, str(e)
                    counts["theory refused"] = counts.get("theory refused", 0) + 1
                    continue
                assert math.isfinite(v) and (v > 0 if name == "D" else True), (c, name, v)
    assert min(counts.get(k, 0) for k in ("params", "refused", "planned")) >= 10, counts


def test_float32_falls_back_where_the_noise_would_leave_its_range():
    """tau' < 1e-30: X's stationary SD 1/sqrt(tau') and the regeneration's squared distances
    16/tau' near float32's 3.4e38 (at tau' = 3e-300 the step's L22 is inf in float32)."""
    p = dj.Params(5.0, DELTA, 1e-300, 0.067, 0.342)
    plan = plan_estimate(p, dtype="float32", n_excursions=1000)
    assert plan.dtype == "float64" and "tau/tau0" in plan.notes[0]
    assert plan_estimate(dj.Params(5.0, DELTA, 1e-20, 0.067, 0.342), dtype="float32").dtype == "float32"


def test_tiny_tau_L_pdmp_scales_as_tau_L_squared_then_is_refused():
    r"""Strong damping, :math:`\tau_L' \to 0`: D/tau_L'^2 and M0/tau_L' of the PDMP converge, and the
    same seed gives the same scaled numbers at tau_L' = 1e-20 and 1e-55 (nothing under- or
    overflows); float32 agrees at 1e-20 and falls back to float64 below tau_L' = 1e-25.
    Below 1e-60 a run is refused by name.  Before (audit): float32 gave NaN at tau_L' = 3e-40 and a
    D 155x too small at 1e-36; float64 gave a CI of 0 at 1e-80 and D = 0 +- 0 at 1e-300, all exit 0."""
    out = {}
    for tl, dtype in ((1e-20, "float64"), (1e-55, "float64"), (1e-20, "float32")):
        p = dj.Params.from_nondim(1.47, tl, 0.089)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", dj.DryfricWarning)
            r = dj.estimate_diffusivity(p, 3, method="pdmp", dtype=dtype, n_excursions=500)
        out[tl, dtype] = (r.dtype, r.D / p.D0 / tl**2, r.D_ci / p.D0 / tl**2, r.M0 / p.v0 / tl)
        assert all(map(math.isfinite, out[tl, dtype][1:])) and out[tl, dtype][2] > 0
    np.testing.assert_allclose(out[1e-55, "float64"][1:], out[1e-20, "float64"][1:], rtol=1e-10)
    # float32 against float64 at 1e-20: the same seed, within float32 rounding of the paths
    f32, f64 = out[1e-20, "float32"], out[1e-20, "float64"]
    assert f32[0] == "float32" and abs(f32[1] - f64[1]) < f64[2]
    plan = plan_estimate(dj.Params.from_nondim(1.47, 1e-40, 0.089), method="pdmp", dtype="float32")
    assert plan.dtype == "float64" and "tau_L/tau0 = 1e-40 < 1e-25" in plan.notes[0]
    for method in ("pdmp", "di", "auto"):
        with pytest.raises(ValueError, match=r"^tau_L must be >= 1e-60 tau0"):
            plan_estimate(dj.Params.from_nondim(1.47, 1e-61, 0.089), method=method)
    with pytest.raises(ValueError, match=r"^tau_L must be >= 1e-60 tau0"):
        dj.bruteforce_diffusivity(dj.Params.from_nondim(1.47, 1e-300, 0.089), 0, t=1.0, n_paths=10, method="pdmp")
