"""Mutation audit of :mod:`dryfric_jax.bench` (``dryfric bench``: the side-by-side bench and the layout sweep).

Mutants tried: 105 one-line mutants of bench.py, by hand (comparisons flipped, off-by-one, arguments swapped,
wrong keys, ratios inverted, a median taken as a mean, a maximum or one round, rounds dropped, wrong dtypes, the
1% CI arithmetic, the numba baseline's unavailable / stopped handling, the engine's settings not restored after
tune_layout, format fields).  The existing tests (test_cli.py's bench tests, test_cli_mutants.py; run per mutant
on the tests that reach the mutated function) killed 30.  3 are equivalent: ``_ratios`` gating the numba ratios
on the PDMP's 2-thread key instead of the DI's (``_numba_round`` gives both or neither); ``_layout_row`` taking
the last round's run for D, N and the utilisation (the rounds share a seed: the same excursions); grouping the
twins of ``_summarise_layouts`` on ``events != "branch"`` (the same partition).  This file kills the other 72;
none is left.  No defect found: every survivor was a gap in the tests (mostly numbers only checked for > 0).

Oracles: hand arithmetic on numbers put into fakes (rates, CIs, ratios, medians of three rounds, the work
per timing), the docstrings and the README's "`dryfric bench`" section (each ratio taken within its round and
reported as the median of the rounds; the RNG bound draws 2 normals per step from ``fold_in(lane_key, b)``;
the chain floor sums a block's increments in their own dtype, skipping a coin's heads; a layout's rate is the
median of its rounds; the engine's settings restored after the sweep; a broken or absent numba baseline is
said and the other numbers kept), and ``jax.random.normal`` itself for the RNG bound's numbers.  The engine,
the timers, the clock and the numba module are replaced by fakes: no test here times anything.
"""
import sys
import types
from types import SimpleNamespace

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from dryfric_jax import bench, excursions
from dryfric_jax import rng as real_rng


# ---------------------------------------------------------------- fakes


class Clock:
    """A clock that moves only when told (``bench.time`` is replaced by it, nothing else's clock)."""

    def __init__(self, t=0.0):
        self.t = t

    def perf_counter(self):
        return self.t


class Stop(Exception):
    """The fake baseline's ``BaselineIncomplete`` (not a RuntimeError: a handler catching too much shows)."""


def fake_numba(monkeypatch, clock, di_steps=1000, pdmp_steps=500, stop_after=None, calls=None):
    """Install a fake ``dryfric_jax.bench_numba`` (and ``numba``): each run takes 2 s of ``clock`` and reports
    ``steps * threads`` steps, so a rate is ``steps * threads / 2``; the DI run raises :class:`Stop` on its
    timed runs once ``stop_after`` timed runs were made."""
    calls = [] if calls is None else calls

    def runner(name, steps):
        def run(model, n, threads, seed=None):
            calls.append((name, model, n, threads, seed))
            timed = [c for c in calls if c[0] == name and c[2] != 20]
            if name == "di" and stop_after is not None and n != 20 and len(timed) > stop_after:
                raise Stop("worker 1 reached its work bound")
            clock.t += 2.0
            return None, steps * threads
        return run

    mod = types.ModuleType("dryfric_jax.bench_numba")
    mod.RNG, mod.BaselineIncomplete = "fake-rng", Stop
    mod.run_numba, mod.run_numba_pdmp = runner("di", di_steps), runner("pdmp", pdmp_steps)
    monkeypatch.setitem(sys.modules, "dryfric_jax.bench_numba", mod)
    monkeypatch.setitem(sys.modules, "numba", SimpleNamespace(__version__="0.0-fake"))
    return calls


def broken_numba(monkeypatch):
    """A numba module that is there but broken: importing a name from it raises a RuntimeError."""
    mod = types.ModuleType("dryfric_jax.bench_numba")

    def getattr_(name):
        raise RuntimeError("numba is broken here")
    mod.__getattr__ = getattr_
    monkeypatch.setitem(sys.modules, "dryfric_jax.bench_numba", mod)


def fake_models(monkeypatch):
    monkeypatch.setattr(bench, "make_di_model", lambda p, h, dtype="float64": ("di", dtype))
    monkeypatch.setattr(bench, "make_pdmp_model", lambda p, delta, dtype="float64": ("pdmp", dtype))


# ---------------------------------------------------------------- _device_timer, rng_bound, chain_floor


