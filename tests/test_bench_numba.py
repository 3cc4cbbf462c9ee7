"""The numba baseline of ``dryfric bench`` is the same algorithm as the engine: its own estimates
of D and M0 (from the sums it accumulates) against the exact white-noise values (DI), and its
PDMP against its DI at the paper's Fig. 3 point (two independent methods).  A baseline that
skipped work or drew the wrong noise would run faster and fail here.

numba is the ``bench`` extra: without it these tests are skipped (CI installs it).
Tolerance: z = 2.81 on each comparison (as ``test_di_exact``), fixed seeds.

Each run is bounded at 30x the plan's predicted work (:func:`_guard`; the prediction is a lower estimate:
the runs here measured 1.0-10.4x it), so a broken baseline stops with ``BaselineIncomplete`` in seconds
instead of running until CI's time limit.
"""
import math

import numpy as np
import pytest

import dryfric_jax as dj
from dryfric_jax.di import make_di_model
from dryfric_jax.estimators import long_excursion_estimates
from dryfric_jax.params import FIG3
from dryfric_jax.pdmp import make_pdmp_model
from dryfric_jax.plan import default_delta, default_h, plan_estimate

numba_bench = pytest.importorskip("dryfric_jax.bench_numba", reason="numba not installed: pip install -e '.[bench]'")
Z = 2.81


def _guard(p, method, n):
    """The work bound of a test's run: 30x the predicted work of ``n`` excursions."""
    return 30 * plan_estimate(p, method=method, n_excursions=n).predicted_work


def _estimates(run, model, n, threads, seed, p, method):
    out, steps = run(model, n, threads, seed, max_work=_guard(p, method, n))
    assert steps == int(out[:, numba_bench.STEPS].sum()) > 0 and not out[:, numba_bench.TRUNC].any()
    return long_excursion_estimates(numba_bench.sums(out))


def test_di_baseline_against_the_exact_white_noise_values():
    """tau' = 1e-5 at the paper's Gamma, Delta, tau_L, gamma_bar (test_di_exact's point), the DI at
    the engine's default h; 1e5 excursions (~0.7 s on 2 threads).  Seeds 1-3 at 3e4 excursions gave
    z(D) = -0.52, +0.30, +0.77 and z(M0) = -0.18, -0.19, +0.17."""
    G, Dl = 5.0, 3.84
    p = dj.Params(G, Dl, 1e-5 * G / Dl**2, 0.067, 0.342)
    e = _estimates(numba_bench.run_numba, make_di_model(p, default_h(p)), 100_000, 2, 4, p, "di")
    assert e["n_excursions"] == 100_000
    D, M0 = dj.theory.exact_D(p) / p.D0, dj.theory.exact_M0(p) / p.v0  # the sums are nondimensional
    assert e["D_ci"] <= 0.02 * e["D"]
    assert abs(e["D"] - D) <= Z / 1.96 * e["D_ci"], (e["D"], e["D_ci"], D)
    assert abs(e["M0"] - M0) <= Z / 1.96 * e["M0_ci"], (e["M0"], e["M0_ci"], M0)


def test_pdmp_baseline_agrees_with_the_di_baseline_at_the_fig3_point():
    """Both at their default h and delta, 4e4 excursions each (the engine's PDMP and DI agree there,
    test_pdmp); measured (seed 11): D = 4.596e-3 +- 1.3e-4 (PDMP), 4.541e-3 +- 1.0e-4 (DI)."""
    p = dj.Params(**FIG3)
    a = _estimates(numba_bench.run_numba_pdmp, make_pdmp_model(p, default_delta(p)), 40_000, 2, 11, p, "pdmp")
    b = _estimates(numba_bench.run_numba, make_di_model(p, default_h(p)), 40_000, 2, 11, p, "di")
    for k in ("D", "M0"):
        assert abs(a[k] - b[k]) <= Z / 1.96 * math.hypot(a[k + "_ci"], b[k + "_ci"]), (k, a, b)


@pytest.mark.parametrize("name", ["run_numba", "run_numba_pdmp"])
def test_same_seed_same_sums_and_every_thread_does_its_share(name):
    """One ``Generator`` per worker from ``SeedSequence(seed).spawn(threads)``: the same seed and
    threads give the same sums to the last bit, another seed other sums, and each of the 2 workers
    runs ceil(n / 2) excursions (the rows are the workers)."""
    p = dj.Params(**FIG3)
    model = make_pdmp_model(p, default_delta(p)) if name.endswith("pdmp") else make_di_model(p, default_h(p))
    run = getattr(numba_bench, name)
    a, sa = run(model, 301, 2, 5)
    b, sb = run(model, 301, 2, 5)
    c, _ = run(model, 301, 2, 6)
    assert np.array_equal(a, b) and sa == sb
    assert not np.array_equal(a[:, 1], c[:, 1])
    assert a.shape == (2, len(numba_bench.SUMS) + len(numba_bench.TAIL))
    assert list(a[:, 0]) == [151.0, 151.0]
    assert numba_bench.sums(a)["n"] == 302.0


