r"""Long excursions of the discrete DI (and of the PDMP, whose chain runs on the same engine) as
vmapped lanes inside one ``lax.while_loop``.

A lane runs one chain and cuts it at regenerations (:mod:`dryfric_jax.regeneration`):

* phase SEEK: run until the first regeneration on :math:`C_+` (stuck, released upwards); the
  heads transition is distributed as :math:`\nu_+` and opens the first excursion.  Nothing
  simulated before it is counted;
* phase PLUS (+HLE): until a regeneration on :math:`C_-` (stuck, released downwards);
* phase MINUS (-HLE): until a regeneration on :math:`C_+`, which closes the long excursion; its
  heads transition opens the next one (the lane refills itself).

So a lane's excursions are consecutive i.i.d. regeneration cycles of one chain.  Each lane
carries its phase, its termination flag and its accumulators: U in float64 (in float32 a block's
<= ``block`` increments are summed in float32 first), the step count n as an integer (t = n h
exactly), and float64 sums of the products the delta method needs.

**Unbiased under a budget.**  A round gives every lane a budget of steps.  When it is spent the
lane *finishes its in-flight excursion*, starts no new one and raises its termination flag.  The
number of excursions a lane starts before its budget runs out is a stopping time for its cycle
sequence, so by Wald's identity :math:`E[\sum U] = E[N] E[U]` and the ratio estimators stay
consistent (regenerative simulation, Glynn & Heidelberger 1990).  Dropping the in-flight
excursion instead keeps only the cycles that *ended* before the budget, which is not a stopping
time and biases D low (``finish_in_flight=False`` of :func:`~dryfric_jax.rounds.run_round`, kept to
demonstrate it in the tests).  The rounds themselves (paused rounds, the final round, its
compacted tail, precision targets, deadlines and Ctrl-C) are driven from the host by
:mod:`dryfric_jax.rounds`; this module is what runs inside the jitted loop.

Steps run in blocks of ``block`` with the block's normals drawn at once (``split`` per lane,
``fold_in`` per block).  The bookkeeping above runs only for steps with an event (a
regeneration or a splitting coin to flip, a budget stop, the work bound): once per block for
each lane's first event, the lane waiting for it (the DI, and every chain on a GPU), or behind
a real branch taken when some lane has one (the PDMP on a CPU); see ``_block``.  Work
is bounded: an excursion that reaches ``max_steps`` is closed, counted as truncated and
reported, and the lane seeks again; no lane runs more than ``budget + max_steps`` steps.
"""
from __future__ import annotations

from functools import lru_cache, partial

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh, NamedSharding, PartitionSpec

from . import rng


# per-lane sufficient statistics of the closed excursions, in float64: every product of two
# entries of (U, U^2, t, U t, t^2), which the delta method for D and M0 needs
STAT_NAMES = ("n", "U", "U2", "U3", "U4", "t", "t2", "t3", "t4", "Ut", "U2t", "U3t", "Ut2", "U2t2", "Ut3",
              "t_half")

SEEK, PLUS, MINUS = 0, 1, 2
BLOCK = 128  # steps per while-iteration (32..256 measured on 2 CPU cores, PERFORMANCE.md)
GPU_DI_BLOCK = 256  # the DI's default K off a CPU (default_block)
MAX_LAYOUT = 1 << 28  # lanes * K: a block's normals are drawn at once (plan.check_layout)
# steps per iteration of the block's loop: best of 5 runs against 1, DI +1-7%, PDMP +10-14% on 2 CPU
# cores; 8 was no better
UNROLL = 4
# steps per iteration of the wait layout's loop (_quiet_steps): x4 ran 1.4x slower on 2 CPU cores
# (XLA:CPU recomputes the step in each kernel that writes one of its arrays; PERFORMANCE.md); on a GPU,
# where each iteration launches kernels, not yet measured (scripts/device_check.py --unroll).
# Unrolling changes how XLA fuses the step, hence its rounding and, through the sticking
# decisions, the paths: at 1024 lanes, float32, 2 CPU devices, unroll 1, 4 and 16 gave D =
# 2.7099e-3, 2.7080e-3 and 2.7085e-3 (CI +-1.5e-4): the law, not the bits, is kept
QUIET_UNROLL = 1
#: on a CPU the float64 DI's quiet loop carries (X, V) and (U, at) stacked as one (2, lanes) complex128 array, two
#: steps an iteration (:func:`_quiet_steps`; not timed on a GPU, which keeps the two-array loop); False: the
#: two-array loop, which gives the same numbers to the bit (tested)
STACKED_QUIET = True