def test_device_timer_runs_every_block_on_every_device_and_counts_n_lane_steps_per_call(monkeypatch):
    """n = 512 d lane-steps of 8 d lanes (d devices), K = 8: 8 blocks of every lane per call, 8 lanes per device,
    each device its own keys; 3 reps in 2 s of the clock: 3 * 512 d / 2 = 768 d lane-steps/s.  Kills: lanes not
    split (per_dev = lanes), n_blocks not divided by the devices, the rate without len(devs) or one rep short,
    the block loop from 1, the devices sharing keys (no fold_in of the axis index)."""
    reads = iter([10.0, 12.0])  # the timer's two clock reads: 2 s
    monkeypatch.setattr(bench, "time", SimpleNamespace(perf_counter=lambda: next(reads)))
    ndev = len(jax.local_devices())
    seen, shapes = [], []

    def per_lane_block(keys, b, c):
        shapes.append(keys.shape)
        jax.debug.callback(lambda bb, kd: seen.append((int(bb), np.asarray(kd).tobytes())), b,
                           jax.random.key_data(keys))
        return c + 1.0

    timer = bench._device_timer(per_lane_block, lambda m: jnp.zeros((m,)), 8 * ndev, 8, 512 * ndev, 3)
    jax.effects_barrier()
    assert shapes == [(8,)]
    assert sorted(b for b, _ in seen) == sorted(list(range(8)) * ndev)  # the compile run: 8 blocks per device
    del seen[:]
    assert timer() == pytest.approx(768 * ndev, rel=1e-12)
    jax.effects_barrier()
    assert sorted(b for b, _ in seen) == sorted(list(range(8)) * ndev * 3)
    assert len({kd for b, kd in seen if b == 0}) == 3 * ndev  # every call and every device its own keys


def capture_device_timer(monkeypatch):
    got = {}

    def fake(per_lane_block, init, lanes, block, n, reps):
        got.update(body=per_lane_block, init=init, lanes=lanes, block=block, n=n, reps=reps)
        return lambda: 123.0
    monkeypatch.setattr(bench, "_device_timer", fake)
    return got


def spy_rng(monkeypatch):
    used = []
    real = bench.rng

    def normals(keys, block, n, dtype, *a):
        used.append(("normals", jnp.dtype(dtype)))
        return real.normals(keys, block, n, dtype, *a)

    def per_lane(sample, keys, n):
        used.append(("per_lane", None))
        return real.per_lane(sample, keys, n)
    monkeypatch.setattr(bench, "rng", SimpleNamespace(normals=normals, per_lane=per_lane))
    return used


@pytest.mark.parametrize("via", ["engine", "jax"])
def test_rng_bound_block_sums_two_normals_per_step_of_each_lanes_block_key(monkeypatch, via):
    """The RNG bound's block: each lane draws (K, 2) normals from fold_in(lane key, b), in the run's dtype, through
    the engine's generator (``via="engine"``) or jax.random.normal (``via="jax"``), and adds both to its float
    accumulator, every row.  Expected: the per-key numbers of the path (rng.normal, jax.random.normal).  Kills: rng_bound passing lanes and
    block swapped or dropping ``via``; the two paths swapped; the engine path drawing float64; one column read
    twice; the row loop from 1."""
    got, used = capture_device_timer(monkeypatch), spy_rng(monkeypatch)
    assert bench.rng_bound(jnp.dtype("float32"), 6, 16, n=4096, reps=2, via=via) == 123.0
    assert (got["lanes"], got["block"], got["n"], got["reps"]) == (6, 16, 4096, 2)
    keys = jax.random.split(jax.random.key(3), 6)
    acc = got["init"](6)
    assert acc.dtype == jnp.float32 and not acc.any()
    out = got["body"](keys, 5, acc)
    assert used == ([("normals", jnp.dtype("float32"))] if via == "engine" else [("per_lane", None)])
    normal = real_rng.normal if via == "engine" else jax.random.normal
    want = [float(jnp.sum(normal(jax.random.fold_in(k, 5), (16, 2), jnp.float32))) for k in keys]
    assert out.dtype == jnp.float32 and np.allclose(out, want, rtol=1e-5, atol=1e-5)


class Chain:
    """A fake chain: step ``i`` of a block adds ``rows[i]`` (float32) to U unless its coin says heads; heads at the
    lane's odd steps (counting from its first), only when the regeneration test is on (``watch_plus``)."""

    def __init__(self, rows, heads=True):
        self.rows, self.heads = rows, heads

    def init_state(self, m):
        return jnp.zeros((m,), jnp.int32)

    def draw_lanes(self, keys, block):
        assert block == len(self.rows)
        return (jnp.broadcast_to(jnp.asarray(self.rows, jnp.float32)[:, None], (block, keys.shape[0])),)

    def advance(self, state, r, watch_plus):
        heads = (state % 2 == 1) & watch_plus & self.heads
        return state + 1, r[0], None, heads