def test_di_baseline_regenerates_as_the_engine_does():
    """D and M0 hardly see the regeneration rule, the mean excursion duration does: the baseline's
    (2e4 excursions) and the engine's (2000) at the Fig. 3 point and the same h agree.  Measured:
    23.36 +- 0.20 (baseline, seed 3); a coin that always lands heads gives 14.41 +- 0.12."""
    p = dj.Params(**FIG3)
    a = _estimates(numba_bench.run_numba, make_di_model(p, default_h(p)), 20_000, 2, 3, p, "di")
    with pytest.warns(dj.DryfricWarning, match="under-covers"):  # N < 1e4: the duration's CI is not D's
        r = dj.estimate_diffusivity(p, 3, n_excursions=2000)
    assert r.h == pytest.approx(default_h(p), rel=1e-12) and r.n_truncated == 0
    b = long_excursion_estimates(r.sums)
    ci = math.hypot(a["mean_duration_ci"], b["mean_duration_ci"])
    assert abs(a["mean_duration"] - b["mean_duration"]) <= Z / 1.96 * ci, (a["mean_duration"], b["mean_duration"], ci)


@pytest.mark.parametrize("name", ["run_numba", "run_numba_pdmp"])
def test_a_worker_at_its_work_bound_stops_and_the_run_says_so_keeping_the_rows(name):
    """At the Fig. 3 point an excursion takes ~1.2e4 steps (~4.6e3 events): 1000 excursions on 2 threads within
    2000 steps in all cannot finish.  Each worker stops at its 1000 steps, and the run raises
    ``BaselineIncomplete`` naming the bound, with the workers' rows (what they did) kept on it."""
    p = dj.Params(**FIG3)
    model = make_pdmp_model(p, default_delta(p)) if name.endswith("pdmp") else make_di_model(p, default_h(p))
    unit = "events" if name.endswith("pdmp") else "steps"
    with pytest.raises(numba_bench.BaselineIncomplete, match=f"work bound of 1000 {unit} after .* of its 500"
                       ) as e:
        getattr(numba_bench, name)(model, 1000, 2, 0, max_work=2000)
    rows = e.value.rows
    assert rows.shape == (2, len(numba_bench.SUMS) + len(numba_bench.TAIL))
    assert list(rows[:, numba_bench.WORK]) == [1000.0, 1000.0] and (rows[:, 0] < 500).all()


def test_excursions_at_max_steps_are_counted_and_reported():
    """The DI baseline at the Fig. 3 point with max_steps = 1e4 (below the mean excursion's ~1.2e4 steps):
    the truncated excursions are counted in the rows, left out of the sums (200 complete ones) and reported by
    a warning; with the default max_steps none is."""
    p = dj.Params(**FIG3)
    model = make_di_model(p, default_h(p))
    with pytest.warns(dj.DryfricWarning, match=r"\d+ excursions reached max_steps"):
        out, _ = numba_bench.run_numba(model, 200, 2, 0, max_steps=10_000, max_work=_guard(p, "di", 200))
    assert out[:, numba_bench.TRUNC].sum() > 0 and numba_bench.sums(out)["n"] == 200.0
    out, _ = numba_bench.run_numba(model, 200, 2, 0, max_work=_guard(p, "di", 200))
    assert not out[:, numba_bench.TRUNC].any()


@pytest.mark.parametrize("kw,name", [(dict(max_work=0), "max_work"), (dict(max_work=float("nan")), "max_work"),
                                     (dict(max_work=2.0**63), "max_work"), (dict(max_steps=True), "max_steps"),
                                     (dict(max_steps="9"), "max_steps"), (dict(threads=0), "threads"),
                                     (dict(threads=1.5), "threads")])
def test_bad_bounds_are_named(kw, name):
    """A bound out of range is a ``ValueError`` that names it (before any worker starts)."""
    p = dj.Params(**FIG3)
    args = {**dict(model=make_di_model(p, default_h(p)), n_excursions=10, threads=2), **kw}
    with pytest.raises(ValueError, match=name):
        numba_bench.run_numba(**args)
