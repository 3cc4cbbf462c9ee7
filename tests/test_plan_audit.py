"""The planner's numbers against values derived here, independently of its code (audit of
dryfric_jax.cost, .plan and .limits by mutation: each test below failed on a mutant that the older
tests let pass).  Nothing here simulates.

* ``method="auto"``: both costs per tau0 and the pick at the cost module's documented points;
* ``default_delta``: each of its three caps where it binds;
* the predicted work and the per-excursion bound: N x (T(x+ -> x-) + T(x- -> x+)) x steps per
  tau0, the passage times by a scipy double quadrature of the scale/speed-measure formula;
* the |gamma_bar'| >= 1 branch of the predicted duration, tau_L' e^{z^2/2} / max(z, 1);
* every range check and float32 threshold just inside and just outside its bound.
"""
import math

import pytest
from scipy import integrate

import dryfric_jax as dj
from dryfric_jax import limits
from dryfric_jax.cost import choose_method, default_delta
from dryfric_jax.plan import (
    MAX_COUNT, check_count, check_layout, check_max_time, check_max_work, check_method, check_rtol, check_settings,
    plan_estimate,
)

FIG3 = dj.Params(**dj.FIG3)  # tau' = 0.5 3.84^2 / 5 = 1.47456, tau_L' = 0.067 3.84^2 / 5, gamma_bar' = 0.342/3.84
BELOW = 1 - 1e-12  # just outside a lower bound (relative)


def _passage(a, b, tau):
    r"""Mean first-passage time a -> b (b < a) of tau dX = -X dt + sqrt2 dW by 2D quadrature:
    :math:`\int_b^a \frac{2}{\sigma^2 p(y)}\int_y^\infty p(z)\,dz\,dy`, sigma^2 = 2/tau^2,
    p(z) ~ e^{-tau z^2/2} (the stationary density); no erfcx, no Dawson function."""
    f = lambda z, y: tau * tau * math.exp(-0.5 * tau * (z * z - y * y))  # noqa: E731
    return integrate.dblquad(f, b, a, lambda y: y, lambda y: y + 40.0 / math.sqrt(tau), epsabs=0, epsrel=1e-10)[0]


def _duration(tau, gamma_bar):
    """T(x+ -> x-) + T(x- -> x+), x+- = +-1 - gamma_bar'; upwards by the symmetry X -> -X."""
    xp, xm = 1.0 - gamma_bar, -1.0 - gamma_bar
    return _passage(xp, xm, tau) + _passage(-xm, -xp, tau)


def test_auto_compares_the_documented_costs_per_tau0():
    """cost module docstring: at the Fig. 3 point the PDMP makes 2/(tau' delta')^2 = 368 noise jumps
    per tau0 (delta' = 0.05) against 1/h' = 100/tau_L' = 506 DI steps, and ``auto`` picks the PDMP;
    at tau = 0.05 s (tau' = 0.147) 3.68e4 jumps, and it picks the DI."""
    tau_nd, tl_nd = 0.5 * 3.84**2 / 5.0, 0.067 * 3.84**2 / 5.0
    jumps, steps = 2.0 / (tau_nd * 0.05) ** 2, 100.0 / tl_nd
    assert (round(jumps), round(steps)) == (368, 506)
    method, why = choose_method(FIG3, dj.default_h(FIG3), default_delta(FIG3))
    assert method == "pdmp" and f"PDMP {jumps:.3g} step-equivalents" in why and f"DI {steps:.3g} steps" in why
    assert plan_estimate(FIG3, method="auto", n_excursions=100).method == "pdmp"
    fast = dj.Params(**{**dj.FIG3, "tau": 0.05})
    method, why = choose_method(fast, dj.default_h(fast), default_delta(fast))
    assert method == "di" and f"PDMP {100 * jumps:.3g} step" in why  # tau' ten times smaller: 100x the jumps
    assert plan_estimate(fast, method="auto", n_excursions=100).method == "di"


