r"""Mutation audit of the lane engine's round loop (``dryfric_jax.rounds``) on a clock chain.

The clock is a deterministic chain whose regenerations are known in advance: lane ``l`` starts
at counter ``-OFFSETS[l]``, each step adds 1, and the step onto a counter ``c >= 1`` that is a
triangular number m(m+1)/2 is a regeneration (on whichever set the lane watches).  Its
increments are ``dU = c - 40`` (both signs) and, for the PDMP-like variant, ``dt = (1 + c mod 3)/4``
(exact binary fractions).  So every excursion, its U, t and t_half, the budget rule and the
work bound can be written down from the definitions (module docstring of ``excursions``) and
checked lane by lane, exactly up to float64 rounding of sums of integers and quarters.
"""
import dataclasses
import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from dryfric_jax import excursions, rounds
from dryfric_jax.excursions import STAT_NAMES
from dryfric_jax.rounds import Lanes, simulate_long_excursions, work_per_excursion

OFFSETS = (0, 1, 3, 7, 12, 20, 33, 60)  # extra seek steps of each lane
H = 0.375  # the DI-like clock's fixed step (t = n h)
POWERS = dict(n=(0, 0), U=(1, 0), U2=(2, 0), U3=(3, 0), U4=(4, 0), t=(0, 1), t2=(0, 2), t3=(0, 3), t4=(0, 4),
              Ut=(1, 1), U2t=(2, 1), U3t=(3, 1), Ut2=(1, 2), U2t2=(2, 2), Ut3=(1, 3))


def _triangular(c):
    m = jnp.floor((jnp.sqrt(8.0 * c + 1.0) - 1.0) / 2.0)
    return (c >= 1) & (m * (m + 1.0) / 2.0 == c)


class Clock(eqx.Module):
    """DI-like clock: fixed step H, the regenerating step belongs to the new cycle, lanes seek."""

    h: jnp.ndarray
    start_regenerated = False
    regen_after_step = False
    coin = None
    cpu_events = "wait"
    fused_quiet = False

    @property
    def fixed_dt(self):
        return self.h.astype(jnp.float64)

    def init_state(self, n: int):
        off = np.resize(np.asarray(OFFSETS, float), n)
        return (-jnp.asarray(off), jnp.zeros((n,)))

    def draw_lanes(self, keys, block: int):
        return (jnp.zeros((block, keys.shape[0])),)

    def advance(self, state, r, watch_plus):
        c = state[0] + 1.0
        return (c, state[1]), c - 40.0, None, _triangular(c)


class PClock(Clock):
    """PDMP-like clock: float64 event times, the regenerating step closes its cycle, lanes start
    regenerated (in the +HLE)."""

    start_regenerated = True
    regen_after_step = True
    cpu_events = "branch"

    @property
    def fixed_dt(self):
        return None

    def advance(self, state, r, watch_plus):
        c = state[0] + 1.0
        return (c, state[1]), c - 40.0, 0.25 * (1.0 + jnp.mod(c, 3.0)), _triangular(c)


def _is_tri(c):
    m = (math.isqrt(8 * c + 1) - 1) // 2 if c >= 1 else 0
    return c >= 1 and m * (m + 1) // 2 == c


