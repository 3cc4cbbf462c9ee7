r"""Mutation audit of the lane engine's host side (``dryfric_jax.excursions``, ``dryfric_jax.rounds``):
layout defaults (``default_block``, ``lanes_for``, ``_is_cuda``, ``_events_layout``, ``compiled_round``), the rounds of
:class:`Lanes` (layout and pad lanes, call caps, deadlines, compaction, paid work), ``run_round``, the stopping
rules of ``simulate_long_excursions``, ``steps_per_excursion``, ``simulate_replicates`` and ``ExcursionStats``.

96 one-line mutants tried: 45 killed by the existing tests (test_engine_audit.py first, then a per-mutant
subset of test_engine.py or test_sharding_mutants.py; two of them only by a hang/timeout), 4 equivalent, 28
alive before and killed only by this file, 18 killed by this file whose run against the existing subset was
not finished (time), 1 alive (``steps_per_excursion`` dividing by complete + truncated excursions: no
documented rule decides it).

Each test here fails on at least one mutant that the other tests (test_engine_audit.py, a subset of
test_engine.py, test_sharding_mutants.py) let live.  Expected values come from hand arithmetic, the documented
rules, or the clock chain of ``test_engine_audit`` (deterministic: every excursion and every lane's block count
known in advance); the stopping rules run on scripted rounds (``Lanes.advance``/``finish`` replaced by a script
of ``ExcursionStats``) and a fake clock, so nothing here depends on the machine's speed.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from dryfric_jax import excursions
from dryfric_jax import rounds as rd
from dryfric_jax.excursions import STAT_NAMES
from dryfric_jax.rounds import ExcursionStats, Lanes, simulate_long_excursions
from test_engine_audit import OFFSETS, H, Clock, PClock, _expected, _lane_blocks, reference_lane

ND = len(jax.local_devices())
two_devices = pytest.mark.skipif(ND != 2, reason="hand values for 2 devices (conftest: one per core)")


def _clock():
    return Clock(jnp.asarray(H))


def _device_blocks(n_lanes, budget, events, block=8, max_steps=10**6):
    """Blocks each device runs in a fresh final round of ``n_lanes`` clock lanes (lane i has offset
    OFFSETS[i mod 8], lanes split evenly over the devices): its slowest lane's block count."""
    per_offset = []
    for off in OFFSETS:
        ev = []
        reference_lane(off, budget, max_steps, False, ev)
        per_offset.append(_lane_blocks(ev, block, events))
    return np.resize(per_offset, n_lanes).reshape(ND, -1).max(axis=1)


def _counting_calls(monkeypatch):
    """Record the lane count of every call of the jitted round."""
    calls, real = [], Lanes._call_once

    def once(self, lane, *a):
        calls.append(int(lane.done.shape[0]))
        return real(self, lane, *a)

    monkeypatch.setattr(Lanes, "_call_once", once)
    return calls


# ---- layout defaults -----------------------------------------------------------------------------------------------

def test_default_block_halves_by_powers_of_two_down_to_one():
    """K is halved while lanes * K > 2^28, and never below 1: at 3 x 2^20 lanes 256 -> 128 -> 64
    (64 x 3 x 2^20 = 201326592 <= 2^28); at 2^28 lanes K = 1 (exactly 2^28); at 2^29 lanes the
    bound cannot hold, K stays 1 (not 0, not 2)."""
    assert excursions.default_block("di", 3 * 2**20, "gpu") == 64
    assert excursions.default_block("pdmp", 2**28, "cpu") == 1
    assert excursions.default_block("di", 2**29, "cpu") == 1


def test_lanes_for_takes_the_power_of_two_at_or_below_n_over_32():
    """32767 // 32 = 1023 -> 512 lanes; 32768 // 32 = 1024 -> 1024 lanes (the floor of log2)."""
    assert excursions.lanes_for(32767, 4096) == 512 and excursions.lanes_for(32768, 4096) == 1024
    assert excursions.lanes_for(2, 4096, per_lane=32, min_lanes=512) == 2


