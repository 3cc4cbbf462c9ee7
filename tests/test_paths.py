"""The PDMP path recorder (Fig. 4) against a plain event loop over the same random stream; the DI
recorders against the per-path definition of their numbers; bad arguments refused by name."""
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from dryfric_jax import rng
from dryfric_jax.params import FIG3, Params
from dryfric_jax.paths import (autocorrelation, autocovariance, di_stationary, di_transient,
                               pdmp_stationary)
from dryfric_jax.pdmp import flow, make_pdmp_model


def _reference(model, key, n_records, dt_rec, burn):
    """One path event by event in Python: V at burn + j dt_rec from the segment containing it."""
    ev = jax.jit(lambda s, r: model.event(s, r))
    vdt = model.delta.dtype
    state = jax.tree_util.tree_map(lambda a: a[0], model.s_plus(1))
    T, i, out = 0.0, 0, []
    grid = burn + dt_rec * np.arange(n_records)
    while len(out) < n_records:
        u = jax.random.uniform(jax.random.fold_in(key, i), (2,), vdt, minval=jnp.finfo(vdt).tiny)
        dt, a, new, _, _ = ev(state, (u[0], u[1]))
        T1 = T + float(dt)
        _, y, v = state
        for tj in grid[len(out):]:
            if tj > T1:
                break
            out.append(float(flow(v, a, model.inv_tau_L, jnp.asarray(tj - T, vdt))) if y != 0 else 0.0)
        state, T, i = new, T1, i + 1
    return np.array(out)


@pytest.mark.parametrize("tau", [0.25, 1.0])
def test_pdmp_recorder_matches_event_loop(tau):
    p = Params(FIG3["Gamma"], FIG3["Delta"], tau, FIG3["tau_L"], FIG3["gamma_bar"])
    m = make_pdmp_model(p, 0.125)
    key = jax.random.key(5)
    V = pdmp_stationary(m, key, 4, 200, 0.05, 2.0)
    keys = jax.random.split(key, 4)
    for i in (2, 3):
        assert np.mean(V[i] != 0) > 0.1  # the path slides: the check is not on a stuck particle
        np.testing.assert_allclose(V[i], _reference(m, keys[i], 200, 0.05, 2.0), rtol=1e-9, atol=1e-12)


def test_pdmp_recorder_reports_its_event_bound():
    p = Params(FIG3["Gamma"], FIG3["Delta"], 1.0, FIG3["tau_L"], FIG3["gamma_bar"])
    with pytest.raises(RuntimeError, match="max_events"):
        pdmp_stationary(make_pdmp_model(p, 0.125), jax.random.key(0), 4, 100, 0.05, 10.0, max_events=50)


def test_pdmp_recorder_raises_when_some_paths_hit_the_event_bound(monkeypatch):
    """3 of these 8 paths need more than 500 events by t = 11 (about 480 expected): the run raises,
    counting them (it must not wait for all paths to stop); the default bound is 10x the expected
    events + 10^4, passed to the recorder as such."""
    from dryfric_jax import paths

    p = Params(FIG3["Gamma"], FIG3["Delta"], 1.0, FIG3["tau_L"], FIG3["gamma_bar"])
    m = make_pdmp_model(p, 0.125)
    with pytest.raises(RuntimeError, match="^[1-7] PDMP paths hit max_events = 500$"):  # some, not all 8
        pdmp_stationary(m, 3, 8, 20, 0.05, 10.0, max_events=500)
    seen = []

    def sampled(fn, args, lane_args, *, n_records):  # over_lanes(_pdmp_sampled, ...), the paths split over devices
        model, keys, t_burn, dt_rec, max_events = args
        seen.append((float(t_burn), float(dt_rec), int(max_events), n_records))
        return jnp.zeros((len(keys), n_records)), jnp.ones(len(keys), bool)

    monkeypatch.setattr(paths, "over_lanes", sampled)
    assert pdmp_stationary(m, 3, 8, 20, 0.05, 10.0).shape == (8, 20)
    assert seen == [(10.0, 0.05, int(10 * float(m.rate) * 11.0 + 10_000), 20)]