def test_chain_floor_sums_a_blocks_increments_without_the_heads_in_their_own_dtype(monkeypatch):
    """Block of 4 steps with increments 1, 2, 3, 4 and heads at steps 1 and 3: U = 1 + 3 = 4 per block (8 after
    two); increments 2^24, 1, 1, 1 in float32 summed in float32 first: 2^24 (float64 would keep 2^24 + 3).  U is
    float64.  Kills: the heads kept or the others dropped (where swapped), no heads test, step 0's numbers every
    step, the regeneration test off, the block summed in float64, U float32, the block one step short,
    chain_floor passing lanes and block swapped."""
    got = capture_device_timer(monkeypatch)
    assert bench.chain_floor(Chain([1.0, 2.0, 3.0, 4.0]), 3, 4, n=4096, reps=2) == 123.0
    assert (got["lanes"], got["block"], got["n"], got["reps"]) == (3, 4, 4096, 2)
    keys = jax.random.split(jax.random.key(0), 3)
    state, U = got["init"](3)
    assert U.dtype == jnp.float64 and not U.any()
    state, U = got["body"](keys, 0, (state, U))
    assert U.dtype == jnp.float64 and list(U) == [4.0] * 3 and list(state) == [4] * 3
    state, U = got["body"](keys, 1, (state, U))
    assert list(U) == [8.0] * 3
    bench.chain_floor(Chain([2.0 ** 24, 1.0, 1.0, 1.0], heads=False), 2, 4)
    _, U = got["body"](jax.random.split(jax.random.key(0), 2), 0, got["init"](2))
    assert list(U) == [2.0 ** 24] * 2


# ---------------------------------------------------------------- _numba_round


def test_numba_round_measures_each_baseline_with_its_own_run_and_lets_other_errors_through():
    """The PDMP rates come from the PDMP run, the DI's from the DI run (steps 100 and 7 per run, 1 s each); an
    error other than ``stopped`` is not taken for a stopped baseline.  Kills: the PDMP rates measured with the DI
    run; ``except Exception`` for ``except stopped``."""
    t = [0.0]

    def runner(steps):
        def run(model, n, threads, seed=None):
            t[0] += 1.0
            return None, steps
        return run

    real = bench.time
    try:
        bench.time = SimpleNamespace(perf_counter=lambda: t[0])
        m = bench._numba_round({}, (runner(100), "p"), (runner(7), "d"), 40, 0, Stop)
    finally:
        bench.time = real
    assert m == {"numba_pdmp_1t_events_per_s": 100.0, "numba_pdmp_2t_events_per_s": 100.0,
                 "numba_1t_steps_per_s": 7.0, "numba_2t_steps_per_s": 7.0}

    def bad(model, n, threads, seed=None):
        raise ValueError("not a work bound")
    out = {}
    with pytest.raises(ValueError, match="not a work bound"):
        bench._numba_round(out, (runner(1), "p"), (bad, "d"), 40, 0, Stop)
    assert out == {}


# ---------------------------------------------------------------- run_bench


def fake_engine_for_run_bench(monkeypatch, rates):
    """Fakes of everything run_bench measures; ``rates[name]`` is the list of that number's values in rounds 1,
    2, 3.  Returns the log of calls (in order)."""
    log, count = [], {}

    def next_value(name):
        i = count[name] = count.get(name, -1) + 1
        return rates[name][i]

    def estimate(p, seed, method="di", n_excursions=None, dtype=None, lanes=None):
        log.append(("estimate", method, seed, n_excursions, dtype, lanes))
        if n_excursions == 200:  # a compile run
            return None
        if method == "pdmp":
            return SimpleNamespace(events_per_s=next_value(f"pdmp_{dtype}"), delta=0.086)
        D, D_ci = (0.5, 0.05) if dtype == "float64" else (0.7, 0.14)
        return SimpleNamespace(lane_steps_per_s=next_value(f"di_{dtype}"), lane_utilization=0.9, D=D, D_ci=D_ci,
                               n_excursions=1000, wall_s=2.0)

    def plan(p, method="di", n_excursions=None):
        return SimpleNamespace(lanes=48, block=bench.BLOCK) if method == "pdmp" else SimpleNamespace(lanes=96,
                                                                                                      block=16)

    def rng_timer(dtype, lanes, block, n=None, via="engine"):
        name = ("rng" if via == "engine" else "jax") + f"_{jnp.dtype(dtype).name}"
        log.append(("timer", name, lanes, block, n))
        return lambda: (log.append(("time", name)), next_value(name))[1]

    def floor_timer(chain, lanes, block=bench.BLOCK, n=None):
        name = f"floor_{chain[0]}_{chain[1]}"
        log.append(("timer", name, lanes, block, n))
        return lambda: (log.append(("time", name)), next_value(name))[1]

    def duration(p, seed, n_excursions=None):  # the first call compiles: its numbers are not used
        log.append(("duration", seed, n_excursions))
        first = sum(c[0] == "duration" for c in log) == 1
        return SimpleNamespace(loop_steps=None if first else 6.0 * next_value("dur"), wall_s=6.0)

    monkeypatch.setattr(bench, "estimate_diffusivity", estimate)
    monkeypatch.setattr(bench, "di_long_excursion_duration", duration)
    monkeypatch.setattr(bench, "plan_estimate", plan)
    monkeypatch.setattr(bench, "rng_bound_timer", rng_timer)
    monkeypatch.setattr(bench, "chain_floor_timer", floor_timer)
    fake_models(monkeypatch)
    return log


