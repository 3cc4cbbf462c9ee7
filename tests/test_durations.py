"""The paper's mean long-excursion duration of the DI by counting releases (dryfric_jax.durations),
against the PDMP's excursions (an independent method: its engine ends an HLE at the grid's release state)."""
import math

import numpy as np
import pytest

import dryfric_jax as dj
from dryfric_jax.durations import di_long_excursion_duration
from dryfric_jax.params import FIG3, Params
from dryfric_jax.plan import default_h

FAST = Params(10.0, 3.84, 0.125, 0.067, 0.342)  # Fig. 3's fastest point: many reversals through V = 0


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore::dryfric_jax.DryfricWarning")
def test_di_duration_tends_to_the_pdmps_as_h_falls():
    """At Gamma = 10, tau = 0.125 s the PDMP's mean excursion is 0.442 s at delta = 0.125 and 0.0625
    (converged in delta).  The DI's count at the default h is far above it (measured 0.548 +- 0.009, 95%)
    and within 3 SE of it at h/16 (0.452 +- 0.008).  Counting every release from V = 0, including V
    landing on 0 while passing through it (the first version), gave 0.374 at h/16: 15 SE below."""
    pd = dj.estimate_diffusivity(FAST, 3, method="pdmp", delta=0.0625, n_excursions=40_000)
    assert pd.n_truncated == 0
    coarse = di_long_excursion_duration(FAST, 1, h=default_h(FAST), n_lanes=1024, n_half=20)
    fine = di_long_excursion_duration(FAST, 1, h=default_h(FAST) / 16, n_lanes=1024, n_half=20)
    assert coarse.n_truncated == fine.n_truncated == 0 and fine.n_lanes == 1024
    se = lambda a, b: math.hypot(a, b) / 1.96  # noqa: E731
    assert abs(fine.mean - pd.mean_duration) <= 3 * se(fine.ci, pd.mean_duration_ci), (fine, pd.mean_duration)
    assert coarse.mean - pd.mean_duration > 5 * se(coarse.ci, pd.mean_duration_ci), (coarse, pd.mean_duration)
    assert coarse.mean > fine.mean


def test_duration_is_reproducible_and_shorter_than_the_cycle():
    """Same seed, same bits; another seed, other bits.  At Fig. 3's point a regeneration cycle (the D
    estimator's mean duration) spans one or more of the paper's excursions: about 1.9 of them."""
    p = Params(**FIG3)
    a = di_long_excursion_duration(p, 7, n_lanes=64, n_half=4)
    assert a == di_long_excursion_duration(p, 7, n_lanes=64, n_half=4)
    assert a.mean != di_long_excursion_duration(p, 8, n_lanes=64, n_half=4).mean
    cyc = dj.estimate_diffusivity(p, 2, n_excursions=2000)
    assert a.mean + a.ci < cyc.mean_duration - cyc.mean_duration_ci
    assert a.lane_steps > 64 * 4 * a.mean / 2 / a.h * 0.5  # the lanes ran their half excursions


def test_a_lane_stopped_by_its_bound_is_counted_not_hidden():
    """With max_steps near the typical lane's need, some lanes stop short: they are counted in n_truncated,
    the mean comes from the others (biased low, as documented), never a NaN; with almost none left, a
    ValueError names max_steps."""
    p = Params(**FIG3)
    full = di_long_excursion_duration(p, 3, n_lanes=128, n_half=2)
    need = int(full.mean / full.h * 1.5)  # steps for one LE plus the seek, about the median lane's
    cut = di_long_excursion_duration(p, 3, n_lanes=128, n_half=2, max_steps=need)
    assert 0 < cut.n_truncated < 128 and cut.n_lanes + cut.n_truncated == 128
    assert math.isfinite(cut.mean) and cut.mean < full.mean
    with pytest.raises(ValueError, match="max_steps = 128 is too small"):
        di_long_excursion_duration(p, 3, n_lanes=16, n_half=2, max_steps=128)


