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
