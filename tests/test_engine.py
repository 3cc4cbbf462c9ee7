"""Lane engine: unbiased under a budget, reproducibility, no recompilation, bounded work."""
import functools
import math
import warnings

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import dryfric_jax as dj
from dryfric_jax import rng
from dryfric_jax.di import DIModel, make_di_model
from dryfric_jax.estimators import long_excursion_estimates
from dryfric_jax.pdmp import PDMPModel, make_pdmp_model
from dryfric_jax.excursions import STAT_NAMES, _close, _run_round, compiled_round, init_lanes
from dryfric_jax.rounds import Lanes, run_round, simulate_long_excursions, steps_per_excursion


@pytest.mark.slow
@pytest.mark.parametrize("events", ["branch", "wait"])
def test_finish_in_flight_is_unbiased_and_dropping_is_not(events):
    """Heavy-tailed white-noise case, b = 0, ~7 excursions per lane (MODEL_NOTES section 4), against
    the exact D of the chain at h' = 0.02 (:func:`dryfric_jax.white_chain_law`; tau/h = 5e-7): 9.926,
    0.74% below the continuum's D' = 10.

    Finishing the in-flight excursion: the CI contains the exact value.  Dropping it (keeping only
    excursions that ended before the budget) fails the same test, on the low side.
    """
    from dryfric_jax.chain_law import white_chain_law

    p = dj.Params.from_nondim(1e-8)
    exact = white_chain_law(p, 0.02).D
    m = make_di_model(p, 0.02)
    per = steps_per_excursion(m, jax.random.key(0))
    budget = int(7 * per)
    kw = dict(block=16, events=events)
    fin = long_excursion_estimates(run_round(m, jax.random.key(1), 32768, budget, **kw).total())
    drop = long_excursion_estimates(run_round(m, jax.random.key(1), 32768, budget, finish_in_flight=False,
                                              **kw).total())
    assert abs(fin["D"] - exact) <= fin["D_ci"], (fin, exact)
    assert drop["D"] + drop["D_ci"] < exact, (drop, exact)  # biased low, outside its own CI


def test_default_lanes_by_backend(monkeypatch):
    from dryfric_jax.excursions import default_chunk_lanes, lanes_for
    assert (default_chunk_lanes("cpu"), default_chunk_lanes("gpu"), default_chunk_lanes("tpu")) == (4096, 2**18, 2**18)
    # the power of two at or below max(N/32, min(512, N)), at most the backend's chunk
    assert [lanes_for(n, 4096) for n in (100, 300, 20_000, 40_000, 10**6)] == [64, 256, 512, 1024, 4096]
    assert [lanes_for(n, 2**18) for n in (20_000, 10**6, 10**7, 10**9)] == [512, 16384, 262144, 262144]
    p = dj.Params(**dj.FIG3)
    assert dj.plan_estimate(p, n_excursions=10**6).lanes == 4096  # this CPU
    monkeypatch.setattr(jax, "default_backend", lambda: "gpu")
    assert dj.plan_estimate(p, n_excursions=10**6).lanes == 16384
    assert dj.plan_estimate(p, n_excursions=10**6, chunk_lanes=4096).lanes == 4096  # the caller's cap wins


def test_default_block_by_backend_and_method(monkeypatch):
    """K = 128 on a CPU and for the PDMP; 256 for the DI on a GPU (measured faster there); halved
    while lanes * K would pass the layout bound; a K the caller gives is kept (and checked)."""
    from dryfric_jax.excursions import default_block
    assert [default_block(m, None, b) for m in ("di", "pdmp") for b in ("cpu", "gpu")] == [128, 256, 128, 128]
    assert [default_block("di", n, "gpu") for n in (2**18, 2**20, 2**21, 2**22)] == [256, 256, 128, 64]
    assert [default_block("pdmp", n, "cpu") for n in (2**21, 2**22)] == [128, 64]
    p = dj.Params(**dj.FIG3)
    assert dj.plan_estimate(p).block == 128  # this CPU
    assert dj.plan_estimate(p, n_excursions=10**9, lanes=2**22, max_work=1e16).block == 64
    monkeypatch.setattr(jax, "default_backend", lambda: "gpu")
    assert [dj.plan_estimate(p, method=m).block for m in ("di", "pdmp")] == [256, 128]
    assert dj.plan_estimate(p, block=64).block == 64
    with pytest.raises(ValueError, match="lanes \\* block"):
        dj.plan_estimate(p, n_excursions=10**9, lanes=2**22, block=128, max_work=1e16)


def test_same_seed_bit_identical():
    p = dj.Params.from_nondim(0.3, 2.0, 0.2)
    a, _ = simulate_long_excursions(make_di_model(p, 0.02), jax.random.key(5), 300, lanes=8)
    b, _ = simulate_long_excursions(make_di_model(p, 0.02), jax.random.key(5), 300, lanes=8)
    assert np.array_equal(a.stats, b.stats) and a.n_excursions >= 300


def test_second_call_does_not_recompile():
    p1, p2 = dj.Params.from_nondim(0.3), dj.Params.from_nondim(0.5, 1.0, 0.1)
    simulate_long_excursions(make_di_model(p1, 0.02), jax.random.key(0), 64, lanes=16, block=8)
    n = compiled_round(DIModel, 8)._cache_size()
    assert n >= 1  # the counted function is the one that ran
    # new parameters, new seed, other budgets and round counts: same shapes, compiled loop reused
    simulate_long_excursions(make_di_model(p2, 0.05), jax.random.key(1), 500, lanes=16, block=8)
    assert compiled_round(DIModel, 8)._cache_size() == n


@pytest.mark.parametrize("events", ["branch", "wait"])
@pytest.mark.parametrize("method", ["di", "pdmp"])
def test_both_event_layouts_keep_the_round_accounting(method, events):
    """Both layouts of a block (CPU "branch", GPU "wait", ``_block``): a fresh paused round runs
    every lane for ceil(budget / block) blocks: exactly budget steps in "branch", fewer in
    "wait" (the idle rest of a block after an event); a final round then closes every in-flight
    excursion; truncations are counted; useful steps never exceed the steps taken."""
    p = dj.Params.from_nondim(0.5, 1.0, 0.2)
    chain = make_di_model(p, 0.02) if method == "di" else make_pdmp_model(p, 0.3)
    budget = 3000
    ln = Lanes(chain, 32, block=8, max_steps=1500 if method == "di" else 150, events=events)
    assert ln.events == events
    a = ln.advance(jax.random.key(1), budget)
    work = np.asarray(ln.lane.work)
    assert np.all(work == budget) if events == "branch" else (np.all(work <= budget) and work.min() < budget)
    assert a.n_unfinished == 0 and a.n_in_flight > 0
    slots = ln.slot_steps
    assert a.useful_steps <= work.sum() and slots == 32 * 375 * 8
    b = ln.finish(jax.random.key(2), 2000)
    assert b.n_unfinished == 0 and b.n_truncated > 0 and b.n_excursions > 50
    assert np.all(np.asarray(ln.lane.phase) == 0)  # SEEK: nothing left in flight


def test_unknown_event_layout_is_refused():
    with pytest.raises(ValueError, match="events must be one of"):
        Lanes(make_di_model(dj.Params.from_nondim(0.5), 0.02), 8, events="every")


