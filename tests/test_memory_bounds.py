"""Sizes that would exhaust memory are refused by name before anything is allocated (a memory audit, 2026-12-07:
each case below ran into gigabytes and was killed, or ended in numpy's MemoryError or JAX's RESOURCE_EXHAUSTED,
instead of a ValueError naming the argument and its range)."""
import subprocess
import sys

import jax
import pytest

import dryfric_jax as dj
from dryfric_jax.estimators import MAX_PATHS
from dryfric_jax.paths import MAX_EXCURSION_STEPS, MAX_RECORDED, di_long_excursion, di_stationary, di_transient
from dryfric_jax.pdmp import MAX_SKELETON_EVENTS, excursion_skeleton, make_pdmp_model
from dryfric_jax.plan import host_memory as real_host_memory

P = dj.Params(1.0, 1.0, 1.0, 1.0, 0.0)


def test_recorded_arrays_are_bounded_before_they_are_allocated():
    """di_stationary(4096 paths x 2^20 records) passed the work bound (4.3e9) and raised numpy's MemoryError for
    32 GiB after 8 GB of RSS.  The bound is 2^28 values per array, inclusive (Fig. 5's 1.6e8 is under it)."""
    m = dj.make_di_model(P, 0.01)
    pm = make_pdmp_model(P, 0.125)
    for call in (lambda: di_stationary(m, 0, 4096, 2**20), lambda: di_transient(m, 0, 2**28, [1, 2]),
                 lambda: dj.paths.pdmp_stationary(pm, 0, 2**15, 2**14, 0.1, 0.0)):
        with pytest.raises(ValueError, match=r"^n_paths x records must be at most 2\^28 = 268435456 values"):
            call()
    assert MAX_RECORDED == 2**28 and 4096 * 40_000 < MAX_RECORDED
    with pytest.raises(ValueError, match="^max_work must be"):  # 2^28 values pass this check, not the work bound
        di_stationary(m, 0, 2**14, 2**14, every=1000, max_work=1e9)


def test_whole_buffers_are_bounded_by_name():
    """di_long_excursion's max_steps (2^31 - 1 passed 6 GB in 5 s) and excursion_skeleton's max_events (1e10: JAX's
    RESOURCE_EXHAUSTED; -5 a TypeError; 2.5 taken as 2; an int seed a TypeError about PRNG key data)."""
    m, pm = dj.make_di_model(P, 0.01), make_pdmp_model(P, 0.125)
    with pytest.raises(ValueError, match=r"^max_steps must be an integer in \[1, 67108864\]"):
        di_long_excursion(m, 0, max_steps=MAX_EXCURSION_STEPS + 1)
    for bad in (-5, 2.5, MAX_SKELETON_EVENTS + 1, 10**10):
        with pytest.raises(ValueError, match=r"^max_events must be an integer in \[1, 67108864\]"):
            excursion_skeleton(pm, 0, bad)
    with pytest.raises(ValueError, match="^model must be a PDMPModel"):
        excursion_skeleton(m, 0)
    a, b = excursion_skeleton(pm, 3, 5000), excursion_skeleton(pm, jax.random.key(3), 5000)
    assert (a["t"] == b["t"]).all() and a["complete"] == b["complete"]  # a seed is its key


def test_brute_force_paths_and_chunks_are_bounded():
    """bruteforce_diffusivity keeps every path's U (~50 bytes each at the peak): 1e9 paths passed the work bound and
    grew towards ~50 GB; chunk_lanes = 2^24 ran 2^24 paths at once (2^31 normals a block) past 8 GB."""
    with pytest.raises(ValueError, match=r"^n_paths must be an integer in \[3, 67108864\] \(with 2 paths the D_t CI "
                                         r"is 0; every path's U is kept, ~50 bytes each in memory\) \(got 67108865\)"):
        dj.bruteforce_diffusivity(P, 0, t=0.05, n_paths=MAX_PATHS + 1)
    with pytest.raises(ValueError, match=r"^min\(chunk_lanes, n_paths\) \* block must be <= 2\^28"):
        dj.bruteforce_diffusivity(P, 0, t=0.05, n_paths=2**21 + 1, chunk_lanes=2**24)
    with pytest.warns(dj.DryfricWarning):  # a chunk larger than the paths runs the paths: allowed
        dj.bruteforce_diffusivity(P, 0, t=0.05, n_paths=8, chunk_lanes=2**24)


