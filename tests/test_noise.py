"""The PDMP's jump noise: its exact stationary law, and its OU limit as delta -> 0."""
import math
import re
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import stats

import dryfric_jax as dj
from dryfric_jax.noise import check_delta, delta_max, grid_size, stationary_law
from dryfric_jax.pdmp import make_pdmp_model, pdmp_grid_info


@partial(jax.jit, static_argnames=("n_lanes",))
def _state_at(model, key, t_end, *, n_lanes):
    """k at time t_end (the time-weighted marginal) of n_lanes independent PDMP paths from s_+,
    through the PDMP's own event function."""
    def lane(key):
        def cond(c):
            return c[1] < t_end

        def body(c):
            i, T, state = c
            u = jax.random.uniform(jax.random.fold_in(key, i), (2,), minval=1e-300)
            dt, _, new, _, _ = model.event(state, (u[0], u[1]))
            keep = T + dt >= t_end  # the state holding at t_end is the one before this event
            new = jax.tree_util.tree_map(lambda a, b: jnp.where(keep, b, a), new, state)
            return i + 1, T + dt, new

        s0 = jax.tree_util.tree_map(lambda a: a[0], model.s_plus(1))
        return jax.lax.while_loop(cond, body, (0, 0.0, s0))[2][0]

    return jax.vmap(lane)(jax.random.split(key, n_lanes))


def test_occupation_matches_exact_stationary_law():
    """Chi-square of the state at a fixed time (20 correlation times after s_+) against the
    product-of-alpha-ratios law, on a coarse grid where it differs visibly from a Gaussian."""
    tau, d = 1.0, 0.2
    p = dj.Params.from_nondim(tau, 0.5, 0.1)
    m = make_pdmp_model(p, d)  # Gamma = Delta = 1: physical delta = delta'
    N = int(m.N)
    k = np.asarray(_state_at(m, jax.random.key(11), 20.0 * tau, n_lanes=40_000))
    x, pi = stationary_law(N, d, tau)
    counts = np.bincount(k + N, minlength=2 * N + 1)
    expect = pi * k.size
    # pool the tails into bins with >= 5 expected
    keep = expect >= 5
    obs = np.concatenate([counts[keep], [counts[~keep].sum()]])
    exp = np.concatenate([expect[keep], [expect[~keep].sum()]])
    chi2, pval = stats.chisquare(obs, exp)
    assert pval > 1e-3, (chi2, pval, obs.size)
    # the test has power: the law of a chain with a 10% larger tau is rejected
    _, wrong = stationary_law(N, d, 1.1 * tau)
    w = wrong * k.size
    assert stats.chisquare(obs, np.concatenate([w[keep], [w[~keep].sum()]]))[1] < 1e-6


def test_stationary_moments_tend_to_ou():
    """Exact law: mean 0 and variance 1/tau at every delta (the chain's drift is linear), and the
    fourth moment tends to the Gaussian 3/tau^2 like delta^2 (fitted order within 1.9-2.1)."""
    tau = 1.5
    errs = []
    for d in (0.16, 0.08, 0.04, 0.02):
        x, pi = stationary_law(grid_size(d, tau), d, tau)
        assert abs((x * pi).sum()) < 1e-12
        assert abs((x * x * pi).sum() * tau - 1.0) < 1e-10
        errs.append(abs((x**4 * pi).sum() * tau**2 - 3.0))
    assert errs[-1] < 1e-3
    orders = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    assert np.all((orders > 1.9) & (orders < 2.1)), orders


@pytest.mark.parametrize("tau", [1e-3, 1.0, 50.0])
def test_grid_choice(tau):
    d = 0.9 * delta_max(tau)
    N = grid_size(d, tau)
    assert N * d >= 8 / math.sqrt(tau) and N * d >= 1.0  # covers the noise and the thresholds
    assert tau * d * N * d < 2.0  # up-probabilities in [0, 1]


@pytest.mark.parametrize("d", [0.0, -0.1, math.nan, math.inf, 0.3])
def test_bad_delta(d):
    with pytest.raises(ValueError, match=r"delta must be in \(0, 0.2"):
        check_delta(d, 1.0)


