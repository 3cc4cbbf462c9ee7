r"""Long excursions of the discrete DI as vmapped lanes inside one ``lax.while_loop``.

A lane runs one chain and cuts it at regenerations (:mod:`dryfric_jax.regeneration`):

* phase SEEK: run until the first regeneration on :math:`C_+` (stuck, released upwards); the
  heads transition is distributed as :math:`\nu_+` and opens the first excursion.  Nothing
  simulated before it is counted;
* phase PLUS (+HLE): until a regeneration on :math:`C_-` (stuck, released downwards);
* phase MINUS (-HLE): until a regeneration on :math:`C_+`, which closes the long excursion; its
  heads transition opens the next one.

So a lane's excursions are consecutive i.i.d. regeneration cycles of one chain.  Each lane
carries its phase, its termination flag and its accumulators: U in float64, the step count n as
an integer (t = n h exactly), and float64 sums of the products the delta method needs.  Steps
run in blocks of ``block`` with the block's normals drawn at once (``split`` per lane,
``fold_in`` per block).  Work is bounded: an excursion (or a seek) that reaches ``max_steps`` is
closed, counted as truncated and reported, and the lane seeks again.  Lanes run in chunks of
``chunk_lanes`` so that any number of excursions fits in memory.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import partial

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

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
    j: jnp.ndarray  # excursions closed so far (complete or truncated)
    target: jnp.ndarray  # excursions this lane must close
    done: jnp.ndarray  # the lane's termination flag
    stats: jnp.ndarray  # (len(STAT_NAMES),) float64 sums over complete excursions
    n_trunc: jnp.ndarray  # excursions closed by the work bound
    steps: jnp.ndarray  # useful steps done by the lane


def _count_closed(lane: _Lane, closed) -> _Lane:
    jn = lane.j + closed
    return eqx.tree_at(lambda l: (l.j, l.done), lane, (jn, lane.done | (jn >= lane.target)))


def _close(lane: _Lane, h64, complete) -> _Lane:
    """Add the in-flight excursion to the lane's sums where ``complete``."""
    U = lane.U
    t = lane.n.astype(jnp.float64) * h64
    th = lane.n_half.astype(jnp.float64) * h64
    U2, t2 = U * U, t * t
    row = jnp.stack([jnp.ones_like(U), U, U2, U2 * U, U2 * U2, t, t2, t2 * t, t2 * t2, U * t, U2 * t, U2 * U * t,
                     U * t2, U2 * t2, U * t2 * t, th])
    lane = eqx.tree_at(lambda l: l.stats, lane, lane.stats + jnp.where(complete, row, 0.0))
    return _count_closed(lane, complete)


SEEK, PLUS, MINUS = 0, 1, 2


def _step(model: DIModel, max_steps, lane: _Lane, z1, z2, u) -> _Lane:
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
    closes = heads & (lane.phase == MINUS)  # long excursion complete
    opens = heads & (lane.phase != PLUS)  # this transition starts an excursion
    halfway = heads & (lane.phase == PLUS)  # the -HLE starts now

    h64 = model.h.astype(jnp.float64)
    lane = _close(lane, h64, closes)
    dU = 0.5 * h64 * (V.astype(jnp.float64) + Vn.astype(jnp.float64))
    counting = (lane.phase != SEEK) | opens
    U = jnp.where(opens, 0.0, lane.U) + jnp.where(active & counting, dU, 0.0)
    n = jnp.where(opens, 0, lane.n) + active
    phase = jnp.where(opens, PLUS, jnp.where(halfway, MINUS, lane.phase))
    lane = eqx.tree_at(
        lambda l: (l.X, l.V, l.U, l.n, l.n_half, l.phase, l.steps),
        lane,
        (jnp.where(active, Xn, X), jnp.where(active, Vn, V), U, n,
         jnp.where(halfway, lane.n, jnp.where(opens, 0, lane.n_half)), phase,
         lane.steps + (active & counting)),
    )
    # work bound: close a runaway excursion (or seek), report it, seek again
    runaway = active & (lane.n >= max_steps) & ~lane.done
    lane = _count_closed(lane, runaway)
    return eqx.tree_at(lambda l: (l.phase, l.n, l.n_trunc), lane,
                       (jnp.where(runaway, SEEK, lane.phase), jnp.where(runaway, 0, lane.n), lane.n_trunc + runaway))


def _lane_block(model, max_steps, block, lane, lane_key, b):
    dt = model.h.dtype
    kb = jax.random.fold_in(lane_key, b)
    k_norm, k_unif = jax.random.split(kb)
    zs = jax.random.normal(k_norm, (block, 2), dt)
    us = jax.random.uniform(k_unif, (block,), dt, minval=jnp.finfo(dt).tiny)

    def body(i, ln):
        return _step(model, max_steps, ln, zs[i, 0], zs[i, 1], us[i])

    return jax.lax.fori_loop(0, block, body, lane)