@pytest.mark.parametrize("kw,match", [
    (dict(n_half=3), "n_half must be even"), (dict(n_half=0), "n_half"), (dict(n_lanes=1), "n_lanes"),
    (dict(max_steps=0), "max_steps"), (dict(dtype="float16"), "dtype"), (dict(h=-1.0), "h"),
    (dict(max_steps=1.5), "max_steps"),
])
def test_bad_arguments_are_refused_by_name(kw, match):
    with pytest.raises(ValueError, match=match):
        di_long_excursion_duration(Params(**FIG3), 0, **{"n_lanes": 8, **kw})


def test_float32_agrees_with_float64():
    p = Params(**FIG3)
    a = di_long_excursion_duration(p, 4, n_lanes=256, n_half=4)
    b = di_long_excursion_duration(p, 5, n_lanes=256, n_half=4, dtype="float32")
    assert abs(a.mean - b.mean) <= 3 * math.hypot(a.ci, b.ci) / 1.96, (a, b)
    assert np.isfinite([b.mean, b.ci]).all()


def test_other_counts_and_bounds_do_not_recompile():
    """A figure's points differ in n_half and max_steps: one compiled loop per lane count serves them."""
    from dryfric_jax import durations

    p = Params(**FIG3)
    di_long_excursion_duration(p, 0, n_lanes=32, n_half=2, max_steps=10**6)
    n = durations._run._cache_size()
    di_long_excursion_duration(p, 1, n_lanes=32, n_half=4, max_steps=10**7)
    assert durations._run._cache_size() == n


def test_max_steps_beyond_the_32_bit_block_count_is_refused():
    from dryfric_jax import durations

    with pytest.raises(ValueError, match="max_steps"):
        di_long_excursion_duration(Params(**FIG3), 0, n_lanes=8, max_steps=durations.MAX_STEPS + 1)


def test_bad_lane_counts_and_dtypes():
    """2^24 lanes ran out of memory instead of a ValueError (an audit): the engine's lane cap holds here too.
    A dtype object is taken like its name (``jnp.float32`` was refused)."""
    import jax.numpy as jnp

    from dryfric_jax.plan import MAX_LANES

    p = Params(**FIG3)
    with pytest.raises(ValueError, match="n_lanes"):
        di_long_excursion_duration(p, 0, n_lanes=MAX_LANES + 1)
    a = di_long_excursion_duration(p, 2, n_lanes=16, n_half=2, dtype=jnp.float32)
    assert a == di_long_excursion_duration(p, 2, n_lanes=16, n_half=2, dtype="float32")
    with pytest.raises(ValueError, match="dtype"):
        di_long_excursion_duration(p, 0, n_lanes=8, dtype=jnp.float16)


def test_mean_ci_and_step_counts_from_the_lanes(monkeypatch):
    """The arithmetic after the loop, on a fake loop: d_l = 2 h span_l / n_half over the lanes that reached
    their count, the CI Student's t_{k-1} sd / sqrt(k) (with 3 lanes t_2 = 4.303, a table's value), lane_steps the
    lanes' steps and loop_steps lanes x the blocks the loop ran (finished lanes stand still in it)."""
    from dryfric_jax import durations

    done = np.array([True, True, False, True])
    span = np.array([100, 200, 0, 300])
    steps = np.array([500, 700, 1280, 900])
    monkeypatch.setattr(durations, "_run", lambda *a, **k: (done, span, steps, np.int32(10)))
    h = 1e-3
    r = di_long_excursion_duration(Params(**FIG3), 0, h=h, n_lanes=4, n_half=4)
    d = 2 * h * np.array([100, 200, 300]) / 4
    assert r.mean == pytest.approx(d.mean(), rel=1e-12)
    assert r.ci == pytest.approx(4.303 * d.std(ddof=1) / math.sqrt(3), rel=1e-3)
    assert (r.n_lanes, r.n_truncated, r.lane_steps, r.loop_steps) == (3, 1, 3380, 4 * 10 * 128)


def test_loop_steps_count_the_idle_lanes_too():
    """Each lane runs its own number of steps; the loop runs until the slowest is done: loop_steps is lanes x the
    slowest lane's steps rounded up to whole blocks, > lane_steps (2.2-2.4x at 20 HLEs per lane in an audit)."""
    r = di_long_excursion_duration(FAST, 5, n_lanes=64, n_half=4)
    assert r.loop_steps % (64 * 128) == 0 and r.loop_steps > r.lane_steps


