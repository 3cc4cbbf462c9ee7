"""The paper's mean long-excursion duration of the DI by counting releases (dryfric_jax.durations),
against the PDMP's excursions (an independent method: its engine ends an HLE at the grid's release state)."""
import math
import re
import warnings

import numpy as np
import pytest

import dryfric_jax as dj
from dryfric_jax.durations import di_long_excursion_duration
from dryfric_jax.params import FIG3, Params
from dryfric_jax.plan import default_h

FAST = Params(10.0, 3.84, 0.125, 0.067, 0.342)  # Fig. 3's fastest point: many reversals through V = 0


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore::dryfric_jax.DryfricWarning")
def test_the_bridged_count_agrees_with_the_pdmp_and_the_raw_one_does_not():
    """At Gamma = 10, tau = 0.125 s (Fig. 3's fastest point, tau/h = 187 at the D estimator's h) against the PDMP
    at delta = 0.03125, an independent method (0.4376 +- 0.0023 with 131072 excursions; 0.4405 at 0.0625, falling
    toward the DI's 0.4326 +- 0.0016 at h/16).  The count's default step here is tau/700 = h/3.7: bridged (module
    docstring) it agrees with the PDMP within 3 SE; raw (the chain's own releases only, a discretely monitored
    barrier) it lies > 5 SE above.  At h the bridge removes at least 4/5 of the raw count's bias, and the two steps
    agree to within that bias plus 3 SE (the bias falls like h).  Measured (0.2.11): PDMP 0.4413 +- 0.0060 (20 072
    excursions; 56 of the test's 70 s were the PDMP's with 40 000, 33 s with 20 000); bridged 0.4337 (-2.1 SE), raw
    0.4793 (+10.0 SE); at h 0.4428 and raw 0.5339, so coarse - fine = 0.009 against a bound of 0.029."""
    from dryfric_jax.durations import default_duration_h

    h = default_h(FAST)
    assert default_duration_h(FAST) == FAST.tau / 700 == pytest.approx(h * 187 / 700, rel=0.01)
    pd = dj.estimate_diffusivity(FAST, 3, method="pdmp", delta=0.03125, n_excursions=20_000)
    fine = di_long_excursion_duration(FAST, 1, n_excursions=40_960)
    raw = di_long_excursion_duration(FAST, 1, n_excursions=40_960, bridge=False)
    coarse = di_long_excursion_duration(FAST, 2, h=h, n_excursions=40_960)
    coarse_raw = di_long_excursion_duration(FAST, 2, h=h, n_excursions=40_960, bridge=False)
    assert pd.n_truncated == fine.n_truncated == raw.n_truncated == coarse.n_truncated == 0
    assert fine.h == default_duration_h(FAST) and fine.bridge and not raw.bridge
    se = lambda a, b: math.hypot(a, b) / 1.96  # noqa: E731
    ref, ref_se = pd.mean_duration, lambda r: se(r.ci, pd.mean_duration_ci)  # noqa: E731
    assert abs(fine.mean - ref) <= 3 * ref_se(fine), (fine, ref)
    assert raw.mean - ref > 5 * ref_se(raw), (raw, ref)
    assert coarse.mean - fine.mean <= (coarse_raw.mean - fine.mean) / 5 + 3 * se(coarse.ci, fine.ci), (coarse, fine)
    assert coarse_raw.mean - fine.mean > 5 * se(coarse_raw.ci, fine.ci)


def test_duration_is_reproducible_and_shorter_than_the_cycle():
    """Same seed, same bits; another seed, other bits.  At Fig. 3's point a regeneration cycle (the D
    estimator's mean duration) spans one or more of the paper's excursions: about 1.9 of them."""
    p = Params(**FIG3)
    a = di_long_excursion_duration(p, 7, n_excursions=128)
    assert a == di_long_excursion_duration(p, 7, n_excursions=128)
    assert a.mean != di_long_excursion_duration(p, 8, n_excursions=128).mean
    cyc = dj.estimate_diffusivity(p, 2, n_excursions=2000)
    assert a.mean + a.ci < cyc.mean_duration - cyc.mean_duration_ci
    assert a.n_excursions >= 128 and a.n_lanes == 32  # default_lanes(128): 2^round(log2(42.7)) = 32
    assert a.lane_steps > a.n_excursions * a.mean / a.h  # the lanes ran their excursions (and their seeks)


