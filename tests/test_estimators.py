"""Delta-method machinery on synthetic i.i.d. cycles whose D and M0 are known exactly."""
import re

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from dryfric_jax.estimators import (
    bruteforce_estimates, delta_method, grad_psi_D_by_hand, long_excursion_estimates, moments_from_sums, psi_D,
    psi_D_paper, psi_M, sums_from_samples,
)


def test_jax_grad_matches_hand_gradient():
    rng = np.random.default_rng(0)
    for _ in range(20):
        x = rng.normal(size=5)
        x[2] = abs(x[2]) + 0.1
        np.testing.assert_allclose(np.asarray(jax.grad(psi_D)(x)), grad_psi_D_by_hand(x), rtol=1e-12, atol=1e-14)


def _cycles(rng, n, mu):
    """Cycles with t ~ Gamma(2, 1) and U = mu t + sqrt(t) * N(0, s^2) (a Brownian motion with
    drift sampled at a random time): M0 = mu and D = s^2 exactly, whatever the law of t."""
    t = rng.gamma(2.0, 1.0, n)
    U = mu * t + np.sqrt(t) * rng.normal(0.0, 1.5, n)
    return U, t


@pytest.mark.parametrize("mu", [0.0, 0.8])
def test_estimator_consistent_and_ci_covers(mu):
    r"""D, M0 and the mean duration E t = 2 over 1600 replicates of n = 2000 synthetic cycles: coverage
    of the exact values within 4 binomial SE of 95%, and the mean half-widths against the exact
    asymptotic SEs (a CI too wide, which covers more, fails as well as one too narrow).

    Mean duration: its half-width is :math:`z\sqrt{m_2/n}` with :math:`m_2` the sample variance of t
    (divisor n).  For :math:`t \sim \Gamma(2, 1)` the central moments are exactly :math:`\mu_2 = 2`,
    :math:`\mu_4 = 3k^2 + 6k = 24` (k = 2), so :math:`E m_2 = \mu_2(1 - 1/n)` and
    :math:`\mathrm{Var}\, m_2 \approx (\mu_4 - \mu_2^2)/n = 20/n`; then (Jensen)
    :math:`E\sqrt{m_2} \approx \sqrt{\mu_2}\,(1 - 1/(2n) - 20/(32 n)) = \sqrt2\,(1 - 1.125/n)`, with
    relative sd :math:`\tfrac12\sqrt{20/n}/\mu_2` = 2.5% per replicate, 0.0625% for the mean of 1600.
    The mean over the replicates of half-width / z must lie within 4 of those SE (0.25%) of
    :math:`\sqrt{2/n}\,(1 - 1.125/n)`: a half-width without its z (1.96x too narrow) fails by 49%.

    D and M0: the same Jensen bias of a square root, :math:`-(\kappa - 1)/(8n) - 1/(2n)` with
    :math:`\kappa` the kurtosis of the influence values (below), and a tolerance of 4 SE of the mean
    half-width measured from the replicates (0.18% of D's, 0.05% of M0's): a half-width 1.5% too wide
    or too narrow fails (at 400 replicates and a fixed 2% an M0 CI 1.5% too wide passed: an audit)."""
    rng = np.random.default_rng(1)
    cover_D = cover_M = cover_t = 0
    reps, n = 1600, 2000
    D, D_ci, M_ci, t_ci = [], [], [], []
    for _ in range(reps):
        U, t = _cycles(rng, n, mu)
        e = long_excursion_estimates(sums_from_samples(U, t))
        cover_D += abs(e["D"] - 2.25) <= e["D_ci"]
        cover_M += abs(e["M0"] - mu) <= e["M0_ci"]
        cover_t += abs(e["mean_duration"] - 2.0) <= e["mean_duration_ci"]  # E t = 2 for Gamma(2, 1)
        D.append(e["D"]), D_ci.append(e["D_ci"]), M_ci.append(e["M0_ci"]), t_ci.append(e["mean_duration_ci"])
    # the two-sided 95% normal quantile, written out (not taken from the code under test)
    z = 1.959963984540054
    # mean duration (docstring): coverage within 4 binomial SE (0.011 each) of 0.95, [0.906, 0.994]
    assert abs(cover_t / reps - 0.95) <= 4 * np.sqrt(0.95 * 0.05 / reps), cover_t / reps
    rel_t = np.mean(t_ci) / z / (np.sqrt(2.0 / n) * (1 - 1.125 / n)) - 1
    assert abs(rel_t) <= 4 * 0.5 * np.sqrt(20 / n) / 2 / np.sqrt(reps), rel_t
    # 95% nominal; binomial sd over 1600 replicates is 0.0054: accept 0.95 +- 4 sd, [0.928, 0.972]
    assert abs(cover_D / reps - 0.95) <= 4 * np.sqrt(0.95 * 0.05 / reps), cover_D / reps
    assert abs(cover_M / reps - 0.95) <= 4 * np.sqrt(0.95 * 0.05 / reps), cover_M / reps
    # coverage alone passes a 99% interval (1.31x too wide): the width against the exact asymptotic
    # SEs. Influence of D: ((U - M0 t)^2 - D t)/E t = t s^2 (Z^2 - 1)/E t, so Var = 2 s^4 E[t^2]/E[t]^2
    # = 2 * 2.25^2 * 6 / 4; of M0: sqrt(t) s Z / E t, Var = s^2 E[t] / E[t]^2 = 2.25 / 2.
    se_D, se_M = np.sqrt(2 * 2.25**2 * 6 / 4 / n), np.sqrt(2.25 / 2 / n)
    # kurtosis of the influence values: D's t (Z^2 - 1), E[t^4] E[(Z^2-1)^4] / (E[t^2] E[(Z^2-1)^2])^2
    # = 120 * 60 / (6 * 2)^2 = 50; M0's sqrt(t) Z, E[t^2] E[Z^4] / E[t]^2 = 6 * 3 / 4 = 4.5
    for ci, se, kappa in ((np.array(D_ci) / z, se_D, 50.0), (np.array(M_ci) / z, se_M, 4.5)):
        rel, bias = ci.mean() / se - 1, -(kappa - 1) / (8 * n) - 1 / (2 * n)
        assert abs(rel - bias) <= 4 * ci.std(ddof=1) / np.sqrt(reps) / se, (rel, bias)
    # and the estimates spread as the SE says: the sd of 1600 nearly normal replicates is known to
    # sqrt(1/(2 * 1600)) = 1.8%; 4 of those, 7% (seeds 1-3 gave -1.2%, -2.9%, +1.6%)
    np.testing.assert_allclose(np.std(D, ddof=1), se_D, rtol=0.07)