class _Lane(eqx.Module):
    state: tuple  # the chain's own state (DI: X, V; PDMP: k, y, v)
    U: jnp.ndarray  # float64 displacement of the in-flight excursion
    n: jnp.ndarray  # steps (events) of the in-flight excursion, or of the current seek
    t: jnp.ndarray  # float64 duration of the in-flight excursion (chains without a fixed step)
    t_half: jnp.ndarray  # duration at which the -HLE began
    phase: jnp.ndarray  # SEEK, PLUS or MINUS
    done: jnp.ndarray  # the lane's termination flag (per round)
    stats: tuple  # len(STAT_NAMES) float64 sums over complete excursions, all rounds (one array each)
    n_trunc: jnp.ndarray  # excursions closed by the work bound
    steps: jnp.ndarray  # useful steps done by the lane, all rounds
    work: jnp.ndarray  # steps done in this round (seeks included): compared with the budget


def _duration(chain, n, t):
    """t = n h exactly (integer count) for a fixed-step chain, the float64 sum otherwise."""
    return n.astype(jnp.float64) * chain.fixed_dt if chain.fixed_dt is not None else t


def _close(lane: _Lane, U, t, complete) -> _Lane:
    """Add the excursion (U, t) to the lane's sums where ``complete``."""
    th = lane.t_half
    U2, t2 = U * U, t * t
    row = (jnp.ones_like(U), U, U2, U2 * U, U2 * U2, t, t2, t2 * t, t2 * t2, U * t, U2 * t, U2 * U * t,
           U * t2, U2 * t2, U * t2 * t, th)
    # one array per sum: a (lanes, 16) array built by stacking made the bookkeeping step ~4x slower
    return eqx.tree_at(lambda l: l.stats, lane,
                       tuple(s + jnp.where(complete, r, 0.0) for s, r in zip(lane.stats, row)))


def _budget_stop(lane: _Lane, budget, finish, phase):
    """In a final round, the budget is spent and nothing is in flight (``phase`` after the step
    is SEEK): the lane stops after this step.  A paused round (or the drop-in-flight demo) stops
    on a block count instead (:func:`_round_impl`), so it has no stop event."""
    return finish & (lane.work >= budget) & (phase == SEEK)


def _advance(chain, lane: _Lane, r):
    """The chain's transition for one lane: ``(state, dU, dt, heads)``; for a chain with a
    splitting coin ``heads`` only marks candidates (:func:`_flip_coins`)."""
    return chain.advance(lane.state, r, lane.phase != PLUS)


def _flip_coins(chain, lane: _Lane, adv, r, coin_keys):
    """Regenerations of a chain with a splitting coin (the DI): a candidate is one when its coin
    (``chain.coin``, one key per lane) says heads.  Run only in the bookkeeping, so steps where
    no lane has a candidate draw no coin at all."""
    if chain.coin is None:
        return adv
    state, dU, dt, candidate = adv
    heads = jax.vmap(chain.coin)(lane.state, r, lane.phase != PLUS, coin_keys)
    return state, dU, dt, candidate & heads