@pytest.mark.parametrize("dtype", ["float64", "float32"])
def test_fused_kernel_is_the_wait_loop_bit_for_bit(dtype):
    """The "fused" layout (the wait loop as one Pallas kernel, run by Pallas's interpreter on a
    CPU) is the "wait" loop step for step: the same sums, steps and slots, bit for bit, in a
    final round with refills, coins, budget stops and truncations.  96 lanes on 2 devices are 48
    per device, so the kernel's tiles are 16 lanes (fused.tile_for), not 256."""
    from dryfric_jax.fused import tile_for

    p = dj.Params.from_nondim(0.5, 1.0, 0.2)
    m = make_di_model(p, 0.02, dtype)
    runs = {ev: run_round(m, jax.random.key(5), 96, 1500, block=32, max_steps=1200, events=ev)
            for ev in ("wait", "fused")}
    w, f = runs["wait"], runs["fused"]
    assert w.n_excursions > 50 and w.n_truncated > 0  # the events of every kind happened
    assert np.array_equal(w.stats, f.stats) and np.array_equal(w.lane_steps, f.lane_steps)
    assert (w.n_truncated, w.useful_steps, w.slot_steps) == (f.n_truncated, f.useful_steps, f.slot_steps)
    assert [tile_for(n) for n in (1 << 18, 48, 96, 7)] == [256, 16, 32, 1]


@pytest.mark.skipif(jax.default_backend() != "cpu", reason="the stacked loop is a CPU layout")
@pytest.mark.parametrize("block", [32, 33])
def test_the_stacked_float64_quiet_loop_is_the_two_array_loop_bit_for_bit(monkeypatch, block):
    """The float64 DI's quiet loop carries (X, V) and (U, at) stacked, two steps an iteration (excursions.STACKED_QUIET,
    x1.04-1.07 on whole runs): the same sums, steps and slots, bit for bit, as the two-array loop, in a final round with
    refills, coins, budget stops and truncations; it is the loop traced at an even K (its barrier seen), and an odd
    K keeps the two-array loop.  Mutant: the barrier dropped (XLA fuses the two steps; D moved in its last digits)."""
    from dryfric_jax import excursions

    barriers, real = [], jax.lax.optimization_barrier
    monkeypatch.setattr(jax.lax, "optimization_barrier", lambda x: barriers.append(1) or real(x))
    m = make_di_model(dj.Params.from_nondim(0.5, 1.0, 0.2), 0.02, "float64")
    runs = {}
    try:
        for stacked in (True, False):
            monkeypatch.setattr(excursions, "STACKED_QUIET", stacked)
            jax.clear_caches()  # the flag is read when the loop is traced
            runs[stacked] = run_round(m, jax.random.key(5), 96, 1500, block=block, max_steps=1200, events="wait")
            if stacked:
                assert bool(barriers) == (block % 2 == 0)
                barriers.clear()
    finally:
        monkeypatch.undo()
        jax.clear_caches()  # no later test runs a loop traced with the flag off
    a, b = runs[True], runs[False]
    assert a.n_excursions > 50 and a.n_truncated > 0 and not barriers
    assert np.array_equal(a.stats, b.stats) and np.array_equal(a.lane_steps, b.lane_steps)
    assert (a.n_truncated, a.useful_steps, a.slot_steps) == (b.n_truncated, b.useful_steps, b.slot_steps)


def test_fused_layout_is_only_for_the_di():
    p = dj.Params.from_nondim(0.5, 1.0, 0.2)
    with pytest.raises(ValueError, match="events 'fused' is only for the DI"):
        Lanes(make_pdmp_model(p, 0.3), 8, events="fused")


def test_default_event_layout_by_device_and_chain():
    """The default layout: the chain's own on a CPU (DI "wait", PDMP "branch"); on an NVIDIA GPU
    "fused" for the DI (its numbers are "wait"'s, bit for bit) and "wait" for the PDMP; "wait"
    on another accelerator.  An explicit layout wins everywhere."""
    from dryfric_jax.excursions import _events_layout

    class Dev:
        def __init__(self, platform, name):
            self.platform, self.name = platform, name

        def __str__(self):
            return self.name

    p = dj.Params.from_nondim(0.5, 1.0, 0.2)
    di, pdmp = make_di_model(p, 0.02), make_pdmp_model(p, 0.3)
    cpu, cuda, rocm = Dev("cpu", "TFRT_CPU_0"), Dev("gpu", "cuda:0"), Dev("gpu", "rocm:0")
    got = {(d.name, type(c).__name__): _events_layout((d,), c, None) for d in (cpu, cuda, rocm) for c in (di, pdmp)}
    assert got == {("TFRT_CPU_0", "DIModel"): "wait", ("TFRT_CPU_0", "PDMPModel"): "branch",
                   ("cuda:0", "DIModel"): "fused", ("cuda:0", "PDMPModel"): "wait",
                   ("rocm:0", "DIModel"): "wait", ("rocm:0", "PDMPModel"): "wait"}
    assert _events_layout((cuda,), di, "wait") == "wait" and _events_layout((cpu,), di, "fused") == "fused"


@pytest.mark.parametrize("events", ["branch", "wait"])
@pytest.mark.parametrize("method", ["di", "pdmp"])
def test_final_round_compaction_runs_the_same_chains(method, events):
    """Compaction moves the lanes still in flight to a smaller batch, each with its own key and
    block count: the sums must be exactly those of the uncompacted round, for fewer slots."""
    p = dj.Params.from_nondim(0.5, 1.0, 0.2)
    chain = make_di_model(p, 0.02) if method == "di" else make_pdmp_model(p, 0.3)
    out = []
    for compact in (False, True):
        ln = Lanes(chain, 256, block=8, max_steps=1500, compact=compact, events=events)
        assert ln.compact == compact
        ln.advance(jax.random.key(1), 3000)
        out.append((ln.finish(jax.random.key(2), 2000), ln.slot_steps))
    (a, slots_a), (b, slots_b) = out
    assert np.array_equal(a.stats, b.stats) and np.array_equal(a.lane_steps, b.lane_steps)
    assert (a.n_truncated, a.useful_steps, a.n_unfinished) == (b.n_truncated, b.useful_steps, b.n_unfinished)
    assert a.n_excursions > 1000 and b.n_unfinished == 0
    assert slots_b < slots_a


@pytest.mark.parametrize("events", ["branch", "wait"])
def test_round_block_bound_counts_from_the_lane_with_fewest_blocks(events):
    """A compacted batch mixes lanes whose devices ran different block counts (``b0``).  The
    round's safety bound (budget + max_steps steps) must hold for the lane with the fewest
    blocks behind it; counted from the largest ``b0`` it cut that lane short (seen with 2 devices
    once the DI's coins changed stream)."""
    chain = make_pdmp_model(dj.Params.from_nondim(0.5, 1.0, 0.2), 0.3)
    block = 8
    budget, max_steps = 64 * block, 2 * block  # lane 0 needs >= 64 blocks to spend its budget
    keys = jax.random.split(jax.random.key(3), 2)
    i64 = lambda v: jnp.asarray(v, jnp.int64)  # noqa: E731
    lane, nb = _run_round(chain, init_lanes(chain, 2), keys, i64([0, 60]), i64(budget), i64(max_steps),
                          jnp.asarray(True), i64(0), jnp.asarray(True), i64(2**62), block=block, events=events)
    assert bool(jnp.all(lane.done)) and int(lane.work[0]) >= budget