@pytest.mark.parametrize("kw,match", [
    (dict(model="di"), "^model must be a PDMPModel"), (dict(n_paths=0), "^n_paths must be"),
    (dict(dt_rec=-0.1), "^dt_rec must be finite and > 0"), (dict(burn=float("nan")), "^burn must be a finite"),
    (dict(burn=-1.0), "^burn must be >= 0"), (dict(max_events=0), "^max_events must be"),
    (dict(max_events=2**63), r"^max_events must be an integer in \[1, 2\^62\]"),
    # an OverflowError (the default event bound past int64), and T stalling in float64 (7e12: a hang, an audit)
    (dict(burn=1e30), r"^burn \+ n_records \* dt_rec must be at most .* float64 cannot resolve"),
    (dict(burn=7e12), r"^burn \+ n_records \* dt_rec must be at most .*\(got 7e\+12\)"),
    (dict(dt_rec=1e300), r"^burn \+ n_records \* dt_rec must be at most")])
def test_pdmp_recorder_refuses_bad_input_by_name(kw, match):
    """It checked nothing (a DIModel: AttributeError; burn = nan: an unnamed conversion error;
    dt_rec < 0: repeated values; n_paths = 0: an empty array); an int seed is taken as elsewhere."""
    from dryfric_jax.di import make_di_model

    p = Params(**FIG3)
    args = dict(model=make_pdmp_model(p, 0.125), key=3, n_paths=2, n_records=5, dt_rec=0.05, burn=0.5)
    args.update(kw)
    if args["model"] == "di":
        args["model"] = make_di_model(p, 1e-3)
    with pytest.raises(ValueError, match=match):
        pdmp_stationary(**args)
    good = dict(model=make_pdmp_model(p, 0.125), n_paths=2, n_records=5, dt_rec=0.05, burn=0.5)
    np.testing.assert_array_equal(pdmp_stationary(key=3, **good), pdmp_stationary(key=jax.random.key(3), **good))


# --- the DI path recorders against the per-path definition of their random numbers ---

def _di_reference(model, carry, key, n_steps):
    """One path's segment as its definition reads: ``rng.normal(key, (n_steps, 2))``, step by step."""
    z = rng.normal(key, (n_steps, 2), model.h.dtype)

    def step(c, zz):
        X, V, U = c
        _, Xn, Vn, dU = model.move(X, V, zz[0], zz[1])
        return (Xn, Vn, U + dU), None

    return jax.lax.scan(step, carry, z)[0] if n_steps else carry