def _book(chain, budget, max_steps, finish, lane: _Lane, adv) -> _Lane:
    """The excursion bookkeeping of one step (DI) or event (PDMP) of one lane.

    ``adv = chain.advance(...)`` says whether this transition is a regeneration on the watched
    set (C_+ in SEEK and MINUS, C_- in PLUS).  For the DI (``regen_after_step`` False) the
    regenerating transition belongs to the new cycle; for the PDMP (True) the state *after* it
    is s_+ or s_-, so it belongs to the cycle it closes.
    """
    active = ~lane.done
    phase = lane.phase
    state, dU, dt, heads = adv
    heads = heads & active
    spent = lane.work >= budget
    closes = heads & (phase == MINUS)  # long excursion complete
    # refill: this regeneration starts an excursion, unless the budget is spent in a final round
    opens = heads & (phase != PLUS) & ~(spent & finish)
    halfway = heads & (phase == PLUS)  # the -HLE starts now
    # a fixed-step chain (dt None) has t = n h: its float64 time sum stays untouched
    add_t = (lambda t, mask: t) if dt is None else (lambda t, mask: t + jnp.where(mask, dt, 0.0))
    if chain.regen_after_step:
        cnt = active & (phase != SEEK)
        U, n, t = lane.U + jnp.where(cnt, dU, 0.0), lane.n + cnt, add_t(lane.t, cnt)
        lane = _close(lane, U, _duration(chain, n, t), closes)
        fresh = opens | closes
        t_half = jnp.where(halfway, _duration(chain, n, t), lane.t_half)
        U, n, t = jnp.where(fresh, 0.0, U), jnp.where(fresh, 0, n), jnp.where(fresh, 0.0, t)
        counted = cnt
    else:
        lane = _close(lane, lane.U, _duration(chain, lane.n, lane.t), closes)
        t_half = jnp.where(halfway, _duration(chain, lane.n, lane.t), lane.t_half)
        counted = active & ((phase != SEEK) | opens)
        U = jnp.where(opens, 0.0, lane.U) + jnp.where(counted, dU, 0.0)
        n = jnp.where(opens, 0, lane.n) + counted
        t = add_t(jnp.where(opens, 0.0, lane.t), counted)
    new_phase = jnp.where(opens, PLUS, jnp.where(halfway, MINUS, jnp.where(closes, SEEK, phase)))
    # a paused round keeps the stopped lane's state for the next round
    stop = active & _budget_stop(lane, budget, finish, new_phase)
    # seeking steps are not useful work but count against the budget
    n = jnp.where(new_phase == SEEK, jnp.where(phase == SEEK, lane.n + active, 0), n)
    state = jax.tree_util.tree_map(lambda new, old: jnp.where(active, new, old), state, lane.state)
    lane = eqx.tree_at(
        lambda l: (l.state, l.U, l.n, l.t, l.t_half, l.phase, l.steps, l.work, l.done),
        lane, (state, U, n, t, t_half, new_phase, lane.steps + counted, lane.work + active, lane.done | stop),
    )
    # work bound: close a runaway excursion (or seek), report it, seek again
    runaway = active & ~stop & (lane.n >= max_steps)
    return eqx.tree_at(lambda l: (l.phase, l.n, l.n_trunc), lane,
                       (jnp.where(runaway, SEEK, lane.phase), jnp.where(runaway, 0, lane.n),
                        lane.n_trunc + (runaway & (lane.phase != SEEK))))


def _has_event(budget, max_steps, finish, lane: _Lane, adv):
    """Lanes whose step needs more than :func:`_quiet`: a regeneration (or a coin to flip), a
    stop on the budget, or the work bound (the cases where :func:`_book` changes phase, flag or
    sums)."""
    # with no regeneration the phase does not change, so the budget stop sees the current one
    stops = _budget_stop(lane, budget, finish, lane.phase)
    return ~lane.done & (adv[3] | stops | (lane.n + 1 >= max_steps))


def _quiet(lane: _Lane, adv) -> _Lane:
    """:func:`_book` for a step with no event in any lane (the same arithmetic): the state
    moves, U, n, t, steps and work grow, nothing else changes."""
    state, dU, dt, _ = adv
    active = ~lane.done
    counted = active & (lane.phase != SEEK)
    t = lane.t if dt is None else lane.t + jnp.where(counted, dt, 0.0)
    state = jax.tree_util.tree_map(lambda new, old: jnp.where(active, new, old), state, lane.state)
    return eqx.tree_at(lambda l: (l.state, l.U, l.n, l.t, l.steps, l.work), lane,
                       (state, lane.U + jnp.where(counted, dU, 0.0), lane.n + active, t, lane.steps + counted,
                        lane.work + active))


def block_keys(keys, b):
    """Block ``b``'s key of every lane, ``fold_in(lane_key, b)``; ``b`` is one block index for all
    lanes or one per lane."""
    return rng.fold_in(keys, b)