def test_cuda_is_recognised_by_its_device_name_in_any_case():
    """``_is_cuda``: a GPU whose name starts with "cuda" (any case); not a ROCm GPU, not a CPU."""

    class Dev:
        def __init__(self, platform, name):
            self.platform, self.name = platform, name

        def __str__(self):
            return self.name

    got = [excursions._is_cuda(Dev(p, n)) for p, n in (("gpu", "cuda:0"), ("gpu", "CUDA:1"), ("gpu", "rocm:0"),
                                                        ("cpu", "cuda_cpu"))]
    assert got == [True, True, False, False]


def test_other_accelerators_take_the_wait_layout():
    """Off a CPU and off an NVIDIA GPU (a TPU here) the default layout is "wait" for every chain, not the
    chain's CPU layout ("branch" for the PDMP-like clock)."""

    class Tpu:
        platform = "tpu"

        def __str__(self):
            return "TPU_0"

    assert [excursions._events_layout((Tpu(),), c, None) for c in (_clock(), PClock(jnp.asarray(H)))] == ["wait"] * 2


def test_compiled_round_is_the_function_lanes_run():
    """``compiled_round(chain class, block)`` is the jitted round a :class:`Lanes` of that chain and block runs (the
    recompilation tests count its cache): for a chain whose CPU layout is "branch" (the PDMP-like clock) too."""
    for chain in (_clock(), PClock(jnp.asarray(H))):
        ln = Lanes(chain, 8, block=8)
        f = getattr(ln._f, "func", ln._f)  # one device: a partial of _run_round
        assert excursions.compiled_round(type(chain), 8) is f


@two_devices
def test_lane_layout_is_at_least_two_lanes_per_device_and_pads_only_the_remainder():
    """2 devices: 1 lane -> 4 in the layout (at least 2 per device), 7 -> 8, 8 -> 8, 9 -> 10; the
    final round compacts only with >= 64 lanes per device (126 lanes: 63 each, no; 128: yes)."""
    assert [Lanes(_clock(), n).n for n in (1, 7, 8, 9)] == [4, 8, 8, 10]
    assert [Lanes(_clock(), n).compact for n in (126, 128)] == [False, True]


# ---- Lanes: calls, deadlines, compaction ----------------------------------------------------------------------