@pytest.mark.parametrize("dtype", [jnp.float32, jnp.float64])
def test_di_recorders_match_the_per_path_definition(dtype):
    """The recorders run all paths at once and draw a long segment a block of rows at a time; the
    numbers, hence the paths, are those of each path drawn and stepped on its own (a jitted vmap
    of one path's loop), for segments shorter than, equal to and longer than a block, with a
    remainder; on every device count (the paths are split over the devices).  Equal to a few units in
    the last place: the two programs may contract a multiply-add differently (a wrong number
    would move a path by O(h^1/2) at once)."""
    from dryfric_jax.di import make_di_model
    from dryfric_jax.paths import di_stationary, di_transient

    m = make_di_model(Params.from_nondim(0.05), 2e-3, dtype)
    key = jax.random.key(11)
    steps = (0, 5, 5 + 128, 5 + 128 + 300)
    V = di_transient(m, key, 5, steps, v0=1.0, chunk=4)  # a chunk of 1: padded on 2 devices
    sd = m.ou.stationary_sd()
    eps = float(jnp.finfo(dtype).eps)
    close = lambda a, b: np.testing.assert_allclose(a, np.asarray(b), rtol=16 * eps, atol=16 * eps)  # noqa: E731

    @jax.jit
    def transient(keys, x0):
        def path(k, x):
            c3, out = (x, jnp.asarray(1.0, dtype), jnp.asarray(0.0, jnp.float64)), []
            for i, s in enumerate(np.diff((0,) + steps)):
                c3 = _di_reference(m, c3, jax.random.fold_in(k, i), int(s))
                out.append(c3[1])
            return jnp.stack(out)
        return jax.vmap(path)(keys, x0)

    for c, lo in ((0, 0), (1, 4)):  # two chunks (the second one short)
        kx, kp = jax.random.split(jax.random.fold_in(key, c))
        n = min(4, 5 - lo)
        ref = transient(jax.random.split(kp, n), sd * jax.random.normal(kx, (n,), dtype))
        close(V[lo:lo + n], ref)
    assert np.all(np.diff(V[:, 1:], axis=1) != 0)  # the paths move

    for every, burn in ((3, 300), (128, 0), (200, 7)):
        @jax.jit
        def stationary(keys):
            def path(k):
                x0 = jax.random.normal(jax.random.fold_in(k, 5), (), dtype) * sd
                c3 = _di_reference(m, (x0, jnp.asarray(0.0, dtype), jnp.asarray(0.0, jnp.float64)),
                                   jax.random.fold_in(k, 4), burn)
                c3, out = (c3[0], c3[1], jnp.asarray(0.0, jnp.float64)), []
                for i in range(4):
                    c3 = _di_reference(m, c3, jax.random.fold_in(k, i), every)
                    out.append((c3[1], c3[2]))
                return jnp.stack([o[0] for o in out]), jnp.stack([o[1] for o in out])
            return jax.vmap(path)(keys)

        Vs, Us = di_stationary(m, key, 3, 4, every, burn_steps=burn)
        Vr, Ur = stationary(jax.random.split(key, 3))
        close(Vs, Vr)
        close(Us, Ur)


@pytest.mark.parametrize("dtype", ["float64", "float32"])
def test_di_stationary_records_one_array_with_the_same_numbers(dtype):
    """record="V" or "U" (Fig. 5's histogram and paths, Figs. 4, 7 and 9) holds only that array and gives the
    numbers of record="VU" bit for bit: the chain does not depend on what is stacked."""
    from dryfric_jax.di import make_di_model

    m = make_di_model(Params.from_nondim(0.3, 4.0, 0.2), 0.01, dtype)
    V, U = di_stationary(m, 11, 5, 6, 7, burn_steps=9)
    V1, none1 = di_stationary(m, 11, 5, 6, 7, burn_steps=9, record="V")
    none2, U1 = di_stationary(m, 11, 5, 6, 7, burn_steps=9, record="U")
    assert none1 is None and none2 is None and V.shape == U.shape == (5, 6)
    np.testing.assert_array_equal(V1, V)
    np.testing.assert_array_equal(U1, U)
    assert len(set(V.ravel())) > 20 and np.count_nonzero(U) > 20


def test_di_recorders_take_keys_of_another_generator():
    """rbg keys draw a segment at once through jax.random (no row offsets); jax.random's rbg is not
    invariant under vmap, so only repeatability and sane values are checked."""
    from dryfric_jax.di import make_di_model
    from dryfric_jax.paths import di_stationary, di_transient

    m = make_di_model(Params.from_nondim(0.05), 2e-3)
    key = jax.random.key(3, impl="rbg")
    V = di_transient(m, key, 5, (10, 300))
    np.testing.assert_array_equal(V, di_transient(m, key, 5, (10, 300)))
    Vs, Us = di_stationary(m, key, 3, 4, 150, burn_steps=20)
    assert np.all(np.isfinite(V)) and np.all(np.isfinite(Us)) and np.all(np.abs(V) < 10) and len(set(V[:, 1])) == 5