def test_an_excursion_in_flight_at_the_bound_is_counted_not_hidden():
    """With max_steps near a lane's first excursion, some are in flight at the bound: counted in n_truncated and
    warned about, the mean from the others (biased low, as documented), never a NaN; with fewer than 2 ended, a
    ValueError names max_steps."""
    p = Params(**FIG3)
    full = di_long_excursion_duration(p, 3, n_excursions=128, n_lanes=128)
    need = int(full.mean / full.h * 1.5)  # steps for one LE plus the seek, about the median lane's
    with pytest.warns(dj.DryfricWarning, match=r"stopped \d+ of the 128 long excursions asked, with \d+ in flight"):
        cut = di_long_excursion_duration(p, 3, n_excursions=128, n_lanes=128, max_steps=need)
    assert 0 < cut.n_truncated <= 128 and cut.max_steps == -(-need // 128) * 128
    assert math.isfinite(cut.mean) and cut.mean < full.mean
    with pytest.raises(ValueError, match="max_steps = 128 is too small"):
        di_long_excursion_duration(p, 3, n_lanes=16, max_steps=128)


@pytest.mark.parametrize("kw,match", [
    (dict(n_excursions=1), "n_excursions"), (dict(n_excursions=2.5), "n_excursions"), (dict(n_lanes=0), "n_lanes"),
    (dict(max_steps=0), "max_steps"), (dict(dtype="float16"), "dtype"), (dict(h=-1.0), "h"),
    (dict(max_steps=1.5), "max_steps"), (dict(n_excursions=2**40 + 1), "n_excursions"), (dict(bridge=1), "bridge"),
    (dict(bridge="no"), "bridge"),
])
def test_bad_arguments_are_refused_by_name(kw, match):
    with pytest.raises(ValueError, match=match):
        di_long_excursion_duration(Params(**FIG3), 0, **{"n_lanes": 8, **kw})


def test_float32_agrees_with_float64():
    p = Params(**FIG3)
    a = di_long_excursion_duration(p, 4, n_excursions=512)
    b = di_long_excursion_duration(p, 5, n_excursions=512, dtype="float32")
    assert abs(a.mean - b.mean) <= 3 * math.hypot(a.ci, b.ci) / 1.96, (a, b)
    assert np.isfinite([b.mean, b.ci]).all() and b.dtype == "float32"


def test_other_counts_and_bounds_do_not_recompile():
    """A figure's points differ in n_excursions and max_steps: one compiled loop per lane count serves them."""
    import jax

    from dryfric_jax import durations, sharding

    p = Params(**FIG3)
    di_long_excursion_duration(p, 0, n_lanes=32, n_excursions=32, max_steps=10**6)
    devices = tuple(jax.local_devices())
    loops = sharding._compiled.cache_info().currsize
    f = sharding._compiled(durations._lane_blocks, (("block", 128), ("bridge", True), ("n_dev", len(devices))),
                           (False, True, True, True, True, False, False), devices)  # the loop that call compiled
    assert sharding._compiled.cache_info().currsize == loops
    n = f._cache_size()
    assert n >= 1
    di_long_excursion_duration(p, 1, n_lanes=32, n_excursions=64, max_steps=10**7)
    assert f._cache_size() == n and sharding._compiled.cache_info().currsize == loops


def test_max_steps_beyond_the_32_bit_block_count_is_refused():
    from dryfric_jax import durations

    with pytest.raises(ValueError, match="max_steps"):
        di_long_excursion_duration(Params(**FIG3), 0, n_lanes=8, max_steps=durations.MAX_STEPS + 1)


def test_bad_lane_counts_and_dtypes():
    """2^24 lanes ran out of memory instead of a ValueError (an audit): the estimator's bound on a block's normals,
    lanes x K <= 2^28, holds here too: 2^21 lanes of 128 steps (2^22 were taken, ~18 GB: another audit).  A dtype
    object is taken like its name (``jnp.float32`` was refused)."""
    import jax.numpy as jnp

    from dryfric_jax import durations

    p = Params(**FIG3)
    assert durations.MAX_COUNT_LANES == 2**28 // 128 == 2**21
    for n in (2**21 + 1, 2**22):
        with pytest.raises(ValueError, match=r"^n_lanes must be an integer in \[1, 2097152\] \(2\^28 / the block"):
            di_long_excursion_duration(p, 0, n_lanes=n)
    for bad in (0, -4, 2.5, True):  # the sweep's planner (check_duration_run) checks them too
        with pytest.raises(ValueError, match=r"^n_lanes must be an integer in \[1, 2097152\]"):
            durations.check_duration_run(p, None, 64, n_lanes=bad)
    a = di_long_excursion_duration(p, 2, n_excursions=16, dtype=jnp.float32)
    assert a == di_long_excursion_duration(p, 2, n_excursions=16, dtype="float32")
    with pytest.raises(ValueError, match="dtype"):
        di_long_excursion_duration(p, 0, n_lanes=8, dtype=jnp.float16)


def test_default_lanes():
    """The power of 2 nearest n / 3, within [32, 256] (measured fastest on 2 cores: RESULTS.md)."""
    from dryfric_jax.durations import default_lanes

    assert [default_lanes(n) for n in (2, 32, 135, 136, 180, 400, 1024, 10**6)] == [32, 32, 32, 64, 64, 128, 256, 256]


def test_mean_ci_and_step_counts_from_the_lanes(monkeypatch):
    """The arithmetic after the loop, on a fake loop: the mean and sd over all the lanes' excursions (their
    durations given through the sums N, S, Q), the CI Student's t_{N-1} s / sqrt(N) (6 excursions: t_5 = 2.571, a
    table's value), an excursion in flight at the bound counted and warned about, lane_steps the lanes' steps and
    loop_steps lanes x the blocks the loop ran (stopped lanes idle in it)."""
    from dryfric_jax import durations

    d = [[100, 300], [200], [], [50, 150, 400]]
    N = np.array([len(x) for x in d])
    S = np.array([sum(x) for x in d])
    Q = np.array([float(sum(v * v for v in x)) for x in d])
    stopped = np.array([True, True, True, False])
    started = np.array([True, True, False, True])  # lane 3 in flight at the bound, lane 2 never started one
    steps = np.array([500, 700, 1280, 900])
    monkeypatch.setattr(durations, "_run", lambda *a, **k: (N, S, Q, stopped, started, steps, 10, "max_steps"))
    h = 1e-3
    with pytest.warns(dj.DryfricWarning, match="stopped 6 of the 6 long excursions asked, with 1 in flight"):
        r = di_long_excursion_duration(Params(**FIG3), 0, h=h, n_lanes=4, n_excursions=6)
    x = h * np.array([100, 300, 200, 50, 150, 400])
    assert r.mean == pytest.approx(x.mean(), rel=1e-12)
    assert r.ci == pytest.approx(2.571 * x.std(ddof=1) / math.sqrt(6), rel=1e-3)
    assert (r.n_excursions, r.n_requested, r.n_truncated, r.lane_steps, r.loop_steps) == (6, 6, 1, 3380, 4 * 10 * 128)
    assert len(r.warnings) == 2 and r.warnings[1].startswith("n_excursions = 6 < 100: the t CI under-covers")


def test_loop_steps_count_the_idle_lanes_too():
    """After the stop each lane finishes its excursion in flight and then idles until the last one ends:
    loop_steps is lanes x the loop's steps, whole blocks, > lane_steps."""
    r = di_long_excursion_duration(FAST, 5, n_excursions=256, n_lanes=64)
    assert r.loop_steps % (64 * 128) == 0 and r.loop_steps > r.lane_steps


def test_the_stopping_rule_is_unbiased_and_a_horizon_cut_is_not():
    """The design (module docstring): once the lanes' total reaches n_excursions no lane starts another and those
    in flight are finished, so whether an excursion counts is decided before its duration is drawn (Wald).  With
    2048 lanes and ~2 excursions each the rule decides most of them, and the mean agrees with 32 lanes of ~2000
    each (3 SE).  Every lane running a fixed horizon of 3 mean durations and the excursions in flight there
    dropped (the bound max_steps does that) leaves out the long ones: far below (-35% here, -32 +- 0.5% over 20
    runs of 256 lanes: RESULTS.md).  At the D estimator's h, where excursions are short."""
    h = default_h(FAST)
    ref = di_long_excursion_duration(FAST, 11, h=h, n_excursions=2**16, n_lanes=32)
    few = di_long_excursion_duration(FAST, 12, h=h, n_excursions=4096, n_lanes=2048)
    with pytest.warns(dj.DryfricWarning, match="in flight: left out, so the mean is biased low"):
        cut = di_long_excursion_duration(FAST, 13, h=h, n_excursions=10**9, n_lanes=2048,
                                         max_steps=int(3 * ref.mean / h), max_work=1e18)
    assert cut.n_truncated > 1000 and few.n_truncated == ref.n_truncated == 0
    se = lambda a, b: math.hypot(a.ci, b.ci) / 1.96  # noqa: E731
    assert abs(few.mean - ref.mean) <= 3 * se(few, ref), (few, ref)
    assert ref.mean - cut.mean > 5 * se(cut, ref), (cut, ref)


def test_the_lanes_spread_matches_the_pooled_sd():
    """The CI treats the excursions of all lanes as i.i.d.: in discrete time X overshoots the threshold, which
    could correlate an excursion with the next in a lane.  The spread of the lanes' sums around the ratio (a
    batch-means variance, which such a correlation would inflate) agrees with the pooled s^2 / N: their ratio is
    within the 99.9% band of a chi^2 with 63 df (Wilson-Hilferty).  64 lanes of ~512 excursions, the D estimator's
    h (the coarsest: the largest overshoot)."""
    import jax
    import jax.numpy as jnp

    from dryfric_jax import durations
    from dryfric_jax.di import make_di_model

    model = make_di_model(FAST, default_h(FAST), jnp.float64)
    N, S, Q, stopped, _, _, _, _ = durations._run(model, jax.random.split(jax.random.key(21), 64), 64 * 512,
                                                  10**6, block=128)
    assert stopped.all()
    n = N.sum()
    r = S.sum() / n
    pooled = (Q.sum() - S.sum() * r) / (n - 1) / n
    batch = ((S - r * N) ** 2).sum() / (64 * 63) / N.mean() ** 2
    k, z = 63, 3.29
    lo, hi = ((1 - 2 / (9 * k) + s * z * math.sqrt(2 / (9 * k))) ** 3 for s in (-1, 1))
    assert lo < batch / pooled < hi, batch / pooled


def test_the_estimators_refusals_hold_here():
    """tau_L = inf with |gamma_bar| >= Delta has no stationary state (the particle runs away): it gave a number
    here (20.8 s, 9 of 32 lanes truncated) where estimate_diffusivity refuses; tau_L below the simulable range too."""
    with pytest.raises(ValueError, match="gamma_bar must satisfy"):
        di_long_excursion_duration(Params(10.0, 3.84, 0.125, math.inf, 1.05 * 3.84), 0, n_lanes=8)
    with pytest.raises(ValueError, match="tau_L must be >= 1e-60 tau0"):
        di_long_excursion_duration(Params(10.0, 3.84, 0.125, 1e-70, 0.0), 0, n_lanes=8)


def _fake_loop(monkeypatch, seen):
    from dryfric_jax import durations

    def run(model, keys, n_excursions, max_blocks, block, bridge, **kw):
        seen.append(model.h.dtype if bridge else "raw")
        n = keys.shape[0]
        ones = np.ones(n, bool)
        S = np.arange(1, n + 1) * 100
        return np.ones(n, np.int64), S, S.astype(float) ** 2, ones, ones, np.full(n, 1000), 8, "n_excursions"
    monkeypatch.setattr(durations, "_run", run)


def test_float32_where_unsafe_runs_float64_and_says_so(monkeypatch):
    """As the estimator: h/tau below 1e-4 rounds the OU decay in float32, so the chain runs in float64 with a
    DryfricWarning, and the result says which dtype ran."""
    import jax.numpy as jnp

    seen = []
    _fake_loop(monkeypatch, seen)
    p = Params(**FIG3)
    with pytest.warns(dj.DryfricWarning, match="float32 is not safe here"):
        r = di_long_excursion_duration(p, 0, h=3e-5, n_lanes=4, n_excursions=2, dtype="float32")
    assert r.dtype == "float64" and seen == [jnp.float64]
    r = di_long_excursion_duration(p, 0, n_lanes=4, n_excursions=2, dtype="float32")
    assert r.dtype == "float32" and seen[-1] == jnp.float32
    assert not di_long_excursion_duration(p, 0, n_lanes=4, n_excursions=2, bridge=False).bridge and seen[-1] == "raw"


def test_tau_below_a_few_steps_is_flagged(monkeypatch):
    """At tau / h < MIN_TAU_STEPS the noise decorrelates within a few steps: releases happen at any X and the
    count is not the paper's long excursion (white noise at tau = 1e-5 s, h = 1.6e-3 s gave 14 s); warned.  The
    default step keeps tau/h >= 700, so only an h asked for can warn.  Here (tau' = 6e-5) tau/20 is far too coarse
    for the band (q = 1500: the band's warning instead), and the default step, the band rule's, makes the count
    too dear: refused, naming that step."""
    from dryfric_jax.durations import MIN_TAU_STEPS

    _fake_loop(monkeypatch, [])
    p = Params(0.16, 1.0, 1e-5, math.inf, 0.0)
    with pytest.warns(dj.DryfricWarning, match=f"tau/h = .* < {MIN_TAU_STEPS}: the noise decorrelates"):
        di_long_excursion_duration(p, 0, h=default_h(p), n_lanes=4, n_excursions=2)
    with pytest.warns(dj.DryfricWarning) as seen:
        di_long_excursion_duration(p, 0, h=p.tau / (2 * MIN_TAU_STEPS), n_lanes=4, n_excursions=2)
    assert not any("decorrelates" in str(w.message) for w in seen)
    (said,) = [str(w.message) for w in seen if "coarse for the count" in str(w.message)]
    # beyond q = 0.4 the measured values, not 30q% (a "~4.6e+04%" overstated it: an audit measured +115% at q = 15)
    assert "X moves 39 of the stuck band's half-width" in said and "by more than 10% (measured +20-26% at q" in said
    with pytest.raises(ValueError, match=r"max_work must be .*lower them; its step tau/2\.06e\+06 keeps "
                                         r"X's step variance against the stuck band at q = 0\.0155"):
        di_long_excursion_duration(p, 0, n_lanes=4, n_excursions=2)


def test_a_step_held_to_the_counts_rules_is_named_and_an_unending_count_refused(tmp_path):
    """A sweep's h is held to the count's rules (sweep.duration_h): where that step is refused, the refusal names
    tau and the count's step, not an h of 2.3e-15 s the user never gave (an audit: 'dryfric sweep --tau 1e-6
    --durations 64 --h 1e-4').  A count whose predicted LE alone exceeds the loop's bound MAX_STEPS is refused
    whatever max_work: a max_work of 1e17 passed one at tau' = 1e-4 that no LE could end (an audit)."""
    from dryfric_jax import durations, sweep

    with pytest.raises(ValueError, match=r"^durations: tau = 1e-06 s is too short for the long-excursion count: its "
                                         r"step tau/4\.38e\+08 = 2\.29e-15 s \(the rules of "):
        sweep.run_sweep(sweep.grid(Gamma=[50.0], tau=[1e-6]), str(tmp_path / "s.jsonl"), durations=64, h=1e-4)
    q = Params.from_nondim(1e-4)
    assert durations.predicted_le_steps(q, durations.default_duration_h(q)) > durations.MAX_STEPS
    with pytest.raises(ValueError, match=r"^the predicted long excursion, 3\.23e\+11 steps of h = .* exceeds the "
                                         r"loop's bound of 2\.75e\+11 steps: no count could end"):
        durations.check_duration_run(q, None, 64, max_work=1e17)


def test_a_run_predicted_beyond_max_work_is_refused_before_it_starts(monkeypatch):
    """h = 1e-10 s at Fig. 3's point ran to its bound (~15 min on 2 cores, an audit estimate) and then failed: the
    estimator's work prediction (limits.check_work, for n_excursions excursions) refuses it at once."""
    from dryfric_jax import durations

    monkeypatch.setattr(durations, "_run", lambda *a, **k: pytest.fail("ran"))
    p = Params(**FIG3)
    with pytest.raises(ValueError, match=r"max_work must be >= .* \(here for the 2048 long excursions "
                                         r"\(n_excursions\) counted in 256 lanes, each of which also seeks"):
        di_long_excursion_duration(p, 0, h=1e-10)
    with pytest.raises(ValueError, match="max_work must be a finite number"):
        di_long_excursion_duration(p, 0, max_work=float("nan"))


@pytest.mark.parametrize("n,lanes,runs", [(2, None, 64), (2, 1024, 2048), (2048, None, 2304), (100, 8, 108)])
def test_the_work_predicted_is_that_of_the_excursions_the_lanes_run(monkeypatch, n, lanes, runs):
    """Every lane seeks its first LE and finishes the one in flight at the stop, so the lanes run about
    max(n, lanes) + lanes LEs: by hand, 2 asked in the default 32 lanes run 64, in 1024 lanes 2048; 2048 in the
    default 256 lanes 2304; 100 in 8 lanes 108.  The prediction for n alone let 2 asked in 32 lanes run 34 times a
    max_work it passed (an audit).  The limit is the estimator's prediction (limits.check_work) for ``runs`` LEs:
    refused just below it, accepted at it."""
    from dryfric_jax import durations
    from dryfric_jax.limits import check_work

    monkeypatch.setattr(durations, "_run", lambda *a, **k: pytest.fail("ran"))
    p = Params(**FIG3)
    h = durations.default_duration_h(p)
    need = check_work(p.tau_nd, p.tau_L_nd, p.gamma_bar_nd, p.tau0 / h, runs, 1e300)
    kw = {} if lanes is None else dict(n_lanes=lanes)
    with pytest.raises(ValueError, match=r"^max_work must be >= "):
        durations.check_duration_run(p, h, n, max_work=need * (1 - 1e-9), **kw)
    durations.check_duration_run(p, h, n, max_work=need * (1 + 1e-9), **kw)
    with pytest.raises(ValueError, match=r"^max_work must be >= "):
        di_long_excursion_duration(p, 0, n_excursions=n, max_work=need * (1 - 1e-9), **kw)


def test_fast_noise_floors_the_predicted_excursion_and_the_loop_bound_is_planned_from_it(monkeypatch):
    """For fast noise the LEs grow like 1/sqrt(tau') while the estimator's predicted duration stays at
    min(1, tau_L') tau0: at tau' = 1e-3, tau_L = inf, the work predicted was 1/30 of what the lanes ran and the
    fixed loop bound of 1e8 steps truncated a count of 64 (0.2.11).  By hand there: the floor 0.25/sqrt(1e-3) tau0
    at tau0/h steps, for the 64 + 32 LEs of 32 lanes, is the limit (refused just below, accepted at it), and the
    loop's default bound is 50 x (64/32 + 2) such LEs (max_steps_for): 1.1e9 steps at tau/h = 700, 2e11 at the
    default step, whose X variance against the band is 0.0155 (1 - e^{-2h/tau} = 0.0155 tau', tau/h = 1.29e5).  At
    Fig. 3's point the floor is below the estimator's prediction, so nothing changes there, and the bound stays
    1e8."""
    from dryfric_jax import durations
    from dryfric_jax.limits import check_work, log_duration_scale

    got = {}

    def fake_run(model, keys, n, max_blocks, **k):
        got["max_blocks"] = max_blocks
        raise RuntimeError("planned")

    monkeypatch.setattr(durations, "_run", fake_run)
    p = Params.from_nondim(1e-3)
    le = 0.25 / math.sqrt(1e-3)
    assert durations.le_duration_floor(p) == pytest.approx(le, rel=1e-12)
    ratio = -2 / math.log(1 - 0.0155e-3)  # tau/h of the default step
    assert ratio == pytest.approx(1.29e5, rel=1e-3)
    need = 96 * le * ratio / 1e-3
    with pytest.raises(ValueError, match=r"^max_work must be >= .* predicted mean duration >= 7\.91 tau0"):
        durations.check_duration_run(p, None, 64, max_work=need * (1 - 1e-9))
    durations.check_duration_run(p, None, 64, max_work=need * (1 + 1e-9))
    assert durations.default_max_steps(p, p.tau / 700, 64) == int(50 * (64 / 32 + 2) * le * 700 / 1e-3)
    bound = 50 * (64 / 32 + 2) * le * ratio / 1e-3
    with pytest.raises(RuntimeError, match="planned"):
        di_long_excursion_duration(p, 0, n_excursions=64)
    assert got["max_blocks"] == pytest.approx(bound / 128, rel=1e-9)
    with pytest.raises(RuntimeError, match="planned"):  # a bound given is kept
        di_long_excursion_duration(p, 0, n_excursions=64, max_steps=1000)
    assert got["max_blocks"] == 8
    f = Params(**FIG3)
    assert durations.le_duration_floor(f) < math.exp(log_duration_scale(f.tau_nd, f.tau_L_nd, f.gamma_bar_nd))
    h = durations.default_duration_h(f)
    assert durations.check_duration_run(f, None, 2048).h == h
    assert check_work(f.tau_nd, f.tau_L_nd, f.gamma_bar_nd, f.tau0 / h, 2304, 1e300, min_duration=durations.
                      le_duration_floor(f)) == check_work(f.tau_nd, f.tau_L_nd, f.gamma_bar_nd, f.tau0 / h, 2304, 1e300)
    assert durations.default_max_steps(f, h, 2048) == 10**8


@pytest.mark.filterwarnings("ignore::dryfric_jax.DryfricWarning")
def test_the_fast_noise_floor_lies_below_the_excursions_measured_where_it_is_tightest():
    """The floor must stay a lower estimate (else a feasible count is refused).  Of the points measured
    (durations.le_duration_floor) it is tightest at tau' = 0.01, tau_L' = 1 (C = 0.40 +- 0.11 against 0.25): the
    count's 95% CI there lies above it, and the old prediction, 1 tau0, was 1/4 of the mean.  512 asked (~640
    counted): the mean is ~3.6 tau0, ~5 SE above the floor of 2.5 (seeds 0-3 at 256 asked: 3.56, 4.00, 3.50, 3.52
    +- 0.53-0.68; at 64 asked, this test's size until 0.3.0, CIs of +- 0.9-1.2 put two of those 4 seeds' lower
    edges below the floor: seed 0 passed there by luck with 0.2.11's streams)."""
    from dryfric_jax import durations

    p = Params.from_nondim(0.01, 1.0)
    r = di_long_excursion_duration(p, 0, n_excursions=512)
    assert r.n_truncated == 0
    assert (r.mean - r.ci) / p.tau0 > durations.le_duration_floor(p)  # 3.44 - 0.38 against 0.25 x 10


def test_a_tau_too_short_for_the_default_step_is_named_not_an_h_never_given(monkeypatch):
    """tau = 1e-11 s: the default step (tau/700 then; now far finer, the band rule's) falls below the smallest
    admissible h, and the refusal named h, which the user never gave (an audit; ``estimate`` runs there).  It names
    tau now; an h given is refused as before."""
    from dryfric_jax import durations

    monkeypatch.setattr(durations, "_run", lambda *a, **k: pytest.fail("ran"))
    p = Params(**dict(FIG3, tau=1e-11))
    with pytest.raises(ValueError, match=r"^tau = 1e-11 s is too short for the long-excursion count: its step "
                                         r"tau/[0-9.e+]+ = [0-9.e-]+ s \(the rules of "
                                         r"durations\.default_duration_h\) is refused \(h must be in "):
        di_long_excursion_duration(p, 0)
    with pytest.raises(ValueError, match=r"^h must be in "):
        di_long_excursion_duration(p, 0, h=1e-15)


def test_the_bridge_crossing_probability_against_finely_stepped_ou_paths():
    """``durations.bridge_crossing`` against 200 000 OU paths (tau' = 1, stationary variance 1/tau', the chain's
    X) over one step h' = 1e-3, from 0.7 step-sd inside a threshold, each in 500 exact sub-steps: by the tower
    rule P(no crossing) = E[1{X_1 inside} (1 - p(d_0, d_1))] over the paths' own ends.  Monitored at the sub-steps
    only, a path's crossings are those of a continuous one at a threshold 0.5826 sub-step sd further (Broadie,
    Glasserman and Kou 1997), used on the formula's side; the OU drift over h'/tau' = 1e-3 is negligible.  Within
    4 binomial SE (a paired difference: conservative); measured -1.5 SE.  The factor-2 mutants (exponent -4 or -1,
    MODEL_NOTES' trap) are ~100 SE off; -4 had passed every other test of the count (an audit)."""
    import numpy as np

    from dryfric_jax.durations import bridge_crossing

    rng = np.random.default_rng(1)
    tau, h, k, m = 1.0, 1e-3, 500, 200_000
    var1 = (1 - np.exp(-2 * h / tau)) / tau
    a, x0 = 1.0, 1.0 - 0.7 * np.sqrt(var1)
    e, s = np.exp(-h / k / tau), np.sqrt((1 - np.exp(-2 * h / k / tau)) / tau)
    x = np.full(m, x0)
    top = x.copy()
    for _ in range(k):
        x = x * e + s * rng.standard_normal(m)
        np.maximum(top, x, out=top)
    sim = np.mean(top < a)
    a_cont = a + 0.5826 * s
    exact = np.mean((x < a_cont) * (1 - np.asarray(bridge_crossing(a_cont - x0, a_cont - x, var1))))
    assert abs(sim - exact) <= 4 * np.sqrt(sim * (1 - sim) / m), (sim, exact)
    # either end outside: crossed
    assert np.all(np.asarray(bridge_crossing(np.array([-0.1, 0.1, 0.0]), np.array([0.1, -0.1, 0.1]), var1)) == 1.0)


def test_the_default_step_is_the_figures():
    """The bridged count's bias falls like h and shrinks as tau/h grows (module docstring): by default it runs at
    the D estimator's step, or tau/700 where that is finer, as Fig. 3 does: at Fig. 3's point (tau/h = 746) the D
    estimator's; at tau = 0.125 s 187/700 of it."""
    from dryfric_jax.durations import TAU_STEPS, default_duration_h
    from dryfric_jax.figures import diffusivity

    p = Params(**FIG3)
    assert TAU_STEPS == 700 and default_duration_h(p) == default_h(p)
    assert default_duration_h(FAST) == FAST.tau / 700 < default_h(FAST)
    assert diffusivity.default_duration_h is default_duration_h
    assert di_long_excursion_duration(p, 0, n_excursions=8).h == default_duration_h(p)


def test_a_few_dozen_excursions_are_said_to_under_cover(monkeypatch):
    """Below MIN_RELIABLE_LE excursions counted the t CI under-covers (0.93 at 63 counted: module docstring): a
    SmallSampleWarning (the estimator's category, which a sweep can silence alone), kept in the result; at 100
    and more, none."""
    import warnings

    from dryfric_jax import durations

    assert durations.MIN_RELIABLE_LE == 100
    for n, said in ((99, True), (100, False)):
        N = np.array([n // 2, n - n // 2])
        S = N * 1000
        monkeypatch.setattr(durations, "_run", lambda *a, N=N, S=S, **k: (
            N, S, S.astype(float) * 1000 + 1.0, np.ones(2, bool), np.ones(2, bool), S, 8, "n_excursions"))
        with warnings.catch_warnings(record=True) as w:
            warnings.simplefilter("always")
            r = di_long_excursion_duration(Params(**FIG3), 0, n_lanes=2, n_excursions=n)
        small = [x for x in w if issubclass(x.category, dj.SmallSampleWarning)]
        assert len(small) == said and r.n_excursions == n and len(r.warnings) == said, (n, w)
        if said:
            assert str(small[0].message) == r.warnings[0] and r.warnings[0].startswith(f"n_excursions = {n} < 100")


def test_the_loop_in_pieces_gives_the_bits_of_one_piece(monkeypatch):
    """The count runs its loop in pieces of ~PIECE_S seconds (a Ctrl-C or max_time acts between them); one block
    per piece, with a max_time it does not reach, must give the bits of the usual pieces, 37 lanes padded to the
    devices, bridged and raw."""
    from dryfric_jax import durations

    kw = dict(n_excursions=300, n_lanes=37)
    whole = [di_long_excursion_duration(FAST, 11, bridge=b, **kw) for b in (True, False)]
    monkeypatch.setattr(durations, "PIECE_S", 1e-9)  # one block per piece
    pieces = [di_long_excursion_duration(FAST, 11, bridge=b, max_time=3600, **kw) for b in (True, False)]
    for a, b in zip(whole, pieces):
        assert (a.mean, a.ci, a.n_excursions, a.n_truncated, a.lane_steps, a.loop_steps) == (
            b.mean, b.ci, b.n_excursions, b.n_truncated, b.lane_steps, b.loop_steps)
        assert a.stopped_by == b.stopped_by == "n_excursions" and (a.max_time, b.max_time) == (None, 3600.0)


def test_progress_reports_every_piece_and_leaves_the_count_alone(monkeypatch):
    """progress(dict) after every piece (one block each here): the LEs counted so far, never fewer than before, of
    those asked; the mean of those counted; the time left projected from the pieces after the first (none in the
    first, whose time holds the compilation, and none once no LE starts: those in flight end when they end); the
    last call is the result's count, none in flight.  The calls leave the bits alone: the usual pieces without
    progress give the same numbers.  On a clock of 1 ms a reading, with 10 000 asked, a max_time of 0.2 s is
    projected to end the count first and is named.  A progress that is not callable is refused by name.
    Mutants: a projection from the first piece; the mean in steps, not seconds; the in-flight LEs of a
    stopped lane counted."""
    from types import SimpleNamespace

    from dryfric_jax import durations

    kw = dict(n_excursions=300, n_lanes=37)
    whole = di_long_excursion_duration(FAST, 11, **kw)
    monkeypatch.setattr(durations, "PIECE_S", 1e-9)  # one block per piece
    got = []
    r = di_long_excursion_duration(FAST, 11, progress=got.append, **kw)
    assert (r.mean, r.ci, r.n_excursions, r.n_truncated, r.lane_steps, r.loop_steps) == (
        whole.mean, whole.ci, whole.n_excursions, whole.n_truncated, whole.lane_steps, whole.loop_steps)
    # a call per piece: the first runs 4 blocks, each later one 1
    assert len(got) == r.loop_steps // 128 // 37 - 3 and got[0]["left_s"] is None
    counts = [d["n_excursions"] for d in got]
    assert counts == sorted(counts) and all(d["target"] == 300 for d in got)
    assert got[-1]["n_excursions"] == r.n_excursions and got[-1]["in_flight"] == 0 and got[-1]["stopping"]
    assert got[-1]["mean_s"] == pytest.approx(r.mean, rel=1e-12)
    going = [d for d in got[1:] if not d["stopping"] and d["in_flight"]]
    ahead = [d for d in going if d["n_excursions"] + d["in_flight"] < 300]
    assert ahead and all(d["left_s"] >= 0 and d["left_to"] == "n_excursions" for d in ahead)
    # once those in flight make up the target, no projection: it counted them as done, "~0 s left" (an audit)
    rest = [d for d in going if d not in ahead]
    assert rest and all(d["left_s"] is None and d["left_to"] is None for d in rest)
    assert all(d["left_s"] is None for d in got if d["stopping"]) and any(d["stopping"] for d in got[:-1])
    assert all(0 <= d["in_flight"] <= 37 and d["elapsed_s"] > 0 for d in got)
    with pytest.raises(ValueError, match=r"progress must be a callable, True \(a live status line\), False or None"):
        di_long_excursion_duration(FAST, 11, progress=1, **kw)

    clock = [0.0]

    def tick():
        clock[0] += 1e-3
        return clock[0]

    monkeypatch.setattr(durations, "time", SimpleNamespace(perf_counter=tick))
    got.clear()
    with pytest.warns(dj.DryfricWarning, match="max_time = 0.2 s stopped the count"):
        di_long_excursion_duration(FAST, 5, max_time=0.2, n_excursions=10_000, n_lanes=64, progress=got.append)
    named = [d for d in got if d["left_to"] == "max_time"]
    assert named and all(d["elapsed_s"] + d["left_s"] == pytest.approx(0.2) for d in named)


def test_max_time_stops_new_excursions_then_cuts_at_twice_it(monkeypatch):
    """On a clock that advances 1 ms per reading and one block per piece: past max_time no lane starts a long
    excursion and those in flight finish (fewer than asked, none truncated, a warning says so); with less time
    those still in flight at twice it are left out (truncated: biased low, said); with too little for 2 long
    excursions a ValueError names max_time.  A count that ends within max_time is not marked."""
    from types import SimpleNamespace

    from dryfric_jax import durations

    clock = [0.0]

    def tick():
        clock[0] += 1e-3
        return clock[0]

    monkeypatch.setattr(durations, "time", SimpleNamespace(perf_counter=tick))
    monkeypatch.setattr(durations, "PIECE_S", 1e-9)
    kw = dict(n_excursions=10_000, n_lanes=64)
    # 0.4 s: no seed of 5-16 had an excursion still in flight at twice it (at 0.2 s, 5 of those 12 seeds had 1-3)
    with pytest.warns(dj.DryfricWarning, match=r"^max_time = 0\.4 s stopped the count at \d+ of the 10000 long "
                                               r"excursions asked: none started after it, those in flight finished"):
        a = di_long_excursion_duration(FAST, 5, max_time=0.4, **kw)
    assert a.stopped_by == "max_time" and a.max_time == 0.4 and 2 <= a.n_excursions < 10_000 and a.n_truncated == 0
    # the time rule, like the count's rule, decides at an excursion's start whether it counts: no bias against
    # a count of another seed stopped by its number (dropping those in flight at the limit instead: -32%)
    ref = di_long_excursion_duration(FAST, 6, n_excursions=2048)
    assert abs(a.mean - ref.mean) < 3 / 1.96 * math.hypot(a.ci, ref.ci), (a.mean, a.ci, a.n_excursions, ref.mean)
    with pytest.warns(dj.DryfricWarning, match=r"still in flight at twice max_time are left out, so the mean is biased"):
        b = di_long_excursion_duration(FAST, 5, max_time=0.04, **kw)
    assert b.stopped_by == "max_time" and b.n_truncated > 0 and b.n_excursions < a.n_excursions
    with pytest.raises(ValueError, match=r"^max_time = 0\.0002 s is too short here: the 8 lanes counted [01] long "):
        di_long_excursion_duration(FAST, 5, max_time=2e-4, **dict(kw, n_lanes=8))  # its first piece: 4 blocks
    for bad in (0, -1.0, "x"):
        with pytest.raises(ValueError, match="^max_time must be > 0 seconds"):
            di_long_excursion_duration(FAST, 5, max_time=bad, **kw)
    c = di_long_excursion_duration(FAST, 5, n_excursions=64, n_lanes=64, max_time=1e6)
    assert c.stopped_by == "n_excursions" and not any(w.startswith("max_time") for w in c.warnings)
    # the rule stopped the starts before max_time passed, and those in flight finished after it, within twice it:
    # the rule's count, to the bit, not marked as stopped by max_time (it was: an audit; 119 counted of 64 asked)
    clock[0] = 0.0
    d = di_long_excursion_duration(FAST, 5, n_excursions=64, n_lanes=64)
    ends = clock[0]
    for t in (0.55 * ends, 0.8 * ends):
        clock[0] = 0.0
        e = di_long_excursion_duration(FAST, 5, n_excursions=64, n_lanes=64, max_time=t)
        assert (e.stopped_by, e.n_excursions, e.mean, e.n_truncated) == ("n_excursions", d.n_excursions, d.mean, 0)
        assert not any(w.startswith("max_time") for w in e.warnings), t
    # ... and where twice max_time cut those in flight after the rule stopped the starts (early in the run here):
    # the limit's, said as such (it said "stopped the count at 118 of the 64 asked: none started after it")
    clock[0] = 0.0
    said = r"^max_time = [0-9.]+ s: at twice it \d+ long excursions still in flight, after the rule had stopped the "
    with pytest.warns(dj.DryfricWarning, match=said + r"starts \(\d+ counted of the 64 "):
        f = di_long_excursion_duration(FAST, 5, n_excursions=64, n_lanes=64, max_time=0.3 * ends)
    assert f.stopped_by == "max_time" and f.n_truncated > 0 and f.n_excursions + f.n_truncated == d.n_excursions
    # ... but where max_time stopped the starts first, those in flight may still take the count past the 64 asked:
    # the limit's note (it chose the rule's on the count alone: a review), whatever the count
    for frac in (0.15, 0.2):
        clock[0] = 0.0
        with warnings.catch_warnings(record=True) as said:
            warnings.simplefilter("always")
            g = di_long_excursion_duration(FAST, 5, n_excursions=64, n_lanes=64, max_time=frac * ends)
        notes = [str(w.message) for w in said if str(w.message).startswith("max_time")]
        assert g.stopped_by == "max_time" and len(notes) == 1, (frac, notes)
        assert re.match(r"max_time = [0-9.]+ s stopped the count(?: at \d+ of the 64 long excursions asked)?: none "
                        r"started after it", notes[0]) and "the rule" not in notes[0], notes
    assert g.n_excursions > 64  # the case the count alone misread; the note says how it got past the 64 asked (it
    assert f"took it to {g.n_excursions} (64 asked)" in notes[0], notes  # said "at 70 of the 64 asked": an audit


def _ctrl_c_at(monkeypatch, pieces):
    """The count's pieces run for real, and a KeyboardInterrupt comes as the pieces numbered in ``pieces`` end
    (the piece is lost, as when a Ctrl-C arrives during its compiled call); one block per piece."""
    from dryfric_jax import durations

    real, count = durations.over_lanes, [0]

    def over_lanes(fn, *a, **k):
        out = real(fn, *a, **k)
        if fn is durations._lane_blocks:
            count[0] += 1
            if count[0] in pieces:
                raise KeyboardInterrupt
        return out

    monkeypatch.setattr(durations, "over_lanes", over_lanes)
    monkeypatch.setattr(durations, "PIECE_S", 1e-9)


def test_a_ctrl_c_finishes_the_excursions_in_flight_and_a_second_drops_them(monkeypatch, capsys):
    """As the estimator's: the first Ctrl-C starts no long excursion and finishes those in flight (said on stderr),
    so nothing counted is lost and nothing is biased; a second keeps what was counted, those in flight dropped
    (truncated); with fewer than 2 counted it is a plain KeyboardInterrupt; within abandon_on_interrupt (a sweep's
    point, a figure's run) it is one at once.  A count it stopped has fewer than asked and says so."""
    from dryfric_jax.rounds import abandon_on_interrupt

    kw = dict(n_excursions=10_000, n_lanes=64)
    _ctrl_c_at(monkeypatch, {30})
    with pytest.warns(dj.DryfricWarning, match=r"^interrupted: \d+ of the 10000 long excursions asked counted, none "
                                               r"started after it, those in flight finished"):
        a = di_long_excursion_duration(FAST, 5, **kw)
    assert a.stopped_by == "interrupted" and a.n_truncated == 0 and 2 <= a.n_excursions < 10_000
    assert "dryfric: interrupted: finishing the long excursions in flight for at most" in capsys.readouterr().err
    _ctrl_c_at(monkeypatch, {30, 32})
    with pytest.warns(dj.DryfricWarning, match=r"still in flight are left out, so the mean is biased low"):
        b = di_long_excursion_duration(FAST, 5, **kw)
    assert b.stopped_by == "interrupted" and b.n_truncated > 0 and b.n_excursions <= a.n_excursions
    _ctrl_c_at(monkeypatch, {1, 2})
    with pytest.raises(KeyboardInterrupt):
        di_long_excursion_duration(FAST, 5, n_excursions=100, n_lanes=2)
    _ctrl_c_at(monkeypatch, {30})
    with abandon_on_interrupt(), pytest.raises(KeyboardInterrupt):
        di_long_excursion_duration(FAST, 5, **kw)


def test_the_first_piece_is_at_most_a_block_at_many_lanes(monkeypatch):
    """The first piece ran 4 blocks whatever the lanes: 1e9 lane-steps at 2^21 lanes, and --max-time 2, which acts
    between pieces, ended the count after 70 s (an audit).  It is 4 blocks up to 2^13 lanes (2^22 lane-steps), 1
    from 2^15."""
    from dryfric_jax import durations

    real, first = durations.over_lanes, []

    def over_lanes(fn, *a, **k):
        if fn is durations._lane_blocks and not first:
            first.append(int(a[0][6]))  # the blocks the piece runs to
        return real(fn, *a, **k)

    monkeypatch.setattr(durations, "over_lanes", over_lanes)
    p = dj.Params.from_nondim(0.3)
    for lanes, blocks in ((64, 4), (1 << 15, 1)):
        first.clear()
        with pytest.raises(durations.NoCountError):  # the limit ends it after the first piece
            dj.di_long_excursion_duration(p, 0, n_excursions=2, n_lanes=lanes, max_time=1e-9)
        assert first == [blocks], (lanes, first)


def test_a_count_whose_excursions_all_last_the_same_says_its_ci_is_none(monkeypatch):
    """Two long excursions of 2 steps each gave "2.857e-06 +- 0 s" as a result (a sweep audit at Gamma = 50,
    tau = 1e-3 s under max_time): a spread of 0 now says the CI of 0 is no interval; a spread > 0 says nothing."""
    from dryfric_jax import durations

    def run(S, Q):
        one = np.ones(2, np.int64)
        monkeypatch.setattr(durations, "_run", lambda *a, **kw: (one, one * S, one * Q, one == 1, one == 1, one * 9,
                                                                 1, "n_excursions"))
        with warnings.catch_warnings(record=True) as said:
            warnings.simplefilter("always")
            r = di_long_excursion_duration(FAST, 5, n_excursions=2, n_lanes=2)
        return r, [str(w.message) for w in said]

    r, said = run(2, 4)
    assert r.ci == 0 and r.mean == 2 * r.h
    assert "the 2 long excursions counted all lasted 2 steps: the CI of 0 is no interval; count more (or a finer h)" \
        in said and said[-1] == r.warnings[-1]
    r, said = run(np.array([2, 3]), np.array([4, 9]))
    assert r.ci > 0 and not any("no interval" in w for w in said)


def test_max_work_stops_the_starts_at_one_block_whatever_the_pieces(monkeypatch):
    """max_work bounded the count's predicted work only; a count ran past it (the prediction 2-13x short at tau =
    1e-3 s, a sweep audit: 5.4x a max_work of 5e7 without a word).  Now, as the estimator's work bound, once the
    lanes have computed it no LE starts and those in flight finish: here (Fig. 3's fastest point, whose LEs are ~1.6x
    the predicted) a max_work just above the prediction for 4096 stops the count short, said in a note, and none is
    truncated; its mean agrees with an unbounded count's (another seed) within their CIs; the stop falls at one
    block whatever the pieces (one block per piece: the same bits); well within the bound, the bits of no bound."""
    import dataclasses

    from dryfric_jax import durations

    n, lanes = 4096, 256
    work = 1.01 * (n + lanes) * durations.predicted_le_steps(FAST, durations.default_duration_h(FAST))
    said = re.escape(f"{work:.3g}")
    with pytest.warns(dj.DryfricWarning, match=rf"^max_work = {said} lane-steps stopped the count at \d+ of the {n} "
                                               "long excursions asked: none started after the lanes had computed it, "
                                               "those in flight finished$"):
        r = di_long_excursion_duration(FAST, 5, n_excursions=n, max_work=work)
    assert r.stopped_by == "work_bound" and 1000 < r.n_excursions < n and r.n_truncated == 0 and r.n_lanes == lanes
    assert r.loop_steps >= work
    free = di_long_excursion_duration(FAST, 6, n_excursions=n)
    assert free.stopped_by == "n_excursions" and abs(r.mean - free.mean) < r.ci + free.ci, (r.mean, free.mean)
    monkeypatch.setattr(durations, "PIECE_S", 1e-9)
    fields = lambda x: {k: v for k, v in dataclasses.asdict(x).items() if k != "wall_s"}  # noqa: E731
    assert fields(di_long_excursion_duration(FAST, 5, n_excursions=n, max_work=work)) == fields(r)
    monkeypatch.undo()
    small = [di_long_excursion_duration(FAST, 5, n_excursions=64, max_work=w) for w in (1e9, 1e18)]
    assert small[0].stopped_by == "n_excursions" and fields(small[0]) == fields(small[1])


def test_fewer_than_two_by_max_work_say_so(monkeypatch):
    """A count that the work bound left with fewer than 2 LEs: a NoCountError naming max_work, not max_steps."""
    from dryfric_jax import durations

    one = np.ones(2, np.int64)
    monkeypatch.setattr(durations, "_run", lambda *a, **kw: (one * 0, one * 0, one * 0.0, one == 1, one == 0,
                                                             one * 9, 4, "work_bound"))
    with pytest.raises(durations.NoCountError, match=r"^max_work = 1e\+09 lane-steps is too small here: the 2 lanes "
                                                     r"counted 0 long excursions by the time they had computed it"):
        di_long_excursion_duration(FAST, 5, n_excursions=6, n_lanes=2, max_work=1e9)


def test_the_step_band_variance_is_the_chains_and_band_h_inverts_it():
    """``step_band_variance`` is the chain's own Var(X_{n+1} | X_n) (its OU step's Cholesky factor, nondimensional
    X, whose stuck band has half-width 1), with or without a viscous term and a bias; ``band_h`` gives the step
    whose variance is q, and inf where no step's reaches it (q tau' >= 1, the stationary variance)."""
    import jax.numpy as jnp

    from dryfric_jax.di import make_di_model
    from dryfric_jax.durations import band_h, step_band_variance

    for p, h in ((FAST, 1e-4), (Params(1.0, 1.0, 0.01), 1e-6), (Params(**FIG3), 2e-3), (Params(2.0, 3.0, 5.0), 0.02)):
        ou = make_di_model(p, h, jnp.float64).ou
        assert step_band_variance(p, h) == pytest.approx(float(ou.L21 ** 2 + ou.L22 ** 2), rel=1e-12)
        for q in (1e-3, 0.0155, 0.38):
            if q * p.tau_nd < 1:
                assert step_band_variance(p, band_h(p, q)) == pytest.approx(q, rel=1e-12)
    assert band_h(Params(1.0, 1.0, 100.0), 0.0155) == math.inf


def test_the_default_step_keeps_the_band_variance_and_fig3s_steps():
    """The default step's X variance against the band is at most MAX_BAND_VARIANCE: below tau' = 0.184 the band
    rule binds (tau/h = 1290 at tau' = 0.1, 12 900 at 0.01, where tau/700 had made the count 5-9% long); over
    Fig. 3's grid (tau' >= 0.184) the step is the D estimator's or tau/700, as before; a sweep's coarse h is held to
    it as to tau/700."""
    from dryfric_jax import sweep
    from dryfric_jax.durations import (MAX_BAND_VARIANCE, TAU_STEPS, band_h, default_duration_h,
                                       step_band_variance)

    for tau in (0.125, 0.25, 0.5, 1.0):
        for g in np.geomspace(1, 10, 10):
            p = Params(**dict(FIG3, Gamma=float(g), tau=tau))
            assert default_duration_h(p) == min(default_h(p), tau / TAU_STEPS)
            assert step_band_variance(p, default_duration_h(p)) <= MAX_BAND_VARIANCE
    for tau, ratio in ((0.1, 1290), (0.01, 12900)):
        p = Params(1.0, 1.0, tau)
        h = default_duration_h(p)
        assert h == band_h(p, MAX_BAND_VARIANCE) and tau / h == pytest.approx(ratio, rel=0.01)
        assert step_band_variance(p, tau / TAU_STEPS) > 1.8 * MAX_BAND_VARIANCE  # 0.029 and 0.29
        assert sweep.duration_h(p, 1.0) == h and sweep.duration_h(p, h / 2) == h / 2


def test_a_step_that_moves_x_across_the_band_makes_the_count_long_and_is_said(recwarn):
    """At tau' = 0.1 a step whose X variance against the band is q = 0.38 (tau/h = 53) finds releases late: the
    count is longer than at the default step (q = 0.0155, tau/h = 1290) by more than their joint CI (measured
    +12% +- 3.5%: ``scripts/duration_step_bias.py``; +13%, +9%, +13% at that q at tau' = 0.1, 0.03, 0.01, against
    each one's fit to q -> 0), and a DryfricWarning says so where q > WARN_BAND_VARIANCE; none at the default step."""
    from dryfric_jax.durations import WARN_BAND_VARIANCE, band_h

    p = Params(1.0, 1.0, 0.1)
    with pytest.warns(dj.DryfricWarning, match=r"coarse for the count: X moves 0\.62 of the stuck band's half-width"
                                               r" per step \(step variance q = 0\.38 > 0\.06\).* by ~11% "
                                               r"\(~30q% where q <= 0\.4"):
        coarse = di_long_excursion_duration(p, 1, h=band_h(p, 0.38), n_excursions=16384)
    recwarn.clear()
    fine = di_long_excursion_duration(p, 2, n_excursions=8192)
    assert not [w for w in recwarn if "coarse for the count" in str(w.message)]
    assert coarse.mean - fine.mean > coarse.ci + fine.ci, (coarse.mean, coarse.ci, fine.mean, fine.ci)
    assert not any("coarse for the count" in w for w in fine.warnings) and WARN_BAND_VARIANCE == 0.06
