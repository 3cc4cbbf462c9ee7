"""The splitting coin is an exact minorisation: P(heads | x) = epsilon for every x in C, and given
heads the next pair is distributed as nu whatever x was (regeneration)."""
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.special import ndtr
from scipy.stats import ks_2samp

from dryfric_jax.ou import ou_step
from dryfric_jax.regeneration import split_set


@pytest.mark.parametrize("r", [1e-3, 1.0, 1e3])  # h/tau
def test_heads_probability_is_epsilon_and_law_after_heads_forgets_x(r, key):
    tau = 0.7
    ou = ou_step(r * tau, tau)
    s = split_set(ou, 0.4, tau)
    eps = float(s.epsilon)  # checked below against the empirical heads rate
    assert 0.25 < eps <= 1.0
    n = 400_000
    means, after, before = [], {}, {}
    for i, frac in enumerate((0.0, 0.3, 0.5, 0.9, 1.0)):
        x = float(s.c1 + frac * (s.c2 - s.c1))
        k1, k2 = jax.random.split(jax.random.fold_in(key, i))
        z1, z2 = jax.random.normal(k1, (2, n))
        u = jax.random.uniform(k2, (n,))
        logr = s.log_coin(x, z1, z2)
        assert float(jnp.max(logr)) <= 1e-12  # r <= 1 on C: a valid coin
        heads = np.asarray(jnp.log(u) < logr)
        p = heads.mean()
        assert abs(p - eps) <= 5 * np.sqrt(eps * (1 - eps) / n)
        Xi, Xn = ou.sample(x, z1, z2)
        means.append((np.asarray(Xi)[heads].mean(), np.asarray(Xn)[heads].mean(), heads.sum()))
        if frac in (0.0, 1.0):  # the two ends of C: the whole law after heads, not only its mean
            after[frac] = (np.asarray(Xi)[heads], np.asarray(Xn)[heads])
            before[frac] = np.asarray(Xn)[: heads.sum()]  # the step without the coin: it remembers x
    # nu is symmetric about c_mid * m: the conditional mean is the same for every x.  Along a-hat
    # nu's whitened coordinate is |N| - half_d restricted to N > half_d, whose variance is below 1,
    # so the conditional standard deviations are at most those of the unconditional step.
    c = float(s.center)
    for mXi, mXn, k in means:
        sd = np.sqrt(np.array([float(ou.L11) ** 2, float(ou.L21) ** 2 + float(ou.L22) ** 2]) / k)
        assert abs(mXi - c * float(ou.m1)) <= 5 * sd[0]
        assert abs(mXn - c * float(ou.m2)) <= 5 * sd[1]
    # the same law whatever x: two-sample KS on both coordinates, from the two ends of C (a law
    # that kept the mean but changed its spread with x would pass the means); 6 tests in all
    for a, b in zip(after[0.0], after[1.0]):
        assert ks_2samp(a, b).pvalue > 1e-3
    if r <= 1.0:  # the test has teeth at this size (at h/tau = 1e3 the step itself forgets x: m2 = e^-1000)
        assert ks_2samp(before[0.0], before[1.0]).pvalue < 1e-6

def test_set_shrinks_to_threshold_when_tau_much_larger_than_h():
    tau = 1.0
    widths = [float(split_set(ou_step(h, tau), 0.0, tau).c2) for h in (1e-2, 1e-4, 1e-6)]
    # w ~ sqrt(h/2)/tau: a factor 10 per factor 100 in h
    assert widths[0] / widths[1] == pytest.approx(10, rel=0.05) and widths[1] / widths[2] == pytest.approx(10, rel=0.05)


def test_set_covers_the_noise_when_tau_much_smaller_than_h():
    tau = 1e-4
    s = split_set(ou_step(1.0, tau), 0.0, tau)
    # epsilon = 2 Phi(-w |a|) with |a| ~ tau/sqrt(2h): 2 Phi(-4 sqrt(tau/(2h))) = 0.977 here
    assert float(s.c2) == pytest.approx(4 / np.sqrt(tau))
    assert float(s.epsilon) == pytest.approx(float(2 * ndtr(-4 * np.sqrt(tau / 2.0))), rel=1e-3)


@pytest.mark.parametrize("dtype", ["float64", "float32"])
@pytest.mark.parametrize("watch_plus", [True, False])
def test_the_chains_coin_is_heads_with_probability_r(key, dtype, watch_plus):
    r"""``DIModel.coin``, the coin the engine flips, is heads with probability
    :math:`\min(1, r(x, y))` = ``min(1, exp(log_coin))`` of the watched set: 10^5 flips at fixed
    (x, z1, z2), within 5 binomial SE, at two points of C_+ (C_-) with r = 0.20 and 0.55.  Only
    ``SplitSet.log_coin`` was tested: a coin heads with probability min(1, 2r) passed every test
    (mutation audit)."""
    import dryfric_jax as dj
    from dryfric_jax.di import make_di_model

    m = make_di_model(dj.Params.from_nondim(0.5, 1.0, 0.2), 0.02, dtype=dtype)
    s = m._set(watch_plus)
    dt = m.h.dtype
    keys = jax.random.split(key, 100_000)
    for frac, z1 in ((0.1, 0.3), (0.8, -0.2)):
        x = jnp.asarray(s.c1 + frac * (s.c2 - s.c1), dt)
        z = (jnp.asarray(z1, dt), jnp.asarray(0.5, dt))
        p = float(jnp.minimum(1.0, jnp.exp(s.log_coin(x, *z))))
        assert 0.05 < p < 0.95, p  # the rate can be told from 2 p and from 1
        heads = jax.vmap(lambda k: m.coin((x, jnp.zeros((), dt)), z, jnp.asarray(watch_plus), k))(keys)
        rate = float(jnp.mean(heads))
        se = (p * (1 - p) / keys.shape[0]) ** 0.5
        assert abs(rate - p) < 5 * se, (frac, rate, p)


def test_small_set_has_its_design_width_and_epsilon():
    """KAPPA = 1: the set's half-width w |a| is 1, so epsilon = 2 Phi(-1) = 0.317 per stuck step (module
    docstring); at h' = 1e-4, tau' = 1 the half-width w = 1/|a| is sqrt(h'/2) to first order."""
    s = split_set(ou_step(1e-4, 1.0), 0.0, 1.0)
    assert float(s.epsilon) == pytest.approx(2 * ndtr(-1.0), rel=1e-12)
    assert float(s.c2) == pytest.approx(np.sqrt(1e-4 / 2), rel=1e-3)