def test_autocorrelation_standard_error_matches_the_spread_over_replicates():
    """Fig. 4's h(rho)/h(0): its SE over paths (delta method for the ratio) against the actual
    spread of r(k) over 300 independent replicates of 32 AR(1) paths (exact r(k) = 0.95^k).
    The old SE, se(c(k))/c(0), was 5-20x too large at these lags (c(k) and c(0) move together)."""
    from dryfric_jax.paths import autocorrelation

    rng = np.random.default_rng(7)
    phi, n, paths, reps, lags = 0.95, 2000, 32, 300, np.array([1, 5, 20])
    r_all, se_all = [], []
    for _ in range(reps):
        x = np.empty((paths, n))
        x[:, 0] = rng.standard_normal(paths) / np.sqrt(1 - phi**2)  # stationary start
        e = rng.standard_normal((paths, n))
        for t in range(1, n):
            x[:, t] = phi * x[:, t - 1] + e[:, t]
        r, se = autocorrelation(x, 20)
        r_all.append(r[lags])
        se_all.append(se[lags])
    r_all, se_all = np.array(r_all), np.array(se_all)
    sd = r_all.std(0, ddof=1)
    # the sd of an sd over 300 replicates is ~4%: 3.7 of them, plus an O(1/paths) bias of the SE (measured ratios
    # 0.992, 0.996, 0.974; 0.2 was 5 sd: a test audit)
    np.testing.assert_allclose(se_all.mean(0), sd, rtol=0.15)
    # r itself, within 4 SE of the mean over replicates plus the first-order bias of subtracting the grand mean of
    # n paths x points: c(k) - Var(mean), Var(mean) = c(0) (1 + phi) / ((1 - phi) n paths), so r(k) is low by
    # (1 + phi) / (1 - phi) (1 - phi^k) / (n paths) (0.4 SE at lag 20; the old allowance 3/n was 21 SE at lag 1)
    bias = (1 + phi) / (1 - phi) * (1 - phi**lags) / (n * paths)
    assert np.all(np.abs(r_all.mean(0) - (phi**lags - bias)) < 4 * sd / np.sqrt(reps)), (r_all.mean(0), phi**lags)


# --- bad arguments: ValueError naming the argument and its range ---

@pytest.fixture(scope="module")
def di_model():
    from dryfric_jax.di import make_di_model

    return make_di_model(Params.from_nondim(0.05), 2e-3)


_V = np.random.default_rng(0).standard_normal((4, 50))  # 4 paths, 50 samples
_V_NAN = np.where(np.arange(50) == 3, np.nan, _V)


