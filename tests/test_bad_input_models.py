"""Bad input to the model builders and the path scenes (an audit): refused by name, before anything runs."""
import time

import jax.numpy as jnp
import pytest

import dryfric_jax as dj
from dryfric_jax import paths
from dryfric_jax.params import FIG3, Params
from dryfric_jax.pdmp import pdmp_grid_info


@pytest.mark.parametrize("dtype", [jnp.int32, jnp.float16, "float16", "bogus", None])
def test_the_pdmp_model_refuses_a_dtype_it_cannot_run(dtype):
    """int32 built a model of zeros (delta = 0), float16 one whose paths were all 0, 'bogus' a TypeError."""
    with pytest.raises(ValueError, match=r"^dtype must be one of \['float32', 'float64'\]"):
        dj.make_pdmp_model(Params(**FIG3), 0.05, dtype=dtype)


def test_the_pdmp_model_refuses_float32_where_its_numbers_overflow_and_takes_it_elsewhere():
    """1/tau_L' = 1e40 is inf in float32: the paths then hit max_events (a RuntimeError naming nothing).  At 1e30
    float32 holds it and is used as asked (as make_di_model does)."""
    with pytest.raises(ValueError, match=r"^dtype float32 cannot hold this PDMP's numbers \(1/tau_L' = 1e\+40"):
        dj.make_pdmp_model(Params(1, 1, 1, 1e-40), 0.05, dtype=jnp.float32)
    m = dj.make_pdmp_model(Params(1, 1, 1, 1e-30), 0.05, dtype="float32")
    assert m.delta.dtype == jnp.float32 and float(m.inv_tau_L) == pytest.approx(1e30, rel=1e-6)
    assert dj.make_pdmp_model(Params(1, 1, 1, 1e-40), 0.05).inv_tau_L.dtype == jnp.float64


def test_the_grid_refuses_a_dict_for_params():
    with pytest.raises(ValueError, match="^params must be a dryfric_jax.Params"):
        pdmp_grid_info(dict(FIG3), 0.05)


def test_the_path_scenes_refuse_work_beyond_max_work_at_once():
    """10^12 paths ran on past a minute's timeout; now refused in no time, naming max_work and the lane-steps;
    raising max_work lets the check pass (it is the estimator's default, 1e11)."""
    m = dj.make_di_model(Params(**FIG3), 1e-3)
    t = time.perf_counter()
    with pytest.raises(ValueError, match=r"^max_work must be >= 1e\+12 lane-steps for 1000000000000 paths of 1 steps"):
        paths.di_transient(m, 0, 10**12, [0, 1])
    with pytest.raises(ValueError, match=r"^max_work must be >= 2\.01e\+11 lane-steps for 1000 paths of 201000000 "):
        paths.di_stationary(m, 0, 1000, 100, 2_000_000, burn_steps=1_000_000)
    assert time.perf_counter() - t < 5
    with pytest.raises(ValueError, match=r"^max_work must be a"):
        paths.di_transient(m, 0, 4, [1], max_work=float("nan"))
    assert paths.di_transient(m, 0, 1000, [1, 2], max_work=2000).shape == (1000, 2)  # exactly at it
    with pytest.raises(ValueError,
                       match=r"^max_work must be >= 2e\+03 lane-steps for 1000 paths of 2 steps \(got 2000;"):
        paths.di_transient(m, 0, 1000, [1, 2], max_work=1999.9)


def test_the_record_counts_are_bounded_by_name():
    """di_transient compiles each record time as its own segment (50 took 52 s, 5000 never finished); di_stationary
    folds its record index into the keys in 32 bits (n_records = 2^32 - 1 was an OverflowError)."""
    m = dj.make_di_model(Params(**FIG3), 1e-3)
    with pytest.raises(ValueError, match=r"^record_steps must hold at most 32 step counts \(got 33\)"):
        paths.di_transient(m, 0, 2, list(range(33)))
    with pytest.raises(ValueError, match=r"^n_records must be an integer in \[1, 4294967294\]"):
        paths.di_stationary(m, 0, 2, 2**32 - 1)