def test_paper_formula_is_biased_with_drift():
    """The printed Var(U)/E[t] misses (M0^2 Var t - 2 M0 Cov(U,t))/E[t]; the corrected Psi does not."""
    rng = np.random.default_rng(2)
    U, t = _cycles(rng, 400_000, 0.8)
    S, C = moments_from_sums(sums_from_samples(U, t))
    D, ci, _ = delta_method(psi_D, S, C, U.size)
    D_paper, ci_paper, _ = delta_method(psi_D_paper, S[:3], C[:3, :3], U.size)
    assert abs(D - 2.25) <= ci
    # here Var(U) = E[t] s^2 + mu^2 Var(t): the paper's value is 2.25 + 0.64 * 2 / 2 = 2.89
    assert abs(D_paper - 2.89) <= 3 / 1.96 * ci_paper and abs(D_paper - 2.25) > 10 * ci_paper  # 3 SE


def test_psi_M_and_units():
    S = np.array([2.0, 9.0, 4.0, 10.0, 20.0])
    assert psi_M(S) == 0.5
    assert psi_D(S) == pytest.approx((9 - 2 * 0.5 * 10 + 0.25 * 20) / 4)


def test_bruteforce_estimates_on_gaussian_displacements():
    r"""U ~ N(M t, D t): coverage within 3 binomial SE of 95%, and the mean half-widths equal the
    exact 1.96 sd (sd of var(U)/t is D sqrt(2/n), of mean(U)/t is sqrt(D / (t n))), so a CI too
    wide (which would cover 100%) fails as well as one too narrow.

    The half-widths' own small-n bias and spread are derived, not fitted.  D's is
    :math:`z\sqrt{X/n}/t` with :math:`X = m_4 - m_2^2` (sample central moments, divisor n): for a
    normal law :math:`E[X] = 2\sigma^4 (n-1)(n-2)/n^2 \approx 2\sigma^4(1 - 3/n)` and
    :math:`\mathrm{Var}\,X \approx 56\sigma^8/n` (the variance of :math:`U^2` estimated from n draws;
    :math:`\chi^2_1` has central moments 2 and 60), so :math:`E\sqrt X \approx \sqrt{2}\sigma^2(1 - 3.25/n)`
    (Jensen) with relative sd :math:`\tfrac12\sqrt{14/n}`.  M0's uses the sample sd with divisor n:
    :math:`E \approx \sigma(1 - 0.75/n)`, relative sd :math:`1/\sqrt{2n}`.  Each mean over the
    replicates must lie within 4 of its SEs (0.68% and 0.26% here) of the biased value.
    Measured at three seeds: D -0.22/-0.33/-0.26% against -0.11% (SE 0.17%), M0 -0.05/-0.12/-0.02%
    against -0.025% (SE 0.06%); the replicates' sd, 3.4% and 1.3%, as derived."""
    rng = np.random.default_rng(3)
    t, D, M, n, paths = 50.0, 3.0, 0.2, 400, 3000
    hits_D = hits_M = 0
    w_D, w_M = [], []
    for _ in range(n):
        U = rng.normal(M * t, np.sqrt(D * t), paths)
        e = bruteforce_estimates(U, t)
        hits_D += abs(e["D_t"] - D) <= e["D_t_ci"]
        hits_M += abs(e["M0_t"] - M) <= e["M0_t_ci"]
        w_D.append(e["D_t_ci"])
        w_M.append(e["M0_t_ci"])
    band = 3 * np.sqrt(0.95 * 0.05 / n)
    assert abs(hits_D / n - 0.95) <= band and abs(hits_M / n - 0.95) <= band
    z = 1.959963984540054
    rel_D = np.mean(w_D) / (z * D * np.sqrt(2 / paths) * (1 - 3.25 / paths)) - 1
    rel_M = np.mean(w_M) / (z * np.sqrt(D / (t * paths)) * (1 - 0.75 / paths)) - 1
    assert abs(rel_D) <= 4 * 0.5 * np.sqrt(14 / paths) / np.sqrt(n)
    assert abs(rel_M) <= 4 / np.sqrt(2 * paths) / np.sqrt(n)


