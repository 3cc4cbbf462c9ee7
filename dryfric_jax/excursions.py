r"""Long excursions of the discrete DI as vmapped lanes inside one ``lax.while_loop``.

A lane runs one chain and cuts it at regenerations (:mod:`dryfric_jax.regeneration`):

* phase SEEK: run until the first regeneration on :math:`C_+` (stuck, released upwards); the
  heads transition is distributed as :math:`\nu_+` and opens the first excursion.  Nothing
  simulated before it is counted;
* phase PLUS (+HLE): until a regeneration on :math:`C_-` (stuck, released downwards);
* phase MINUS (-HLE): until a regeneration on :math:`C_+`, which closes the long excursion; its
  heads transition opens the next one (the lane refills itself).

So a lane's excursions are consecutive i.i.d. regeneration cycles of one chain.  Each lane
carries its phase, its termination flag and its accumulators: U in float64, the step count n as
an integer (t = n h exactly), and float64 sums of the products the delta method needs.

**Unbiased under a budget.**  A round gives every lane a budget of steps.  When it is spent the
lane *finishes its in-flight excursion*, starts no new one and raises its termination flag.  The
number of excursions a lane starts before its budget runs out is a stopping time for its cycle
sequence, so by Wald's identity :math:`E[\sum U] = E[N] E[U]` and the ratio estimators stay
consistent (regenerative simulation, Glynn & Heidelberger 1990).  Dropping the in-flight
excursion instead keeps only the cycles that *ended* before the budget, which is not a stopping
time and biases D low (``finish_in_flight=False``, kept to demonstrate it in the tests).

Steps run in blocks of ``block`` with the block's normals drawn at once (``split`` per lane,
``fold_in`` per block).  Work is bounded: an excursion that reaches ``max_steps`` is closed,
counted as truncated and reported, and the lane seeks again; no lane runs more than
``budget + max_steps`` steps.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from functools import lru_cache, partial

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh, NamedSharding, PartitionSpec

from .di import DIModel


# per-lane sufficient statistics of the closed excursions, in float64: every product of two
# entries of (U, U^2, t, U t, t^2), which the delta method for D and M0 needs
STAT_NAMES = ("n", "U", "U2", "U3", "U4", "t", "t2", "t3", "t4", "Ut", "U2t", "U3t", "Ut2", "U2t2", "Ut3",
              "t_half")


class _Lane(eqx.Module):
    X: jnp.ndarray
    V: jnp.ndarray
    U: jnp.ndarray  # float64 displacement of the in-flight excursion
    n: jnp.ndarray  # steps of the in-flight excursion (t = n h), or of the current seek
    n_half: jnp.ndarray  # steps at which the -HLE began
    phase: jnp.ndarray  # SEEK, PLUS or MINUS
    done: jnp.ndarray  # the lane's termination flag
    stats: jnp.ndarray  # (len(STAT_NAMES),) float64 sums over complete excursions
    n_trunc: jnp.ndarray  # excursions closed by the work bound
    steps: jnp.ndarray  # useful steps done by the lane
    work: jnp.ndarray  # all steps done by the lane (seeks included): compared with the budget


def _close(lane: _Lane, h64, complete) -> _Lane:
    """Add the in-flight excursion to the lane's sums where ``complete``."""
    U = lane.U
    t = lane.n.astype(jnp.float64) * h64
    th = lane.n_half.astype(jnp.float64) * h64
    U2, t2 = U * U, t * t
    row = jnp.stack([jnp.ones_like(U), U, U2, U2 * U, U2 * U2, t, t2, t2 * t, t2 * t2, U * t, U2 * t, U2 * U * t,
                     U * t2, U2 * t2, U * t2 * t, th])
    return eqx.tree_at(lambda l: l.stats, lane, lane.stats + jnp.where(complete, row, 0.0))


SEEK, PLUS, MINUS = 0, 1, 2