RATES = dict(di_float64=[40.0, 10.0, 20.0], rng_float64=[80.0, 80.0, 10.0], jax_float64=[20.0, 40.0, 5.0],
             floor_di_float64=[50.0, 20.0, 25.0], di_float32=[60.0, 30.0, 90.0], rng_float32=[120.0, 100.0, 90.0],
             jax_float32=[30.0, 50.0, 30.0], floor_di_float32=[100.0, 60.0, 90.0], pdmp_float64=[30.0, 6.0, 12.0],
             floor_pdmp_float64=[60.0, 12.0, 6.0], pdmp_float32=[50.0, 10.0, 20.0],
             floor_pdmp_float32=[25.0, 20.0, 40.0], dur=[10.0, 5.0, 2.0])


def test_run_bench_times_every_number_in_rounds_and_reports_the_medians_of_each_rounds_ratios(monkeypatch):
    """run_bench with fakes, 3 rounds (values in RATES).  Each number: the median of its 3 rounds; each ratio:
    the median of its rounds' ratios (DI/bound float64: 0.5, 0.125, 2 -> 0.5; the ratio of the medians would be
    0.25); the 1% CI time from the float64 run: rel 0.05 / 0.5 = 0.1, N_1% = 1000 * (0.1 / 0.01)^2 = 1e5 runs of
    2 s per 1000 -> 200 s; the floors' and numba's work: N = 50 -> 2^20 lane-steps, min(30, 50) = 30 numba
    excursions.  Kills: wrong seeds, method, dtypes, lanes, block, via; the 1% arithmetic (rel inverted, not
    squared, float32's run, N asked for N run); floor_n and numba_excursions bounds; one round only; ratios not
    taken; the numba runs swapped or given N; the numba DI model not float64; the utilization key."""
    log = fake_engine_for_run_bench(monkeypatch, RATES)
    clock = Clock()
    monkeypatch.setattr(bench, "time", clock)
    ncalls = fake_numba(monkeypatch, clock)
    b = bench.run_bench(n_excursions=50, numba_excursions=30, seed=4, repeat=3)
    med = lambda xs: sorted(xs)[1]
    for name, key in (("di_float64", "di_float64_lane_steps_per_s"),
                      ("rng_float64", "rng_bound_float64_lane_steps_per_s"),
                      ("jax_float32", "jax_random_normal_float32_lane_steps_per_s"),
                      ("floor_di_float32", "di_chain_floor_float32_lane_steps_per_s"),
                      ("pdmp_float64", "pdmp_float64_events_per_s"),
                      ("floor_pdmp_float32", "pdmp_event_floor_float32_events_per_s")):
        assert b[key] == med(RATES[name]), key
        assert b["ranges"][key] == [min(RATES[name]), max(RATES[name])], key
    assert len(b["rounds"]) == 3 and b["repeat"] == 3
    R = RATES
    for key, num, den in (("ratio_di_float64_to_rng_bound", "di_float64", "rng_float64"),
                          ("ratio_rng_bound_float32_to_jax_random_normal", "rng_float32", "jax_float32"),
                          ("ratio_di_float32_to_chain_floor", "di_float32", "floor_di_float32"),
                          ("ratio_di_chain_floor_float64_to_rng_bound", "floor_di_float64", "rng_float64"),
                          ("ratio_pdmp_float64_to_event_floor", "pdmp_float64", "floor_pdmp_float64")):
        per_round = [a / c for a, c in zip(R[num], R[den])]
        assert [r[key] for r in b["rounds"]] == per_round, key
        assert b[key] == med(per_round), key
    # the duration count: loop_steps / wall_s = 10, 5, 2 over floors 50, 20, 25 -> 0.2, 0.25, 0.08; its N = 32
    assert b["di_duration_lane_steps_per_s"] == 5.0 and b["ratio_di_duration_to_chain_floor"] == 0.2
    assert [c for c in log if c[0] == "duration"] == [("duration", 4, 32)] + [("duration", 5, 32)] * 3
    assert b["di_duration_excursions"] == 32
    assert b["ratio_di_float64_to_rng_bound"] == 0.5 and b["di_float64_lane_steps_per_s"] == 20.0
    # numba: 2 s per run, steps 1000 * threads (DI) and 500 * threads (PDMP)
    assert (b["numba_1t_steps_per_s"], b["numba_2t_steps_per_s"]) == (500.0, 1000.0)
    assert (b["numba_pdmp_1t_events_per_s"], b["numba_pdmp_2t_events_per_s"]) == (250.0, 500.0)
    assert b["ratio_di_float32_to_numba_2t"] == med([x / 1000.0 for x in R["di_float32"]])
    assert b["ratio_pdmp_float64_to_numba_2t"] == med([x / 500.0 for x in R["pdmp_float64"]])
    assert sorted({c[:3] for c in ncalls}) == [("di", ("di", "float64"), 20), ("di", ("di", "float64"), 30),
                                               ("pdmp", ("pdmp", "float64"), 20), ("pdmp", ("pdmp", "float64"), 30)]
    assert all(c[4] == 4 for c in ncalls if c[2] == 30)
    assert (b["numba_version"], b["numba_rng"], b["numba_excursions"]) == ("0.0-fake", "fake-rng", 30)
    # the 1% CI from the float64 run
    assert (b["D"], b["D_ci"], b["di_float64_utilization"], b["pdmp_delta"]) == (0.5, 0.05, 0.9, 0.086)
    assert b["excursions_for_1pct"] == pytest.approx(1e5, rel=1e-12)
    assert b["time_to_1pct_ci_s"] == pytest.approx(200.0, rel=1e-12)
    assert (b["block"], b["di_lanes"], b["pdmp_lanes"], b["n_excursions"]) == (16, 96, 48, 50)
    # the layout of every timer and run: the plan's, 2^20 lane-steps (N = 50 is small)
    timers = [c[1:] for c in log if c[0] == "timer"]
    n = 1 << 20
    assert timers == [("rng_float64", 96, 16, n), ("jax_float64", 96, 16, n), ("floor_di_float64", 96, 16, n),
                      ("rng_float32", 96, 16, n), ("jax_float32", 96, 16, n), ("floor_di_float32", 96, 16, n),
                      ("floor_pdmp_float64", 48, bench.BLOCK, n), ("floor_pdmp_float32", 48, bench.BLOCK, n)]
    runs = [c[1:] for c in log if c[0] == "estimate"]
    assert runs[:2] == [("di", 4, 200, "float64", 96), ("di", 4, 200, "float32", 96)]  # compiled first, same layout
    assert runs[2:4] == [("pdmp", 4, 200, "float64", 48), ("pdmp", 4, 200, "float32", 48)]
    assert runs[4:8] == [("di", 5, 50, "float64", 96), ("di", 5, 50, "float32", 96),
                         ("pdmp", 5, 50, "float64", 48), ("pdmp", 5, 50, "float32", 48)]
    assert len(runs) == 4 + 4 * 3
    # one number after the other, in the documented order, every round
    order = [c[1] if c[0] == "time" else f"{c[1]}_{c[4]}" for c in log if c[0] == "time" or c[0] == "estimate"
             and c[3] != 200]
    assert order == 3 * ["di_float64", "rng_float64", "jax_float64", "floor_di_float64", "di_float32", "rng_float32",
                         "jax_float32", "floor_di_float32", "pdmp_float64", "floor_pdmp_float64", "pdmp_float32",
                         "floor_pdmp_float32"]