def test_too_few_samples_refused():
    with pytest.raises(ValueError, match=r"^need at least 2 complete excursions for a CI \(got 1\)"):
        long_excursion_estimates(sums_from_samples([1.0], [1.0]))
    with pytest.raises(ValueError, match="n_paths"):
        bruteforce_estimates([1.0], 1.0)
    # two paths: the centred U^2 are equal, so the D_t CI came out 0 (a certainty from two samples)
    with pytest.raises(ValueError, match=r"^n_paths must be >= 3 \(got 2\)"):
        bruteforce_estimates([0.3, 1.7], 1.0)
    assert bruteforce_estimates([0.3, 1.7, -0.4], 1.0)["D_t_ci"] > 0


def test_bruteforce_ci_under_covers_at_few_paths_as_the_warning_says():
    """The numbers behind MIN_RELIABLE_PATHS and the brute-force small-N' warning: the delta-method
    CI of D^t on N' Gaussian U(t) (true D^t = 1) covers ~0.74 at N' = 10 and ~0.92 at N' = 100,
    well below 0.95 (3 binomial SE bands, 3000 replicates)."""
    rng = np.random.default_rng(5)
    for n, said in ((10, 0.74), (100, 0.92)):
        hits = [abs((e := bruteforce_estimates(rng.standard_normal(n), 1.0))["D_t"] - 1) <= e["D_t_ci"]
                for _ in range(3000)]
        assert abs(np.mean(hits) - said) <= 3 * np.sqrt(said * (1 - said) / 3000), (n, np.mean(hits))