def draw_block(chain, keys, b, block: int):
    """Block ``b``'s random numbers of every lane, drawn at once: ``chain.draw`` from the block
    key (:func:`block_keys`), each leaf of shape (block, lanes): a step reads one contiguous
    row.  Against (lanes, block), +3% (float64) and +6% (float32) DI lane-steps/s in paused rounds
    on 2 CPU cores (7 interleaved runs each); the numbers themselves are the same."""
    return chain.draw_lanes(block_keys(keys, b), block)


def numbers_at(rs, i):
    """Step ``i``'s numbers of every lane from :func:`draw_block`'s output."""
    return jax.tree_util.tree_map(lambda a: a[i], rs)


def increment_dtype(advance, state, rs, *args):
    """The dtype of the increment dU that ``advance(state, numbers_at(rs, 0), *args)`` returns,
    found by tracing only (``jax.eval_shape``): float64 for the PDMP, the simulation dtype for
    the DI.  A block of increments narrower than the float64 U is summed in its own dtype first
    (:func:`_quiet_steps`, ``bench.chain_floor``)."""
    return jax.eval_shape(lambda: advance(state, numbers_at(rs, 0), *args))[1].dtype


def _pair(state):
    """True for a chain state of two float arrays of one dtype (the DI's X, V)."""
    return (isinstance(state, tuple) and len(state) == 2 and state[0].dtype == state[1].dtype
            and jnp.issubdtype(state[0].dtype, jnp.floating))