def test_auto_chooses_the_di_where_the_default_pdmp_grid_cannot_be_built():
    """Delta = 1e-8 at Fig. 3's Gamma and tau: tau' = tau Delta^2 / Gamma = 1e-17, so 8 noise sds at the default
    delta' = 0.05 need 2 * 8 / sqrt(1e-17) / 0.05 ~ 1.0e11 grid points > 2^31 - 1.  ``auto`` refused the run
    ("use method 'di'") where it should pick the DI (found by an audit); a delta the caller gives is still
    refused by name, in the caller's units (it printed delta' = 0.0224 for a delta of 1e-10 s^-1/2)."""
    p = dj.Params(**{**dj.FIG3, "Delta": 1e-8})
    assert 8 / math.sqrt(p.tau_nd) / 0.05 * 2 > 2**31
    plan = plan_estimate(p, method="auto", n_excursions=100, max_work=1e30)
    assert plan.method == "di" and plan.reason.startswith("the PDMP cannot run here (delta = ")
    assert plan.reason.endswith("; chose di")
    with pytest.raises(ValueError, match=r"^delta = 1e-10 s\^-1/2 \(delta' = 0\.02236\) is too small: the noise "
                                         r"grid would have 2\.26e\+11 points"):
        plan_estimate(p, method="auto", delta=1e-10, n_excursions=100)
    with pytest.raises(ValueError, match=r"^delta = 2\.236e-10 s\^-1/2 \(delta' = 0\.05\) is too small"):
        plan_estimate(p, method="pdmp", n_excursions=100)


def _delta_max(tau, gamma_bar):
    """noise docstring: the admissible bound (-a + sqrt(a^2 + 16 tau)) / (4 tau), a = tau L,
    L = max(8/sqrt(tau), 1 + |gamma_bar|), written out unrationalised."""
    a = tau * max(8.0 / math.sqrt(tau), 1.0 + abs(gamma_bar))
    return (-a + math.sqrt(a * a + 16.0 * tau)) / (4.0 * tau)


@pytest.mark.parametrize("tau_nd,gamma_bar,cap", [
    (1.0, 0.2, "0.05"),  # 1/16/sqrt(1) = 0.0625 > 0.05
    (4.0, 0.2, "sd"),  # 1/16/2 = 0.03125 < 0.05 and < delta_max/2 = 0.0566
    (100.0, 1.0, "max"),  # delta_max/2 = 0.00495 < 1/16/10 = 0.00625
])
def test_default_delta_each_cap_where_it_binds(tau_nd, gamma_bar, cap):
    """cost.default_delta: delta' = min(0.05, (1/16)/sqrt(tau'), delta_max'/2), returned in physical
    units delta' Delta/sqrt(Gamma); Gamma = 2, Delta = 4 (tau0 = 1/8) so that units matter."""
    G, D = 2.0, 4.0
    p = dj.Params(G, D, tau_nd * G / D**2, 3.0 * G / D**2, gamma_bar * D)
    caps = {"0.05": 0.05, "sd": 0.0625 / math.sqrt(tau_nd), "max": 0.5 * _delta_max(tau_nd, gamma_bar)}
    assert min(caps, key=caps.get) == cap and sorted(caps.values())[1] > 1.1 * caps[cap]  # binds, with margin
    assert default_delta(p) == pytest.approx(caps[cap] * D / math.sqrt(G), rel=1e-12)


@pytest.mark.parametrize("method", ["pdmp", "di"])
def test_predicted_work_and_the_excursion_bound_at_fig3(method):
    """limits docstring: predicted work = N x (T(x+ -> x-) + T(x- -> x+)) x (steps or noise jumps)
    per tau0 and max_steps = ceil(1e4 x that duration x per tau0) at most max_work / lanes (and at
    least 64), the passage times by double quadrature here."""
    tau_nd, tl_nd, gb = 0.5 * 3.84**2 / 5.0, 0.067 * 3.84**2 / 5.0, 0.342 / 3.84
    per_tau0 = 2.0 / (tau_nd * 0.05) ** 2 if method == "pdmp" else 100.0 / tl_nd
    T = _duration(tau_nd, gb)
    assert 11 < T < 13  # > 1 and > tau': the passage bound is the tail time scale here
    plan = plan_estimate(FIG3, method=method, n_excursions=1000)
    assert plan.predicted_work == pytest.approx(1000 * T * per_tau0, rel=1e-8)
    assert plan.max_steps == pytest.approx(1e4 * T * per_tau0, rel=1e-8, abs=1)  # ceil
    capped = plan_estimate(FIG3, method=method, n_excursions=1000, max_work=1e9)
    assert capped.max_steps == math.ceil(1e9 / capped.lanes) or capped.max_steps == int(1e9 / capped.lanes)
    if method == "di":  # max_work / lanes = 45 < 64 where the work itself is allowed: ~40 steps per excursion
        floored = plan_estimate(dj.Params.from_nondim(0.1, 1.0, 0.0), h=0.1, n_excursions=2, lanes=2**20, block=64,
                                max_work=45 * 2**20)
        assert floored.max_steps == 64