def test_bruteforce_estimate_does_not_depend_on_a_shift_of_U():
    """D^t is a variance: U + 1e6 (a strong bias over a long horizon) must give the D and CI of U.
    The raw y2 - y1^2 cancelled: sd 1e-3 about a mean of 1e6 gave D = 2.4e-4 for 1.0e-6."""
    rng = np.random.default_rng(4)
    U = rng.normal(0.0, 1e-3, 100_000)
    a, b = bruteforce_estimates(U, 2.0), bruteforce_estimates(U + 1e6, 2.0)
    # adding 1e6 rounds each U by <= 6e-11, 6e-8 of its sd
    assert b["D_t"] == pytest.approx(a["D_t"], rel=1e-6) and b["D_t_ci"] == pytest.approx(a["D_t_ci"], rel=1e-6)
    assert bruteforce_estimates(np.full(8, 1e-27), 1e-12)["D_t"] == 0.0  # never below 0


@pytest.mark.parametrize("n", [0, -3, float("nan"), True, float("inf"), 1.5])
def test_delta_method_refuses_a_sample_size_below_one(n):
    """n = 0 gave an infinite half-width, n < 0 a NaN one, inf a half-width of 0; 1.5 is no sample size."""
    from dryfric_jax.estimators import delta_method

    with pytest.raises(ValueError, match="^n must be a sample size >= 1"):
        delta_method(lambda m: m[0], [1.0], [[1.0]], n)


def test_delta_method_refuses_what_gave_nan_or_a_number_from_clamped_indices():
    """An audit: psi_D of a 2-vector read clamped indices and gave a plausible number; a zero mean duration gave
    (nan, nan, nan) and a negative definite cov a half-width of 0, all without a word."""
    from dryfric_jax.estimators import delta_method, psi_D, psi_M

    m, c = np.array([0.1, 2.0, 1.0, 0.3, 1.5]), np.eye(5) * 0.01
    assert np.isfinite(delta_method(psi_D, m, c, 100)).all()
    with pytest.raises(ValueError, match=r"^x must be a vector of at least 5 numbers for psi_D \(got shape \(2,\)\)"):
        delta_method(psi_D, m[:2], c[:2, :2], 100)
    with pytest.raises(ValueError, match=r"^x must be a vector of at least 3 numbers for psi_M"):
        psi_M(np.ones(2))
    # called directly: strings were a TypeError from the division, E[t] = 0 a NaN or inf with a numpy warning
    for psi, x in ((psi_D, ["a"] * 5), (psi_D, [1.0, 2.0, 0.0, 1.0, 1.0]), (psi_M, [1.0, 2.0, np.nan])):
        msg = rf"^x must hold finite real numbers with x_3 = E\[t\] > 0 for {psi.__name__}"
        with pytest.raises(ValueError, match=msg):
            psi(x)
    with pytest.raises(ValueError, match=r"^psi and its gradient must be finite at mean \(got estimate nan"):
        delta_method(psi_D, np.zeros(5), c, 100)
    with pytest.raises(ValueError, match=r"^cov must be a covariance matrix"):
        delta_method(psi_D, m, -c, 100)
    with pytest.raises(ValueError, match=r"^cov must be a covariance matrix"):
        delta_method(psi_D, m, c + np.triu(np.ones((5, 5)), 1) * 1e-3, 100)  # not symmetric


@pytest.mark.parametrize("psi,mean,cov,match", [
    (lambda m: m[0], [1.0, 2.0], np.eye(3)[:2], r"^mean must be a vector of k >= 1 numbers and cov a k x k matrix "
                                                r"\(got shapes \(2,\) and \(2, 3\)"),
    (lambda m: m[0], [[1.0]], [[1.0]], r"^mean must be a vector"),
    (lambda m: m[0], [], np.zeros((0, 0)), r"^mean must be a vector"),
    (lambda m: m, [1.0, 2.0], np.eye(2), r"^psi must map a vector of 2 numbers to one number \(Gradient only"),
    (lambda m: m[0], [1.0, float("nan")], np.eye(2), r"^mean must hold finite real numbers \(got \[1\.0, nan\]\)"),
    (lambda m: m[0], [1.0, 2.0], [[1.0, 0.0], [0.0, float("inf")]], r"^cov must hold finite real numbers"),
    (lambda m: m[0], "x", [[1.0]], r"^mean must hold finite real numbers \(got 'x'\)"),
    (lambda m: m[0], [1j], [[1.0]], r"^mean must hold finite real numbers"),
])
def test_delta_method_refuses_bad_moments_and_psi_by_name(psi, mean, cov, match):
    """A public function, so a caller's mistake is a ValueError naming the argument: a cov of the wrong shape and a
    psi with a vector output were JAX TypeErrors from inside the gradient, and a NaN in an entry psi ignores
    gave a finite CI (a 'left as is' item of stop 64, fixed)."""
    from dryfric_jax.estimators import delta_method

    with pytest.raises(ValueError, match=match):
        delta_method(psi, mean, cov, 10)