def test_run_bench_floor_and_numba_work_scale_with_n(monkeypatch):
    """floor_n = min(2^23, max(2^20, 840 N)); numba excursions = min(asked, max(20, N)): N = 5000 -> 4 200 000
    lane-steps and min(10^4, 5000) = 5000; N = 5 -> 2^20 and 20; N = 10^4 -> 2^23.  Kills: 84 N; max for min;
    numba's N unbounded above (max) or below (no floor of 20)."""
    for N, floor_n, nx in ((5000, 4_200_000, 5000), (5, 1 << 20, 20), (10_000, 1 << 23, 10_000)):
        log = fake_engine_for_run_bench(monkeypatch, {k: [1.0] for k in RATES})
        clock = Clock()
        monkeypatch.setattr(bench, "time", clock)
        calls = fake_numba(monkeypatch, clock)
        b = bench.run_bench(n_excursions=N, numba_excursions=10_000)
        assert {c[4] for c in log if c[0] == "timer"} == {floor_n}, N
        assert b["numba_excursions"] == nx and {c[2] for c in calls} == {20, nx}, N


def test_run_bench_without_numba_or_with_a_broken_one_says_so_and_keeps_the_rest(monkeypatch):
    """numba absent (ImportError) or broken (another error on import): ``numba`` says "unavailable (...)", no numba
    number or ratio, the engine's numbers are all there.  A baseline that stops (``BaselineIncomplete``) in round 2:
    "stopped (...)", no numba numbers.  Kills: ``except ImportError`` for ``except Exception``; run_bench handing
    _numba_round another exception than BaselineIncomplete."""
    for how in ("absent", "broken"):
        fake_engine_for_run_bench(monkeypatch, {k: [2.0] for k in RATES})
        if how == "absent":
            monkeypatch.setitem(sys.modules, "dryfric_jax.bench_numba", None)
        else:
            broken_numba(monkeypatch)
        b = bench.run_bench(n_excursions=50)
        want = "ModuleNotFoundError" if how == "absent" else "RuntimeError: numba is broken here"
        assert b["numba"].startswith(f"unavailable ({want}"), b["numba"]
        # an installed package has no checkout: the hint was only "pip install -e '.[bench]'" (a packaging audit)
        assert b["numba"].endswith("; pip install numba (the bench extra; in a checkout pip install -e '.[bench]')")
        assert not any("numba" in k and k != "numba_excursions" for k in b if k != "numba")
        assert b["ratio_di_float64_to_rng_bound"] == 1.0 and b["pdmp_float32_events_per_s"] == 2.0
    fake_engine_for_run_bench(monkeypatch, {k: [2.0, 2.0] for k in RATES})
    clock = Clock()
    monkeypatch.setattr(bench, "time", clock)
    fake_numba(monkeypatch, clock, stop_after=2)  # round 1: the 1- and 2-thread runs; round 2 stops
    b = bench.run_bench(n_excursions=50, repeat=2)
    assert b["numba"] == "stopped (worker 1 reached its work bound)"
    assert not any("numba" in k and (k.endswith("_per_s") or k.startswith("ratio")) for k in b)
    assert b["rounds"][0]["numba_2t_steps_per_s"] == 1000.0 and "numba_2t_steps_per_s" not in b["rounds"][1]