def _quiet_steps(chain, budget, max_steps, finish, block, lane: _Lane, rs, fused: bool = False):
    """The ``wait`` layout's loop (:func:`_block`): every lane runs through the block until its
    first step with an event (:func:`_has_event`) and then waits.  Returns the lanes after their
    quiet steps and ``at``, each lane's pending step (``block``: none; -1: a done lane).

    XLA:CPU computes each array a step writes in its own kernel and recomputes the step's
    arithmetic in each, so the loop writes as few arrays as it can: only the chain's state, U,
    t and ``at`` change per step (n, steps and work are added after the loop from the number of
    steps each lane took), and the pairs (X, V) of the DI and (U, at) are carried as the real
    and imaginary parts of one complex array each (exact: no arithmetic touches the packing).
    The step went from 1.56 to 0.87 us (float64) and from 1.22 to 0.67 us (float32) at 256
    lanes, one device; the estimates are bit-identical.

    ``fused``: the same loop as one Pallas kernel, a lane's steps in registers
    (:func:`dryfric_jax.fused.quiet_steps`, the ``"fused"`` layout)."""
    watch = lane.phase != PLUS
    counted = lane.phase != SEEK
    # the steps of the block at which a lane's counters trigger an event (_has_event with n and
    # work i ahead, the phase fixed: quiet steps do not change it): the budget stop from step
    # budget - work of a final round's seek, the work bound from step max_steps - n - 1
    big = jnp.iinfo(jnp.int64).max
    stop_at = jnp.where(finish & (lane.phase == SEEK), budget - lane.work, big)
    first = jnp.minimum(stop_at, max_steps - lane.n - 1)
    pair = _pair(lane.state)
    pack = (lambda s: jax.lax.complex(*s)) if pair else (lambda s: s)
    unpack = (lambda c: (jnp.real(c), jnp.imag(c))) if pair else (lambda c: c)

    def body(i, c):
        state, Ua, t = c
        state, U, at = unpack(state), jnp.real(Ua), jnp.imag(Ua)
        adv = jax.vmap(chain.advance)(state, numbers_at(rs, i), watch)
        new, dU, dt, _ = adv
        fi = i.astype(at.dtype)
        free = at == block
        # a free lane has taken the block's first i steps: its counters are i ahead
        event = free & (adv[3] | (fi >= first))
        go = free & ~event
        state = jax.tree_util.tree_map(lambda a, b: jnp.where(go, a, b), new, state)
        U = U + jnp.where(go & counted, dU, 0.0)
        t = t if dt is None else t + jnp.where(go & counted, dt, 0.0)
        return pack(state), jax.lax.complex(U, jnp.where(event, fi, at)), t

    # a chain whose dU is narrower than float64 (the DI in float32) sums the block's increments in
    # its dtype from 0 and adds them to the float64 U after the loop, so the loop runs in one
    # dtype: float32 DI 1.60e8 -> 1.78e8 lane-steps/s at the Fig. 3 point (N = 1e4, 4 interleaved
    # runs each), D moved by ~1e-8 relative; a chain with a float64 dU sums straight into U
    dU_dtype = increment_dtype(jax.vmap(chain.advance), lane.state, rs, watch)
    part = dU_dtype != lane.U.dtype
    U0 = jnp.zeros(lane.U.shape, dU_dtype) if part else lane.U
    at = jnp.where(lane.done, -1.0, float(block)).astype(U0.dtype)
    # the step test in the loop's dtype (exact: 0 <= i < block <= 1024): with the int64 ``first``
    # the float32 loop mixed widths, +14% on the float32 quiet loop (512 lanes, K = 128, 2 CPU devices,
    # medians of 3), the same events
    first = jnp.clip(first, 0, block).astype(U0.dtype)
    if fused:
        from .fused import quiet_steps

        state, U, at = quiet_steps(chain, block, lane.state, U0, at, first, watch, counted, rs)
        t, at = lane.t, at.astype(jnp.int32)
    elif (STACKED_QUIET and pair and chain.fixed_dt is not None and U0.dtype == lane.state[0].dtype == jnp.float64
          and block % 2 == 0 and QUIET_UNROLL == 1 and jax.default_backend() == "cpu"):
        # the float64 DI: XLA:CPU gave the two-array loop 7 kernels a step (one per array the step writes, each
        # computing the whole step, two copies of the carry, the counter, its copy, the test).  With (X, V) and
        # (U, at) stacked as one (2, lanes) array a step is one kernel (each row still computes the step) and the
        # carry is not copied; two steps an iteration halve the counter's kernels, and the barrier between them
        # keeps XLA from fusing them into other roundings (D moved in its last digits without it).  The same
        # numbers to the bit; whole float64 runs x1.04 (idle) to x1.07 (loaded) (stop 91: PERFORMANCE.md).  float32 ran
        # slower so (x0.92)
        def step(i, c):
            state, Ua, _ = body(i, (c[0], c[1], None))
            return jnp.stack([state, Ua])

        c = jax.lax.fori_loop(0, block // 2, lambda j, c: step(2 * j + 1, jax.lax.optimization_barrier(step(2 * j, c))),
                              jnp.stack([pack(lane.state), jax.lax.complex(U0, at)]))
        state, U, at, t = unpack(c[0]), jnp.real(c[1]), jnp.imag(c[1]).astype(jnp.int32), lane.t
    else:
        state, Ua, t = jax.lax.fori_loop(0, block, body, (pack(lane.state), jax.lax.complex(U0, at), lane.t),
                                         unroll=QUIET_UNROLL)
        state, U, at = unpack(state), jnp.real(Ua), jnp.imag(Ua).astype(jnp.int32)
    U = lane.U + U.astype(lane.U.dtype) if part else U
    taken = jnp.where(at == block, block, jnp.maximum(at, 0))
    lane = eqx.tree_at(lambda l: (l.state, l.U, l.t, l.n, l.steps, l.work), lane,
                       (state, U, t, lane.n + taken, lane.steps + jnp.where(counted, taken, 0), lane.work + taken))
    return lane, at