def test_delta_max_is_stable_at_extreme_tau():
    """delta_max = 4 / (tau L + sqrt((tau L)^2 + 16 tau)), the rationalised root: the printed
    form (-tau L + sqrt(...))/(4 tau) lost every digit to cancellation for tau L^2 >> 1 and came
    out negative for tiny tau (tau^2 underflows), which made the refusal print "(0, -1e+150)"."""
    def printed(tau, g=0.0):
        L = max(8 / math.sqrt(tau), 1 + abs(g))
        return (-tau * L + math.sqrt(tau * tau * L * L + 16 * tau)) / (4 * tau)

    for tau in (1e-6, 1e-2, 1.0, 30.0, 1e3):
        assert delta_max(tau) == pytest.approx(printed(tau), rel=1e-9)
    for tau in (1e-300, 1e-150):  # the noise sets L = 8/sqrt(tau): delta_max = 0.2361/sqrt(tau)
        assert delta_max(tau) * math.sqrt(tau) == pytest.approx(4 / (8 + math.sqrt(80)), rel=1e-12)
    for tau in (1e150, 1e300):  # the thresholds set L = 1: delta_max -> 2/(tau L)
        assert delta_max(tau) * tau == pytest.approx(2.0, rel=1e-12)


def test_a_grid_too_fine_is_refused_with_the_smallest_delta_that_fits():
    """The refusal said only "use method 'di'"; it now states the smallest delta whose grid fits (L_req / (2^30 - 2),
    rounded up: 8 / (2^30 - 2) = 7.4506e-9 at tau = 1), which is accepted, in the caller's units from
    pdmp_grid_info, and says when no delta is admissible (the smallest above delta_max: tau = 1e-300 with the
    thresholds at 1e300)."""
    with pytest.raises(ValueError, match=r"1\.6e\+11 points \(at most 2147483647\); delta' must be >= 7\.451e-09 "
                                         r"here, or use method 'di'$"):
        grid_size(1e-10, 1.0)
    assert grid_size(7.451e-09, 1.0) <= 2**30 - 1  # accepted
    with pytest.raises(ValueError, match=r"no delta is admissible for these parameters: use method 'di'$"):
        grid_size(1e-300, 1.0, 1e300)
    p = dj.Params(**{**dj.FIG3, "Delta": 1e-8})  # delta = delta' Delta / sqrt(Gamma)
    with pytest.raises(ValueError, match=r"delta must be >= ([0-9.e+-]+) s\^-1/2 here") as e:
        pdmp_grid_info(p, 1e-10)
    least = float(re.search(r">= ([0-9.e+-]+) s", str(e.value)).group(1))
    scale = 1e-8 / math.sqrt(dj.FIG3["Gamma"])
    assert least / scale == pytest.approx(8 / math.sqrt(p.tau_nd) / (2**30 - 2), rel=1e-3)
    assert pdmp_grid_info(p, least)["N"] <= 2**30 - 1


def test_a_grid_beyond_int_range_is_refused_with_a_readable_count():
    with pytest.raises(ValueError, match=r"^delta' = .* too small: the noise grid would have 1.6e\+11 points"):
        grid_size(1e-10, 1.0)
    with pytest.raises(ValueError, match=r"would have inf points"):
        grid_size(1e-300, 1.0, 1e300)  # L_req / delta overflows


def test_jump_noise_relaxes_exactly_like_ou():
    r"""The chain's drift :math:`\Lambda\delta(2\alpha_k - 1) = -x_k/\tau` is linear and its jump variance
    :math:`\Lambda\delta^2 = 2/\tau^2` constant, so away from the grid's ends (8 SD out) the mean
    and variance from :math:`x_0` are exactly OU's: :math:`x_0 e^{-t/\tau}` and
    :math:`(1 - e^{-2t/\tau})/\tau`.  Checked at t = tau through the PDMP's own event function (the
    noise does not see the velocity's stick and slide events), |z| <= 4 on 2e5 lanes.  This is what
    pins the jump rate: the stationary law does not depend on it, and a 5% faster clock was caught
    only by a slow test, at 1.2x its tolerance; here it is rejected at |z| > 6 (checked below)."""
    tau, d, t = 1.0, 0.2, 1.0
    m = make_pdmp_model(dj.Params.from_nondim(tau, 0.5, 0.1), d)  # Gamma = Delta = 1: physical delta = delta'
    n = 200_000
    x = np.asarray(_state_at(m, jax.random.key(5), t, n_lanes=n), np.float64) * d
    x0 = (int(m.kp) + 1) * d  # s_+: k = k_+ + 1, the first grid point past the release threshold
    mean, var = x0 * math.exp(-t / tau), (1 - math.exp(-2 * t / tau)) / tau
    z_mean = (x.mean() - mean) / math.sqrt(var / n)
    z_var = (x.var() - var) / (var * math.sqrt(2.0 / n))  # near-Gaussian: Var(s^2) ~ 2 var^2 / n
    assert abs(z_mean) <= 4 and abs(z_var) <= 4, (z_mean, z_var)
    # power: a clock 5% fast or slow (the mean at t' = 1.05 t or 0.95 t) is rejected
    for c in (0.95, 1.05):
        assert abs((x.mean() - x0 * math.exp(-c * t / tau)) / math.sqrt(var / n)) > 6