# ---------------------------------------------------------------- tune_layout


def fake_engine_for_tune(monkeypatch, rates, fail=(), clock=None):
    """Fakes for tune_layout: each run takes 1 s of ``clock``; a timed run of ``lanes`` in round r has rate
    ``rates[lanes][r]`` and wall time ``[1, 2, 6][r]`` s; D = seed / 10; compile runs of lanes in ``fail`` raise."""
    log, count = [], {}
    clock = clock or Clock()
    monkeypatch.setattr(bench, "time", clock)

    def estimate(p, seed, dtype=None, lanes=None, block=None, n_excursions=None):
        clock.t += 1.0
        log.append(dict(seed=seed, lanes=lanes, block=block, n=n_excursions, dtype=dtype,
                        events=excursions.DEFAULT_EVENTS, unroll=excursions.QUIET_UNROLL))
        if n_excursions == 200:
            if lanes in fail:
                raise RuntimeError("no kernel: " + "x" * 3000)
            return None
        r = count[lanes] = count.get(lanes, -1) + 1
        return SimpleNamespace(lane_steps_per_s=rates[lanes][r], wall_s=[1.0, 2.0, 6.0][r], n_excursions=n_excursions,
                               lane_utilization=0.75, D=seed / 10, D_ci=1.96, n_truncated=3, stopped_by="n_excursions")

    got = {}
    monkeypatch.setattr(bench, "estimate_diffusivity", estimate)
    def bound(dtype, lanes, block, n=None):
        got.update(bound=(dtype, lanes, block, n))
        return 400.0

    def floor(chain, lanes, block, n=None):
        got.update(floor=(chain, lanes, block, n))
        return 200.0
    monkeypatch.setattr(bench, "rng_bound", bound)
    monkeypatch.setattr(bench, "chain_floor", floor)
    fake_models(monkeypatch)
    clears = []
    monkeypatch.setattr(jax, "clear_caches", lambda: clears.append(excursions.QUIET_UNROLL))
    monkeypatch.setattr(excursions, "QUIET_UNROLL", 1)  # the package's defaults, whatever another test left
    monkeypatch.setattr(excursions, "DEFAULT_EVENTS", None)
    return log, got, clears, clock