def _step(model: DIModel, budget, max_steps, finish, lane: _Lane, z1, z2, u) -> _Lane:
    active = ~lane.done
    X, V = lane.X, lane.V
    Xi, Xn = model.ou.sample(X, z1, z2)
    Vn = model.step(V, Xi)

    # retrospective splitting coin: stuck on C_+ and released upwards (SEEK, MINUS), or stuck on
    # C_- and released downwards (PLUS)
    watch_plus = lane.phase != PLUS
    s = jax.tree_util.tree_map(lambda p, m: jnp.where(watch_plus, p, m), model.plus, model.minus)
    released = jnp.where(watch_plus, Vn > 0, Vn < 0)
    eligible = active & (V == 0) & released & s.contains(X)
    heads = eligible & (jnp.log(u) < s.log_coin(X, z1, z2))
    spent = lane.work >= budget
    closes = heads & (lane.phase == MINUS)  # long excursion complete
    opens = heads & (lane.phase != PLUS) & ~spent  # refill: this transition starts an excursion
    halfway = heads & (lane.phase == PLUS)  # the -HLE starts now

    h64 = model.h.astype(jnp.float64)
    lane = _close(lane, h64, closes)
    # budget spent: stop once nothing is in flight (or at once, dropping it, if not ``finish``)
    stop = active & spent & ((lane.phase == SEEK) | closes | ~finish)
    dU = 0.5 * h64 * (V.astype(jnp.float64) + Vn.astype(jnp.float64))
    counting = (lane.phase != SEEK) | opens
    U = jnp.where(opens, 0.0, lane.U) + jnp.where(active & counting, dU, 0.0)
    n = jnp.where(opens, 0, lane.n) + active
    phase = jnp.where(opens, PLUS, jnp.where(halfway, MINUS, jnp.where(closes, SEEK, lane.phase)))
    lane = eqx.tree_at(
        lambda l: (l.X, l.V, l.U, l.n, l.n_half, l.phase, l.steps, l.work, l.done),
        lane,
        (jnp.where(active, Xn, X), jnp.where(active, Vn, V), U, n,
         jnp.where(halfway, lane.n, jnp.where(opens, 0, lane.n_half)), phase,
         lane.steps + (active & counting), lane.work + active, lane.done | stop),
    )
    # work bound: close a runaway excursion (or seek), report it, seek again
    runaway = active & ~stop & (lane.n >= max_steps)
    return eqx.tree_at(lambda l: (l.phase, l.n, l.n_trunc), lane,
                       (jnp.where(runaway, SEEK, lane.phase), jnp.where(runaway, 0, lane.n),
                        lane.n_trunc + (runaway & (lane.phase != SEEK))))


def _lane_block(model, budget, max_steps, finish, block, lane, lane_key, b):
    dt = model.h.dtype
    kb = jax.random.fold_in(lane_key, b)
    k_norm, k_unif = jax.random.split(kb)
    zs = jax.random.normal(k_norm, (block, 2), dt)
    us = jax.random.uniform(k_unif, (block,), dt, minval=jnp.finfo(dt).tiny)

    def body(i, ln):
        return _step(model, budget, max_steps, finish, ln, zs[i, 0], zs[i, 1], us[i])

    return jax.lax.fori_loop(0, block, body, lane)


def _round_impl(model: DIModel, keys, budget, max_steps, finish, *, block: int):
    n_lanes = keys.shape[0]
    dt = model.h.dtype
    z = lambda d: jnp.zeros((n_lanes,), d)
    lane = _Lane(
        X=jnp.full((n_lanes,), model.x_plus, dt), V=z(dt), U=z(jnp.float64), n=z(jnp.int64),
        n_half=z(jnp.int64), phase=jnp.full((n_lanes,), SEEK, jnp.int32), done=z(bool),
        stats=jnp.zeros((n_lanes, len(STAT_NAMES)), jnp.float64), n_trunc=z(jnp.int64),
        steps=z(jnp.int64), work=z(jnp.int64),
    )
    # every lane stops within budget + max_steps steps: this bound never binds
    max_blocks = (budget + max_steps) // block + 2
    vblock = jax.vmap(_lane_block, in_axes=(None, None, None, None, None, 0, 0, None))

    def cond(c):
        b, ln = c
        return (b < max_blocks) & jnp.any(~ln.done)

    def body(c):
        b, ln = c
        return b + 1, vblock(model, budget, max_steps, finish, block, ln, keys, b)

    nb, lane = jax.lax.while_loop(cond, body, (jnp.asarray(0, jnp.int64), lane))
    out = (lane.stats, lane.n_trunc, lane.steps, lane.done)
    return out, jnp.full((1,), nb)  # blocks run, one entry per device