def test_delta_method_returns_floats_and_the_textbook_interval():
    """psi(m) = m0 m1 at m = (2, 3), C = diag(4, 9), n = 100: grad (3, 2), sigma^2 = 9*4 + 4*9 = 72, half-width
    1.959964 sqrt(72)/10 = 1.663057; plain floats, not numpy scalars (the half-width was an np.float64)."""
    from dryfric_jax.estimators import delta_method

    out = delta_method(lambda m: m[0] * m[1], np.array([2.0, 3.0]), np.diag([4.0, 9.0]), 100)
    assert [type(x) for x in out] == [float, float, float]
    assert out[0] == 6.0 and out[2] == pytest.approx(72**0.5, rel=1e-14)
    assert out[1] == pytest.approx(1.959963984540054 * 72**0.5 / 10, rel=1e-14)


def test_moments_from_sums_are_the_sample_mean_and_covariance():
    """The mean and covariance (divisor N, as documented) of X = (U, U^2, t, Ut, t^2) from the
    sums equal numpy's on the samples: every product of the covariance is the right one
    (an n/(n-1) divisor or a swapped product passed the CI tests: mutation audit)."""
    from dryfric_jax.estimators import moments_from_sums, sums_from_samples

    rng = np.random.default_rng(4)
    t = rng.exponential(2.0, 7)
    U = rng.normal(0.3 * t, np.sqrt(t))
    S, C = moments_from_sums(sums_from_samples(U, t))
    X = np.stack([U, U**2, t, U * t, t**2])
    np.testing.assert_allclose(S, X.mean(axis=1), rtol=1e-13)
    np.testing.assert_allclose(C, np.cov(X, bias=True), rtol=1e-10, atol=1e-12 * np.abs(C).max())


@pytest.mark.parametrize("level,z", [(0.95, 1.959963984540054), (0.9, 1.6448536269514722)])
def test_estimates_and_half_widths_on_five_cycles_by_hand(level, z):
    r"""Every number of :func:`long_excursion_estimates` and :func:`bruteforce_estimates` on five fixed
    samples, computed here without the delta-method code: a ratio estimator's delta-method variance
    (covariance with divisor n) is the mean square of its empirical influence values,
    :math:`\hat\sigma^2 = \frac1n\sum_i \mathrm{IF}_i^2`, with (:math:`m = \bar U/\bar t`,
    :math:`c = \overline{(U - mt)t}/\bar t`)

    .. math::
        \mathrm{IF}^{M_0}_i = \frac{U_i - m t_i}{\bar t}, \qquad
        \mathrm{IF}^{D}_i = \frac{(U_i - m t_i)^2 - D t_i - 2c\,(U_i - m t_i)}{\bar t},

    and for brute force :math:`\mathrm{IF}^{D^t}_i = ((U_i - \bar U)^2 - \overline{(U - \bar U)^2})/t`.
    The z values are written out (two-sided 95% and 90%).  At n = 5 a divisor n - 1 anywhere (the
    covariance, a sqrt(n - 1), the sd of t or of U(t)) moves a half-width by >= 10%: the synthetic
    coverage tests (n >= 2000) cannot see it (mutation audit)."""
    U = np.array([1.0, -2.0, 3.0, 0.5, 2.5])
    t = np.array([1.0, 2.0, 3.0, 2.0, 0.5])
    th = np.array([0.25, 1.5, 1.0, 0.5, 0.5])
    n, tb = U.size, t.mean()
    m = U.sum() / t.sum()
    r = U - m * t
    D = (r**2).mean() / tb
    c = (r * t).mean() / tb
    if_D, if_M = (r**2 - D * t - 2 * c * r) / tb, r / tb
    assert abs(if_D.mean()) < 1e-14 and abs(if_M.mean()) < 1e-14  # influence values are centred
    e = long_excursion_estimates(sums_from_samples(U, t, th), level)
    want = dict(D=D, D_ci=z * np.sqrt((if_D**2).mean() / n), M0=m, M0_ci=z * np.sqrt((if_M**2).mean() / n),
                mean_duration=tb, mean_duration_ci=z * np.sqrt(((t - tb) ** 2).mean() / n),
                mean_half_duration=th.mean(), n_excursions=n)
    assert e.keys() == want.keys()
    for k in want:
        assert e[k] == pytest.approx(want[k], rel=1e-12), k
    horizon = 4.0
    v = ((U - U.mean()) ** 2).mean()
    if_bf = ((U - U.mean()) ** 2 - v) / horizon
    b = bruteforce_estimates(U, horizon, level)
    want = dict(D_t=v / horizon, D_t_ci=z * np.sqrt((if_bf**2).mean() / n), M0_t=U.mean() / horizon,
                M0_t_ci=z * np.sqrt(v / n) / horizon, n_paths=n, t=horizon)
    assert b.keys() == want.keys()
    for k in want:
        assert b[k] == pytest.approx(want[k], rel=1e-12), k