@pytest.mark.parametrize("call,match", [
    (lambda m: di_transient(m, 0, 0, [10]), "^n_paths must be an integer >= 1"),  # was "need at least one array"
    (lambda m: di_transient(m, 0, 3, []), "^record_steps must be a non-empty sequence"),  # was an IndexError
    (lambda m: di_transient(m, 0, 3, [10, 5]), "^record_steps must"),
    (lambda m: di_transient(m, 0, 3, [10.5]), "^record_steps must"),  # was taken as 10
    (lambda m: di_transient(m, 0, 3, 10), "^record_steps must"),
    (lambda m: di_transient(m, 0, 3, [10], chunk=0), "^chunk must be an integer >= 1"),  # was a ZeroDivisionError
    (lambda m: di_transient(m, 0, 3, [10], v0=math.nan), "^v0 must be a finite number"),
    (lambda m: di_transient(m, "x", 3, [10]), "^key must be a seed"),
    (lambda m: di_transient(dict(FIG3), 0, 3, [10]), "^model must be a DIModel"),
    (lambda m: di_stationary(m, 0, 0, 4), "^n_paths must be an integer >= 1"),  # was an IndexError
    (lambda m: di_stationary(m, 0, 2, 0), r"^n_records must be an integer in \[1, 4294967294\]"),
    (lambda m: di_stationary(m, 0, 2, 4, every=0), r"^every must be an integer in \[1, 2147483647\]"),  # was accepted
    (lambda m: di_stationary(m, 0, 2, 4, every=-1), r"^every must be an integer in \[1, 2147483647\]"),  # was accepted
    (lambda m: di_stationary(m, 0, 2, 4, every=True), r"^every must be an integer in \[1, 2147483647\]"),
    (lambda m: di_stationary(m, 0, 2, 4, burn_steps=-5), r"^burn_steps must be an integer in \[0, "),  # was accepted
    (lambda m: di_stationary(m, 0, 2, 4, record="X"), "^record must be one of 'VU', 'V' or 'U'"),
    (lambda m: di_stationary(m, 0, 2, 4, record=["V"]), "^record must be one of 'VU', 'V' or 'U'"),
    (lambda m: autocorrelation(_V, 60), r"^max_lag must be an integer in \[0, 49\]"),  # was a broadcast error
    (lambda m: autocorrelation(_V, -1), r"^max_lag must be an integer in \[0, 49\]"),  # was an IndexError
    (lambda m: autocorrelation(_V, 2.0), r"^max_lag must be an integer in \[0, 49\]"),
    (lambda m: autocovariance(_V, 50), r"^max_lag must be an integer in \[0, 49\]"),
    (lambda m: autocorrelation(_V[:1], 5), "^V must be a real array .* at least 2 paths"),  # was an all-NaN SE
    (lambda m: autocovariance(_V[:1], 5), "^V must be a real array .* at least 2 paths"),
    (lambda m: autocorrelation(_V[0], 5), "^V must be a real array of shape"),
    (lambda m: autocorrelation(_V_NAN, 5), "^V must be finite"),
    (lambda m: autocovariance(_V * 1e200, 5), r"^V must have \|V\| <= 1e\+75"),  # was inf and NaN, silently
    (lambda m: autocorrelation(np.ones((3, 10)), 2), "^V must vary"),  # r = 0/0
    (lambda m: autocorrelation(_V, 5, center="yes"), "^center must be True or False"),
    # "a recorded segment must have fewer than 2**31 steps", naming none of them
    (lambda m: di_stationary(m, 0, 2, 3, burn_steps=2**31), r"^burn_steps must be an integer in \[0, 2147483647\]"),
    (lambda m: di_stationary(m, 0, 2, 3, every=2**31), r"^every must be an integer in \[1, 2147483647\] \(steps"),
    (lambda m: di_transient(m, 0, 2, [1, 2**31 + 5]), r"^record_steps must be at most 2147483647 apart"),
])
def test_path_recorders_refuse_bad_arguments_by_name(di_model, call, match):
    with pytest.raises(ValueError, match=match):
        call(di_model)


def test_path_recorders_take_an_int_seed_as_the_api_does(di_model):
    """An integer seed means jax.random.key(seed), as in estimate_diffusivity (it was a JAX
    TypeError); numpy integers and 0-d arrays are counts like Python ints."""
    k = jax.random.key(5)
    V = di_transient(di_model, 5, 3, np.array([0, 10]))
    np.testing.assert_array_equal(V, di_transient(di_model, k, 3, [0, 10]))
    a = di_stationary(di_model, np.int64(5), np.int64(2), np.array(3), 2, 1)
    for x, y in zip(a, di_stationary(di_model, k, 2, 3, 2, 1)):
        np.testing.assert_array_equal(x, y)
    r, se = autocorrelation(_V, np.int64(49))
    assert r.shape == se.shape == (50,) and r[0] == 1.0 and np.all(np.isfinite(se))


