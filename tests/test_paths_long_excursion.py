"""``paths.di_long_excursion``: the paper's long excursion (section 6.1; Figs. 1-2) from release to release, as
``dryfric_jax.durations`` counts them, not the Nummelin cycle of ``di_excursion`` (an audit: the figure's DI row
plotted a cycle of ~3 long excursions at seed 0).  The checks read the returned arrays only: the release rule
(V_{n-1} = V_n = 0 != V_{n+1}) is applied to them here, not taken from the function's flags."""
import math

import jax
import numpy as np
import pytest

from dryfric_jax.di import make_di_model
from dryfric_jax.durations import di_long_excursion_duration
from dryfric_jax.estimators import t_quantile
from dryfric_jax.params import FIG3, Params
from dryfric_jax.paths import di_long_excursion
from dryfric_jax.plan import default_h


def _releases(v_before, v):
    """(index of the state before the step, direction) of every release along the recorded V: the step from
    index j to j + 1 releases where V[j - 1] = V[j] = 0 != V[j + 1] (``v_before`` stands for V[-1]: NaN, "not
    stuck", where nothing came before)."""
    w = np.concatenate([[v_before], v])
    j = np.nonzero((w[:-2] == 0) & (w[1:-1] == 0) & (w[2:] != 0))[0]
    return [(int(i), int(np.sign(v[i + 1]))) for i in j]


def _check_structure(e, h):
    v, n, k = e["v"], len(e["t"]), e["i_half"]
    assert e["complete"] and len(e["x"]) == len(v) == len(e["U"]) == n and 0 < k < n - 2
    np.testing.assert_array_equal(e["t"], np.arange(n) * h)
    # the first recorded move: from rest towards V > 0 (that V[-1] = 0 too, a release, the replay test checks)
    assert v[0] == 0.0 and v[1] > 0
    rel = _releases(0.0, v)
    assert rel[0] == (0, 1), rel[:3]
    assert rel[-1] == (n - 2, 1), rel[-3:]  # the last recorded move: a release towards V > 0
    # the direction of release changes exactly twice: to V < 0 at i_half, back to V > 0 at the end
    changes = [(i, s) for (i, s), (_, s0) in zip(rel[1:], rel[:-1]) if s != s0]
    assert changes == [(k, -1), (n - 2, 1)], changes
    assert e["duration"] == pytest.approx((n - 2) * h, rel=1e-12) and e["duration"] == e["t"][-2]
    trapezoid = np.concatenate([[0.0], np.cumsum(0.5 * h * (v[1:] + v[:-1]))])
    np.testing.assert_allclose(e["U"], trapezoid, rtol=0, atol=1e-12 * max(1.0, np.abs(trapezoid).max()))
    assert e["U"][0] == 0.0 and np.ptp(e["U"]) > 0  # U moves (an all-zero U would match an all-zero v)
    return rel


def _replay(m, key, n_steps):
    """The chain of the docstring's keys, replayed here by a ``lax.scan`` (independent of the function's loop and
    flags): X_0 = the stationary sd x normal(split(key)[0]), V_0 = 0, step i from model.draw(fold_in(split(key)[1],
    i), 1).  Returns X and V at steps 0..n_steps and the changes of release direction, (index, sign), the first
    step no release (V_{-1} "not stuck", NaN, as in the count's lanes)."""
    ks, kst = jax.random.split(key)

    def step(c, i):
        X, V = c
        z1, z2 = m.draw(jax.random.fold_in(kst, i), 1)
        _, Xn, Vn, _ = m.move(X, V, z1[0], z2[0])
        return (Xn, Vn), (Xn, Vn)

    x0 = m.ou.stationary_sd() * jax.random.normal(ks, (), m.h.dtype)
    _, (xs, vs) = jax.lax.scan(step, (x0, jax.numpy.zeros((), m.h.dtype)),
                               jax.numpy.arange(n_steps, dtype=np.uint32))
    xs, vs = np.concatenate([[float(x0)], np.asarray(xs)]), np.concatenate([[0.0], np.asarray(vs)])
    rel = _releases(math.nan, vs)
    return xs, vs, [(i, s) for (i, s), (_, s0) in zip(rel[1:], rel[:-1]) if s != s0]