def test_delta_method_is_compiled_once_and_matches_the_traced_formula():
    """``delta_method`` runs psi and its gradient as one compiled function per psi (op by op it cost
    12 ms per estimate, and replicate loops ran thousands): a second call with another sample of the
    same shape compiles nothing, and the numbers are those of ``jax.grad`` traced op by op."""
    from dryfric_jax.estimators import _value_and_variance

    rng = np.random.default_rng(9)
    sizes = []
    for _ in range(3):
        sizes.append(_value_and_variance(psi_D)._cache_size())  # other tests may have compiled other shapes
        t = rng.exponential(1.0, 40) + 0.1
        S, C = moments_from_sums(sums_from_samples(rng.standard_normal(40) * t + 0.2 * t, t))
        D, ci, sigma = delta_method(psi_D, S, C, 40, 0.9)
        g = jax.grad(psi_D)(jnp.asarray(S))
        assert D == pytest.approx(float(psi_D(jnp.asarray(S))), rel=1e-14, abs=0)
        assert sigma == pytest.approx(float(jnp.sqrt(g @ jnp.asarray(C) @ g)), rel=1e-13, abs=0)
        assert ci == pytest.approx(1.6448536269514722 * sigma / np.sqrt(40), rel=1e-13)
    assert sizes[1] == sizes[2] == _value_and_variance(psi_D)._cache_size() <= sizes[0] + 1


def _centred_half_width(U, t, level_z=1.959963984540054):
    """The D half-width from centred samples (no raw-moment cancellation): the delta method's
    influence values (r^2 - D t - 2 c r) / E[t] with r = U - M0 t, c = E[r t] / E[t]."""
    tb, m = t.mean(), U.sum() / t.sum()
    r = U - m * t
    D, c = (r**2).mean() / tb, (r * t).mean() / tb
    return level_z * np.sqrt((((r**2 - D * t - 2 * c * r) / tb) ** 2).mean() / U.size)


@pytest.mark.parametrize("mu, noted", [(0.0, False), (100.0, False), (1e3, False), (3e3, True)])
def test_rounding_of_the_d_interval_is_bounded_and_flagged(mu, noted):
    """The D interval's variance is a difference of raw moment sums: with a drift per excursion far
    above its spread it cancels (kappa = M0^2 E[t^2] / (D E[t]) = 1.3e6 at mu = 1e3, 1.2e7 at 3e3; feasible
    runs reach ~1.6e4).  ``ci_rounding`` must bound the actual error of sigma^2 (against the centred
    computation; measured 3-30x above it, seeds 0-3) and ``rounding_note`` flag it past ROUNDING_TOL: at
    mu = 3e3 the half-width was 8% off (rho = 0.86), at mu = 1e3 0.013% (rho = 0.009, not flagged).  D
    itself stays right to 1e-8, as the note says."""
    from dryfric_jax.estimators import ROUNDING_TOL, ci_rounding, rounding_note

    U, t = _cycles(np.random.default_rng(0), 100_000, mu)
    T = sums_from_samples(U, t)
    e, want = long_excursion_estimates(T), _centred_half_width(U, t)
    rho = ci_rounding(T)
    err = abs(e["D_ci"] ** 2 / want**2 - 1)  # the actual relative error of sigma^2
    assert err <= rho < 1 and (rho > ROUNDING_TOL) == noted, (err, rho)
    tb, m = t.mean(), U.sum() / t.sum()
    assert e["D"] == pytest.approx(((U - m * t) ** 2).mean() / tb, rel=1e-8)
    note = rounding_note(T)
    assert (note is not None) == noted
    if noted:
        # the bound the note states covers the half-width's actual error (centred computation)
        stated = float(re.search(r"half-width by up to ~([0-9.e+-]+)%", note).group(1))
        assert note.startswith("the CI of D is not reliable") and stated >= 100 * abs(e["D_ci"] / want - 1)