def test_tune_layout_interleaves_rounds_and_reports_each_layouts_median_and_the_ratios_of_the_best(monkeypatch):
    """Layouts 16 and 64 lanes at K = 8, 3 rounds, unroll 3, events "fused", N = 300: the timed runs ask
    max(300, 8 lanes) = 300 and 512 excursions, with seeds 11 and 12 (seed + 1 + i), compiled once each with seed
    10 and 200 excursions, the rounds interleaved.  Rates [5, 1, 3] and [2, 9, 4]: medians 3 and 4 (means 3 and
    5, maxima 5 and 9); wall [1, 2, 6]: median 2; the best is 64 lanes at 4 lane-steps/s, against the bound 400
    (0.01), the floor 200 (0.02; floor / bound 0.5) and numba's 2 threads (800 steps in 2 s: 400/s, 0.01).  Kills:
    the seeds, N not raised to 8 lanes, the unroll or the event layout not set, one round only counted, the rows
    handed on wrong, mean or max for median, wall_s of one round, the ratios inverted, the bound at the default
    N, the floor's or numba's model in the wrong dtype, numba at 1 thread, best_block/unroll/events."""
    log, got, clears, clock = fake_engine_for_tune(monkeypatch, {16: [5.0, 1.0, 3.0], 64: [2.0, 9.0, 4.0]})
    ncalls = fake_numba(monkeypatch, clock, di_steps=400)
    unroll0, events0 = excursions.QUIET_UNROLL, excursions.DEFAULT_EVENTS
    assert unroll0 != 3 and events0 != "fused"
    seen = []
    b = bench.tune_layout([16, 64], [8], "float32", n_excursions=300, seed=10, numba_excursions=77, repeat=3,
                          unrolls=[3], events=["fused"], on_layout=seen.append, bound_n=1234)
    assert [(c["seed"], c["lanes"], c["n"]) for c in log] == [
        (10, 16, 200), (11, 16, 300), (10, 64, 200), (12, 64, 512), (11, 16, 300), (12, 64, 512), (11, 16, 300),
        (12, 64, 512)]
    assert all((c["unroll"], c["events"], c["dtype"], c["block"]) == (3, "fused", "float32", 8) for c in log)
    assert (excursions.QUIET_UNROLL, excursions.DEFAULT_EVENTS) == (unroll0, events0)  # restored
    assert clears == [3, unroll0]  # the unroll traced anew: caches cleared when it changes, both ways
    rows = b["layouts"]
    assert seen == rows and [r["lanes"] for r in rows] == [16, 64]
    assert [r["lane_steps_per_s"] for r in rows] == [3.0, 4.0]
    assert [r["lane_steps_per_s_range"] for r in rows] == [[1.0, 5.0], [2.0, 9.0]]
    assert [r["wall_s"] for r in rows] == [2.0, 2.0] and [r["n_excursions"] for r in rows] == [300, 512]
    assert rows[0]["compile_and_200_s"] == 1.0 and rows[0]["D"] == 1.1 and rows[1]["D"] == 1.2
    assert (rows[0]["utilization"], rows[0]["n_truncated"], rows[0]["stopped_by"]) == (0.75, 3, "n_excursions")
    assert (rows[0]["unroll"], rows[0]["events"], rows[0]["block"]) == (3, "fused", 8)
    assert (b["best_lanes"], b["best_block"], b["best_unroll"], b["best_events"]) == (64, 8, 3, "fused")
    assert b["best_lane_steps_per_s"] == 4.0
    assert got["bound"] == (jnp.dtype("float32"), 64, 8, 1234) and got["floor"] == (("di", "float32"), 64, 8, 1234)
    assert (b["rng_bound_lane_steps_per_s"], b["chain_floor_lane_steps_per_s"]) == (400.0, 200.0)
    assert b["ratio_best_to_rng_bound"] == 0.01 and b["ratio_best_to_chain_floor"] == 0.02
    assert b["ratio_chain_floor_to_rng_bound"] == 0.5
    assert b["numba_2t_steps_per_s"] == 400.0 and b["ratio_best_to_numba_2t"] == 0.01
    assert [c[1:] for c in ncalls] == [(("di", "float64"), 20, 1, None), (("di", "float64"), 77, 2, 10)]
    text = bench.format_layouts(b).splitlines()
    assert text[0].endswith("DI float32, Fig. 3 point; medians of 3 interleaved rounds [min-max]")
    assert text[2].split() == ["16", "8", "3", "fused", "300", "3", "0.750", "2.00", "1.1", "±", "2", "[1-5]"]


