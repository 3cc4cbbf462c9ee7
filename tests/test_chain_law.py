"""The DI chain at a finite step against its exact white-noise law (dryfric_jax.chain_law).

1. The chain law itself: grid-converged, and tending to the continuum white-noise law of
   dryfric_jax.theory as h -> 0 at first order (a fitted order, with a band).
2. The simulation at the coarsest step allowed (h = 0.1 min(tau0, tau_L), tau/h = 1e-3, where the
   chain is white to O(tau/h)) against the chain law: stationary moments from paths, and the
   long-excursion D and M0 (regeneration, stopping rule and delta-method CI at a coarse step).
   There the continuum values are several CIs away, so these checks can tell the chain from the
   continuum: each test asserts that it can.

Tolerances: z = 2.81 (0.5% per comparison, as test_di_exact), fixed seeds.
"""
import math
import re

import jax
import numpy as np
import pytest

import dryfric_jax as dj
from dryfric_jax.chain_law import white_chain_atom, white_chain_law
from dryfric_jax.paths import di_stationary

Z = 2.81
CASES = {  # (tau_L', gamma_bar'): Fig. 5's point (viscous + bias), pure dry friction
    "fig5": (6.17472, 0.0890625),
    "b0": (math.inf, 0.0),
}



def _params(case, tau=1e-4):
    tl, g = CASES[case]
    return dj.Params.from_nondim(tau, tl, g)


def _coarse_h(p):
    return 0.1 * min(p.tau0, p.tau_L)


@pytest.mark.parametrize("case", list(CASES))
def test_chain_law_is_grid_converged_and_first_order_in_h(case, solve_rounding):
    p = _params(case)
    exact = np.array([dj.theory.exact_mean_square_velocity(p), dj.theory.exact_D(p)])
    hs = np.array([0.1, 0.05, 0.025]) * min(p.tau0, p.tau_L)
    gaps = []
    for h in hs:
        c = white_chain_law(p, h)
        got = np.array([c.mean_v2, c.D])
        if h == hs[0]:  # O(dv^2) grid error: measured 1e-4 at 8 nodes per sd against 12
            c12 = white_chain_law(p, h, nodes_per_sd=12)
            assert np.all(np.abs(got / np.array([c12.mean_v2, c12.D]) - 1) < 3e-4)
        gaps.append(got / exact - 1)
    gaps = np.array(gaps)  # (h, [E V^2, D])
    assert np.all(gaps < 0)  # the chain sticks more than the continuum: both fall with h
    order = np.polyfit(np.log(hs), np.log(-gaps), 1)[0]
    assert np.all((order > 0.85) & (order < 1.15)), f"fitted orders {order}"
    if case == "b0":  # symmetric: no drift at any h, up to the dense solve's rounding
        c = white_chain_law(p, hs[0])
        assert abs(c.M0) < solve_rounding(c)


@pytest.mark.parametrize("g", [3.0, -3.0])
def test_chain_law_covers_a_bump_far_from_zero(g):
    """|gamma_bar'| > 1 with a finite tau_L: the law is a bump of sd sqrt(tau_L') at
    |v*| = (|gamma_bar'| - 1) tau_L' = 20, beyond the decay width the grid was sized by (it reached
    15: D came out 86% low, M0 15%, no error).  The bump is 6.3 sd from 0, where the particle
    sticks (mass ~ exp(-20) ~ 2e-9), so the chain is an Euler AR(1) velocity, whose long-run
    variance, hence D, and whose mean are those of the continuum at any h; its E[V^2] is
    first order in h."""
    p = dj.Params.from_nondim(1e-4, 10.0, g)
    hs = np.array([0.1, 0.05]) * min(p.tau0, p.tau_L)
    laws = [white_chain_law(p, h, width=15.0) for h in hs]  # the narrowest grid allowed: 4x faster than 30
    for c in laws:  # measured 2e-12 and 2e-13
        assert c.D == pytest.approx(dj.theory.exact_D(p), rel=1e-7)
        assert c.M0 == pytest.approx(dj.theory.exact_M0(p), rel=1e-7)
    v2 = dj.theory.exact_mean_square_velocity(p)
    gaps = [c.mean_v2 / v2 - 1 for c in laws]  # measured 1.23e-4, 6.11e-5
    assert 0 < gaps[0] < 1e-3 and 1.8 < gaps[0] / gaps[1] < 2.2, gaps