@pytest.mark.parametrize("events", ["branch", "wait"])
@pytest.mark.parametrize("method", ["di", "pdmp"])
def test_final_round_in_many_calls_equals_one_call(method, events, monkeypatch):
    """A final round runs in calls of at most FINAL_CALL_LANE_STEPS lane-steps (so a Ctrl-C acts
    between them): one block per call, compaction included, gives the same lanes as the default."""
    from dryfric_jax import rounds

    p = dj.Params.from_nondim(0.5, 1.0, 0.2)
    chain = make_di_model(p, 0.02) if method == "di" else make_pdmp_model(p, 0.3)
    # a small work bound: a wrong block count between calls could otherwise run ~max_steps calls (a hang)
    one = run_round(chain, jax.random.key(4), 128, 600, block=8, events=events, max_steps=5000)
    calls = []
    real = Lanes._call_once
    monkeypatch.setattr(Lanes, "_call_once", lambda *a: calls.append(1) or real(*a))
    monkeypatch.setattr(rounds, "FINAL_CALL_LANE_STEPS", 1)  # one block per call
    many = run_round(chain, jax.random.key(4), 128, 600, block=8, events=events, max_steps=5000)
    assert len(calls) > 50  # the round really was split
    assert np.array_equal(one.stats, many.stats) and np.array_equal(one.lane_steps, many.lane_steps)
    assert (one.slot_steps, one.n_truncated, one.n_unfinished) == (many.slot_steps, many.n_truncated,
                                                                  many.n_unfinished)


@pytest.mark.parametrize("events", ["branch", "wait"])
@pytest.mark.parametrize("method", ["di", "pdmp"])
def test_paused_rounds_in_many_calls_equal_one_call(method, events, monkeypatch):
    """A paused round's calls are cut by time (once a block is timed) so that a Ctrl-C acts between them: with three
    blocks per call (which divides neither round: the last call of each is shorter), two paused rounds and the final
    one give the lanes and sums of the default calls."""
    from dryfric_jax import rounds

    p = dj.Params.from_nondim(0.5, 1.0, 0.2)
    chain = make_di_model(p, 0.02) if method == "di" else make_pdmp_model(p, 0.3)

    calls, real = [], Lanes._call_once
    monkeypatch.setattr(Lanes, "_call_once", lambda *a: calls.append(1) or real(*a))

    def run():
        calls.clear()
        ln = Lanes(chain, 64, block=8, events=events, max_steps=5000)
        ln._block_s = 1.0  # as if timed
        out = [ln.advance(jax.random.key(1), 200), ln.advance(jax.random.key(2), 300)]
        paused = len(calls)
        return out + [ln.finish(jax.random.key(3))], ln, paused

    default, ln_default, paused = run()
    assert paused == 2
    monkeypatch.setattr(rounds, "FINAL_CALL_S", 0.0)
    monkeypatch.setattr(rounds, "FINAL_CALL_MIN_BLOCKS", 3)
    split, ln_split, paused = run()
    assert paused == 9 + 13  # the paused rounds' ceil(200 / 8) = 25 and ceil(300 / 8) = 38 blocks, 3 a call
    for a, b in zip(default, split):
        assert np.array_equal(a.stats, b.stats) and np.array_equal(a.lane_steps, b.lane_steps)
        assert (a.slot_steps, a.n_truncated, a.n_unfinished) == (b.slot_steps, b.n_truncated, b.n_unfinished)
    assert ln_default.paid == ln_split.paid


@pytest.mark.parametrize("final", [False, True])
def test_ctrl_c_acts_between_the_calls_of_a_round(monkeypatch, final):
    """A KeyboardInterrupt arriving during a round's calls leaves it at the next call's return, instead of after
    every in-flight excursion has finished (a final round) or after the whole round (a paused one: ~50 s on one
    PDMP lane); the lanes keep the state of the last completed round."""
    from dryfric_jax import rounds

    chain = make_di_model(dj.Params.from_nondim(0.5, 1.0, 0.2), 0.02)
    ln = Lanes(chain, 64, block=8)
    ln.advance(jax.random.key(0), 400)
    before = ln.lane
    calls, real = [], Lanes._call_once

    def interrupted(*a):
        calls.append(1)
        if len(calls) == 3:
            raise KeyboardInterrupt  # as Python raises it once the call returns
        return real(*a)

    monkeypatch.setattr(Lanes, "_call_once", interrupted)
    if final:
        monkeypatch.setattr(rounds, "FINAL_CALL_LANE_STEPS", 1)
    else:  # cut by time (a paused round's budget bounds it, not the lane-steps)
        monkeypatch.setattr(rounds, "FINAL_CALL_S", 0.0)
        monkeypatch.setattr(rounds, "FINAL_CALL_MIN_BLOCKS", 1)
    with pytest.raises(KeyboardInterrupt):
        ln.finish(jax.random.key(1)) if final else ln.advance(jax.random.key(1), 400)
    assert len(calls) == 3 and ln.lane is before


@pytest.mark.parametrize("where", ["before the round is kept", "as the round is kept"])
def test_a_ctrl_c_at_the_end_of_a_round_never_runs_a_kept_rounds_key_again(monkeypatch, where):
    """Round r runs on fold_in(key, r).  The lanes were kept before the round's stats were built and before the
    caller counted the round, so a Ctrl-C in between (a window of microseconds; injected here) ran the final round
    on the key of the paused round just kept, on lanes that had used it (a reproducibility audit).  Now a round
    is kept all at once, after its stats: a Ctrl-C before that reruns it on the same key from the same lanes (not
    kept), one during it waits for its end and the round is kept; either way no kept round's key runs again, and
    the kept rounds' keys are fold_in(key, 0), fold_in(key, 1), ... in order."""
    import contextlib

    from dryfric_jax import rounds

    chain = make_di_model(dj.Params.from_nondim(0.5, 1.0, 0.2), 0.02)
    key, seen, real = jax.random.key(3), [], Lanes._round

    def recording(self, k, *a, **kw):
        before = self.lane
        try:
            return real(self, k, *a, **kw)
        finally:  # kept: the lanes moved on
            seen.append((np.asarray(jax.random.key_data(k)).tobytes(), self.lane is not before))

    monkeypatch.setattr(Lanes, "_round", recording)
    calls = [0]
    if where == "before the round is kept":
        real_stats = rounds.ExcursionStats

        def stats(*a):
            calls[0] += 1
            if calls[0] == 2:  # the second round's stats
                raise KeyboardInterrupt
            return real_stats(*a)
        monkeypatch.setattr(rounds, "ExcursionStats", stats)
    else:
        real_held = rounds.held_interrupts

        @contextlib.contextmanager
        def held():
            with real_held():
                yield
            calls[0] += 1
            if calls[0] == 2:  # a signal held over the second round's keeping, raised at its end
                raise KeyboardInterrupt
        monkeypatch.setattr(rounds, "held_interrupts", held)
    total, stopped = simulate_long_excursions(chain, key, 2000, lanes=64, block=8)
    assert stopped == "interrupted" and calls[0] >= 2 and len(seen) >= 3
    assert seen[1][1] == (where == "as the round is kept")
    kept = [k for k, ok in seen if ok]
    assert kept == [np.asarray(jax.random.key_data(jax.random.fold_in(key, i))).tobytes() for i in range(len(kept))]
    assert total.n_excursions >= 2 and total.n_in_flight == 0  # the final round finished the excursions in flight