def test_tune_layout_budget_failures_and_settings(monkeypatch):
    """Each run takes 1 s: with a 2.5 s budget the first two layouts (2 s each) start, the third (started after
    4 s) is skipped; a layout whose compile run raises is listed as failed with its error (2000 characters at
    most), the others go on, and a sweep with none left raises with the engine's settings restored; numba absent,
    broken, stopped or not asked for (0 excursions).  Kills: the budget test reversed or attempts not counted, a
    skip not listed, the error without its type, the restore of the events or the unroll dropped or not in a
    ``finally``, the unavailable or stopped baseline not caught (``ImportError`` / ``RuntimeError``), numba run
    with 0 excursions, the compile run without its block, the first layout skipped when the budget is spent
    before it starts, the table's head saying float32 or "medians of 1 rounds"."""
    log, _, _, clock = fake_engine_for_tune(monkeypatch, {16: [1.0], 32: [2.0], 64: [3.0]})
    b = bench.tune_layout([16, 32, 64], [8], "float64", n_excursions=50, numba_excursions=0, budget_s=2.5)
    assert [r["lanes"] for r in b["layouts"]] == [16, 32]
    assert b["skipped"] == [dict(lanes=64, block=8, unroll=excursions.QUIET_UNROLL, events=None)]
    assert all(c["block"] == 8 for c in log)
    text = bench.format_layouts(b).splitlines()
    assert text[4].split()[-2:] == ["skipped", "(budget_s)"]
    assert text[0].endswith("CPU cores), DI float64, Fig. 3 point")  # one round: no "medians of" in the head
    # a budget spent before the first layout starts (each clock read 0.5 s later): the first runs all the same
    ticking = Clock()
    ticking.perf_counter = lambda: setattr(ticking, "t", ticking.t + 0.5) or ticking.t
    fake_engine_for_tune(monkeypatch, {16: [1.0], 32: [2.0]}, clock=ticking)
    b = bench.tune_layout([16, 32], [8], "float64", n_excursions=50, numba_excursions=0, budget_s=0.1)
    assert [r["lanes"] for r in b["layouts"]] == [16] and [r["lanes"] for r in b["skipped"]] == [32]
    # a failing layout; numba broken, absent, stopped
    for how in ("broken", "absent", "stopped", "zero"):
        fake_engine_for_tune(monkeypatch, {16: [1.0], 64: [3.0]}, fail=(32,))
        calls = []
        if how == "broken":
            broken_numba(monkeypatch)
        elif how == "absent":
            monkeypatch.setitem(sys.modules, "dryfric_jax.bench_numba", None)
        else:
            fake_numba(monkeypatch, clock, stop_after=0 if how == "stopped" else None, calls=calls)
        b = bench.tune_layout([16, 32, 64], [8], "float64", n_excursions=50,
                              numba_excursions=0 if how == "zero" else 40)
        assert [r["lanes"] for r in b["layouts"]] == [16, 64] and b["best_lanes"] == 64
        (f,) = b["failed"]
        assert (f["lanes"], f["block"], f["events"]) == (32, 8, None) and len(f["error"]) == 2000
        assert f["error"].startswith("RuntimeError: no kernel: xxx")
        want = dict(broken="unavailable (RuntimeError: numba is broken here)",
                    absent="unavailable (ModuleNotFoundError",
                    stopped="stopped (worker 1 reached its work bound)", zero=None)[how]
        if want is None:
            assert "numba" not in b and calls == []
        else:
            assert b["numba"].startswith(want), b["numba"]
        assert "ratio_best_to_numba_2t" not in b
    text = bench.format_layouts(b).splitlines()
    assert text[4] == "      32     8      1 default  failed: " + ("RuntimeError: no kernel: " + "x" * 200)[:200]
    assert not any("numba" in line for line in text)
    # nothing runs: raises, and the engine's settings are back
    fake_engine_for_tune(monkeypatch, {}, fail=(16,))
    unroll0, events0 = excursions.QUIET_UNROLL, excursions.DEFAULT_EVENTS
    with pytest.raises(ValueError, match="no layout ran"):
        bench.tune_layout([16], [8], "float64", n_excursions=50, numba_excursions=0, unrolls=[5], events=["branch"])
    assert (excursions.QUIET_UNROLL, excursions.DEFAULT_EVENTS) == (unroll0, events0)


# ---------------------------------------------------------------- format_table


def test_format_table_says_medians_with_a_single_range():
    """One number with a range: the "medians of R rounds" line is there (it was tested with two).  Kills: the
    line only with more than one range."""
    b = dict(device="cpu:0", n_devices=1, cpu_count=2, params={}, repeat=3, D=0.5, ranges=dict(D=[0.25, 0.75]),
             rounds=[{}, {}, {}])
    assert bench.format_table(b).splitlines() == [
        "device  cpu:0 (x1, 2 CPU cores)",
        "        medians of 3 rounds [min-max]; each ratio is taken within its round",
        "repeat  3", "D       0.5  [0.25-0.75]"]


def test_tune_layout_runs_a_layout_at_the_bound_skips_one_past_it_and_refuses_bad_settings(monkeypatch):
    """lanes * K = the bound (2^7 here) is a layout (``<=``): 16 x 8 runs, 32 x 8 is skipped, once; a dtype, a
    repeat, an unroll or an event layout out of range is refused before anything runs.  Kills: ``<`` for ``<=``
    in the fits and ``>=`` for ``>`` in the skipped (the bound's layout run and listed as skipped); the checks
    of the repeat, the unroll and the events dropped; only the first of several event layouts run."""
    log, _, _, _ = fake_engine_for_tune(monkeypatch, {16: [1.0]})
    monkeypatch.setattr(bench, "MAX_LAYOUT", 1 << 7)
    b = bench.tune_layout([16, 32], [8], "float64", n_excursions=50, numba_excursions=0)
    assert [(r["lanes"], r["block"]) for r in b["layouts"]] == [(16, 8)]
    assert [(r["lanes"], r["block"], r["reason"]) for r in b["skipped"]] == [(32, 8, "lanes * K > 2^28")]
    log, _, _, _ = fake_engine_for_tune(monkeypatch, {16: [1.0, 2.0]})
    b = bench.tune_layout([16], [8], "float64", n_excursions=50, numba_excursions=0, events=["wait", "branch"])
    assert [r["events"] for r in b["layouts"]] == ["wait", "branch"] and [c["events"] for c in log] == [
        "wait", "wait", "branch", "branch"]
    del log[:]
    for kw, word in ((dict(dtype="float16"), "dtype"), (dict(repeat=0), "repeat"), (dict(unrolls=[0]), "unroll"),
                     (dict(events=["bogus"]), "events")):
        with pytest.raises(ValueError, match=word):
            bench.tune_layout(**dict(dict(lanes_list=[16], blocks=[8], numba_excursions=0), **kw))
    assert log == []