def test_the_package_runs_as_a_module():
    """``python -m dryfric_jax`` was "No module named dryfric_jax.__main__" (two audits)."""
    out = subprocess.run([sys.executable, "-m", "dryfric_jax", "bruteforce", "--t", "1", "--n-paths", "1000000000"],
                         capture_output=True, text=True)
    assert out.returncode == 2 and "--n-paths must be an integer in [3, 2^26]" in out.stderr, out.stderr


@pytest.mark.skipif(jax.default_backend() != "cpu", reason="checked against host memory on a CPU only")
def test_a_layout_beyond_this_machines_memory_is_refused_by_name(monkeypatch, capsys):
    """An audit item (stop 91): --lanes 4194304 --block 64, which check_layout allows (lanes x K = 2^28), peaked at
    9.0 GB RSS here (float64): on an 8 GiB machine it would be killed, its results with it.  Now the plan refuses a
    layout whose lower memory fit exceeds the machine's memory.  Worked by hand at 8 GiB: float64 2^22 x (1.2 x 2 x 64
    x 8 + 768) + 0.4e9 = 8.775e9 B = 8.17 GiB > 8 GiB, refused, at most (8 GiB - 0.4e9) / 1996.8 = 4101529 lanes;
    float32 2^22 x (1.2 x 2 x 64 x 4 + 768) + 0.4e9 = 4.8e9 B, run; 2^21 lanes in float64, 4.3e9 B, run."""
    from dryfric_jax import plan
    from dryfric_jax.cli import main

    if sys.platform.startswith("linux"):  # known here (conftest pins 64 GiB for the other tests)
        assert real_host_memory() > 0
    monkeypatch.setattr(plan, "host_memory", lambda: 8 * 2**30)
    p = dj.Params(5.0, 3.84, 0.5, 0.067, 0.342)
    kw = dict(n_excursions=10**7, max_work=1e15, block=64)
    with pytest.raises(ValueError, match=r"^lanes = 4194304 at block = 64 \(float64\) needs at least 8\.17 GiB of "
                                         r"memory .* more than this machine's 8 GiB: use at most 4101529 lanes "
                                         r"at this block, or a smaller block$"):
        plan.plan_estimate(p, lanes=2**22, **kw)
    assert plan.plan_estimate(p, lanes=2**22, dtype="float32", **kw).lanes == 2**22
    assert plan.plan_estimate(p, lanes=2**21, **kw).lanes == 2**21
    assert main(["estimate", "--lanes", "4194304", "--block", "64", "--n-excursions", "10000000", "--max-work",
                 "1e15"]) == 2
    assert "lanes = 4194304 at block = 64 (float64) needs at least 8.17 GiB" in capsys.readouterr().err
    # the long-excursion count's lanes too (K = 128: 2^21 x (1.2 x 2 x 128 x 8 + 768) + 0.4e9 = 6.67 GiB > 4 GiB)
    monkeypatch.setattr(plan, "host_memory", lambda: 4 * 2**30)
    with pytest.raises(ValueError, match=r"^n_lanes = 2097152 at block = 128 \(float64\) needs at least 6\.67 GiB"):
        dj.durations.check_duration_run(p, n_excursions=10**6, n_lanes=2**21, max_work=1e15)
    with pytest.raises(ValueError, match=r"use at most 1207517 lanes$"):  # (4 GiB - 0.4e9) / 3225.6; its K is fixed
        dj.durations.check_duration_run(p, n_excursions=10**6, n_lanes=2**21, max_work=1e15)
    monkeypatch.setattr(plan, "host_memory", lambda: None)  # unknown (Windows): not checked
    assert plan.plan_estimate(p, lanes=2**22, **kw).lanes == 2**22