def test_max_time_cuts_the_final_round_and_counts_what_it_cut(monkeypatch):
    """max_time bounds the run at about FINAL_DEADLINE x max_time: the rounds stop once max_time has
    passed, and the final round, which finishes the excursions in flight, stops between its calls
    once the deadline has; the lanes it cut are counted (n_unfinished, reported as truncated).
    Before, the final round finished every in-flight excursion whatever max_time said: at
    Gamma = 1e30 (excursions ~1e17 times longer than planned) a 30-s run had not ended after 2
    minutes.  A fake clock, one second per reading, makes this independent of the machine."""
    from dryfric_jax import rounds

    chain = make_di_model(dj.Params.from_nondim(0.5, 1.0, 0.2), 0.005)  # excursions of ~10^3 steps
    clock = iter(range(10**6))
    monkeypatch.setattr(rounds, "_now", lambda: float(next(clock)))
    monkeypatch.setattr(rounds, "FINAL_CALL_LANE_STEPS", 1)  # one block per call of the final round
    monkeypatch.setattr(rounds, "FINAL_CALL_S", 1e9)  # no call cut by (real) time: a paused round is one call
    calls, real = [], Lanes._call_once
    monkeypatch.setattr(Lanes, "_call_once", lambda *a: calls.append(1) or real(*a))
    st, stopped = simulate_long_excursions(chain, jax.random.key(3), 10**6, lanes=64, block=8, pilot_budget=64,
                                           max_time=5.0)
    assert stopped == "max_time" and 0 < st.n_unfinished <= 64
    # t_start reads 0, each paused round 1 (stopping at 5), each call of the final round 1 (cut at 10)
    assert len(calls) == 5 + 5
    # the API reports it: the cut excursions count as truncated (the CLI exits 3), and it says why
    p = dj.Params.from_nondim(0.5, 1.0, 0.2)
    with pytest.warns(dj.DryfricWarning, match="was cut at 2 x max_time"):
        r = dj.estimate_diffusivity(p, 3, h=0.005 * p.tau0, n_excursions=10**6, lanes=64, block=8, max_time=2.0)
    assert r.stopped_by == "max_time" and r.n_truncated > 0 and not any("Ctrl-C" in w for w in r.warnings)


def test_no_compacted_tail_starts_past_the_deadline(monkeypatch):
    """The final round's compacted tail is further calls: past the deadline none starts, and the
    lanes still in flight are counted as unfinished.  It used to start one (a new shape to compile:
    a --max-time 3 run took 15 s on 2 cores, audit).  Before the deadline the tail runs as usual."""
    from dryfric_jax import rounds

    chain = make_di_model(dj.Params.from_nondim(0.5, 1.0, 0.2), 0.02)
    got = {}
    for past in (False, True):
        monkeypatch.setattr(rounds, "_now", lambda: 10.0 if past else 0.0)
        ln = Lanes(chain, 256, block=8, max_steps=1500)
        ln.advance(jax.random.key(1), 3000)
        calls, real = [], Lanes._call_once
        monkeypatch.setattr(Lanes, "_call_once", lambda self, lane, *a: calls.append(lane.done.shape[0])
                            or real(self, lane, *a))
        got[past] = ln.finish(jax.random.key(2), 2000, deadline=5.0), calls
        monkeypatch.setattr(Lanes, "_call_once", real)
    (st, calls), (cut, calls_cut) = got[False], got[True]
    assert st.n_unfinished == 0 and min(calls) == 256 // 8  # the tail ran on 1/8 of the lanes
    assert calls_cut == [256] and 0 < cut.n_unfinished <= 256 // 8


def test_pilot_rounds_stay_within_a_rounds_lane_steps(monkeypatch):
    """Before any excursion closes, the pilot budget grows 4x per round but no further than
    round_lane_steps per round, as later rounds: it grew without bound (one pilot round of a case
    whose excursions were far longer than planned ran for minutes, deaf to max_time and Ctrl-C)."""
    chain = make_di_model(dj.Params.from_nondim(0.5, 1.0, 0.2), 0.005)  # excursions of ~10^3 steps
    seen, real = [], Lanes.advance

    def advance(self, key, budget):
        st = real(self, key, budget)
        seen.append((budget, st.n_excursions + st.n_truncated))
        return st

    monkeypatch.setattr(Lanes, "advance", advance)
    # bounded, so that a defect cannot hang the suite (a mutant that ran every round on one key cycled the lanes
    # through the same numbers for ~10 min under the default bounds): ~5e4 lane-steps are needed
    simulate_long_excursions(chain, jax.random.key(3), 40, lanes=16, block=8, pilot_budget=16,
                             round_lane_steps=16 * 64, max_steps=10**5, max_work=10**8)
    pilot = [b for (b, _), closed_before in zip(seen, [0] + [c for _, c in seen]) if closed_before == 0]
    assert len(pilot) >= 3 and max(pilot) == 64, pilot  # 16, 64, 64, ...; it was 16, 64, 256, ...


@pytest.mark.parametrize("events", ["branch", "wait"])
def test_every_lane_finishes_in_flight_and_work_is_bounded(events):
    m = make_di_model(dj.Params.from_nondim(0.1), 0.02)
    budget, max_steps = 500, 10**6
    r = run_round(m, jax.random.key(2), 64, budget, max_steps=max_steps, events=events)
    assert r.n_unfinished == 0 and r.n_truncated == 0
    assert r.n_excursions > 0 and 0 < r.useful_steps <= r.slot_steps
    # a lane stops within budget + max_steps + 1 steps: with max_steps about twice the mean
    # excursion (~1060 steps here) the bound is tight, and some excursions are truncated
    budget, max_steps, block = 500, 2000, 64
    ln = Lanes(m, 64, block=block, max_steps=max_steps, events=events)
    r = ln.finish(jax.random.key(2), budget)
    assert r.n_unfinished == 0 and r.n_truncated > 0 and r.n_excursions > 0
    work = np.asarray(ln.lane.work)
    assert work.max() <= budget + max_steps + 1 and work.max() > budget + max_steps // 2
    if events == "branch":  # whole blocks: the slots are bounded by the same steps plus one block
        assert r.slot_steps <= 64 * (budget + max_steps + block)
    else:  # "wait" idles the rest of a block after each event, and takes at least one step per block
        assert r.slot_steps <= 64 * (budget + max_steps + 1) * block


@pytest.mark.parametrize("events", ["branch", "wait"])
def test_di_durations_are_the_lanes_counted_steps(events):
    r"""A DI lane's summed durations are its counted steps times h, to the step: for every lane,
    ``lane_steps - stats_t / h`` is exactly 1 if the lane opened an excursion and 0 if it never did.

    From ``_book`` (DI: ``regen_after_step`` False, t = n h with h the chain's ``fixed_dt``): the
    regenerating step that opens an excursion is counted in ``steps`` and is the excursion's first
    step (n = 1 after it); every later step is counted in both, and a closing step that refills is
    the next excursion's first step.  Seek steps are counted in neither.  Once the budget is
    spent, the closing step opens nothing: it is counted in ``steps`` (phase MINUS) but in no
    excursion, and the lane stops there (``_budget_stop``), so it happens once per lane.  A
    truncated excursion would be counted in ``steps`` only: none here (``n_truncated == 0``).
    The comparison is exact up to the float64 rounding of t: a sum of k products n h, so
    :math:`|t/h - \sum n| \le (k + 2)\,\epsilon\, t/h` (< 1e-11 here).  A closed excursion's t
    counting one extra step gives 1 - k (k >= 2 excursions per lane here)."""
    m = make_di_model(dj.Params.from_nondim(0.5, 1.0, 0.2), 0.02)
    h = float(m.fixed_dt)
    r = run_round(m, jax.random.key(3), 64, 3000, block=8, events=events)
    assert r.n_truncated == 0 and r.n_unfinished == 0 and r.n_excursions > 100
    s = dict(zip(STAT_NAMES, r.stats.T))
    steps = np.asarray(r.lane_steps)
    assert steps.sum() == r.useful_steps
    t_steps = s["t"] / h
    rounding = (s["n"] + 2) * np.finfo(float).eps * t_steps
    assert np.all(np.abs(t_steps - np.rint(t_steps)) <= rounding)
    # the exact admissible difference (docstring): 1 for a lane that ran an excursion, 0 otherwise
    np.testing.assert_array_equal(steps - np.rint(t_steps).astype(np.int64), (steps > 0).astype(np.int64))