@pytest.mark.parametrize("center", [False, True])
def test_autocovariance_is_the_lagged_mean_product_at_every_lag(center):
    """The FFT autocovariance against its definition, the mean over the n - k pairs of each path at
    every lag up to samples - 1, then over paths (a factor 1.05 on it, or a circular FFT without
    the zero padding, passed every other test of this file)."""
    V = np.random.default_rng(3).normal(0.3, 1.0, (4, 37)).cumsum(1)  # correlated, not centred
    W = V - V.mean() if center else V
    n = V.shape[1]
    direct = np.array([[np.mean(w[: n - k] * w[k:]) for k in range(n)] for w in W])
    c, se = autocovariance(V, n - 1, center=center)
    np.testing.assert_allclose(c, direct.mean(0), rtol=1e-12, atol=1e-12 * np.abs(direct).max())
    np.testing.assert_allclose(se, direct.std(0, ddof=1) / 2, rtol=1e-9, atol=1e-12 * np.abs(direct).max())


@pytest.mark.parametrize("tau", [1e-3, 0.1, 10.0, 1e3])
def test_the_stationary_start_is_the_noise_law(tau):
    """The paths start with X from the stationary law of the OU noise, N(0, 1/tau') (no test saw
    a start 3 times too wide: the tests of the paths run where one step forgets X)."""
    from dryfric_jax.di import make_di_model

    p = Params.from_nondim(tau)
    for h in (1e-3, 0.1):  # h/tau from 1e-6 to 100
        # 1 - m2^2 ~ 2h/tau carries the OU constants' rounding times tau/h (2.7e-12 at tau/h = 1e6); the
        # rel = 1e-12 written here was 3e-11 in effect (pytest's absolute 1e-12 on an sd of 0.03), until the
        # conftest made rel alone relative
        rel = max(1e-13, 1e-16 * tau / h)
        assert float(make_di_model(p, h * p.tau0).ou.stationary_sd()) == pytest.approx(1 / math.sqrt(tau), rel=rel)


def test_a_float32_model_whose_noise_decay_rounds_to_1_is_refused():
    """At h/tau = 1e-8 exp(-h/tau) is 1 in float32: the start's sd was inf and the paths inf or NaN."""
    from dryfric_jax.di import make_di_model

    p = Params.from_nondim(1e7)
    m = make_di_model(p, 0.1 * p.tau0, "float32")
    for call in (lambda: di_transient(m, 0, 2, [0, 4]), lambda: di_stationary(m, 0, 2, 3)):
        with pytest.raises(ValueError, match=r"^model must have a noise decay exp\(-h/tau\) < 1 .*float64"):
            call()
    V = di_transient(make_di_model(p, 0.1 * p.tau0), 0, 2, [0, 4])  # float64: fine
    assert np.all(np.isfinite(V))


@pytest.mark.parametrize("args,match", [
    ((dict(FIG3), 6.7e-4), "^params must be a dryfric_jax.Params"),  # was an AttributeError
    ((Params(**FIG3), 1.0), r"^h must be in \[6.7e-14, 0.0067\] s"),  # above 0.1*min(tau0, tau_L): was accepted
    ((Params(**FIG3), -1e-3), r"^h must be in \["),
    ((Params(**FIG3), 6e-14), r"^h must be in \[6.7e-14, "),  # > 1e12 steps per tau0 (5e-324: inf)
    ((Params(**FIG3), math.nan), r"^h must be in \["),
    ((Params(**FIG3), "1e-3"), r"^h must be in \["),
    ((Params(**FIG3), 6.7e-4, jnp.float16), "^dtype must be one of"),  # was accepted
    ((Params(**FIG3), 6.7e-4, None), "^dtype must be one of"),
])
def test_make_di_model_checks_its_arguments_as_the_planner_does(args, match):
    from dryfric_jax.di import make_di_model

    with pytest.raises(ValueError, match=match):
        make_di_model(*args)


def test_make_di_model_default_step_and_dtype_names():
    """h = None is the planner's default step (it was a TypeError); a dtype may be named."""
    from dryfric_jax.di import make_di_model
    from dryfric_jax.plan import default_h

    p = Params(**FIG3)
    assert float(make_di_model(p, None).h) == pytest.approx(default_h(p) / p.tau0, rel=1e-15)
    assert make_di_model(p, np.float32(1e-3), "float32").h.dtype == jnp.float32