@pytest.mark.filterwarnings("ignore::dryfric_jax.SmallSampleWarning")
def test_more_lanes_than_excursions_count_an_excursion_per_lane_in_the_work():
    """Every lane finishes the excursion it is in, so a run closes about one per lane whatever n_excursions: an
    audit's 2^18 lanes asked for 2000 ran 201,925 (predicted 1.2e6 lane-steps), and 2^22 at the default point
    needed ~5e10 against a predicted 1.2e8, unrefused and unsaid.  Now the work counts max(N, lanes) excursions,
    the refusal says why, and the plan notes it (a run here closes > 10x the N asked for)."""
    per_excursion = plan_estimate(FIG3, n_excursions=2**18).predicted_work / 2**18
    plan = plan_estimate(FIG3, n_excursions=2000, lanes=2**18)
    assert plan.predicted_work == pytest.approx(2**18 * per_excursion, rel=1e-12)
    assert [n for n in plan.notes if n.startswith("lanes = 262144 > n_excursions = 2000: every lane finishes")]
    assert not plan_estimate(FIG3, n_excursions=2**18, lanes=2**18).notes
    with pytest.raises(ValueError, match=r"^max_work must be >= .* steps for these parameters \(got 1e\+09\): ~4194304 "
                                         r"excursions \(about one per lane: every lane finishes the excursion it is "
                                         r"in, whatever n_excursions = 2000\) of predicted mean duration .*; many lanes "
                                         r"\(fewer lanes\)\.  Raise max_work \(--max-work\), coarsen h or delta, use "
                                         r"fewer lanes, or"):
        plan_estimate(FIG3, n_excursions=2000, lanes=2**22, max_work=1e9)
    with pytest.raises(ValueError, match=r"use fewer lanes and lower N, or"):  # 2000 alone are over 1e6 too
        plan_estimate(FIG3, n_excursions=2000, lanes=3000, max_work=1e6)
    assert not plan_estimate(FIG3, n_excursions=4095, lanes=4096).notes  # under 2x: not said (a review: "~1x")
    assert plan_estimate(FIG3, n_excursions=2048, lanes=4096).notes
    with pytest.warns(dj.DryfricWarning, match="^lanes = 4096 > n_excursions = 200"):
        r = dj.estimate_diffusivity(dj.Params.from_nondim(1.0, 1.0, 0.0), 0, n_excursions=200, lanes=4096)
    assert r.n_excursions > 10 * 200, r.n_excursions


@pytest.mark.parametrize("g,tau,tl", [(1.0, 0.01, 10.0), (-1.2, 0.01, 10.0), (1.2, 0.01, 10.0), (3.0, 1.0, 4.0)])
def test_bias_at_or_above_the_friction_predicts_the_return_to_rest(g, tau, tl):
    r"""limits docstring: for |gamma_bar'| >= 1 the duration is at least tau_L' e^{z^2/2}/max(z, 1),
    z^2 = (|gamma_bar'| - 1)^2 (tau_L' + tau') (z = 0 at |gamma_bar'| = 1, z < 1 and z > 1 here), which
    here is larger than both the passage sum (quadrature) and the floor min(1, tau_L')."""
    z = (abs(g) - 1.0) * math.sqrt(tl + tau)
    want = tl * math.exp(0.5 * z * z) / max(z, 1.0)
    assert want > 2 * max(_duration(tau, g), min(1.0, tl))  # the bias term is what binds
    assert math.exp(limits.log_duration_scale(tau, tl, g)) == pytest.approx(want, rel=1e-12)