def _block(chain, budget, max_steps, finish, block, events, lane: _Lane, keys, b) -> _Lane:
    """``block`` steps of a batch of lanes, the block's random numbers drawn at once per lane
    (lane i's block index is ``b[i]``).  Events (a regeneration or a coin to flip, a budget
    stop, the work bound: :func:`_has_event`) are rare, a few per excursion of 1e3-1e5 steps,
    and only they need the full bookkeeping (:func:`_book`).  Two layouts (``events``; the
    default is the chain's ``cpu_events`` on a CPU; on an NVIDIA GPU ``"fused"`` for the DI, else
    ``"wait"``: :func:`_events_layout`):

    * ``"wait"``: a lane runs quiet steps until its first step with an event and then waits
      (:func:`_quiet_steps`); its pending step runs after the loop with the full bookkeeping,
      for all lanes at once, and the DI flips its coin there (one coin key per lane and
      block).  The block's numbers after a pending step are never used, so the chain's law is
      that of the step-by-step loop; the rest of the block idles (about ``block/2`` steps per
      event, counted in the slot steps).  A step reads and writes only the chain's state, U, t
      and a step index, not the lane's sums, and has no branch (a GPU would read a branch's
      predicate back every step).  The DI's layout on a CPU too.
    * ``"fused"``: ``"wait"`` with the quiet loop as one Pallas kernel, a lane's steps in
      registers (:mod:`dryfric_jax.fused`; the DI only; the default on an NVIDIA GPU): the same
      arithmetic, bit for bit on a CPU (where Pallas interprets it) and on an H100 (five layouts,
      both dtypes).
    * ``"branch"``: a step runs the bookkeeping only if some lane of the batch has an event,
      through a real branch (``lax.cond`` outside the ``vmap``), otherwise the cheap
      :func:`_quiet` update.  For a chain without a splitting coin the quiet update is computed
      *before* the branch, where XLA fuses it into the event's kernels, and the branch only
      chooses (PDMP: 8.9 -> 6.6 us per step); with one, the coins are flipped only at steps
      where some lane is a candidate (key ``fold_in(coin_key, i)``), then the bookkeeping runs
      only if a coin said heads or another event is due.  The PDMP's layout on a CPU: with
      ``"wait"`` XLA:CPU recomputes its event (log, expm1, log1p) for each array a step writes.

    Measured on 2 CPU devices, Fig. 3 point, paused rounds, wait / branch: DI 0.97 (float64)
    and 1.02 (float32) at 512 lanes, 1.32 and 1.63 at 4096 lanes (there some lane has an event
    at most steps, so "branch" runs the full bookkeeping at most steps); PDMP 0.85 at 512 lanes,
    1.01 at 4096.  The two layouts use the block's numbers differently: same law, different
    sample paths.
    """
    bk = block_keys(keys, b)  # hashed once per block, for the draws and the coins
    rs = chain.draw_lanes(bk, block)
    ck = None if chain.coin is None else jax.vmap(chain.coin_key)(bk)
    adv_fn = jax.vmap(partial(_advance, chain))
    book_fn = jax.vmap(partial(_book, chain, budget, max_steps, finish))

    if events in ("wait", "fused"):
        lane, at = _quiet_steps(chain, budget, max_steps, finish, block, lane, rs, events == "fused")
        pending = (at >= 0) & (at < block)
        r = jax.tree_util.tree_map(lambda a: jnp.take_along_axis(a, jnp.clip(at, 0, block - 1)[None], 0)[0], rs)
        adv = _flip_coins(chain, lane, adv_fn(lane, r), r, ck)
        return jax.tree_util.tree_map(lambda new, old: jnp.where(pending, new, old), book_fn(lane, adv), lane)

    def any_event(ln, adv):
        return jnp.any(jax.vmap(partial(_has_event, budget, max_steps, finish))(ln, adv))

    def body(i, ln):
        r = numbers_at(rs, i)
        adv = adv_fn(ln, r)
        if chain.coin is None:
            q = _quiet(ln, adv)
            return jax.lax.cond(any_event(ln, adv), lambda: book_fn(ln, adv), lambda: q)

        def flip(ln, adv):  # some lane has a candidate (or another event): flip, then book if needed
            adv = _flip_coins(chain, ln, adv, r, rng.fold_in(ck, i))
            return jax.lax.cond(any_event(ln, adv), book_fn, _quiet, ln, adv)

        return jax.lax.cond(any_event(ln, adv), flip, _quiet, ln, adv)

    return jax.lax.fori_loop(0, block, body, lane, unroll=UNROLL)


def init_lanes(chain, n_lanes: int, sharding=None) -> _Lane:
    """Fresh lanes: at the chain's start state, in PLUS if that state is a regeneration point
    (PDMP: s_+), else seeking the first regeneration (DI).  Built on the host and placed on the
    device (or over ``sharding``) in one transfer: 35 small arrays made one by one on a device and
    then sharded took 6-9 ms per run (2 CPU devices), now ~2 ms."""
    z = lambda d: np.zeros((n_lanes,), d)
    lane = _Lane(
        state=jax.tree_util.tree_map(np.asarray, chain.init_state(n_lanes)), U=z(np.float64), n=z(np.int64),
        t=z(np.float64), t_half=z(np.float64),
        phase=np.full((n_lanes,), PLUS if chain.start_regenerated else SEEK, np.int32), done=z(bool),
        stats=tuple(z(np.float64) for _ in STAT_NAMES), n_trunc=z(np.int64), steps=z(np.int64),
        work=z(np.int64),
    )
    return jax.device_put(lane, sharding)