@pytest.mark.parametrize("center", [False, True])
def test_autocorrelation_is_the_ratio_of_the_mean_lagged_products(center):
    """r(k) = mean_i c_i(k) / mean_i c_i(0) and its delta-method SE sd_i(c_i(k) - r(k) c_i(0), ddof=1)
    / (sqrt(n) mean_i c_i(0)), c_i the mean over the T - k pairs of path i, by a direct O(T^2) sum
    (the SE with ddof=0, 6% smaller with 4 paths, passed the replicate test's 20%)."""
    V = np.random.default_rng(4).normal(0.5, 1.0, (4, 23)).cumsum(1)  # correlated, mean far from 0
    W = V - V.mean() if center else V
    n = V.shape[1]
    c = np.array([[np.mean(w[: n - k] * w[k:]) for k in range(n)] for w in W])
    r = c.mean(0) / c[:, 0].mean()
    se = (c - r * c[:, :1]).std(0, ddof=1) / (2 * c[:, 0].mean())
    got_r, got_se = autocorrelation(V, n - 1, center=center)
    np.testing.assert_allclose(got_r, r, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(got_se, se, rtol=1e-9, atol=1e-12)
    assert got_r[0] == 1.0 and got_se[0] == pytest.approx(0.0, abs=1e-15)


def test_the_moments_default_to_the_raw_covariance_and_the_centred_correlation():
    """autocovariance's default is the raw moment (the pure dry friction case, mean 0), autocorrelation's
    the centred one (Fig. 4's h(rho)/h(0)); a swapped default passed every test."""
    V = np.random.default_rng(5).normal(2.0, 1.0, (3, 12))
    for f, default in ((autocovariance, False), (autocorrelation, True)):
        for a, b in zip(f(V, 5), f(V, 5, center=default)):
            np.testing.assert_array_equal(a, b)
        assert not np.allclose(f(V, 5)[0], f(V, 5, center=not default)[0])


def test_record_steps_may_repeat_and_are_not_bools(di_model):
    """Non-decreasing, as the message says: a repeated step count records the same V twice (a
    zero-length segment); a bool is no step count (it was taken as 0 or 1)."""
    from dryfric_jax.paths import _record_steps

    assert _record_steps(np.array([0, 4, 4, 9])) == [0, 4, 4, 9]
    for bad in ([True], [0, np.bool_(True)]):
        with pytest.raises(ValueError, match="^record_steps must"):
            _record_steps(bad)
    V = di_transient(di_model, 0, 2, [0, 4, 4])
    assert np.all(V[:, 0] == 1.0) and np.array_equal(V[:, 1], V[:, 2]) and np.all(V[:, 1] != 1.0)


def test_the_model_refusals_name_functions_that_exist():
    """Each path function's refusal of a wrong model names the constructor to use, and that constructor is
    what it says: dryfric_jax.make_pdmp_model did not exist (a PDMP audit: an AttributeError for a user who
    followed the message)."""
    import re

    import dryfric_jax as dj
    from dryfric_jax import paths

    di = dj.make_di_model(dj.Params.from_nondim(1.0, 1.0, 0.0), 0.01)
    pd = dj.make_pdmp_model(dj.Params.from_nondim(1.0, 1.0, 0.0), 0.1)
    for call, wrong in ((lambda m: paths.pdmp_stationary(m, 0, n_paths=2, n_records=2, dt_rec=0.1, burn=0.0), di),
                        (lambda m: paths.di_stationary(m, 0, n_paths=2, n_records=2, every=1, burn_steps=0), pd)):
        with pytest.raises(ValueError) as e:
            call(wrong)
        name = re.search(r"from dryfric_jax\.(\w+)\(", str(e.value)).group(1)
        assert callable(getattr(dj, name)) and name in dj.__all__, str(e.value)