def reference_lane(offset, budget, max_steps, pdmp, events=None):
    """One lane of a fresh final round, step by step from the definitions: a lane opens an
    excursion at a regeneration in SEEK or -HLE only while its work (steps taken before this one)
    is below ``budget``; the +HLE ends at the next regeneration (t_half), the -HLE at the one after
    (closing it); DI: the regenerating step is the new cycle's first, PDMP: the last of the cycle
    it closes.  The lane stops at the first step after which it seeks with its work spent; an
    excursion (or a seek) whose step count reaches ``max_steps`` is dropped and the lane seeks
    again (a truncation only for an excursion).  Returns the closed (U, t, t_half), counted steps,
    truncations, work and the step count n at the stop (of the seek it stopped in).  ``events``
    (a list) collects, step by step, whether the step has an event (``_has_event``'s definition: a
    regeneration, the work bound at this step, or a seek with the work spent)."""
    c, phase, U, t, n, th = -offset, ("plus" if pdmp else "seek"), 0.0, 0.0, 0, 0.0
    closed, steps, trunc, work = [], 0, 0, 0
    while True:
        c += 1
        dU, dt, heads, spent = c - 40.0, 0.25 * (1 + c % 3), _is_tri(c), work >= budget
        if events is not None:
            events.append(heads or n + 1 >= max_steps or (spent and phase == "seek"))
        work += 1
        old = phase
        opens = heads and old != "plus" and not spent
        counted = old != "seek" or (opens and not pdmp)
        if pdmp and counted:  # the step belongs to the cycle in flight
            U, t, n, steps = U + dU, t + dt, n + 1, steps + 1
        if heads and old == "minus":
            closed.append((U, t if pdmp else n * H, th))
        if heads and old == "plus":
            th, phase = (t if pdmp else n * H), "minus"
        elif heads:
            phase = "plus" if opens else "seek"
            U, t, n = 0.0, 0.0, (0 if old != "seek" or opens else n)
        if not pdmp and counted:  # the step belongs to the cycle it is in after the step
            U, n, steps = U + dU, n + 1, steps + 1
        if phase == "seek":
            n = n + 1 if old == "seek" else 0
            if spent:
                return closed, steps, trunc, work, n
        if n >= max_steps:
            trunc += phase != "seek"
            phase, n = "seek", 0


def _expected(budget, max_steps, pdmp):
    want = np.zeros((len(OFFSETS), len(STAT_NAMES)))
    steps, trunc, work, n_stop = [], [], [], []
    for lane, off in enumerate(OFFSETS):
        closed, s, tr, w, n = reference_lane(off, budget, max_steps, pdmp)
        steps.append(s), trunc.append(tr), work.append(w), n_stop.append(n)
        for U, t, th in closed:
            for k, (a, b) in POWERS.items():
                want[lane, STAT_NAMES.index(k)] += U**a * t**b
            want[lane, STAT_NAMES.index("t_half")] += th
    return want, np.array(steps), np.array(trunc), np.array(work), np.array(n_stop)