def test_chain_law_refuses_a_step_too_small_or_too_large():
    p = _params("fig5")
    with pytest.raises(ValueError, match=r"h must be in \[\S+, \S+\] s for the chain law .* would exceed") as err:
        white_chain_law(p, 1e-4 * p.tau0)
    # the range it prints is taken: its lower end fits (it was ~5% too small, and refused in turn), and so does
    # a value inside it that check_h alone would have refused with a wider range (an audit: h = 0 was told
    # [6.7e-14, 0.0067] s, then 1e-12 was refused for its grid)
    need, top = (float(x) for x in re.search(r"\[(\S+), (\S+)\]", str(err.value)).groups())
    assert white_chain_law(p, need).n_nodes <= dj.chain_law.MAX_NODES
    assert white_chain_law(p, top).n_nodes <= dj.chain_law.MAX_NODES
    with pytest.raises(ValueError, match=re.escape(f"h must be in [{need:.4g}, {top:.4g}] s for the chain law")):
        white_chain_law(p, 0.0)
    for bad in (math.nan, math.inf, -1.0):  # these were told check_h's wider range (an audit)
        with pytest.raises(ValueError, match=re.escape(f"h must be in [{need:.4g}, {top:.4g}] s for the chain law "
                                                       f"(got {bad!r})") + "$"):
            white_chain_law(p, bad)
    with pytest.raises(ValueError, match="no admissible h"):  # the bump at v* = 50 with sd 10 spans +-350
        white_chain_law(dj.Params.from_nondim(1e-4, 100.0, 1.5), 0.05)
    # above the range: the reason is the step's own bound, not the grid's size (it said "below it ... would exceed"
    # for every h out of range: an audit)
    with pytest.raises(ValueError, match=r"h must be in .*: above it the step is coarse against min\(tau0, tau_L\)"):
        white_chain_law(p, 0.5 * p.tau0)


@pytest.mark.parametrize("kw,match", [
    (dict(nodes_per_sd=0), r"^nodes_per_sd must be an integer in \[4, 68\]"),  # was a ZeroDivisionError
    (dict(nodes_per_sd=2), "^nodes_per_sd must"),  # grid error 2e-3
    (dict(nodes_per_sd=True), "^nodes_per_sd must"),  # was taken for 1
    (dict(nodes_per_sd=1.5), "^nodes_per_sd must"),  # was taken as it came
    (dict(nodes_per_sd=10**400), "^nodes_per_sd must"),
    (dict(width=-1.0), "^width must be a finite number >= 15"),  # was D = 9.0e-4 instead of 0.0228
    (dict(width=1e-300), "^width must be a finite number >= 15"),  # was D = 0.0121
    (dict(width=10.0), "^width must"),
    (dict(width=math.inf), "^width must"),
    (dict(width=math.nan), "^width must"),
    (dict(width="30"), "^width must"),
    (dict(width=None), "^width must"),
])
def test_chain_law_refuses_a_grid_that_would_cost_its_accuracy(kw, match):
    with pytest.raises(ValueError, match=match):
        white_chain_law(dj.Params(**dj.FIG3), 1e-3, **kw)


def test_chain_law_at_its_coarsest_grid_keeps_its_accuracy():
    """The bounds are where the result still holds: 4 nodes per sd and 15 widths change D and
    E[V^2] by < 1e-3 against a grid-converged law (12 nodes per sd, 30 widths); numpy numbers pass."""
    p = _params("b0")  # exponential tails: the slowest to converge in the width
    h = _coarse_h(p)
    ref = white_chain_law(p, h, nodes_per_sd=12)
    for law in (white_chain_law(p, h, nodes_per_sd=np.int64(4), width=np.float32(15.0)),
                white_chain_law(p, h, width=15)):
        assert abs(law.D / ref.D - 1) < 1e-3 and abs(law.mean_v2 / ref.mean_v2 - 1) < 1e-3