@pytest.mark.parametrize("d,tau,gb", [(1 / 64, 64.0, 0.0), (0.01, 100.0, 0.5), (0.01, 100.0, -0.5)])
def test_the_grid_holds_both_release_states(d, tau, gb):
    """s_+ (k_+ + 1) and s_- (k_- - 1) lie on the grid where the thresholds, not 8/sqrt(tau), set the
    reach (with a threshold on a grid point too): without them the chain never releases on that side."""
    from dryfric_jax.noise import required_reach
    from dryfric_jax.pdmp import grid_offsets

    N = grid_size(d, tau, gb)
    kp, km, _, _ = grid_offsets(d, gb)
    assert -N <= km - 1 and kp + 1 <= N, (N, kp, km)
    assert N * d >= required_reach(tau, gb) + d * (1 - 1e-12)


def test_stationary_law_on_a_wide_grid_and_at_the_reflecting_ends():
    """20 001 points: no overflow (normalised by the largest term), and the variance exactly 1/tau (the
    chain's drift is linear: test_stationary_moments_tend_to_ou; 1.3e-12 relative measured here, the grid's
    ends 100 sd out); at the ends the detailed balance of the reflecting rule, pi_N / pi_(N-1) = alpha_(N-1)
    exactly."""
    from dryfric_jax.noise import up_probability

    d, tau = 1e-4, 1e4
    x, pi = stationary_law(grid_size(d, tau), d, tau)
    assert np.all(np.isfinite(pi)) and abs(pi.sum() - 1) < 1e-12
    assert (pi * x**2).sum() == pytest.approx(1 / tau, rel=1e-10)
    d, tau = 0.2, 1.0
    N = grid_size(d, tau)
    x, pi = stationary_law(N, d, tau)
    alpha = lambda k: 0.5 - 0.25 * tau * d * d * k  # noqa: E731
    assert pi[-1] / pi[-2] == pytest.approx(alpha(N - 1), rel=1e-12)
    assert pi[0] / pi[1] == pytest.approx(1 - alpha(-N + 1), rel=1e-12)
    assert up_probability(N, N, d, tau) == 0 and up_probability(-N, N, d, tau) == 1


def test_grid_limits_are_exclusive_as_stated():
    with pytest.raises(ValueError, match="^delta must be in"):  # delta_max itself is excluded
        check_delta(delta_max(1.0), 1.0)
    with pytest.raises(ValueError, match="too small: the noise grid would have"):  # more than 2^31 - 1 points
        grid_size(8 / (2**30 + 100), 1.0)


def test_a_refused_delta_is_told_the_least_delta_whose_grid_fits():
    """"(0, delta_max)" alone sent a user to a delta that grid_size then refused for its size (an audit: 1e-9 after
    "delta must be in (0, 0.3338)"); the least delta is said, and it fits, where half of it does not."""
    import re

    with pytest.raises(ValueError) as e:
        check_delta(0.0, 1.0)
    least = float(re.search(r"; and delta >= (\S+) here, or the grid exceeds 2147483647 points$", str(e.value)).group(1))
    assert 2 * grid_size(least, 1.0) + 1 <= 2**31 - 1
    with pytest.raises(ValueError, match="is too small: the noise grid would have"):
        grid_size(least / 2, 1.0)
    with pytest.raises(ValueError, match=r"; no delta is admissible here \(its grid would exceed 2147483647 points\)"):
        check_delta(math.nan, 1e12)  # the thresholds' reach needs 1e-9, delta_max is ~4e-12
