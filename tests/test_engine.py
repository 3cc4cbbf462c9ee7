"""Lane engine: reproducibility, no recompilation, bounded work with reported truncation."""
import math
import warnings

import jax
import numpy as np
import pytest

import dryfric_jax as dj
from dryfric_jax.di import make_di_model
from dryfric_jax.excursions import _run_chunk, simulate_long_excursions


def test_same_seed_bit_identical():
    p = dj.Params.from_nondim(0.3, 2.0, 0.2)
    a = simulate_long_excursions(make_di_model(p, 0.02), jax.random.key(5), 300, per_lane=4, chunk_lanes=32)
    b = simulate_long_excursions(make_di_model(p, 0.02), jax.random.key(5), 300, per_lane=4, chunk_lanes=32)
    assert np.array_equal(a.stats, b.stats) and a.n_excursions == 300


def test_second_call_does_not_recompile():
    p1, p2 = dj.Params.from_nondim(0.3), dj.Params.from_nondim(0.5, 1.0, 0.1)
    kw = dict(per_lane=4, chunk_lanes=16, block=8)
    simulate_long_excursions(make_di_model(p1, 0.02), jax.random.key(0), 64, **kw)
    n = _run_chunk._cache_size()
    # new parameters, new seed, more chunks: same shapes, so the compiled loop is reused
    simulate_long_excursions(make_di_model(p2, 0.05), jax.random.key(1), 200, **kw)
    assert _run_chunk._cache_size() == n


def test_exact_count_of_excursions_over_chunks():
    p = dj.Params.from_nondim(0.1)
    s = simulate_long_excursions(make_di_model(p, 0.02), jax.random.key(2), 1001, per_lane=3, chunk_lanes=50)
    assert s.n_excursions + s.n_truncated == 1001
    assert 0 < s.useful_steps <= s.slot_steps


def test_truncation_is_counted_and_reported():
    p = dj.Params.from_nondim(1.0)
    with pytest.warns(dj.DryfricWarning, match="work bound"):
        r = dj.estimate_diffusivity(p, 3, h=0.01, n_excursions=400, max_steps=300, per_lane=4)
    assert r.n_truncated > 0
    assert r.n_excursions + r.n_truncated == 400
    assert math.isfinite(r.D) and math.isfinite(r.D_ci)
    assert any("work bound" in w for w in r.warnings)


def test_small_n_warns():
    p = dj.Params.from_nondim(1e-3)
    with pytest.warns(dj.DryfricWarning, match="under-covers"):
        dj.estimate_diffusivity(p, 0, n_excursions=100)


def test_float32_runs_and_agrees_with_float64():
    """float32 simulation (float64 statistics) vs float64, white noise b = 0, vs exact D' = 10."""
    p = dj.Params.from_nondim(1e-5)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", dj.DryfricWarning)
        r32 = dj.estimate_diffusivity(p, 4, n_excursions=60_000, dtype="float32", h=0.02, per_lane=32)
    assert r32.dtype == "float32" and r32.n_truncated == 0
    assert abs(r32.D - 10.0) <= r32.D_ci and abs(r32.M0) <= r32.M0_ci


@pytest.mark.parametrize("kw,match", [
    (dict(h=-1.0), "h must"), (dict(h=math.nan), "h must"), (dict(h=1.0), "h must"),
    (dict(n_excursions=1), "n_excursions"), (dict(method="pdmp"), "method"), (dict(dtype="float16"), "dtype"),
])
def test_api_bad_input(kw, match):
    with pytest.raises(ValueError, match=match):
        dj.estimate_diffusivity(dj.Params(**dj.FIG3), 0, **kw)


def test_negative_seed_refused():
    with pytest.raises(ValueError, match="seed"):
        dj.estimate_diffusivity(dj.Params(**dj.FIG3), -1)