@pytest.mark.parametrize("case", list(CASES))
def test_chain_law_nodes_per_sd_is_the_grid_density(case):
    """nodes_per_sd nodes per step-noise sd: the grid spacing is sd / nodes_per_sd, so on the same
    span 8 nodes per sd take twice the half-grid k = ceil(span / spacing) of 4, up to the ceiling
    (k8 = 2 k4 or 2 k4 - 1).  A spacing of sd / (nodes_per_sd - 1) (7 and 3 per sd: k8 / k4 = 2.3) kept
    D within the grid-convergence band of the tests above, unseen. ~0.1 s."""
    p = _params(case)
    k4, k8 = ((white_chain_law(p, _coarse_h(p), nodes_per_sd=n, width=15.0).n_nodes - 3) // 2 for n in (4, 8))
    assert k8 in (2 * k4 - 1, 2 * k4), (k4, k8)


@pytest.mark.parametrize("Gamma,Delta", [(1e-6, 1e-3), (1e4, 1e2)])
def test_chain_law_is_unit_free_for_tiny_and_huge_gamma(Gamma, Delta):
    """Physical units only scale the nondimensional law: the same relative step bias, no NaN."""
    tl, g = CASES["fig5"]
    ref, p = dj.Params.from_nondim(1e-4, tl, g), dj.Params.from_nondim(1e-4, tl, g, Gamma=Gamma, Delta=Delta)
    a, b = white_chain_law(ref, 0.05 * ref.tau0), white_chain_law(p, 0.05 * p.tau0)
    for x, y, scale in ((a.D, b.D, p.D0), (a.M0, b.M0, p.v0), (a.mean_v2, b.mean_v2, p.v0**2)):
        assert math.isfinite(y) and y / scale == pytest.approx(x, rel=1e-9)


def test_chain_law_near_the_runaway_bias():
    """|gamma_bar| -> Delta with tau_L = inf: the law widens as 1/(Delta - |gamma_bar|); at 0.8
    Delta it is still solved (finite, below the continuum), at 0.97 Delta the grid is refused by
    name, and at Delta the runaway is refused (theory's check)."""
    p = dj.Params.from_nondim(1e-4, math.inf, 0.8)
    c = white_chain_law(p, 0.1 * p.tau0)
    assert math.isfinite(c.D) and 0.99 < c.D / dj.theory.exact_D(p) < 1.0
    with pytest.raises(ValueError, match="grid nodes .* no admissible h"):
        white_chain_law(dj.Params.from_nondim(1e-4, math.inf, 0.97), 0.1)
    with pytest.raises(ValueError, match="gamma_bar"):
        white_chain_law(dj.Params.from_nondim(1e-4, math.inf, 1.0), 0.1)


@pytest.mark.parametrize("dtype", ["float64", "float32"])
@pytest.mark.parametrize("case", list(CASES))
def test_stationary_moments_match_the_chain_law(case, dtype):
    """E[V], E[V^2] and P(V = 0) of long stationary paths at the coarse step; standard errors
    from per-path means (paths are independent, samples along one are not)."""
    p = _params(case)
    h = _coarse_h(p)
    law = white_chain_law(p, h)
    V, _ = di_stationary(dj.make_di_model(p, h, dtype), jax.random.key(5), 1024, 2000, 5, burn_steps=400)
    V = V.astype(np.float64) * p.v0
    for stat, ref, cont in ((V, law.M0, dj.theory.exact_M0(p)),
                            (V**2, law.mean_v2, dj.theory.exact_mean_square_velocity(p)),
                            (V == 0, law.p_stuck, None)):
        per_path = stat.mean(1)
        se = per_path.std(ddof=1) / math.sqrt(per_path.size)
        assert abs(per_path.mean() - ref) <= Z * se, f"{per_path.mean():.6g} ± {se:.2g} vs chain {ref:.6g}"
    # teeth: E[V^2] of the continuum is far outside (measured 10-23 SE)
    m2 = (V**2).mean(1)
    assert abs(law.mean_v2 - dj.theory.exact_mean_square_velocity(p)) > 5 * m2.std(ddof=1) / math.sqrt(m2.size)


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore::dryfric_jax.DryfricWarning")  # tau_L' = 6.2: CI under-covers at small N
def test_long_excursion_D_matches_the_chain_law_at_a_coarse_step():
    """The regeneration rule is exact for the chain at any h: at h' = 0.1 the long-excursion D
    and M0 agree with the chain's exact values, and D's CI excludes the continuum D."""
    p = _params("fig5")
    h = _coarse_h(p)
    law = white_chain_law(p, h)
    r = dj.estimate_diffusivity(p, 31, h=h, n_excursions=500_000)
    assert r.n_truncated == 0
    assert abs(r.D - law.D) <= Z / 1.96 * r.D_ci, f"D = {r.D:.5g} ± {r.D_ci:.2g}, chain {law.D:.5g}"
    assert abs(r.M0 - law.M0) <= Z / 1.96 * r.M0_ci, f"M0 = {r.M0:.5g} ± {r.M0_ci:.2g}, chain {law.M0:.5g}"
    # teeth: the chain and the continuum are more than two CIs apart (measured: D within 0.01 SE
    # of the chain's, the continuum's 2.5 CIs = 4.9 SE away)
    assert abs(law.D - dj.theory.exact_D(p)) > 2 * r.D_ci


@pytest.mark.parametrize("h_nd", [0.005, 0.05])
def test_white_chain_atom_is_the_leading_order_of_the_chains_exact_atom(h_nd):
    """Fig. 6's mark at v' = 0, 2 h' p(0), against the exact stationary atom of the chain (b = 0,
    p(0) = 1/2): their ratio is 1 - c sqrt(h') with c = 0.80 and 0.75 at h' = 0.005 and 0.05 (the
    function's docstring), so it tends to 1 as h' -> 0.  Teeth: an atom of h' p(0) or 4 h' p(0)
    (half or twice) is outside."""
    p = dj.Params.from_nondim(5e-5)
    exact = white_chain_law(p, h_nd * p.tau0).p_stuck
    lead = float(white_chain_atom(0.5, h_nd))
    c = (1 - exact / lead) / math.sqrt(h_nd)
    assert 0.65 < c < 0.9, c
    assert white_chain_atom([0.5, 0.25], h_nd) == pytest.approx([h_nd, h_nd / 2], rel=1e-15)