_run_round = jax.jit(_round_impl, static_argnames=("block",))


@lru_cache(maxsize=None)
def _sharded_round(devices: tuple, block: int):
    """The round over all ``devices``: lanes split evenly, each device runs its own while_loop
    (no cross-device sync per iteration); per-lane sums are gathered at the end."""
    mesh = Mesh(np.array(devices), ("lanes",))
    rep, lanes = PartitionSpec(), PartitionSpec("lanes")
    f = jax.shard_map(partial(_round_impl, block=block), mesh=mesh, in_specs=(rep, lanes, rep, rep, rep),
                      out_specs=(lanes, lanes), check_vma=False)
    return jax.jit(f), NamedSharding(mesh, lanes)


@dataclass
class ExcursionStats:
    """Per-lane sums over complete long excursions, nondimensional (U in u0, t in tau0).

    ``stats[:, k]`` is the lane sum of ``STAT_NAMES[k]``; lanes are independent, so any
    grouping of lanes is an independent replicate.
    """

    stats: np.ndarray  # (lanes, len(STAT_NAMES))
    n_truncated: int  # excursions closed by the work bound (not in stats)
    useful_steps: int  # lane-steps that advanced an excursion (seeks excluded)
    slot_steps: int  # lane-steps paid for, idle lanes included
    n_unfinished: int = 0  # lanes the block bound stopped (never expected; reported, not hidden)

    @property
    def n_excursions(self) -> int:
        return int(round(self.stats[:, 0].sum()))

    def total(self) -> dict:
        return dict(zip(STAT_NAMES, self.stats.sum(0)))

    def __add__(self, other: "ExcursionStats") -> "ExcursionStats":
        return ExcursionStats(np.concatenate([self.stats, other.stats]), self.n_truncated + other.n_truncated,
                              self.useful_steps + other.useful_steps, self.slot_steps + other.slot_steps,
                              self.n_unfinished + other.n_unfinished)