def test_a_d_interval_lost_to_rounding_is_flagged_not_reported_as_zero_silently():
    """At mu = 1e4 (kappa = 1.3e8) the variance came out negative and the half-width 0 (seed 0): the
    note says the interval means nothing."""
    from dryfric_jax.estimators import ci_rounding, rounding_note

    U, t = _cycles(np.random.default_rng(0), 100_000, 1e4)
    T = sums_from_samples(U, t)
    assert long_excursion_estimates(T)["D_ci"] == 0.0
    assert ci_rounding(T) == float("inf") and "half-width is 0 and means nothing" in rounding_note(T)


@pytest.mark.parametrize("df,level,table", [(1, 0.95, 12.706), (2, 0.95, 4.303), (3, 0.95, 3.182), (10, 0.95, 2.228),
                                            (31, 0.95, 2.040), (120, 0.95, 1.980), (5, 0.99, 4.032), (20, 0.9, 1.725),
                                            (1000, 0.95, 1.962)])
def test_t_quantile_against_a_table(df, level, table):
    """Student's t quantiles as printed in statistics tables (3 decimals)."""
    from dryfric_jax.estimators import t_quantile

    assert abs(t_quantile(level, df) - table) < 6e-4


@pytest.mark.parametrize("df", [1, 2, 7, 31, 200, 201, 5000])
def test_t_quantile_integrates_to_its_level(df):
    """An independent check: the t density, integrated numerically (Simpson, on [0, q] after t = q u), holds
    ``level`` / 2 below the quantile; both sides of the switch to the series (T_SERIES_DF = 200) included."""
    from math import gamma, lgamma, pi, sqrt

    from dryfric_jax.estimators import t_quantile

    q = t_quantile(0.95, df)
    c = np.exp(lgamma((df + 1) / 2) - lgamma(df / 2)) / sqrt(df * pi) if df > 100 else gamma((df + 1) / 2) / (
        gamma(df / 2) * sqrt(df * pi))
    x = np.linspace(0.0, q, 20001)
    f = c * (1 + x**2 / df) ** (-(df + 1) / 2)
    simpson = (x[1] - x[0]) / 3 * (f[0] + f[-1] + 4 * f[1:-1:2].sum() + 2 * f[2:-1:2].sum())
    assert abs(2 * simpson - 0.95) < 1e-9


def test_t_quantile_refuses_bad_degrees_of_freedom():
    from dryfric_jax.estimators import t_quantile

    for bad in (0, -1, 2.5, True, None):
        with pytest.raises(ValueError, match="df must be an integer"):
            t_quantile(0.95, bad)
    with pytest.raises(ValueError, match="level"):
        t_quantile(1.0, 5)


def test_t_quantile_at_the_edges():
    """An audit: a level below ~1e-16 looped for ever (z_quantile rounds it to 0, and doubling 0 stays 0), a df
    beyond float range raised OverflowError, a 0-d integer array was refused.  Near level 0 the quantile is
    level x its density's reciprocal at 0, sqrt(df pi) Gamma(df/2) / Gamma((df + 1)/2) / 2 (5: 1.3172); a huge
    df gives the normal quantile."""
    from math import gamma, pi, sqrt

    from dryfric_jax.estimators import t_quantile, z_quantile

    slope = sqrt(5 * pi) * gamma(2.5) / gamma(3.0) / 2
    for level in (1e-17, 1e-300):
        assert t_quantile(level, 5) == pytest.approx(level * slope, rel=1e-9)
    assert t_quantile(0.95, 10**400) == z_quantile(0.95)
    assert t_quantile(0.95, np.array(5)) == t_quantile(0.95, 5) == t_quantile(0.95, np.int8(5))