@partial(jax.jit, static_argnames=("block",))
def _run_chunk(model: DIModel, keys, targets, max_steps, max_blocks, *, block: int):
    n_lanes = keys.shape[0]
    dt = model.h.dtype
    z = lambda d: jnp.zeros((n_lanes,), d)
    lane = _Lane(
        X=jnp.full((n_lanes,), model.x_plus, dt), V=z(dt), U=z(jnp.float64), n=z(jnp.int64),
        n_half=z(jnp.int64), phase=jnp.full((n_lanes,), SEEK, jnp.int32), j=z(jnp.int32),
        target=targets.astype(jnp.int32), done=targets <= 0,
        stats=jnp.zeros((n_lanes, len(STAT_NAMES)), jnp.float64), n_trunc=z(jnp.int64),
        steps=z(jnp.int64),
    )
    vblock = jax.vmap(_lane_block, in_axes=(None, None, None, 0, 0, None))

    def cond(c):
        b, ln = c
        return (b < max_blocks) & jnp.any(~ln.done)

    def body(c):
        b, ln = c
        return b + 1, vblock(model, max_steps, block, ln, keys, b)

    nb, lane = jax.lax.while_loop(cond, body, (jnp.asarray(0, jnp.int64), lane))
    return lane, nb


@dataclass
class ExcursionStats:
    """Per-lane sums over complete long excursions, nondimensional (U in u0, t in tau0).

    ``stats[:, k]`` is the lane sum of ``STAT_NAMES[k]``; lanes hold i.i.d. excursions, so any
    grouping of lanes is an independent replicate.
    """

    stats: np.ndarray  # (lanes, len(STAT_NAMES))
    n_truncated: int  # excursions closed by the work bound (not in stats)
    useful_steps: int  # lane-steps that advanced an excursion (seeks excluded)
    slot_steps: int  # lane-steps paid for, idle lanes included
    h: float

    @property
    def n_excursions(self) -> int:
        return int(self.stats[:, 0].sum())

    def total(self) -> dict:
        return dict(zip(STAT_NAMES, self.stats.sum(0)))


def simulate_long_excursions(model: DIModel, key, n_excursions: int, *, per_lane: int = 32,
                             chunk_lanes: int = 4096, block: int = 16, max_steps: int = 10**8,
                             progress=None) -> ExcursionStats:
    """Simulate ``n_excursions`` i.i.d. long excursions of the DI chain ``model``.

    Args:
        model: from :func:`dryfric_jax.di.make_di_model`.
        key: a ``jax.random`` key; chunk c uses ``fold_in(key, c)`` and ``split`` per lane.
        n_excursions: excursions to close (complete + truncated).
        per_lane: excursions run back to back per lane (evens out the heavy-tailed lengths).
        chunk_lanes: lanes per compiled call (memory bound); every chunk has this many lanes,
            so the second call does not recompile.
        block: steps per while-iteration, their normals drawn at once.
        max_steps: work bound per excursion; excursions reaching it are counted as truncated.
    """
    if n_excursions < 1:
        raise ValueError(f"n_excursions must be >= 1 (got {n_excursions})")
    n_lanes_total = -(-n_excursions // per_lane)
    lanes = min(chunk_lanes, n_lanes_total)
    n_chunks = -(-n_lanes_total // lanes)
    max_blocks = 2 * per_lane * (-(-max_steps // block) + 1) + 1  # seeks are bounded too
    out, n_tr, useful, slots = [], 0, 0, 0
    remaining = n_excursions
    for c in range(n_chunks):
        keys = jax.random.split(jax.random.fold_in(key, c), lanes)
        want = min(remaining, lanes * per_lane)
        targets = np.minimum(per_lane, np.maximum(0, want - per_lane * np.arange(lanes)))
        lane, nb = _run_chunk(model, keys, jnp.asarray(targets), jnp.asarray(max_steps, jnp.int64),
                              jnp.asarray(max_blocks, jnp.int64), block=block)
        lane = jax.device_get(lane)
        live = targets > 0
        out.append(np.asarray(lane.stats)[live])
        # a lane stopped by the block bound (cannot happen: max_blocks covers every lane) is
        # reported as truncated, never dropped silently
        n_tr += int(np.asarray(lane.n_trunc).sum()) + int((targets - np.asarray(lane.j)).clip(0).sum())
        useful += int(np.asarray(lane.steps).sum())
        slots += int(nb) * block * lanes
        remaining -= want
        if progress is not None:
            progress(n_excursions - remaining, n_excursions)
    return ExcursionStats(np.concatenate(out), n_tr, useful, slots, float(model.h))