def test_the_estimators_refusals_hold_here():
    """tau_L = inf with |gamma_bar| >= Delta has no stationary state (the particle runs away): it gave a number
    here (20.8 s, 9 of 32 lanes truncated) where estimate_diffusivity refuses; tau_L below the simulable range too."""
    with pytest.raises(ValueError, match="gamma_bar must satisfy"):
        di_long_excursion_duration(Params(10.0, 3.84, 0.125, math.inf, 1.05 * 3.84), 0, n_lanes=8)
    with pytest.raises(ValueError, match="tau_L must be >= 1e-60 tau0"):
        di_long_excursion_duration(Params(10.0, 3.84, 0.125, 1e-70, 0.0), 0, n_lanes=8)


def _fake_loop(monkeypatch, seen):
    from dryfric_jax import durations

    def run(model, keys, n_half, max_blocks, block):
        seen.append(model.h.dtype)
        n = keys.shape[0]
        return np.ones(n, bool), np.arange(1, n + 1) * 100, np.full(n, 1000), np.int32(8)
    monkeypatch.setattr(durations, "_run", run)


def test_float32_where_unsafe_runs_float64_and_says_so(monkeypatch):
    """As the estimator: h/tau below 1e-4 rounds the OU decay in float32, so the chain runs in float64 with a
    DryfricWarning, and the result says which dtype ran."""
    import jax.numpy as jnp

    seen = []
    _fake_loop(monkeypatch, seen)
    p = Params(**FIG3)
    with pytest.warns(dj.DryfricWarning, match="float32 is not safe here"):
        r = di_long_excursion_duration(p, 0, h=3e-5, n_lanes=4, n_half=2, dtype="float32")
    assert r.dtype == "float64" and seen == [jnp.float64]
    r = di_long_excursion_duration(p, 0, n_lanes=4, n_half=2, dtype="float32")
    assert r.dtype == "float32" and seen[-1] == jnp.float32


def test_tau_below_a_few_steps_is_flagged(monkeypatch):
    """At tau / h < MIN_TAU_STEPS the noise decorrelates within a few steps: releases happen at any X and the
    count is not the paper's long excursion (white noise at tau = 1e-5 s, h = 1.6e-3 s gave 14 s); warned."""
    from dryfric_jax.durations import MIN_TAU_STEPS

    _fake_loop(monkeypatch, [])
    p = Params(0.16, 1.0, 1e-5, math.inf, 0.0)
    with pytest.warns(dj.DryfricWarning, match=f"tau/h = .* < {MIN_TAU_STEPS}: the noise decorrelates"):
        di_long_excursion_duration(p, 0, n_lanes=4, n_half=2)
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        di_long_excursion_duration(p, 0, h=p.tau / (2 * MIN_TAU_STEPS), n_lanes=4, n_half=2)


def test_a_run_predicted_beyond_max_work_is_refused_before_it_starts(monkeypatch):
    """h = 1e-10 s at Fig. 3's point ran to its bound (~15 min on 2 cores, an audit estimate) and then failed: the
    estimator's work prediction (limits.check_work, for n_lanes x n_half / 2 excursions) refuses it at once."""
    from dryfric_jax import durations

    monkeypatch.setattr(durations, "_run", lambda *a, **k: pytest.fail("ran"))
    p = Params(**FIG3)
    with pytest.raises(ValueError, match=r"max_work must be >= .* \(here the excursions are n_lanes x n_half / 2"):
        di_long_excursion_duration(p, 0, h=1e-10)
    with pytest.raises(ValueError, match="max_work must be a finite number"):
        di_long_excursion_duration(p, 0, max_work=float("nan"))


def test_the_default_step_is_the_figures():
    """The count's bias falls slowly with h (+24% at Gamma = 10, tau = 0.125 s at the D estimator's default h, 5% at
    an eighth of it): by default it runs at default_h / 8, as Fig. 3 does."""
    from dryfric_jax.durations import H_DIV, default_duration_h
    from dryfric_jax.figures import diffusivity

    p = Params(**FIG3)
    assert default_duration_h(p) == default_h(p) / H_DIV and H_DIV == diffusivity.DUR_H_DIV == 8
    assert di_long_excursion_duration(p, 0, n_lanes=8, n_half=2).h == default_duration_h(p)