def _lane_blocks(events, block, layout):
    """Blocks a lane of a final round runs until it stops (its steps' event flags, ``events``):
    ``"branch"`` takes whole blocks; ``"wait"`` ends a block at its first step with an event and
    idles the rest of it (``_block``)."""
    if layout == "branch":
        return -(-len(events) // block)
    blocks = taken = 0
    for ev in events:
        taken += 1
        if ev or taken == block:
            blocks, taken = blocks + 1, 0
    return blocks + (taken > 0)


def _slot_steps(ln, budget, max_steps, pdmp, block):
    """The slots a fresh final round pays: each device runs blocks until its last lane stopped, a
    block costing ``block`` steps for each of its lanes (pad lanes included: layout lane i is the
    clock of offset OFFSETS[i mod 8])."""
    per_offset = []
    for off in OFFSETS:
        events = []
        reference_lane(off, budget, max_steps, pdmp, events)
        per_offset.append(_lane_blocks(events, block, ln.events))
    blocks = np.resize(per_offset, ln.n).reshape(len(ln.devices), -1)
    return int(blocks.max(axis=1).sum()) * block * blocks.shape[1]


def _chain(pdmp):
    return (PClock if pdmp else Clock)(jnp.asarray(H))


def _check_final_round(pdmp, events, budget, max_steps, block=8):
    ln = Lanes(_chain(pdmp), len(OFFSETS), block=block, max_steps=max_steps, events=events)
    got = ln._round(jax.random.key(0), budget, True)
    want, steps, trunc, work, n_stop = _expected(budget, max_steps, pdmp)
    real = lambda a: np.asarray(a)[:len(OFFSETS)]  # noqa: E731
    np.testing.assert_allclose(got.stats, want, rtol=1e-13, atol=0)
    np.testing.assert_array_equal(got.lane_steps, steps)
    np.testing.assert_array_equal(real(ln.lane.n_trunc), trunc)
    np.testing.assert_array_equal(real(ln.lane.work), work)
    # the clock moved on the lane's own steps only, and the stopped lane's count is its seek's
    np.testing.assert_array_equal(real(ln.lane.state[0]), work - np.asarray(OFFSETS))
    np.testing.assert_array_equal(real(ln.lane.n), n_stop)
    assert (got.n_truncated, got.useful_steps, got.n_unfinished, got.n_in_flight) == (trunc.sum(), steps.sum(), 0, 0)
    assert got.slot_steps == _slot_steps(ln, budget, max_steps, pdmp, block)
    return want, trunc


@pytest.mark.parametrize("events", ["wait", "branch"])
@pytest.mark.parametrize("pdmp", [False, True])
def test_final_round_sums_are_the_clocks_excursions(pdmp, events):
    """A fresh final round of the clock (budget 300, no work bound): per lane, every one of the 16
    sums, the counted steps, the work and no truncation, against the step-by-step definition.  The
    first lanes close ~5-7 excursions of 20-50 steps; lane 7 (60 seek steps) fewer."""
    want, _ = _check_final_round(pdmp, events, 300, 10**6)
    assert want[:, 0].min() >= 2 and want[:, 0].sum() >= 30  # the case has excursions to count


@pytest.mark.parametrize("events", ["wait", "branch"])
@pytest.mark.parametrize("pdmp", [False, True])
def test_work_bound_truncates_excursions_not_seeks(pdmp, events):
    """max_steps = 30 (excursions grow 4 steps each, from 9 steps): the later excursions are
    truncated at exactly 30 steps and the lane seeks again; the DI-like lane 7's first seek (60
    steps) is restarted at 30 steps but is no truncation (the PDMP-like one starts in an excursion)."""
    want, trunc = _check_final_round(pdmp, events, 500, 30)
    assert trunc.sum() >= 8 and want[:, 0].sum() >= 20


@pytest.mark.parametrize("events", ["wait", "branch"])
@pytest.mark.parametrize("pdmp", [False, True])
def test_small_budgets_stop_seeking_lanes(pdmp, events):
    """Budgets 0 and 1: a seeking lane stops at its first step with its work spent (1 or 2 steps),
    and a lane that opened nothing has no sums; lane 0's first regeneration (step 1) opens an
    excursion only while its work (0 before the step) is below the budget.  With max_steps 1 a
    budget-0 lane's one seek step both stops it and reaches the work bound: it stops (its seek
    count stays 1); max_steps 3 truncates lane 0's first excursion at its third step."""
    for budget, max_steps in ((0, 10**6), (1, 10**6), (5, 10**6), (0, 1), (2, 3)):
        _check_final_round(pdmp, events, budget, max_steps)


@pytest.mark.parametrize("events", ["wait", "branch"])
def test_paused_rounds_then_final_round_close_exactly_the_started_excursions(events):
    """Two paused rounds (budgets 5 and 100) and a final round of budget 0 (what simulate_long_excursions runs) give the
    sums of one final round whose budget is each lane's paused work, lane by lane (the lanes pause
    and continue the same chain), and the final round closes every excursion in flight: closed +
    in flight after the pauses = closed after the final round."""
    ln = Lanes(_chain(False), len(OFFSETS), block=8, max_steps=10**6, events=events)
    a = ln.advance(jax.random.key(1), 5)
    w1 = np.asarray(ln.lane.work)
    assert w1[7] == 8  # still seeking, no event: a paused round has no budget stop, it runs its block
    b = ln.advance(jax.random.key(2), 100)
    paused = w1 + np.asarray(ln.lane.work)
    assert a.n_unfinished == 0 and b.n_unfinished == 0 and b.n_in_flight > 0
    if events == "branch":
        assert np.all(paused == 8 + 104)  # ceil(budget / 8) blocks of 8 steps per round
    c = ln.finish(jax.random.key(3))
    for lane, off in enumerate(OFFSETS):
        closed, steps, _, _, _ = reference_lane(off, int(paused[lane]), 10**6, False)
        want = [sum(U**p * t**q for U, t, _ in closed) for p, q in ((0, 0), (1, 0), (2, 0), (0, 1), (1, 1))]
        got = c.stats[lane, [STAT_NAMES.index(k) for k in ("n", "U", "U2", "t", "Ut")]]
        np.testing.assert_allclose(got, want, rtol=1e-13, atol=0, err_msg=str(lane))
        assert c.lane_steps[lane] == steps, lane
    assert c.n_excursions + c.n_truncated == b.n_excursions + b.n_truncated + b.n_in_flight
    assert c.n_in_flight == 0 and c.n_unfinished == 0


def test_simulate_stops_the_paused_rounds_once_closed_plus_in_flight_reach_n(monkeypatch):
    """The rounds pause until closed (complete or truncated) plus in-flight excursions reach N, then
    one final round closes those in flight: every paused round but the last is short of N, and the
    result has at least N excursions, all closed ("n_excursions")."""
    seen, real = [], Lanes.advance
    monkeypatch.setattr(Lanes, "advance", lambda self, k, b: seen.append(real(self, k, b)) or seen[-1])
    st, stopped = simulate_long_excursions(_chain(False), jax.random.key(0), 40, lanes=8, block=8, pilot_budget=16,
                                           max_steps=20)
    reached = [s.n_excursions + s.n_truncated + s.n_in_flight >= 40 for s in seen]
    assert stopped == "n_excursions" and reached[-1] and not any(reached[:-1]) and len(seen) >= 2
    assert st.n_truncated > 0 and st.n_excursions + st.n_truncated >= 40 and st.n_in_flight == 0


def test_simulate_says_which_bound_stopped_it(monkeypatch):
    """stopped_by: "work_bound" once the lanes paid max_work, "target" when ``more`` asks for
    nothing after the final round, "n_excursions" otherwise; a ``more`` that asks for more moves
    the target to closed + extra."""
    ch = _chain(False)
    _, stopped = simulate_long_excursions(ch, jax.random.key(0), 10**6, lanes=8, block=8, max_work=4000)
    assert stopped == "work_bound"
    asked = []

    def more(st):
        asked.append(st.n_excursions + st.n_truncated)
        return 30 if len(asked) == 1 else 0

    st, stopped = simulate_long_excursions(ch, jax.random.key(0), 20, lanes=8, block=8, more=more)
    assert stopped == "target" and st.n_excursions >= asked[0] + 30 and st.n_in_flight == 0


def test_work_per_excursion_counts_each_in_flight_one_as_one():
    assert work_per_excursion(120.0, 7, 5) == 10.0 and work_per_excursion(9.0, 0, 3) == 3.0


def test_pad_lanes_are_dropped_from_the_sums_and_the_work():
    """Seven real lanes: where the device count does not divide them (2 devices: 8 layout lanes,
    the shape the other tests compiled) pad lanes fill the layout, dropped from the results.  A
    final round's sums and steps are the 7 lanes' alone, and a paused round's paid work (what
    max_work sees) counts the real lanes' slots only: ceil(20 / 8) = 3 blocks of 8 steps each."""
    r = len(OFFSETS) - 1
    ln = Lanes(_chain(False), r, block=8, max_steps=10**6, events="wait")
    assert ln.n > r or len(ln.devices) == 1  # one device: 7 lanes, no pad
    ln.advance(jax.random.key(0), 20)
    assert ln.paid == 24 * r
    ln = Lanes(_chain(False), r, block=8, max_steps=10**6, events="branch")
    got = ln.finish(jax.random.key(0), 300)
    want, steps, _, work, _ = _expected(300, 10**6, False)
    np.testing.assert_allclose(got.stats, want[:r], rtol=1e-13, atol=0)
    assert got.lane_steps.tolist() == steps[:r].tolist() and ln.paid == work[:r].sum()


def test_a_stopped_lane_has_no_event():
    """``_has_event`` (which steps the "branch" layout books): a lane that has stopped needs no
    bookkeeping, whatever its regeneration flag, step count or budget say; a live one seeking with
    its budget spent (0) does.  Without the ``done`` test the final round's tail booked every step
    of a stopped lane at a regeneration (same results, the full bookkeeping each step: audit)."""
    from dryfric_jax.excursions import _has_event, init_lanes

    lane = init_lanes(_chain(False), 4)
    done = jnp.asarray([True, False, True, False])
    lane = eqx.tree_at(lambda l: (l.done, l.n), lane, (done, jnp.full((4,), 10, jnp.int64)))
    adv = (lane.state, jnp.zeros(4), None, jnp.asarray([True, True, False, False]))
    for budget, max_steps in ((0, 10**6), (10**6, 11), (0, 11)):
        has = jax.vmap(lambda l, a: _has_event(budget, max_steps, True, l, a))(lane, adv)
        assert np.asarray(has).tolist() == [False, True, False, budget == 0 or max_steps == 11]


def test_simulate_counts_the_excursions_in_flight_towards_n(monkeypatch):
    """The paused rounds stop as soon as closed plus in-flight excursions reach N, even with fewer
    closed: N = the first paused round's closed + in flight (that round run alone, the same key and
    lanes) gives exactly one paused round, then the final round that closes them all.  Stopping
    on the closed ones alone ran more paused rounds (mutation audit)."""
    ch, key = _chain(False), jax.random.key(0)
    first = Lanes(ch, 8, block=8, max_steps=10**6).advance(jax.random.fold_in(key, 0), 16)
    n = first.n_excursions + first.n_truncated + first.n_in_flight
    assert first.n_in_flight > 0
    seen, real = [], Lanes.advance
    monkeypatch.setattr(Lanes, "advance", lambda self, k, b: seen.append(real(self, k, b)) or seen[-1])
    st, stopped = simulate_long_excursions(ch, key, n, lanes=8, block=8, pilot_budget=16, max_steps=10**6)
    assert len(seen) == 1 and stopped == "n_excursions" and st.n_excursions + st.n_truncated == n


def test_lanes_for_keeps_at_least_min_lanes_up_to_n():
    """A power of two near N / per_lane, but at least min(min_lanes, N) (and at most chunk_lanes):
    N = 1000 gets 512 lanes, not 16 (1000 // 32 = 31); N = 100 gets 64; N = 1e6 gets 2^14 capped
    at the chunk."""
    assert excursions.lanes_for(1000, 4096) == 512
    assert excursions.lanes_for(100, 4096) == 64
    assert excursions.lanes_for(10**6, 4096) == 4096 and excursions.lanes_for(10**6, 2**20) == 2**14
    assert excursions.lanes_for(1, 4096) == 1


def test_replicates_run_on_a_fresh_key_with_a_5_percent_margin(monkeypatch):
    """simulate_replicates: the pilot (fold_in(key, 0), discarded) sizes one final round of
    n_replicates x L fresh lanes on another key (fold_in(key, 1): reusing the pilot's numbers ties
    the budget to the excursions it measured), with a budget of 1.05 n_per_replicate mean
    excursions per replicate: ceil(1.05 * 40 * 12.5 / 4) = 132 steps per lane."""
    keys, calls = [], []
    monkeypatch.setattr(rounds, "steps_per_excursion", lambda ch, k, **kw: keys.append(k) or 12.5)
    monkeypatch.setattr(rounds, "run_round", lambda ch, k, lanes, budget, **kw: calls.append((k, lanes, budget)))
    key = jax.random.key(7)
    rounds.simulate_replicates(_chain(False), key, 3, 40, lanes_per_replicate=4)
    ((k, lanes, budget),) = calls
    assert (lanes, budget) == (12, math.ceil(1.05 * 40 * 12.5 / 4))
    data = lambda k: np.asarray(jax.random.key_data(k)).tolist()  # noqa: E731
    assert data(keys[0]) == data(jax.random.fold_in(key, 0)) and data(k) == data(jax.random.fold_in(key, 1))


class _Far(Clock):
    """A clock that never regenerates within the test (every lane starts 1e9 steps before c = 1)."""

    def init_state(self, n: int):
        return (jnp.full((n,), -1e9), jnp.zeros((n,)))


def test_a_run_with_nothing_closed_stops_past_64_max_steps_per_lane(monkeypatch):
    """No excursion ever opens: the pilot rounds grow x4 until the lanes have paid more than 64
    max_steps each, then stop with "work_bound".  max_steps 16, 8 lanes: the first pilot round
    (1024 steps per lane) pays exactly 64 * 16 * 8 = 8192, not more, so a second round runs."""
    seen, real = [], Lanes.advance
    monkeypatch.setattr(Lanes, "advance", lambda self, k, b: seen.append((b, real(self, k, b))) or seen[-1][1])
    st, stopped = simulate_long_excursions(_Far(jnp.asarray(H)), jax.random.key(0), 10, lanes=8, block=8,
                                           pilot_budget=1024, max_steps=16)
    assert stopped == "work_bound" and [b for b, _ in seen] == [1024, 4096] and st.n_excursions == 0


def test_paused_rounds_never_plan_past_max_work(monkeypatch):
    """With max_work the paused rounds' budgets are capped at what is left of it (plus a block):
    the lanes have paid at most max_work + block steps each past it when the rounds stop
    (max_work = 2000 lane-steps, 8 lanes: N = 1e6 excursions would ask for far more)."""
    paid, real = [], Lanes.advance

    def advance(self, k, b):
        out = real(self, k, b)
        paid.append(self.paid)
        return out

    monkeypatch.setattr(Lanes, "advance", advance)
    _, stopped = simulate_long_excursions(_chain(False), jax.random.key(0), 10**6, lanes=8, block=8, pilot_budget=16,
                                          max_work=2000)
    assert stopped == "work_bound" and len(paid) >= 2
    assert paid[-1] <= 2000 + 2 * 8 * 8  # the cap's extra block, and the round's own last block


def test_round_budgets_count_the_in_flight_excursions_as_one_each(monkeypatch):
    """After the pilot, a paused round's budget is the steps still wanted at the measured steps per
    excursion, the in-flight excursions counted as done: ceil((N - closed - in flight) x per / lanes),
    between 4 blocks (or per / 4) and a round's lane-steps.  Checked on each round's recorded sums."""
    seen, real = [], Lanes.advance
    monkeypatch.setattr(Lanes, "advance", lambda self, k, b: seen.append((b, real(self, k, b))) or seen[-1][1])
    n, lanes, block, cap = 400, 8, 8, 2**26
    simulate_long_excursions(_chain(False), jax.random.key(0), n, lanes=lanes, block=block, pilot_budget=16,
                             max_steps=10**6)
    assert len(seen) >= 3
    for (_, st), (b_next, _) in zip(seen, seen[1:]):
        done = st.n_excursions + st.n_truncated
        if done == 0:
            continue
        per = st.useful_steps / (done + st.n_in_flight)
        want = math.ceil((n - done - st.n_in_flight) * per / lanes)
        assert b_next == max(4 * block, int(per) // 4, min(want, cap // lanes))


def _interrupting(monkeypatch, finish_raises: bool):
    """Lanes whose second paused round is interrupted (Ctrl-C) and whose final round is counted,
    raises Ctrl-C (``finish_raises``) or returns a round that the deadline cut (1 unfinished, the
    clock past every deadline)."""
    calls = dict(advance=0, finish=0)
    real = Lanes.advance

    def advance(self, k, b):
        calls["advance"] += 1
        if calls["advance"] == 2:
            raise KeyboardInterrupt
        return real(self, k, b)

    def finish(self, k, budget=0, deadline=None):
        calls["finish"] += 1
        clock[0] = 1e9  # the final round ran past every deadline
        st = real(self, k, 16)
        if finish_raises:
            raise KeyboardInterrupt
        return dataclasses.replace(st, n_unfinished=1)

    monkeypatch.setattr(Lanes, "advance", advance)
    monkeypatch.setattr(Lanes, "finish", finish)
    clock = [0.0]
    monkeypatch.setattr(rounds, "_now", lambda: clock[0])
    return calls


def test_a_ctrl_c_during_the_rounds_stays_the_reason_and_a_second_one_ends_the_final_round(monkeypatch):
    """A Ctrl-C in the paused rounds is the run's first: the final round then finishes the in-flight
    excursions, and its stop reason stays "interrupted" even where a deadline cut it (max_time
    would misname why the run ended); a Ctrl-C in that final round is the second, which ends it
    at once instead of running it again."""
    calls = _interrupting(monkeypatch, finish_raises=False)
    _, stopped = simulate_long_excursions(_chain(False), jax.random.key(0), 10**6, lanes=8, block=8,
                                          pilot_budget=16, max_time=100.0)
    assert stopped == "interrupted" and calls == dict(advance=2, finish=1)
    calls = _interrupting(monkeypatch, finish_raises=True)
    _, stopped = simulate_long_excursions(_chain(False), jax.random.key(0), 10**6, lanes=8, block=8, pilot_budget=16)
    assert stopped == "interrupted" and calls == dict(advance=2, finish=1)