@pytest.mark.parametrize("events", ["branch", "wait"])
def test_di_truncated_excursions_are_counted_once_at_exactly_max_steps(events):
    r"""The work bound's accounting, lane by lane, over a paused and a final round: a lane's counted
    steps are those of its complete excursions (t / h), plus exactly ``max_steps`` per truncated
    excursion (closed by the work bound once its n reaches ``max_steps``), plus 1 if its last
    closing step opened nothing (:func:`test_di_durations_are_the_lanes_counted_steps`).  A seek
    that reaches ``max_steps`` is restarted but is no excursion: it is counted neither in the
    steps nor in ``n_truncated``.  ``max_steps`` near the mean excursion (~10^3 steps) truncates
    both excursions and seeks (a seek after a truncation starts anywhere).  Counting the seeks as
    truncated, or closing a runaway one step late (``n > max_steps``, or the "wait" layout's work
    bound event one step late), fails the identity.  A final round of budget 0 closes exactly the
    excursions in flight (``n_in_flight``; counting only those in the -HLE passed), and a paused
    round runs ceil(budget / block) blocks (floor passed: the other tests use multiples of the
    block).  Each mutant passed every test before (mutation audit)."""
    m = make_di_model(dj.Params.from_nondim(0.5, 1.0, 0.2), 0.02)
    h, max_steps = float(m.fixed_dt), 900
    ln = Lanes(m, 64, block=8, max_steps=max_steps, events=events)
    a = ln.advance(jax.random.key(5), 2001)
    assert ln.slot_steps == 64 * 251 * 8  # ceil(2001 / 8) blocks, budget not a multiple of the block
    # budget 0 (what simulate_long_excursions runs): the final round closes the in-flight excursions, opens none
    r = ln.finish(jax.random.key(6))
    assert r.n_unfinished == 0 and r.n_excursions > 50
    assert r.n_excursions + r.n_truncated == a.n_excursions + a.n_truncated + a.n_in_flight
    n_trunc = np.asarray(ln.lane.n_trunc)[:64]
    assert n_trunc.sum() == r.n_truncated >= 10
    t_steps = np.rint(r.stats[:, STAT_NAMES.index("t")] / h).astype(np.int64)
    extra = np.asarray(r.lane_steps) - t_steps - max_steps * n_trunc
    assert set(extra.tolist()) <= {0, 1} and r.lane_steps.sum() == r.useful_steps, extra


def test_di_lane_sums_match_a_step_by_step_rebuild_of_each_lane():
    r"""The engine's per-lane sums equal those of each lane rebuilt one step at a time from the same
    numbers (``"branch"`` layout: lane key ``split(key, lanes)[l]``, block key ``fold_in(lane_key,
    b)``, normals ``chain.draw``, step i's coin key ``fold_in(chain.coin_key(block_key), i)``), with
    the bookkeeping written out here from the definition (section 4; DI: the regenerating step is
    the new cycle's first step): seek a regeneration on C_+, the +HLE runs to one on C_-, the
    -HLE to the next on C_+, which closes the excursion and opens the next.  Every closed
    excursion's U, U^2, t = n h, t U and t_half, and the lane's counted steps, must agree: the
    engine adds in blocks, so to float64 rounding.  A first excursion that missed its opening
    step (found by mutation: no CI-based test can see one step) fails here."""
    m = make_di_model(dj.Params.from_nondim(0.5, 1.0, 0.2), 0.02)
    h, block, lanes, key = float(m.fixed_dt), 8, 4, jax.random.key(3)
    r = run_round(m, key, lanes, 1500, block=block, events="branch")
    s = dict(zip(STAT_NAMES, r.stats.T))
    assert r.n_truncated == 0 and r.n_unfinished == 0 and s["n"].min() >= 2

    @jax.jit
    def draw(lane_key, b):
        bkey = jax.random.fold_in(lane_key, b)
        return m.draw(bkey, block), m.coin_key(bkey)

    @jax.jit
    def step(X, V, z1, z2, watch_plus, ck, i):
        _, Xn, Vn, dU = m.move(X, V, z1, z2)
        released = jnp.where(watch_plus, Vn > 0, Vn < 0)
        cand = (V == 0) & released & m._set(watch_plus).contains(X)
        return Xn, Vn, dU, cand & m.coin((X, V), (z1, z2), watch_plus, jax.random.fold_in(ck, i))

    for lane, lane_key in enumerate(jax.random.split(key, lanes)):
        X, V = (a[0] for a in m.init_state(1))
        phase, U, n, t_half, counted, closed = "seek", 0.0, 0, 0.0, 0, []
        b = 0
        while len(closed) < int(s["n"][lane]):
            (z1, z2), ck = jax.device_get(draw(lane_key, b))
            for i in range(block):
                X, V, dU, heads = step(X, V, z1[i], z2[i], phase != "plus", ck, i)
                dU, heads = jax.device_get((dU, heads))
                if phase == "minus" and heads:  # closes the excursion; this step opens the next
                    closed.append((U, n * h, t_half))
                if heads and phase != "plus":
                    phase, U, n = "plus", 0.0, 0
                elif heads:  # on C_-: the -HLE starts with this step
                    phase, t_half = "minus", n * h
                if phase != "seek":
                    U, n, counted = U + dU, n + 1, counted + 1
                if len(closed) == int(s["n"][lane]):  # the engine's lane stops at this closing step,
                    break  # counted in its steps, opening nothing
            b += 1
        Us, ts, th = (np.array(c) for c in zip(*closed))
        got = {k: s[k][lane] for k in ("U", "U2", "t", "t2", "Ut", "t_half")}
        want = dict(U=Us.sum(), U2=(Us ** 2).sum(), t=ts.sum(), t2=(ts ** 2).sum(), Ut=(Us * ts).sum(),
                    t_half=th.sum())
        for k in got:
            scale = {"U": np.abs(Us).sum(), "Ut": np.abs(Us * ts).sum()}.get(k, abs(want[k]))
            assert abs(got[k] - want[k]) <= 1e-12 * scale, (lane, k, got[k], want[k])
        assert int(r.lane_steps[lane]) == counted, lane