def _round_impl(chain, lane: _Lane, keys, b0, budget, max_steps, finish, min_active, fresh, cap, *, block: int,
                events: str):
    """Blocks of a round.  A paused round (``finish`` False) runs ``ceil(budget / block)`` blocks.
    A final round runs until every lane is done, or until at most ``min_active`` lanes (of this
    device) are not (the final round's compaction,
    :meth:`~dryfric_jax.rounds.Lanes._compact_tail`).  Lane i runs blocks ``b0[i], b0[i] + 1, ...``
    of the round; a ``fresh`` round resets the flags and round work.
    At most ``cap`` blocks run per call: a round is a sequence of calls, each continuing
    the last (``fresh`` False, ``b0`` advanced), with the same result as one call
    (:meth:`~dryfric_jax.rounds.Lanes._call`).  No lane of a paused round is done before its end, so a
    paused round's flags start cleared in every call (the last call raised them)."""
    # a final round: every lane stops within budget + max_steps + 1 steps of its round, and takes
    # a whole block of them per block ("branch") or at least one ("wait"): this bound never
    # binds.  The lane with the fewest blocks behind it sets it (a compacted batch mixes lanes of
    # devices that ran different block counts; the largest count would cut the others short).
    # A paused round runs every lane for the same ceil(budget / block) blocks: a lane that waited
    # at events ("wait") has taken fewer steps, but no lane idles at the end of the round
    # waiting for the lane that waited most (7% of the slots at the Fig. 3 point, K = 128)
    per_block = block if events == "branch" else 1
    max_blocks = jnp.where(finish, (budget + max_steps) // per_block + 2, -(-budget // block)) - jnp.min(b0)
    lane = eqx.tree_at(lambda l: (l.done, l.work), lane,
                       (lane.done & ~fresh & finish, jnp.where(fresh, 0, lane.work)))

    def cond(c):
        b, ln = c
        return (b < max_blocks) & (b < cap) & (jnp.sum(~ln.done) > min_active)

    def body(c):
        b, ln = c
        return b + 1, _block(chain, budget, max_steps, finish, block, events, ln, keys, b0 + b)

    nb, lane = jax.lax.while_loop(cond, body, (jnp.asarray(0, jnp.int64), lane))
    # a paused round is done (for this round) when its blocks are; blocks run, one entry per device
    return eqx.tree_at(lambda l: l.done, lane, lane.done | ~finish), jnp.full((1,), nb)


_run_round = jax.jit(_round_impl, static_argnames=("block", "events"))


@lru_cache(maxsize=None)
def _sharded_round(devices: tuple, block: int, events: str):
    """The round over all ``devices``: lanes split evenly, each device runs its own while_loop
    (no cross-device sync per iteration); lane states stay on their device between rounds."""
    mesh = Mesh(np.array(devices), ("lanes",))
    rep, lanes = PartitionSpec(), PartitionSpec("lanes")
    f = jax.shard_map(partial(_round_impl, block=block, events=events), mesh=mesh,
                      in_specs=(rep, lanes, lanes, lanes, rep, rep, rep, rep, rep, rep), out_specs=(lanes, lanes),
                      check_vma=False)
    return jax.jit(f), NamedSharding(mesh, lanes)


EVENTS = (None, "branch", "wait", "fused")
DEFAULT_EVENTS = None  # None: by chain and platform (_events_layout); the tests set "wait" to run it on a CPU


def _is_cuda(device) -> bool:
    """An NVIDIA GPU (``str(device)`` is ``"cuda:0"`` there): where the ``"fused"`` kernel's
    Triton lowering was compiled and measured."""
    return device.platform == "gpu" and str(device).lower().startswith("cuda")


def _events_layout(devices, chain, events: str | None) -> str:
    """How a block handles events (:func:`_block`).  The default: on a CPU the chain's
    ``cpu_events`` (the DI ``"wait"``, the PDMP ``"branch"``, measured: README); on an NVIDIA GPU
    ``"fused"`` for the DI (:mod:`dryfric_jax.fused`: the same numbers as ``"wait"``, bit for bit,
    and 1.6-3.0x faster in float32 on an H100, PERFORMANCE.md "On an H100"), ``"wait"`` for the PDMP and on
    other accelerators.  ``DEFAULT_EVENTS`` (or ``events``) overrides it; only the DI has
    ``"fused"``."""
    events = DEFAULT_EVENTS if events is None else events
    if events not in EVENTS:
        raise ValueError(f"events must be one of 'branch', 'wait', 'fused' or None (got {events!r})")
    if events == "fused" and not getattr(chain, "fused_quiet", False):
        raise ValueError(f"events 'fused' is only for the DI (got a {type(chain).__name__})")
    if events is None:
        if devices[0].platform == "cpu":
            return chain.cpu_events
        return "fused" if getattr(chain, "fused_quiet", False) and _is_cuda(devices[0]) else "wait"
    return events


def compiled_round(chain, block: int = BLOCK, events: str | None = None):
    """The jitted round that :class:`~dryfric_jax.rounds.Lanes` runs for ``chain`` (a model or its
    class) on the local devices (its ``_cache_size()`` counts compilations; the tests use it to check that new
    parameters do not recompile)."""
    devices = tuple(jax.local_devices())
    if len(devices) == 1:
        return _run_round
    return _sharded_round(devices, block, _events_layout(devices, chain, events))[0]


CPU_CHUNK_LANES = 4096
GPU_CHUNK_LANES = 1 << 18


def default_chunk_lanes(backend: str | None = None) -> int:
    """The most lanes :func:`lanes_for` gives by default: 4096 on a CPU, 2^18 on a GPU (or any
    accelerator).  A GPU runs one lane per thread and needs ~10^5 of them: on an H200 (jax 0.11.2,
    Fig. 3 point, float32, K = 256, 8 excursions per lane) the DI ran 0.90, 2.7, 3.9, 6.1, 5.5 and
    4.8e9 useful lane-steps/s at 2^14, 2^16, 2^17, 2^18, 2^19 and 2^20 lanes, and 1.7e8 at 2048
    lanes (K = 128, the CPU default at N = 1e5; PERFORMANCE.md, "On a GPU")."""
    backend = backend or jax.default_backend()
    return CPU_CHUNK_LANES if backend == "cpu" else GPU_CHUNK_LANES


def default_block(method: str = "di", lanes: int | None = None, backend: str | None = None) -> int:
    """The default block K: :data:`BLOCK` = 128 on a CPU and for the PDMP, :data:`GPU_DI_BLOCK` =
    256 for the DI on a GPU (or any accelerator); halved while ``lanes * K`` exceeds the layout
    bound 2^28 (:func:`~dryfric_jax.plan.check_layout`).  On an H200 (jax 0.11.2, Fig. 3 point,
    float32, 8 excursions per lane) K = 256 ran 18%, 11% and 5% faster than 128 at 2^14, 2^16 and
    2^17 lanes (PERFORMANCE.md "On a GPU"); the PDMP's K was not measured there."""
    backend = backend or jax.default_backend()
    k = BLOCK if backend == "cpu" or method != "di" else GPU_DI_BLOCK
    while lanes is not None and k > 1 and lanes * k > MAX_LAYOUT:
        k //= 2
    return k


def lanes_for(n_excursions: int, chunk_lanes: int | None = None, per_lane: int = 32, min_lanes: int = 512) -> int:
    """The power of two at or below max(n_excursions / per_lane, min(min_lanes, N)) (N = 300 gives 256), at most
    ``chunk_lanes`` (default :func:`default_chunk_lanes`: few compiled shapes).  More lanes fill
    the vector units (the GPU's threads), fewer excursions per lane leave more lanes idle in the
    final round; 32 and 512 measured best for the DI and the PDMP at N = 1e4-2e4 on 2 CPU cores
    (+10-25% over 64 and 256; PERFORMANCE.md).  32 excursions per lane also keep the per-excursion work
    bound ``max_work / lanes`` at >= 32 predicted mean excursions for N >= 16384
    (:mod:`dryfric_jax.plan`)."""
    chunk_lanes = chunk_lanes or default_chunk_lanes()
    want = max(1, n_excursions // per_lane, min(min_lanes, n_excursions))
    return int(min(chunk_lanes, 2 ** max(0, int(np.floor(np.log2(want))))))