def test_float32_thresholds_just_inside_and_outside():
    """h/tau >= 1e-4, h' >= 1e-5 and tau' >= 1e-30 for the DI, tau_L' >= 1e-25 for the PDMP (the
    bounds included); each reason names its own quantity."""
    f = limits.float32_unsafe_reason
    assert f(1e-4, 1e-5, 1e-30) is None
    assert "h/tau = " in f(1e-4 * BELOW, 1.0, 1.0)
    assert "h/tau0 = " in f(1.0, 1e-5 * BELOW, 1.0)
    assert "tau/tau0 = " in f(1.0, 1.0, 1e-30 * BELOW)
    assert limits.pdmp_float32_unsafe_reason(1e-25) is None
    assert "tau_L/tau0" in limits.pdmp_float32_unsafe_reason(1e-25 * BELOW)


def test_float32_falls_back_where_the_speeds_sit_far_from_1_and_the_friction_rounds_alike():
    """Float32 audits (2026-12-07): where the speeds sit in a few binades far from 1, float32 rounds each step's
    friction h' onto V's grid the same way every step.  Brute force's M0_t (paired with float64 on the same normals
    by a review) came out +0.23% (8 CIs) at tau_L' = 500, gamma_bar' = 11, h' = 0.01, +0.27% at 1000, 1.1, 0.0109
    and +0.96% at 1e4, 0.999, 0.0109 (not a runaway: the width sqrt(tau_L') = 100), and the PDMP's 1.1% low at 2000,
    29, float32 kept and unsaid.  Now float32 needs 2^-24 V_s/(h' F) <= 1e-3 where V_s > 2 (limits.speed_scale: V_s =
    tau_L'(|g| - 1) in a runaway, else min(1/(1 - |g|), sqrt(tau_L')); F = min(1, max(||g| - 1|, 1/sqrt(tau_L')))),
    the bound included; where V_s <= 2 (the paper's points) the roundings average out and nothing changes."""
    from dryfric_jax.plan import choose

    f, fp, scale = limits.float32_unsafe_reason, limits.pdmp_float32_unsafe_reason, limits.speed_scale
    assert scale(500.0, -11.0) == (5000.0, 1.0) and scale(math.inf, 0.0) == (1.0, 1.0)
    assert scale(1e4, 0.999) == pytest.approx((100.0, 0.01), rel=1e-12) and scale(math.inf, 1.0)[0] == math.inf
    assert scale(1000.0, 1.1) == pytest.approx((100.0, 0.1), rel=1e-12)
    # just above 1 the width sqrt(tau_L') still sets the speeds (a review: 1 + 1e-4 at tau_L' = 1e4 kept float32,
    # measured +0.53% in mean V, 7.6 SE, while 1 - 1e-4 fell back)
    assert scale(1e4, 1.0001) == pytest.approx((100.0, 0.01), rel=1e-9) == scale(1e4, -1.0001)
    for g in (0.9999, 1.0001, 1.0002, -1.0001):
        assert choose(dj.Params.from_nondim(0.1, 1e4, g), "di", None, None, "float32").dtype == "float64", g
    edge = 2.0**-24 * 5000.0 / 1e-3  # the smallest h' kept at tau_L' = 500, |gamma_bar'| = 11
    assert f(1.0, edge, 1.0, 500.0, 11.0) is None and fp(500.0, 1 / edge, -11.0) is None
    said = f(1.0, edge * BELOW, 1.0, 500.0, 11.0)
    assert said.startswith("h = 0.298 tau0 against speeds ~5e+03 v0 and a net force 1 Delta (tau_L' = 500, "
                           "gamma_bar' = 11): float32 rounds each step's friction onto V's grid alike"), said
    assert fp(500.0, 1 / (edge * BELOW), 11.0).startswith("mean time between events (tau delta)^2/2 = 0.298 tau0")
    for tl, g, h in ((500.0, 11.0, 0.01), (1000.0, 1.1, 0.0109), (1e4, 0.999, 0.0109)):  # the audited points
        assert choose(dj.Params.from_nondim(1e-3, tl, g), "di", h, None, "float32").dtype == "float64", (tl, g)
    runaway = dj.Params.from_nondim(1e-3, 500.0, 2.5)  # 750 v0: 2^-24 750/h' <= 1e-3 for h' >= 0.0447
    for method, h, dt in (("di", 0.04, "float64"), ("di", 0.05, "float32"), ("pdmp", None, "float64")):
        plan = choose(runaway, method, h, None, "float32")
        assert plan.dtype == dt and bool(plan.notes) == (dt == "float64"), (method, h, plan.notes)
    for tl, g in ((math.inf, 0.0), (math.inf, 0.5), (0.067 * 3.84**2 / 5, 0.342 / 3.84)):  # V_s <= 2: unchanged
        assert choose(dj.Params.from_nondim(1e-3, tl, g), "di", 1e-4, None, "float32").dtype == "float32"