@pytest.mark.parametrize("value", ["no", 1, None, "False"])
def test_flags_take_true_or_false_only(tmp_path, monkeypatch, value):
    """A string like 'no' is truthy: skip_refused='no' recorded a refused point and ran on, and
    allow_mixed_versions='no' pooled two versions (an audit)."""
    from dryfric_jax import sweep

    monkeypatch.setattr(sweep, "estimate_diffusivity", lambda *a, **k: pytest.fail("ran"))
    with pytest.raises(ValueError, match=r"^skip_refused must be True or False"):
        sweep.run_sweep([dict(Gamma=5.0)], str(tmp_path / "s.jsonl"), skip_refused=value)
    r = dj.estimate_diffusivity(Params(**FIG3), 0, n_excursions=100)
    with pytest.raises(ValueError, match=r"^allow_mixed_versions must be True or False"):
        dj.combine_estimates([r], allow_mixed_versions=value)


def test_the_sweep_helpers_and_the_atom_refuse_by_name(tmp_path):
    """An audit: rows(None) and rows(5) were TypeErrors, rows(seed='a') gave [] silently, duration_h(p, nan) NaN,
    white_chain_atom(nan | inf | -1, h) a NaN, an inf and a negative probability."""
    from dryfric_jax import sweep
    from dryfric_jax.chain_law import white_chain_atom

    for f in (sweep.rows, sweep.failures, sweep.read_results):
        for bad in (None, 5):
            with pytest.raises(ValueError, match=r"^path must be a sweep file's path"):
                f(bad)
    assert sweep.rows(str(tmp_path / "none.jsonl")) == []  # a missing file: no records
    for seed in ("a", -1):
        with pytest.raises(ValueError, match=r"^seed must be"):
            sweep.rows(str(tmp_path / "none.jsonl"), seed=seed)
    p = Params(**FIG3)
    for h in (float("nan"), "x", -1.0, 0.0):
        with pytest.raises(ValueError, match=r"^h must be (finite and > 0|a real number) \(got "):
            sweep.duration_h(p, h)
    assert sweep.duration_h(p, 1.0) == p.tau / 700
    assert white_chain_atom([0.5, 0.25], 0.01) == pytest.approx([0.01, 0.005], rel=1e-15)
    for d in (float("nan"), float("inf"), -1.0, "x", [0.5, -0.1]):
        with pytest.raises(ValueError, match=r"^density_at_zero must hold finite numbers >= 0"):
            white_chain_atom(d, 1e-3)
    for h in (0.0, float("inf"), "x", None):
        with pytest.raises(ValueError, match=r"^h_nd must be (finite and > 0|a real number) \(got "):
            white_chain_atom(0.5, h)


def test_the_point_seeds_and_the_grid_offsets_refuse_by_name():
    """Internal helpers that a user may call to reproduce a sweep point or inspect the PDMP's grid: a missing
    parameter was a KeyError, a None settings an AttributeError, delta = 0 a ZeroDivisionError and delta < 0
    returned a mirrored grid (-10, 10)."""
    from dryfric_jax import sweep
    from dryfric_jax.pdmp import grid_offsets

    pt = dict(Gamma=1.0, Delta=1.0, tau=1.0, tau_L=1.0, gamma_bar=0.0)
    for f in (sweep.point_seed, sweep.duration_seed):
        s = f(3, pt, {})
        assert 0 <= s < 2**31 and f(3, dict(pt), {}) == s and f(4, pt, {}) != s
        for seed in (1.5, None, -1, True):
            with pytest.raises(ValueError, match=r"^seed must be an integer in \[0, 2\^62\] \(got "):
                f(seed, pt, {})
        for params in ({"Gamma": 1.0}, "x", None):
            with pytest.raises(ValueError, match=r"^params must be a dict with the keys Gamma, Delta, tau, tau_L, "):
                f(3, params, {})
        with pytest.raises(ValueError, match=r"^settings must be a dict \(got None\)"):
            f(3, pt, None)
    assert grid_offsets(0.25, 0.0) == (4, -4, 0.0, 0.0)
    for d, gb in ((0.0, 0.0), (-0.1, 0.0), (float("nan"), 0.0), (float("inf"), 0.0), (0.1, float("inf"))):
        with pytest.raises(ValueError, match=r"^delta must be a finite number > 0 and gamma_bar finite \(got "):
            grid_offsets(d, gb)