def test_fig3_point_seed_0_is_one_long_excursion():
    """Figs. 1-2's DI row (Fig. 3's parameters, the default step, seed 0): one long excursion (2.316 s, its +HLE
    1.196 s, measured), where ``di_excursion``'s cycle was 18.68 s with ~3 of them.  Its start, half and end are
    the replayed chain's first change of release direction to V > 0, the next (to V < 0) and the one after.  More
    than one release towards V > 0 in the +HLE (the particle sticks and moves on), so the rule is "the direction
    changes", not "any release"."""
    p = Params(**FIG3)
    h = default_h(p)
    m = make_di_model(p, h)
    e = di_long_excursion(m, jax.random.key(0))
    rel = _check_structure(e, h / p.tau0)
    _, _, changes = _replay(m, jax.random.key(0), 60_000)
    k = next(j for j, (_, s) in enumerate(changes) if s == 1)  # to V > 0, after a release to V < 0
    (start, _), (half, down), (end, up) = changes[k:k + 3]
    assert (down, up) == (-1, 1)
    assert e["duration"] == pytest.approx((end - start) * h / p.tau0, rel=1e-12)
    assert e["i_half"] == half - start
    assert len(rel) > 3


@pytest.mark.parametrize("tau,h,seed", [(0.05, 2e-3, 1), (1.0, 1e-2, 0), (1.0, 1e-2, 7)])
def test_release_to_release_at_other_points(tau, h, seed):
    e = di_long_excursion(make_di_model(Params.from_nondim(tau), h), seed, 100_000)
    _check_structure(e, h)