def run_round(model: DIModel, key, lanes: int, budget: int, *, block: int = 32, max_steps: int = 10**8,
              finish_in_flight: bool = True) -> ExcursionStats:
    """One round: ``lanes`` lanes, each refilling until ``budget`` steps, then finishing its
    in-flight excursion.  Lane keys: ``split(key, lanes)``.

    Lanes are sharded over all local devices (CPU devices from
    ``--xla_force_host_platform_device_count``, or GPUs); ``lanes`` is rounded up to a multiple
    of the device count.
    """
    devices = tuple(jax.local_devices())
    lanes = -(-lanes // len(devices)) * len(devices)
    keys = jax.random.split(key, lanes)
    args = (jnp.asarray(budget, jnp.int64), jnp.asarray(max_steps, jnp.int64), jnp.asarray(finish_in_flight))
    if len(devices) == 1:
        out, nb = _run_round(model, keys, *args, block=block)
    else:
        f, sharding = _sharded_round(devices, block)
        out, nb = f(model, jax.device_put(keys, sharding), *args)
    stats, n_trunc, steps, done = (np.asarray(a) for a in jax.device_get(out))
    nb = np.asarray(jax.device_get(nb))
    return ExcursionStats(stats, int(n_trunc.sum()), int(steps.sum()), int(nb.sum()) * block * lanes // len(nb),
                          int((~done).sum()))


def lanes_for(n_excursions: int, chunk_lanes: int = 4096, per_lane: int = 64, min_lanes: int = 256) -> int:
    """A power of two near n_excursions / per_lane, at least min(min_lanes, N) (vector width; 256
    measured best on 2 CPU cores), at most ``chunk_lanes`` (few compiled shapes)."""
    want = max(1, n_excursions // per_lane, min(min_lanes, n_excursions))
    return int(min(chunk_lanes, 2 ** max(0, int(np.floor(np.log2(want))))))


def simulate_long_excursions(model: DIModel, key, n_excursions: int, *, lanes: int | None = None,
                             chunk_lanes: int = 4096, block: int = 32, max_steps: int = 10**8,
                             pilot_budget: int = 1024, more=None, max_time: float | None = None,
                             round_lane_steps: int = 2**26, progress=None):
    """Long excursions of the DI chain ``model`` in rounds, until enough are closed.

    Round r uses ``fold_in(key, r)``.  The first round has a small pilot budget; later rounds
    size the per-lane budget from the measured steps per excursion, capped at
    ``round_lane_steps`` lane-steps per round (a few seconds on a CPU) so that progress,
    ``max_time`` and Ctrl-C act between rounds.  The cap is a step count, not a time, so the
    same seed and settings give bit-identical results (except when ``max_time`` stops the run).

    Args:
        model: from :func:`dryfric_jax.di.make_di_model`.
        key: a ``jax.random`` key.
        n_excursions: closed (complete or truncated) excursions to reach at least.
        lanes: lanes per round (default :func:`lanes_for`; a power of two up to ``chunk_lanes``).
        block: steps per while-iteration, their normals drawn at once.
        max_steps: work bound per excursion; excursions reaching it are counted as truncated.
        more: optional ``more(total) -> int``: further excursions wanted once ``n_excursions``
            are reached (0 to stop); used for precision targets.
        max_time: stop after the round that passes this many seconds.
        progress: optional ``progress(total)`` called after every round.

    Returns:
        ``(stats, stopped_by)`` with ``stopped_by`` in ``{"n_excursions", "target", "max_time",
        "interrupted", "work_bound"}``.  Rounds already completed are never lost: Ctrl-C ends
        the loop with ``"interrupted"``.
    """
    if n_excursions < 1:
        raise ValueError(f"n_excursions must be >= 1 (got {n_excursions})")
    lanes = lanes or lanes_for(n_excursions, chunk_lanes)
    closed = lambda st: st.n_excursions + st.n_truncated  # truncated count too: work stays bounded
    total, budget, r, want, stopped = None, pilot_budget, 0, n_excursions, "n_excursions"
    t_start = time.perf_counter()
    try:
        while True:
            res = run_round(model, jax.random.fold_in(key, r), lanes, budget, block=block, max_steps=max_steps)
            total = res if total is None else total + res
            r += 1
            if progress is not None:
                progress(total)
            done = closed(total)
            if done >= want and more is not None:
                extra = int(more(total))
                want = done + extra if extra > 0 else want
                stopped = "target" if extra <= 0 else stopped
            if done >= want:
                break
            if max_time is not None and time.perf_counter() - t_start >= max_time:
                stopped = "max_time"
                break
            if done == 0:
                budget *= 4  # nothing closed yet: longer pilot
                if budget > 64 * max_steps:
                    stopped = "work_bound"
                    break
                continue
            per_exc = total.useful_steps / done
            budget = int(np.ceil((want - done) * per_exc / lanes))
            budget = max(4 * block, min(budget, round_lane_steps // lanes))
    except KeyboardInterrupt:
        stopped = "interrupted"
        if total is None:
            raise
    return total, stopped


def steps_per_excursion(model: DIModel, key, *, lanes: int = 256, budget: int = 4096, block: int = 32,
                        max_steps: int = 10**8) -> float:
    """Pilot estimate of the mean number of steps of one long excursion."""
    while True:
        res = run_round(model, key, lanes, budget, block=block, max_steps=max_steps)
        if res.n_excursions >= lanes or budget > 64 * max_steps:
            return res.useful_steps / max(res.n_excursions, 1)
        budget *= 4


def simulate_replicates(model: DIModel, key, n_replicates: int, n_per_replicate: int, *,
                        lanes_per_replicate: int = 16, block: int = 32, max_steps: int = 10**8):
    """Independent replicates of about ``n_per_replicate`` excursions each (for calibration).

    One pilot round (discarded) measures the steps per excursion; then one round runs
    ``n_replicates * lanes_per_replicate`` lanes with a budget of ``1.05 n_per_replicate`` mean
    excursions per replicate.  Replicate k is lanes ``[k L, (k+1) L)``.
    """
    per = steps_per_excursion(model, jax.random.fold_in(key, 0), block=block, max_steps=max_steps)
    budget = int(np.ceil(1.05 * n_per_replicate * per / lanes_per_replicate))
    return run_round(model, jax.random.fold_in(key, 1), n_replicates * lanes_per_replicate, budget, block=block,
                     max_steps=max_steps)