def test_half_durations_are_half_the_durations_at_zero_bias():
    r"""At :math:`\bar\gamma' = 0` the mean duration of the +HLE, ``t_half`` (the duration at which
    the -HLE began), is exactly half the long excursion's: z of :math:`\sum (t_{1/2} - t/2)` within
    3.5.

    Why exact: with b(v) = -v/tau_L' odd, the DI is symmetric under (X, V) -> (-X, -V) (the
    proximal step is odd, the OU step's law even, :math:`C_- = -C_+` with the mirrored coin and
    release direction), so the +HLE (from the regeneration on :math:`C_+` to the one on
    :math:`C_-`) and the -HLE (the rest, :math:`t - t_{1/2}`) have one law:
    :math:`E[t_{1/2} - t/2] = 0`.  Per lane, :math:`d_l = \sum (t_{1/2} - t/2)` over its
    excursions; the number of excursions a lane starts is a stopping time, so (Wald)
    :math:`E d_l = E N_l \cdot 0 = 0` exactly, and the lanes are i.i.d.  So the lanes are the
    blocks: :math:`z = \sum_l d_l / \sqrt{L s_d^2}` with :math:`s_d` the sample sd of the L = 1024
    lane totals (it includes the fluctuation of :math:`N_l`; no ratio is needed since the mean is 0).
    |z| <= 3.5: a two-sided normal tail of 4.7e-4 (the CLT over 1024 i.i.d. lanes of ~11
    excursions, light-tailed with viscous damping).  Over 40 other seeds z had mean -0.004, sd
    0.92, max |z| 2.3.  A ``t_half`` recorded at half its value shifts the mean of d by -E t/4
    per excursion, z ~ -130 (~1.1e4 excursions of ~172 steps)."""
    m = make_di_model(dj.Params.from_nondim(1e-5, 1.0, 0.0), 0.02)
    r = run_round(m, jax.random.key(0), 1024, 1800)
    assert r.n_truncated == 0 and r.n_excursions > 10_000
    s = dict(zip(STAT_NAMES, r.stats.T))
    d = s["t_half"] - s["t"] / 2
    z = d.sum() / math.sqrt(d.size * d.var(ddof=1))
    assert abs(z) <= 3.5, z


def test_close_adds_every_product_by_name():
    """``_close`` adds, to each of the 16 sums of ``STAT_NAMES``, the product its name says, for the
    lanes whose excursion is complete.  Two closes on 6 lanes with chosen U (both signs, |U| != 1),
    t (!= 1) and t_half; the expected sums are U^a t^b computed in numpy from an exponent table
    written here, independently of the engine (``estimators.sums_from_samples`` is not used: it is a
    second implementation of the same table).  Every term has the lane's sign in both closes, so the
    sums do not cancel and each agrees within a few roundings: rel 1e-14."""
    import equinox as eqx

    powers = dict(n=(0, 0), U=(1, 0), U2=(2, 0), U3=(3, 0), U4=(4, 0), t=(0, 1), t2=(0, 2), t3=(0, 3),
                  t4=(0, 4), Ut=(1, 1), U2t=(2, 1), U3t=(3, 1), Ut2=(1, 2), U2t2=(2, 2), Ut3=(1, 3))
    assert sorted(STAT_NAMES) == sorted([*powers, "t_half"]) and len(STAT_NAMES) == 16
    lane = init_lanes(make_di_model(dj.Params.from_nondim(0.5, 1.0, 0.2), 0.02), 6)
    sign = np.array([-1.0, 1.0, 1.0, -1.0, 1.0, -1.0])
    closes = [(sign * [1.7, 0.3, 2.9, 0.45, 1.3, 3.1], [0.7, 2.3, 1.9, 4.1, 0.35, 3.3],
               [0.2, 1.1, 0.8, 2.5, 0.1, 1.4], [True] * 6),
              (sign * [0.6, 2.2, 1.45, 3.7, 0.8, 0.25], [1.6, 0.55, 2.7, 0.9, 5.2, 1.3],
               [0.9, 0.3, 1.2, 0.4, 2.6, 0.5], [True, False, True, True, False, True])]
    want = {k: np.zeros(6) for k in STAT_NAMES}
    for U, t, th, complete in closes:
        U, t, th, complete = (np.asarray(a) for a in (U, t, th, complete))
        lane = eqx.tree_at(lambda ln: ln.t_half, lane, jnp.asarray(th))
        lane = _close(lane, jnp.asarray(U), jnp.asarray(t), jnp.asarray(complete))
        for k, (a, b) in powers.items():
            want[k] += np.where(complete, U**a * t**b, 0.0)
        want["t_half"] += np.where(complete, th, 0.0)
    got = dict(zip(STAT_NAMES, (np.asarray(s) for s in lane.stats)))
    for k in STAT_NAMES:
        assert got[k].dtype == np.float64, k
        np.testing.assert_allclose(got[k], want[k], rtol=1e-14, atol=0, err_msg=k)


def test_truncation_is_counted_and_reported():
    p = dj.Params.from_nondim(1.0)
    with pytest.warns(dj.DryfricWarning, match="work bound"):
        r = dj.estimate_diffusivity(p, 3, h=0.01, n_excursions=400, max_steps=300, lanes=4)
    assert r.n_truncated > 0
    assert math.isfinite(r.D) and math.isfinite(r.D_ci)
    assert any("work bound" in w for w in r.warnings)


def test_small_n_warns():
    p = dj.Params.from_nondim(1e-3)
    with pytest.warns(dj.DryfricWarning, match="under-covers"):
        dj.estimate_diffusivity(p, 0, n_excursions=100)


def test_float32_agrees_with_exact_white_noise():
    """float32 simulation (integer step count, float64 statistics), white noise b = 0: against the exact
    D of the chain at h' = 0.02 (:func:`dryfric_jax.white_chain_law`, tau/h = 5e-7), 9.926, 0.74% below
    the continuum's D' = 10, and M0 = 0.  A fast check (a ~5% CI); the tight float32 tests are
    test_di_exact.test_float32_at_paper_values and the paired ones below."""
    from dryfric_jax.chain_law import white_chain_law

    p = dj.Params.from_nondim(1e-8)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", dj.DryfricWarning)
        r32 = dj.estimate_diffusivity(p, 4, n_excursions=60_000, dtype="float32", h=0.02)
    law = white_chain_law(p, 0.02)
    assert r32.dtype == "float32" and r32.n_truncated == 0
    assert abs(r32.D - law.D) <= r32.D_ci and abs(r32.M0) <= r32.M0_ci


class _DI64OnFloat32Numbers(DIModel):
    """The DI in float64 arithmetic on the float32 chain's random numbers (normals and coin
    uniforms drawn in float32, then widened): float32 against this isolates the arithmetic."""

    @property
    def random_dtype(self):
        return jnp.dtype(jnp.float32)


def _coupled_bits(a, b):
    """A 52-bit integer from one threefry hash ``(a, b)`` whose top 23 bits are the float32 draw's,
    ``(a ^ b) >> 9`` (``rng._unit``, ``rng._normal``), and whose low 29 bits are ``a >> 3``
    (independent of ``a ^ b``): exactly as uniform as float64's own 52 bits."""
    return (((a ^ b) >> np.uint32(9)).astype(jnp.uint64) << np.uint64(29)) | (a >> np.uint32(3)).astype(jnp.uint64)


def _coupled_unit(a, b):
    """The uniform on [0, 1) of :func:`_coupled_bits` (as ``rng._unit`` makes it): within 2^-23 of
    float32's."""
    return jax.lax.bitcast_convert_type(_coupled_bits(a, b) | np.array(1.0).view(np.uint64), jnp.float64) - 1.0


def _coupled_word(a, b):
    """A 32-bit word from one threefry hash ``(a, b)`` whose top 23 bits are the float32 draw's, ``(a ^ b) >> 9``,
    and whose low 9 bits are ``a``'s (independent of ``a ^ b``): what a float64 pair reads for its u or t."""
    return (((a ^ b) >> np.uint32(9)) << np.uint32(9)) | (a & np.uint32(511))