@pytest.mark.parametrize("seed", [3, 1, 14, 28, 32])
def test_the_steps_are_the_chain_of_the_documented_keys(seed):
    """Replayed step by step here from the docstring's keys: X_0 = the stationary sd x normal(split(key)[0]),
    V_0 = 0, step i from model.draw(fold_in(split(key)[1], i), 1); the recorded states are the chain's from the
    first release towards V > 0 after one towards V < 0, the first step no release (V_{-1} "not stuck", as in the
    count's lanes).  A wrong key, a start one step off, a start at the first release towards V > 0 whatever came
    before, or a V_{-1} of 0 (seeds 14 and 32 then start at a move at step 0: a review) fails.  The scan and the
    loop are compiled apart, so X may differ in its last bit (seeds 1 and 28): compared to 1e-12."""
    tau, h = 1.0, 1e-2
    m = make_di_model(Params.from_nondim(tau), h)
    key = jax.random.key(seed)
    e = di_long_excursion(m, key, 100_000)
    N = 30_000
    xs, vs, changes = _replay(m, key, N)
    firsts = [i for i, s in changes if s == 1]  # a change to V > 0: a release to V < 0 came before
    assert firsts and firsts[0] + len(e["v"]) <= N + 1
    s = firsts[0]
    assert s >= 1 and vs[s - 1] == vs[s] == 0.0 < vs[s + 1]  # the start is a release towards V > 0
    np.testing.assert_allclose(e["x"], np.array(xs[s:s + len(e["x"])]), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(e["v"], np.array(vs[s:s + len(e["v"])]), rtol=1e-12, atol=1e-12)


def test_mean_duration_is_the_raw_release_counts():
    """The mean of 800 excursions' durations (seeds 0-799) against ``di_long_excursion_duration`` at the same
    point and h, 4096 asked: the raw count (``bridge=False``, the same release rule), within the 95% CI of their
    difference; the bridged count, which also takes crossings between steps, is ~20% lower at this tau/h = 187
    (durations.py) and is not what a path's releases give.  Measured: 0.5302 +- 0.0332 s (paths) against the raw
    count's 0.5386 +- 0.0143 s (4381 LEs; -0.46 SE of the difference) and the bridged 0.4350 +- 0.0128 s (+5.3
    SE; 95% CIs); ~15 s on 2 cores."""
    p = Params(10.0, FIG3["Delta"], 0.125, FIG3["tau_L"], FIG3["gamma_bar"])
    h = default_h(p)
    m = make_di_model(p, h)
    runs = [di_long_excursion(m, s, 20_000) for s in range(800)]
    assert all(r["complete"] for r in runs)
    d = np.array([r["duration"] for r in runs]) * p.tau0
    n = len(d)
    mean, se = d.mean(), d.std(ddof=1) / math.sqrt(n)
    raw = di_long_excursion_duration(p, 0, h=h, n_excursions=4096, bridge=False)
    bridged = di_long_excursion_duration(p, 0, h=h, n_excursions=4096)
    se_raw, se_br = (r.ci / t_quantile(0.95, r.n_excursions - 1) for r in (raw, bridged))
    both = math.hypot(se, se_raw)
    assert abs(mean - raw.mean) <= 1.96 * both, (mean, se, raw.mean, raw.ci)
    assert mean - bridged.mean > 3 * math.hypot(se, se_br), (mean, se, bridged.mean, bridged.ci)


def test_same_seed_same_bits_and_a_key_is_a_seed():
    m = make_di_model(Params.from_nondim(1.0), 1e-2)
    a, b, c = (di_long_excursion(m, k, 50_000) for k in (11, 11, jax.random.key(11)))
    for k in ("t", "x", "v", "U"):
        np.testing.assert_array_equal(a[k], b[k])
        np.testing.assert_array_equal(a[k], c[k])
    assert a["i_half"] == b["i_half"] == c["i_half"] and a["duration"] == b["duration"] == c["duration"]
    d = di_long_excursion(m, 12, 50_000)
    assert len(d["t"]) != len(a["t"]) or not np.array_equal(d["v"], a["v"])


def test_bounds_stop_it_incomplete():
    """``max_steps`` recorded steps: the same states so far, ``complete`` False, no duration; exactly the
    excursion's recorded steps is complete.  ``max_seek`` too short for a start: empty arrays."""
    m = make_di_model(Params.from_nondim(1.0), 1e-2)
    e = di_long_excursion(m, 4, 100_000)
    n, k = len(e["t"]) - 1, e["i_half"]
    exact = di_long_excursion(m, 4, n)
    assert exact["complete"] and np.array_equal(exact["v"], e["v"])
    short = di_long_excursion(m, 4, n - 1)
    assert not short["complete"] and math.isnan(short["duration"]) and len(short["t"]) == n
    np.testing.assert_array_equal(short["x"], e["x"][:n])
    half = di_long_excursion(m, 4, k)  # stopped in the +HLE: no -HLE yet
    assert not half["complete"] and half["i_half"] == -1 and len(half["t"]) == k + 1
    none = di_long_excursion(m, 4, 100_000, max_seek=3)
    assert not none["complete"] and len(none["t"]) == 0 and none["i_half"] == -1


@pytest.mark.parametrize("kw,match", [
    (dict(max_steps=0), r"^max_steps must be an integer in \[1, "),
    (dict(max_steps=-1), r"^max_steps must be an integer in \[1, "),
    (dict(max_steps=2**40), r"^max_steps must be an integer in \[1, "),
    (dict(max_steps=1.5), r"^max_steps must be an integer in \[1, "),
    (dict(max_seek=0), r"^max_seek must be an integer in \[1, "),
    (dict(max_steps=10, max_seek=2**32 - 10), r"^max_seek must be an integer in \[1, 4294967285\]"),
])
def test_bad_arguments_are_refused_by_name(kw, match):
    m = make_di_model(Params.from_nondim(1.0), 1e-2)
    with pytest.raises(ValueError, match=match):
        di_long_excursion(m, 0, **kw)


def test_a_wrong_model_or_key_is_refused_by_name():
    from dryfric_jax.pdmp import make_pdmp_model

    with pytest.raises(ValueError, match="^model must be a DIModel"):
        di_long_excursion(make_pdmp_model(Params.from_nondim(1.0), 0.1), 0)
    with pytest.raises(ValueError, match="seed"):
        di_long_excursion(make_di_model(Params.from_nondim(1.0), 1e-2), -1)