@pytest.mark.parametrize("G,tau,h,why", [
    (1e6, 1e-26, None, "tau/tau0 = 1e-32"),  # tau' = 1e-32 although tau = 1e-26 s: the nondimensional tau
    (1.0, 1e3, 1e-8, "h/tau = 1e-11"),  # h' = 1e-8: both fail, h/tau named first
    (1.0, 1e-9, 1e-9, "h/tau0 = 1e-09"),  # h/tau = 1, h' = 1e-9
    (1.0, 1e-3, 1e-5, None),  # h/tau = 1e-2 and h' = 1e-5: safe
])
def test_plan_falls_back_to_float64_on_the_right_quantity(G, tau, h, why):
    p = dj.Params(G, 1.0, tau, math.inf, 0.0)
    plan = plan_estimate(p, h=h, dtype="float32", n_excursions=100, max_work=1e300)
    assert plan.dtype == ("float32" if why is None else "float64")
    assert (plan.notes == []) if why is None else (why in plan.notes[0])


def test_simulable_tau_L_bound_is_included():
    plan_estimate(dj.Params.from_nondim(1.47, 1e-60, 0.089), method="pdmp", n_excursions=100)
    with pytest.raises(ValueError, match=r"^tau_L must be >= 1e-60 tau0"):
        plan_estimate(dj.Params.from_nondim(1.47, 1e-60 * BELOW, 0.089), method="pdmp", n_excursions=100)


def test_h_lower_bound_is_included():
    lo = 1e-12 * min(FIG3.tau0, FIG3.tau_L)
    assert plan_estimate(FIG3, h=lo, n_excursions=2, max_work=1e300).h == lo
    with pytest.raises(ValueError, match=r"^h must be in \["):
        plan_estimate(FIG3, h=lo * BELOW, n_excursions=2, max_work=1e300)


def test_work_at_exactly_max_work_is_accepted():
    """check_work refuses a prediction *above* max_work: fast noise (the floor min(1, tau_L') = 1
    binds, log 1 = 0 exactly) with N x steps = max_work is accepted, one more excursion is not."""
    assert math.log(4) + math.log(250.0) == math.log(1e3)  # the float comparison is exact here
    assert limits.check_work(1e-6, 1.0, 0.0, 250.0, 4, max_work=1e3) == pytest.approx(1e3, rel=1e-12)
    with pytest.raises(ValueError, match=r"^max_work must be >= 1.25e\+03 steps"):
        limits.check_work(1e-6, 1.0, 0.0, 250.0, 5, max_work=1e3)