def _coupled_units(keys, block: int, normals: bool = False):
    """Every lane's two columns of coupled uniforms (counter ``2 row + column``, the layout of
    ``rng.normals`` / ``rng.uniforms``), each (block, lanes); with ``normals``, ``rng._normal`` of
    the two columns' coupled words instead (Box-Muller of their 32-bit cells, as a float64 pair's are
    made, which lie in the float32 cells of float32's u and t)."""
    kd = jax.random.key_data(keys)
    rows = jnp.arange(block, dtype=jnp.uint32)[:, None]

    def units():
        out = []
        for c in range(2):
            i = rows * np.uint32(2) + np.uint32(c)
            ab = rng.threefry2x32(kd[:, 0][None, :], kd[:, 1][None, :], jnp.zeros_like(i), i)
            out.append(_coupled_word(*ab) if normals else _coupled_unit(*ab))
        return rng._normal(*out, jnp.float64) if normals else tuple(out)

    # materialised as rng._bits does: unfused, XLA 0.12 (jax 0.12.0.1) compiled this model's round
    # for > 20 min on 2 CPU cores (0.10.2: ~9 s)
    return rng.materialised(units, kd)


def _coupled_coin_unit(keys):
    """The coupled uniform of ``rng.uniform``'s counter 0 of every key."""
    kd = jax.random.key_data(keys)
    zero = jnp.zeros_like(kd[..., 0])
    return _coupled_unit(*rng.threefry2x32(kd[..., 0], kd[..., 1], zero, zero))


def _twin(cls, model):
    """``model``'s fields in the test subclass ``cls`` (its numbers drawn another way)."""
    import dataclasses

    return cls(**{f.name: getattr(model, f.name) for f in dataclasses.fields(model)})


class _DI64OnCoupledNumbers(DIModel):
    r"""The DI in float64 on float64 random numbers coupled to the float32 chain's: each normal
    is ``rng._normal`` of coupled bits (:func:`_coupled_units`), as float64's own are made, and
    each coin :math:`f` of a :func:`_coupled_unit` ``f``, both from the same hash as float32's.
    Against :class:`_DI64OnFloat32Numbers` it isolates the float32 generator's coarser numbers."""

    def draw_lanes(self, keys, block: int):
        return _coupled_units(rng.split_at(keys, 0), block, normals=True)

    def coin(self, state, r, watch_plus, key):
        u = jnp.maximum(np.finfo(np.float64).tiny, _coupled_coin_unit(key))
        return jnp.log(u) < self._set(watch_plus).log_coin(state[0], *r)


@functools.lru_cache(maxsize=None)
def _fig3_paired_round(numbers: str):
    """One round at the Fig. 3 point (tau = 750 h, 2048 lanes, ~4 excursions each, key 7) of the
    float32 chain (``numbers="float32"``) or of the float64 chain on the float32 chain's numbers
    (``"float32_in_float64"``) or on the coupled float64 numbers (``"coupled_float64"``): the lanes'
    sums, (lanes, len(STAT_NAMES))."""
    from dryfric_jax.params import FIG3

    p = dj.Params(**FIG3)
    h = dj.default_h(p)
    model = {"float32": lambda: make_di_model(p, h, "float32"),
             "float32_in_float64": lambda: _twin(_DI64OnFloat32Numbers, make_di_model(p, h, "float64")),
             "coupled_float64": lambda: _twin(_DI64OnCoupledNumbers, make_di_model(p, h, "float64"))}[numbers]()
    budget = int(4 * 23.2 * p.tau0 / h)
    return np.asarray(run_round(model, jax.random.key(7), 2048, budget).stats)


def _D(s):
    r"""The point estimate :math:`\Psi_D` of the mean moments of the lanes' sums ``s`` (``long_excursion_estimates``'
    D, without its CI's gradient, which would cost a trace per jackknife group)."""
    from dryfric_jax.estimators import moments_from_sums, psi_D
    return float(psi_D(moments_from_sums(dict(zip(STAT_NAMES, s.sum(0))))[0]))


def _jackknife_se(stat, n_lanes: int, groups: int = 64):
    """The delete-a-group jackknife SE of ``stat(mask)`` (a function of the kept lanes) over
    ``groups`` lane groups (lane l in group l mod groups)."""
    g = np.arange(n_lanes) % groups
    jk = np.array([stat(g != k) for k in range(groups)])
    return math.sqrt((groups - 1) / groups * np.sum((jk - jk.mean()) ** 2))


def _paired_difference(sa, sb, groups: int = 64):
    """D(sa) - D(sb) and its jackknife SE over ``groups`` lane groups (the lanes are paired), and D(sb)."""
    return _D(sa) - _D(sb), _jackknife_se(lambda m: _D(sa[m]) - _D(sb[m]), len(sa), groups), _D(sb)


def _unpaired_se(s, groups: int = 64):
    """The jackknife SE of D(s) alone over the same lane groups as :func:`_paired_difference`: what
    the paired SE is compared with."""
    return _jackknife_se(lambda m: _D(s[m]), len(s), groups)


def test_a_float32_chains_excursion_displacement_is_summed_in_float64():
    """In float32 the quiet loop sums a block's increments in float32 from 0 and adds the sum to
    the excursion's float64 U: a block moves U by the same amount whether U starts at 0 or at
    1e5, to float64 rounding.  Rounding the running U to float32 each block (off by float32's
    ulp of 1e5, 0.008) passed every test (mutation audit)."""
    import equinox as eqx

    from dryfric_jax.excursions import PLUS, _quiet_steps

    m = make_di_model(dj.Params.from_nondim(0.5, 1.0, 0.2), 0.02, dtype=jnp.float32)
    lanes, block = 64, 128
    rs = m.draw_lanes(jax.random.split(jax.random.key(5), lanes), block)
    moved = []
    for U0 in (0.0, 1e5):
        ln = init_lanes(m, lanes)
        ln = eqx.tree_at(lambda l: (l.phase, l.U), ln, (jnp.full((lanes,), PLUS, jnp.int32),
                                                        jnp.full((lanes,), U0, jnp.float64)))
        out, _ = _quiet_steps(m, 10**6, 10**6, False, block, ln, rs)
        assert out.U.dtype == jnp.float64
        moved.append(np.asarray(out.U) - U0)
    assert np.count_nonzero(moved[0]) > lanes // 2
    np.testing.assert_allclose(moved[1], moved[0], rtol=0, atol=1e-9)


def test_float32_arithmetic_matches_float64_on_the_same_numbers():
    """Fig. 3 point: float32 against float64 arithmetic, both driven by the same float32 random
    numbers, so the lanes' paths stay coupled (the same excursion counts in >= 95% of lanes)
    and the difference of D has a paired (jackknife over lane groups) SE far below the unpaired
    SE of either, ~2.2% of D here: 0.044% with jax.random.normal's numbers (version 0.2.3), 0.20%
    with the inverse-CDF normals of 0.2.4, where one lane of 2048 split a long excursion (U^2 =
    3.6) differently in float64 arithmetic.  The pairing must gain at least 8x in SE (the bound
    was 0.2% of D, 4.5x the 0.2.3 value, before), and float32 rounding must not move D beyond 4
    paired SE.  (Unpaired runs of 6e6 excursions differed by -0.27%, 1.9 SE, on 2 CPU cores: RESULTS.md.)"""
    s32, s64 = _fig3_paired_round("float32"), _fig3_paired_round("float32_in_float64")
    assert np.mean(s32[:, 0] == s64[:, 0]) >= 0.95
    diff, se, d64 = _paired_difference(s32, s64)
    assert se < _unpaired_se(s64) / 8  # the pairing works
    assert abs(diff) <= 4 * se, (diff, se)