@pytest.mark.parametrize("per_call", [1, 3])
def test_final_round_calls_are_capped_at_final_call_lane_steps(monkeypatch, per_call):
    """A final round runs in calls of at most FINAL_CALL_LANE_STEPS lane-steps, i.e. ``per_call``
    blocks of 8 lanes x 8 steps, each device running its own block count: it takes
    max_d floor(B_d / per_call) + 1 calls (the last one finds every device stopped short of the
    cap), B_d the blocks of the device's slowest clock lane, and the sums are the clock's."""
    calls = _counting_calls(monkeypatch)
    monkeypatch.setattr(rd, "FINAL_CALL_LANE_STEPS", per_call * 8 * 8)
    ln = Lanes(_clock(), 8, block=8, events="wait")
    got = ln.finish(jax.random.key(0), 300)
    blocks = _device_blocks(8, 300, "wait")
    assert len(calls) == int((blocks // per_call).max()) + 1
    want = _expected(300, 10**6, False)[0]
    np.testing.assert_allclose(got.stats, want, rtol=1e-13, atol=0)
    assert got.n_unfinished == 0 and got.slot_steps == int(blocks.sum()) * 8 * (8 // ND)


def test_final_round_calls_are_cut_by_time_once_a_block_is_timed(monkeypatch):
    """Once the last call timed a block, a final round's calls are also cut to ~FINAL_CALL_S seconds, but to no
    fewer than FINAL_CALL_MIN_BLOCKS blocks: with 1 s a block, FINAL_CALL_S = 0 and a floor of 3 blocks, the calls
    are those of a lane-step cap of 3 blocks, and the sums the clock's, as one call gives.  The lane-steps alone made
    final calls of 15-100 s with few lanes, past the 20 s a Ctrl-C is promised (a hard-cases audit).  Untimed (a new
    Lanes), the round is one call, and its call times a block."""
    calls = _counting_calls(monkeypatch)
    ln = Lanes(_clock(), 8, block=8, events="wait")
    one = ln.finish(jax.random.key(0), 300)
    assert len(calls) == 1 and ln._block_s is not None and ln._block_s > 0
    calls.clear()
    monkeypatch.setattr(rd, "FINAL_CALL_S", 0.0)
    monkeypatch.setattr(rd, "FINAL_CALL_MIN_BLOCKS", 3)
    ln = Lanes(_clock(), 8, block=8, events="wait")
    ln._block_s = 1.0
    many = ln.finish(jax.random.key(0), 300)
    blocks = _device_blocks(8, 300, "wait")
    assert len(calls) == int((blocks // 3).max()) + 1 > 3
    np.testing.assert_array_equal(many.stats, one.stats)
    assert (many.n_unfinished, many.slot_steps) == (one.n_unfinished, one.slot_steps)


def test_a_paused_round_is_one_call_whatever_the_final_call_cap(monkeypatch):
    """A paused round is one call of ceil(budget / block) blocks (its budget bounds it), even with
    compaction on (128 lanes) and a final-call cap of one block: 3 blocks of 8 steps for budget
    20, "branch" (whole blocks), every lane 24 steps; no compacted tail."""
    calls = _counting_calls(monkeypatch)
    monkeypatch.setattr(rd, "FINAL_CALL_LANE_STEPS", 1)
    ln = Lanes(_clock(), 128, block=8, events="branch")
    st = ln.advance(jax.random.key(0), 20)
    assert calls == [128] and np.all(np.asarray(ln.lane.work) == 24) and st.n_unfinished == 0
    assert ln.paid == 24 * 128 and st.slot_steps == 24 * 128


def test_a_paused_round_cut_by_time_runs_its_blocks_in_several_calls(monkeypatch):
    """A paused round's calls are cut by time too (a first Ctrl-C waited for a paused round's end, ~50 s on one PDMP
    lane), but its length fixes the random streams: a timed block and a time cap of one block run its
    ceil(80 / 8) = 10 blocks in 10 calls (no empty eleventh), every lane 80 steps, and the lanes and sums of one
    call.  (A first cut by time ran 1 call of 1 block, marked its lanes done and paid 192 slots, not 640: a review.)
    Then a final round continues from either alike."""
    one = Lanes(_clock(), 8, block=8, events="branch")
    first = one.advance(jax.random.key(0), 80)
    calls = _counting_calls(monkeypatch)
    monkeypatch.setattr(rd, "FINAL_CALL_S", 0.0)
    monkeypatch.setattr(rd, "FINAL_CALL_MIN_BLOCKS", 1)
    ln = Lanes(_clock(), 8, block=8, events="branch")
    ln._block_s = 1.0
    st = ln.advance(jax.random.key(0), 80)
    assert calls == [8] * 10 and np.all(np.asarray(ln.lane.work) == 80) and st.slot_steps == 80 * 8 == ln.paid
    np.testing.assert_array_equal(st.stats, first.stats)
    np.testing.assert_array_equal(st.lane_steps, first.lane_steps)
    for a, b in zip(jax.tree_util.tree_leaves(ln.lane), jax.tree_util.tree_leaves(one.lane)):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(ln.finish(jax.random.key(1), 40).stats, one.finish(jax.random.key(1), 40).stats)


def test_a_final_round_call_at_the_deadline_is_the_last(monkeypatch):
    """Past the deadline, or at it (``_now() >= deadline``), no further call starts: with one block
    per call and the clock standing exactly at the deadline, the round stops after one call, and
    all 8 clock lanes (which need ~50 blocks) are left unfinished."""
    calls = _counting_calls(monkeypatch)
    monkeypatch.setattr(rd, "FINAL_CALL_LANE_STEPS", 1)
    monkeypatch.setattr(rd, "_now", lambda: 5.0)
    st = Lanes(_clock(), 8, block=8, events="wait").finish(jax.random.key(0), 300, deadline=5.0)
    assert calls == [8] and st.n_unfinished == 8


@two_devices
def test_no_compacted_tail_starts_at_the_deadline(monkeypatch):
    """The tail starts only before the deadline (``_now() < deadline``): with the clock standing at
    it, the round ends after its first call, the 16 slowest lanes unfinished."""
    calls = _counting_calls(monkeypatch)
    monkeypatch.setattr(rd, "_now", lambda: 5.0)
    st = Lanes(_clock(), 128, block=8, events="wait").finish(jax.random.key(0), 300, deadline=5.0)
    assert calls == [128] and st.n_unfinished == 16


@two_devices
def test_the_compacted_tail_stops_at_the_deadline_too(monkeypatch):
    """Budget 310: the offset-60 clock lanes need 56 blocks, the others at most 54, so the tail (8 lanes per
    device) has 2 blocks to run.  One block per call; the clock reads 0 until the tail's first call, then 10,
    past the deadline 5: the tail stops after that call and its 16 lanes are unfinished."""
    clock, calls, real = [0.0], [], Lanes._call_once

    def once(self, lane, *a):
        calls.append(int(lane.done.shape[0]))
        if calls[-1] == 16:
            clock[0] = 10.0
        return real(self, lane, *a)

    monkeypatch.setattr(Lanes, "_call_once", once)
    monkeypatch.setattr(rd, "FINAL_CALL_LANE_STEPS", 1)
    monkeypatch.setattr(rd, "_now", lambda: clock[0])
    assert list(_device_blocks(128, 310, "wait")) == [56, 56]
    st = Lanes(_clock(), 128, block=8, events="wait").finish(jax.random.key(0), 310, deadline=5.0)
    assert calls.count(16) == 1 and calls[-1] == 16 and st.n_unfinished == 16


def test_a_final_round_starts_nothing_by_default():
    """``Lanes.finish`` with its default budget 0 (what simulate_long_excursions runs): fresh clock lanes all seek,
    and lane 0's first step is a regeneration, which opens nothing with the budget spent: no excursion, every lane
    stops after one step."""
    ln = Lanes(_clock(), 8, block=8, events="wait")
    st = ln.finish(jax.random.key(0))
    assert st.n_excursions == 0 and st.useful_steps == 0 and np.all(np.asarray(ln.lane.work)[:8] == 1)


def _closed_by(off, steps):
    """The DI-like clock's excursions that close within a lane's first ``steps`` steps, with no budget
    stop (a paused round): lane counter c = step - off; regenerations at the triangular numbers T_k; the
    excursion j runs over the counters [T_{2j-1}, T_{2j+1}) (half at T_{2j}), closing at step T_{2j+1} + off."""
    T = lambda k: k * (k + 1) // 2  # noqa: E731
    out, j = [], 1
    while T(2 * j + 1) + off <= steps:
        a, m, b = T(2 * j - 1), T(2 * j), T(2 * j + 1)
        out.append((sum(c - 40 for c in range(a, b)), (b - a) * H, (m - a) * H))
        j += 1
    return out


def test_dropping_the_in_flight_excursion_keeps_only_those_closed_within_the_budget():
    """``run_round(finish_in_flight=False)``: the lanes run ceil(300 / 8) = 38 blocks ("branch": 304
    steps each) and keep only the excursions that closed within them (the biased demo): the sums
    are those, lane by lane, and nothing is reported in flight."""
    st = rd.run_round(_clock(), jax.random.key(0), 8, 300, block=8, finish_in_flight=False,
                              events="branch")
    for lane, off in enumerate(OFFSETS):
        closed = _closed_by(off, 304)
        want = [len(closed), sum(U for U, _, _ in closed), sum(t for _, t, _ in closed),
                sum(th for _, _, th in closed)]
        got = st.stats[lane, [STAT_NAMES.index(k) for k in ("n", "U", "t", "t_half")]]
        np.testing.assert_allclose(got, want, rtol=1e-13, atol=0, err_msg=str(lane))
    assert st.n_in_flight == 0 and st.n_excursions >= 30


# ---- steps_per_excursion and simulate_replicates on scripted rounds ------------------------------------------------

def _stats(closed=0, trunc=0, in_flight=0, useful=0, unfinished=0):
    s = np.zeros((1, len(STAT_NAMES)))
    s[0, 0] = closed
    return ExcursionStats(s, trunc, useful, 0, unfinished, in_flight, np.array([useful]))


def test_steps_per_excursion_grows_the_budget_until_a_lane_has_one_each(monkeypatch):
    """The pilot stops once it has as many excursions as lanes (4 of 4: at once), else x4 the
    budget until it passes 64 max_steps (1024 = 64 x 16 is not past it: one more round, 4096);
    it returns useful steps per excursion (50 / max(0, 1) with none); block and max_steps reach
    each round."""
    seen = []

    def fake(n_exc):
        def run_round(chain, key, lanes, budget, **kw):
            seen.append((lanes, budget, kw["block"], kw["max_steps"]))
            assert len(seen) < 10, "runaway"
            return _stats(closed=n_exc, useful=50 if n_exc == 0 else 100)
        return run_round

    monkeypatch.setattr(rd, "run_round", fake(4))
    assert rd.steps_per_excursion(_clock(), jax.random.key(0), lanes=4, budget=64, block=8,
                                          max_steps=16) == 25.0
    assert seen == [(4, 64, 8, 16)]
    seen.clear()
    monkeypatch.setattr(rd, "run_round", fake(0))
    assert rd.steps_per_excursion(_clock(), jax.random.key(0), lanes=4, budget=1024, block=8,
                                          max_steps=16) == 50.0
    assert seen == [(4, 1024, 8, 16), (4, 4096, 8, 16)]


def test_replicates_pass_block_and_work_bound_to_the_pilot_and_the_round(monkeypatch):
    got = []
    monkeypatch.setattr(rd, "steps_per_excursion", lambda ch, k, **kw: got.append(kw) or 10.0)
    monkeypatch.setattr(rd, "run_round", lambda ch, k, lanes, budget, **kw: got.append(kw))
    rd.simulate_replicates(_clock(), jax.random.key(0), 2, 20, lanes_per_replicate=4, block=16,
                                   max_steps=77)
    assert got == [dict(block=16, max_steps=77)] * 2


def test_excursion_stats_total_sums_every_lane_by_name():
    s = np.arange(2 * len(STAT_NAMES), dtype=float).reshape(2, -1)
    tot = ExcursionStats(s, 0, 0, 0).total()
    assert list(tot) == list(STAT_NAMES)
    assert [tot[k] for k in ("n", "U", "t_half")] == [0 + 16, 1 + 17, 15 + 31]


# ---- simulate_long_excursions on scripted rounds -----------------------------------------------------------------

class _Script:
    """Replaces Lanes.advance/finish: the k-th paused (final) round returns ``rounds[k]`` (``finals[k]``),
    the last one repeated, and adds its ``paid``; records budgets, keys and the lanes' settings.  Each round is
    kept as Lanes._round keeps one: ``rounds`` counted (the next round's key), ``last`` its stats."""

    def __init__(self, monkeypatch, rounds, finals=(None,), more=(), clock=None, limit=12):
        self.rounds, self.finals, self.more_left = list(rounds), list(finals), list(more)
        self.budgets, self.keys, self.deadlines, self.lanes, self.more_calls = [], [], [], [], 0
        script = self

        def advance(ln, key, budget):
            script._log(ln, "a", key)
            script.budgets.append(budget)
            assert len(script.budgets) <= limit, "runaway paused rounds"
            st, paid = script.rounds[min(len(script.budgets), len(script.rounds)) - 1]
            ln.paid += paid
            ln.rounds, ln.last = ln.rounds + 1, st
            return st

        def finish(ln, key, budget=0, deadline=None):
            script._log(ln, "f", key)
            script.deadlines.append(deadline)
            n = sum(1 for k in script.keys if k[0] == "f")
            assert n <= limit, "runaway final rounds"
            st = script.finals[min(n, len(script.finals)) - 1]
            st = st if st is not None else _stats(closed=10)
            ln.rounds, ln.last = ln.rounds + 1, st
            return st

        monkeypatch.setattr(Lanes, "advance", advance)
        monkeypatch.setattr(Lanes, "finish", finish)
        if clock is not None:
            times = iter(clock)
            last = [clock[-1]]
            monkeypatch.setattr(rd, "_now", lambda: next(times, last[0]))

    def _log(self, ln, kind, key):
        self.keys.append((kind, np.asarray(jax.random.key_data(key)).tolist()))
        self.lanes.append((ln.n_real, ln.block, ln.max_steps))

    def more(self, st):
        self.more_calls += 1
        return self.more_left.pop(0) if self.more_left else 0


def _run(n, **kw):
    kw = dict(dict(lanes=8, block=8, pilot_budget=16), **kw)
    return simulate_long_excursions(_clock(), jax.random.key(0), n, **kw)


def test_n_must_be_at_least_one():
    with pytest.raises(ValueError, match="n_excursions must be >= 1"):
        _run(0)


def test_truncated_excursions_count_towards_n_and_settings_reach_the_lanes(monkeypatch):
    """4 complete + 36 truncated = 40 closed reach N = 40 in one paused round; then the final round.
    The lanes are lanes_for(N, chunk_lanes) = 8 (chunk 8, not 32 = 2^floor(log2 40)), with the given
    block and max_steps."""
    s = _Script(monkeypatch, [(_stats(closed=4, trunc=36), 0)])
    _, stopped = simulate_long_excursions(_clock(), jax.random.key(0), 40, chunk_lanes=8, block=8, max_steps=99)
    assert stopped == "n_excursions" and s.budgets == [1024] and s.lanes == [(8, 8, 99)] * 2


def test_more_is_asked_once_closed_plus_in_flight_reach_n_and_moves_the_target_from_closed(monkeypatch):
    """N = 10: the first round has 6 closed + 4 in flight = N, so ``more`` is asked (not only past N) and
    its 5 make the target 6 + 5 = 11 (from the closed ones, not N + 5 = 15); the second round's 11
    closed reach it, ``more`` says 0 there and after the final round ("target").  ``progress`` sees
    every paused round's stats."""
    r1, r2 = _stats(closed=6, in_flight=4, useful=100), _stats(closed=11)
    s = _Script(monkeypatch, [(r1, 0), (r2, 0)], finals=[_stats(closed=11)], more=[5])
    seen = []
    _, stopped = _run(10, more=s.more, progress=seen.append)
    assert stopped == "target" and len(s.budgets) == 2 and s.more_calls == 3
    assert len(seen) == 2 and seen[0] is r1 and seen[1] is r2


def test_a_target_moved_after_the_final_round_counts_from_its_closed_and_keys_never_repeat(monkeypatch):
    """After a final round (12 closed) ``more`` asks 5: the target becomes 12 + 5 = 17, so a paused
    round with 15 closed is short of it; one with 17 reaches it, ``more`` says 0 twice ("target").  Round
    r runs on fold_in(key, r), paused and final alike: a0 f1 a2 a3 f4."""
    rounds = [(_stats(closed=10), 0), (_stats(closed=15), 0), (_stats(closed=17), 0)]
    s = _Script(monkeypatch, rounds, finals=[_stats(closed=12), _stats(closed=17)], more=[0, 5])
    _, stopped = _run(10, more=s.more)
    key = jax.random.key(0)
    want = [(k, np.asarray(jax.random.key_data(jax.random.fold_in(key, r))).tolist())
            for r, k in enumerate("afaaf")]
    assert stopped == "target" and s.keys == want and s.more_calls == 4


def test_a_ctrl_c_in_the_first_round_propagates(monkeypatch):
    """Nothing completed yet: a Ctrl-C in the first paused round is re-raised (there is nothing to keep)."""

    def advance(ln, key, budget):
        raise KeyboardInterrupt

    monkeypatch.setattr(Lanes, "advance", advance)
    with pytest.raises(KeyboardInterrupt):
        _run(10)


def test_pilot_budgets_grow_within_a_rounds_lane_steps_and_stop_past_64_max_steps(monkeypatch):
    """Nothing closes: the pilot budget grows x4 but at most max(round_lane_steps / lanes, 4 block) =
    max(64 / 8, 32) = 32; the rounds stop ("work_bound") once the lanes paid more than 64 max_steps
    each (64 x 1 x 8 = 512): 16 x 8 + 32 x 8 + 32 x 8 = 640 after the third round."""
    s = _Script(monkeypatch, [(_stats(), 128), (_stats(), 256)])
    _, stopped = _run(10, round_lane_steps=64, max_steps=1)
    assert stopped == "work_bound" and s.budgets == [16, 32, 32]


def test_the_round_cap_defaults_to_the_engine_constant(monkeypatch):
    """``round_lane_steps`` left out is ``rounds.ROUND_LANE_STEPS`` (read per run, so that
    ``scripts/device_check.py --round-steps`` can try GPU-sized rounds): set to 4000, the second round of
    the case below is capped at 4000 / 8 = 500, as with the argument; at the default 2^26 it is
    ceil(92 x 100 / 8) = 1150."""

    assert rd.ROUND_LANE_STEPS == 2**26
    s = _Script(monkeypatch, [(_stats(closed=4, in_flight=4, useful=800), 0), (_stats(closed=100), 0)])
    _run(100)
    assert s.budgets == [16, 1150]
    monkeypatch.setattr(rd, "ROUND_LANE_STEPS", 4000)
    s = _Script(monkeypatch, [(_stats(closed=4, in_flight=4, useful=800), 0), (_stats(closed=100), 0)])
    _run(100)
    assert s.budgets == [16, 500]


def test_round_budget_is_at_least_a_quarter_excursion_and_at_most_a_rounds_lane_steps(monkeypatch):
    """After a round with 4 closed + 4 in flight and 8000 useful steps (1000 per excursion), N = 9
    leaves 1 excursion: ceil(1 x 1000 / 8) = 125 < 1000 // 4 = 250, so 250.  With 800 useful steps
    (100 each) and N = 100: ceil(92 x 100 / 8) = 1150, capped at round_lane_steps / lanes = 4000 / 8 =
    500.  With nothing closed (8 in flight) the pilot still grows x4."""
    s = _Script(monkeypatch, [(_stats(closed=4, in_flight=4, useful=8000), 0), (_stats(closed=100), 0)])
    _run(9)
    assert s.budgets == [16, 250]
    s = _Script(monkeypatch, [(_stats(closed=4, in_flight=4, useful=800), 0), (_stats(closed=100), 0)])
    _run(100, round_lane_steps=4000)
    assert s.budgets == [16, 500]
    # none closed, 8 in flight: still the pilot, x4 (README: "4x longer each time nothing has closed"), not
    # ceil((100 - 0 - 8) x 100 / 8) = 1150 sized from the in-flight ones
    s = _Script(monkeypatch, [(_stats(in_flight=8, useful=800), 0), (_stats(closed=100), 0)])
    _run(100)
    assert s.budgets == [16, 64]


def test_max_work_caps_the_next_budget_and_stops_the_rounds_once_reached(monkeypatch):
    """max_work = 10000, 800 paid by 8 lanes after the first round: the next budget is at most
    (10000 - 800) // 8 + 8 = 1158 steps per lane; once the lanes have paid exactly 10000 the rounds
    stop ("work_bound").  A pilot of 1 step grows to 4, raised to one block (8) by the cap's floor."""
    first = _stats(closed=4, in_flight=4, useful=800)
    s = _Script(monkeypatch, [(first, 800), (first, 9200)])
    _, stopped = _run(10**6, max_work=10000)
    assert stopped == "work_bound" and s.budgets == [16, 1158]
    s = _Script(monkeypatch, [(_stats(), 0), (_stats(closed=10), 0)])
    _run(10, pilot_budget=1, max_work=10**9)
    assert s.budgets == [1, 8]


def test_max_time_stops_the_rounds_once_reached_and_sets_the_final_deadline(monkeypatch):
    """The clock reads 0 at the start and 5 after the first round: max_time = 5 has passed (>=), so one
    paused round, then the final round with deadline 0 + 2 x 5 = 10 ("max_time")."""
    s = _Script(monkeypatch, [(_stats(closed=1), 0)], clock=[0.0, 5.0])
    _, stopped = _run(10**6, max_time=5.0)
    assert stopped == "max_time" and len(s.budgets) == 1 and s.deadlines == [10.0]


@pytest.mark.parametrize("unfinished,now,want", [(0, 100.0, "n_excursions"), (1, 1.0, "n_excursions"),
                                                 (1, 20.0, "max_time")])
def test_the_final_round_is_said_cut_only_with_lanes_unfinished_past_the_deadline(monkeypatch, unfinished, now,
                                                                                    want):
    """N reached in the first round (max_time 10, deadline 20): the stop reason becomes "max_time" only
    if the final round left lanes unfinished and the clock is at or past the deadline."""
    _Script(monkeypatch, [(_stats(closed=10), 0)], finals=[_stats(closed=10, unfinished=unfinished)],
            clock=[0.0, now])
    assert _run(10, max_time=10.0)[1] == want