def test_setting_bounds_just_inside_and_outside():
    assert check_count("n", 2) == 2 and check_count("n", MAX_COUNT, hi=MAX_COUNT) == MAX_COUNT
    for n, hi in ((1, None), (MAX_COUNT + 1, MAX_COUNT)):
        with pytest.raises(ValueError, match="^n must be an integer"):
            check_count("n", n, hi=hi)
    assert check_layout(2**18, 1024) == (2**18, 1024) and check_layout(2**22, 64) == (2**22, 64)  # 2^28
    assert check_layout(1, 1) == (1, 1) and check_layout(None, 1) == (None, 1)
    for lanes, block, name in ((2**22 + 1, 1, "lanes"), (1, 1025, "block"), (0, 1, "lanes"), (1, 0, "block"),
                               (2**22, 65, "lanes \\* block")):
        with pytest.raises(ValueError, match=f"^{name} must"):
            check_layout(lanes, block)
    assert check_max_work(1e3) == 1e3
    assert check_rtol(1e-300) == 1e-300 and check_rtol(1 - 1e-16) == 1 - 1e-16 and check_rtol(None) is None
    assert check_max_time(5e-324) == 5e-324 and check_max_time(math.inf) == math.inf
    for call, bad, name in ((check_max_work, 1e3 * BELOW, "max_work"), (check_rtol, 1.0, "rtol"),
                            (check_rtol, 0.0, "rtol"), (check_max_time, 0.0, "max_time")):
        with pytest.raises(ValueError, match=f"^{name} must"):
            call(bad)
    for kw in (dict(h=0.0), dict(delta=0.0, method="pdmp"), dict(h=math.inf)):
        with pytest.raises(ValueError, match=f"^{next(iter(kw))} must be in"):
            check_settings(**kw)
    assert check_settings(h=5e-324)["h"] == 5e-324  # any positive h may be in range at some point
    with pytest.raises(ValueError, match="^delta must not be given with method 'di'"):
        check_method("di", delta=0.05)
    with pytest.raises(ValueError, match="^h must not be given with method 'pdmp'"):
        check_method("pdmp", h=1e-3)
    check_method("auto", h=1e-3, delta=0.05)


@pytest.mark.parametrize("tl,drift", [(30.0, 30.0), (math.inf, 100.0), (5e3, 100.0)])
def test_excursion_bound_follows_the_drift_time_against_weak_net_friction(tl, drift):
    """limits.tail_time_scale: for |gamma_bar'| < 1 the tail lasts min(1/(1 - |gamma_bar'|)^2, tau_L')
    (= 100 at gamma_bar' = -0.9 unless tau_L' is shorter); fast noise (tau' = 1e-3) makes the
    passage sum and the floor min(1, tau_L') smaller, so max_steps = 1e4 x drift x steps per tau0."""
    assert limits.max_steps_per_excursion(1e-3, tl, -0.9, 10.0) == pytest.approx(1e4 * drift * 10.0, abs=1)


def test_work_refusal_names_the_bias_from_gamma_bar_equal_to_delta():
    """The reason for a refusal where the duration dominates: |gamma_bar| >= Delta (the bound
    included) is the bias, below it the rarely reached threshold."""
    for g, why in ((1.0, "the bias |gamma_bar| >= Delta keeps the particle moving"),
                   (0.0, "the noise rarely reaches the far threshold")):
        with pytest.raises(ValueError, match=r"^max_work must be >= ") as e:
            limits.check_work(60.0 if g == 0 else 1e-2, 1e40, g, 10.0, 2, max_work=1e3)
        assert why in str(e.value)


def test_layout_and_counts_of_the_plan_just_inside_and_outside():
    """lanes * block <= 2^28 also for the default lanes (the caller's chunk_lanes and block); the
    smallest max_steps and chunk_lanes (1) are taken; max_work is kept; a bad delta is refused by
    ``auto`` even where it picks the DI (a delta that costs more than the DI steps)."""
    plan = plan_estimate(FIG3, n_excursions=2, max_steps=1, chunk_lanes=1, max_work=1e5)
    assert (plan.max_steps, plan.lanes, plan.max_work) == (1, 1, 1e5)
    assert plan_estimate(FIG3, n_excursions=100).max_work == 1e11  # README: default 1e11 lane-steps or events
    with pytest.raises(ValueError, match=r"^lanes \* block must be <= 2\^28"):
        plan_estimate(FIG3, n_excursions=2**40, chunk_lanes=2**22, block=128, max_work=1e300)
    for bad in (-1e-9, 0.0, math.nan):
        with pytest.raises(ValueError, match="^delta must"):
            plan_estimate(FIG3, method="auto", delta=bad, n_excursions=100)