def test_coupled_float64_numbers_are_normal_and_within_float32s_resolution():
    """The coupled generator of the next test: its uniforms lie in [u32, u32 + 2^-23) of the
    float32 chain's, its normal pairs' radii and angles within a float32 cell's of float32's, and 2^20 of
    them have the normal law's mean and variance (5 SE)."""
    p = dj.Params(**dj.FIG3)
    m64 = make_di_model(p, dj.default_h(p), "float64")
    keys = jax.random.split(jax.random.key(3), 1024)
    z32 = np.stack(_twin(_DI64OnFloat32Numbers, m64).draw_lanes(keys, 512))
    z64 = np.stack(_twin(_DI64OnCoupledNumbers, m64).draw_lanes(keys, 512))
    # a pair's radius^2 is -2 ln u, with the coupled u within half a float32 cell (2^-24) of float32's,
    # and its angle 2 pi t, with the coupled t in [t32, t32 + 2^-23)
    r32, r64 = (np.sum(z.astype(np.float64) ** 2, 0) for z in (z32, z64))
    u_lo = np.exp(-np.maximum(r32, r64) / 2) - 2.0**-24
    assert np.all(np.abs(r64 - r32) <= 2 * 2.0**-24 / u_lo + 1e-6 * (1 + r64))
    turn = np.arctan2(z64[1] * z32[0] - z64[0] * z32[1], z64[0] * z32[0] + z64[1] * z32[1])
    assert np.all((turn >= -1e-6) & (turn <= 2 * math.pi * 2.0**-23 + 1e-6))
    assert np.mean(z64 != z32) > 0.99  # the low bits are there
    n = z64.size
    assert abs(z64.mean()) < 5 / math.sqrt(n) and abs(z64.var() - 1) < 5 * math.sqrt(2 / n)
    ck = rng.split_at(keys, 1)
    u32 = np.asarray(rng.uniform(ck, jnp.float32)).astype(np.float64)
    u64 = np.asarray(_coupled_coin_unit(ck))
    assert np.all((u64 >= u32) & (u64 < u32 + 2.0**-23))


def test_float32_numbers_match_float64_numbers_in_float64_arithmetic():
    """Fig. 3 point, float64 arithmetic: the float32 chain's random numbers (23 random bits per
    uniform) against coupled float64 numbers (52 bits, the top 23 the same): D must agree within
    4 paired SE.  With the arithmetic test above this splits float32 minus float64 into its two
    causes; the whole of it, the float32 chain against the float64 chain on coupled numbers,
    must agree within 4 paired SE too.  (Means over 16 independent rounds like this one, with
    their SE: numbers -0.02 +- 0.03%, the whole -0.01 +- 0.03%; RESULTS.md "float32 against float64".)"""
    s32, s64 = _fig3_paired_round("float32_in_float64"), _fig3_paired_round("coupled_float64")
    assert np.mean(s32[:, 0] == s64[:, 0]) >= 0.95
    diff, se, d64 = _paired_difference(s32, s64)
    assert se < 4e-3 * d64
    assert abs(diff) <= 4 * se, (diff, se)
    diff, se, d64 = _paired_difference(_fig3_paired_round("float32"), s64)
    assert se < 4e-3 * d64 and abs(diff) <= 4 * se, (diff, se)


class _PDMP64OnFloat32Numbers(PDMPModel):
    """The PDMP in float64 arithmetic on the float32 chain's uniforms, widened."""

    @property
    def random_dtype(self):
        return jnp.dtype(jnp.float32)


class _PDMP64OnCoupledNumbers(PDMPModel):
    """The PDMP in float64 on uniforms coupled to the float32 chain's (:func:`_coupled_unit`,
    mapped to [tiny, 1) as ``rng.uniforms`` maps them)."""

    def draw_lanes(self, keys, block: int):
        tiny = np.finfo(np.float64).tiny
        return tuple(jnp.maximum(tiny, f * (1.0 - tiny) + tiny) for f in _coupled_units(keys, block))


def test_pdmp_float32_matches_float64_paired():
    """The PDMP at the Fig. 3 point (default delta), paired as for the DI: the float32 chain
    against float64 arithmetic on its own uniforms, and that against float64 on coupled 52-bit
    uniforms.  The noise lives on an exact integer grid, so the lanes stay coupled (all of them
    with the same excursion count, measured) and the paired SE is ~0.001%: D must agree within 4
    paired SE plus 1e-6 relative (a few float32 ulps: what rounding alone can reach when the
    paths coincide; float32 arithmetic measured -3.8e-8 +- 0.4e-8, coupled numbers -1.1e-5 +-
    1.1e-5)."""
    from dryfric_jax.cost import default_delta
    from dryfric_jax.params import FIG3

    p = dj.Params(**FIG3)
    delta = default_delta(p)
    m64 = make_pdmp_model(p, delta, "float64")
    budget = 4 * 4500  # ~4 excursions per lane (~4 500 events each)
    s = [np.asarray(run_round(m, jax.random.key(7), 1024, budget).stats)
         for m in (make_pdmp_model(p, delta, "float32"), _twin(_PDMP64OnFloat32Numbers, m64),
                   _twin(_PDMP64OnCoupledNumbers, m64))]
    assert s[2][:, 0].sum() > 4000
    for a, b in ((s[0], s[1]), (s[1], s[2]), (s[0], s[2])):
        assert np.mean(a[:, 0] == b[:, 0]) >= 0.99
        diff, se, d = _paired_difference(a, b)
        assert se < 2e-4 * d and abs(diff) <= 4 * se + 1e-6 * d, (diff, se, d)


@pytest.mark.parametrize("kw,match", [
    (dict(h=-1.0), "h must"), (dict(h=math.nan), "h must"), (dict(h=1.0), "h must"),
    (dict(n_excursions=1), "n_excursions"), (dict(method="euler"), "method"), (dict(dtype="float16"), "dtype"),
    (dict(chunk_lanes=0), "chunk_lanes"),  # was taken for the default
])
def test_api_bad_input(kw, match):
    with pytest.raises(ValueError, match=match):
        dj.estimate_diffusivity(dj.Params(**dj.FIG3), 0, **kw)


@pytest.mark.parametrize("kw,match", [
    (dict(block=0), "^block must"), (dict(chunk_lanes=0), "^chunk_lanes must"),
    (dict(method="pdmp", max_events=0), "^max_events must"), (dict(t="1"), "^t must be a real number"),
    (dict(method="pdmp", max_events=2**63), r"^max_events must be an integer in \[1, 2\^62\]"),
])
def test_bruteforce_bad_input(kw, match):
    """Before: an IndexError (block 0), a ZeroDivisionError (chunk_lanes 0), a run that failed
    after simulating (max_events 0), a TypeError (t = "1"), an OverflowError past int64 (max_events 2^63)."""
    with pytest.raises(ValueError, match=match):
        dj.bruteforce_diffusivity(dj.Params(**dj.FIG3), 0, **(dict(t=1.0, n_paths=10) | kw))