def test_passage_to_where_the_path_already_is_takes_no_time_and_a_huge_bias_is_refused_at_once():
    """T(a -> a) = 0 (log -inf) without a quadrature over an empty range (log 0 raised); at
    gamma_bar' = 1e300 both thresholds round to one point and the work is refused up front (a NaN
    duration there let the run start instead)."""
    assert limits.log_ou_passage_time(0.5, 0.5, 1.0) == -math.inf
    assert limits.log_ou_passage_time(-7.0, -7.0, 2.0) == -math.inf
    with pytest.raises(ValueError, match=r"^the parameters must give excursions of predicted mean duration < 1.8e308 "
                                         r"tau0 \(float range; got >= 10\^\(1.79e\+308\) tau0 at "):
        plan_estimate(dj.Params(5.0, 3.84, 0.5, 0.067, 1e300), n_excursions=100)


@pytest.mark.parametrize("tau,a,b", [(1.0, 0.0, -40.0), (2.0, -30.0, -40.0), (1.0, -50.0, -50.5)])
def test_passage_far_beyond_overflow_of_the_integrand(tau, a, b):
    r"""Below u = -26.6 e^{u^2} overflows a float: the passage time from Dawson's function stays
    finite and equals the Laplace expansion :math:`\int_{u_b}^{u_a} 2e^{u^2}du \approx
    e^{u_b^2}/|u_b| (1 + 1/(2u_b^2) + 3/(4u_b^4))` (minus the same at u_a), to 1e-8 in the log."""
    s = math.sqrt(tau / 2.0)
    lap = lambda u: u * u - math.log(abs(u)) + math.log1p(1 / (2 * u * u) + 3 / (4 * u**4))  # noqa: E731
    ub, ua = b * s, a * s
    log_int = lap(ub) + (math.log1p(-math.exp(lap(ua) - lap(ub))) if ua < -5 else 0.0)
    want = math.log(tau * math.sqrt(math.pi)) + log_int
    assert limits.log_ou_passage_time(a, b, tau) == pytest.approx(want, abs=1e-8)  # next term 15/(8u^6) < 5e-9


@pytest.mark.parametrize("tau,a,b", [(1.0, 0.5, -5.0), (1.0, 0.0, -9.0), (0.5, -6.0, -14.0)])
def test_passage_time_against_the_double_quadrature_on_both_sides_of_the_dawson_cut(tau, a, b):
    """u_b = b sqrt(tau/2) = -3.5, -6.4, -7.0: the erfcx quadrature and the Dawson form (u < -6) to
    1e-9 of the quadrature here (the Dawson form used from u = -3 leaves out 2e-5 at the first)."""
    assert math.exp(limits.log_ou_passage_time(a, b, tau)) == pytest.approx(_passage(a, b, tau), rel=1e-9)


def test_pdmp_float32_falls_back_where_events_are_too_short():
    """The PDMP's velocity increments are of order its event time 1/Lambda' = (tau' delta')^2/2: below the DI's
    bound on h' (1e-5) float32 rounds them away (a PDMP audit: U 1% low on every path at 5e-7 tau0, paired
    with float64 arithmetic on the same uniforms), and the plan kept float32 with no note. The bound is
    inclusive, and the reason names the event time."""
    import jax.numpy as jnp

    from dryfric_jax.pdmp import flow

    f = limits.pdmp_float32_unsafe_reason
    assert f(1.0, 1e5) is None and f(1.0) is None
    assert f(1.0, 1e5 / BELOW).startswith("mean time between events (tau delta)^2/2 = 1e-05 tau0 < 1e-05 tau0")
    p = dj.Params.from_nondim(1.0, 10.0, 0.5)  # the audit's gamma_bar' = 3 is a runaway, whose own bound binds first
    for delta, dtype in ((1e-3, "float64"), (0.0045, "float32"), (0.05, "float32")):
        plan = plan_estimate(p, method="pdmp", delta=delta, dtype="float32", n_excursions=100, max_work=1e300)
        assert plan.dtype == dtype, delta
        assert [n.startswith("float32 is not safe here (mean time between events") for n in plan.notes] == \
            ([True] if dtype == "float64" else [])
    # why: at v = 0.5 an increment 0.3 s of s = 5e-9 (delta' = 1e-4) is lost in float32, kept in float64
    assert float(flow(jnp.float32(0.5), jnp.float32(0.3), jnp.float32(0.0), jnp.float32(5e-9))) == 0.5
    assert float(flow(0.5, 0.3, 0.0, 5e-9)) - 0.5 == pytest.approx(1.5e-9, rel=1e-6)
