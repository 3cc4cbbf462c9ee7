"""The accelerator check, as one prepared run (a lent GPU has minutes, not hours).

Prints one JSON line per measurement as soon as it is made (a run stopped at its time limit
keeps what it printed), at the paper's Fig. 3 point:

* ``layout``: DI useful lane-steps/s for each (dtype, lanes, block K, unroll, event layout), N = max(--n, 8 lanes)
  excursions after a compile run, with D +- CI (the layouts change the streams, not the law:
  their D must agree within their CIs);
* ``tune``: per dtype, :func:`dryfric_jax.bench.tune_layout`'s summary: the best layout, the RNG
  bound and the chain floor there (the engine's generator alone, and the chain without the
  excursion bookkeeping), and how far the layouts' D agree;
* ``numba``: the compiled CPU loop of the same DI chain (numpy ``Generator`` normals,
  :mod:`dryfric_jax.bench_numba`) with 1, 2 and all host threads, 16000 excursions per timing;
* ``bench``: the side-by-side ``dryfric bench`` (the plan's own lanes), when --bench-n > 0;
* ``kernel`` (``--kernel-tiles``, first): the fused quiet loop alone (:func:`dryfric_jax.fused.quiet_steps`
  on fixed inputs, the first --lanes and --block), slot-steps/s for each Triton tile (lanes per program,
  ``fused.TILE``) and ``--kernel-warps`` (``fused.NUM_WARPS``), beside the draw of the same block's normals;
  neither changes a lane's numbers or arithmetic, so the layouts then run at the default tile and again
  at the fastest one, and ``tile_check`` says whether D came out the same bit for bit (on a CPU, where
  XLA compiles each tile shape apart, a tile can move a lane's U by an ulp: tests/test_fused_cost_mutants);
* ``breakdown`` (``--breakdown``, first): where one engine block goes, at the first --lanes and --block:
  the block's draw (materialised, as the kernel reads it), its quiet loop (the fused kernel, or the wait
  loop), and the whole block (:func:`dryfric_jax.excursions._block`: draw, loop, the pending step's
  bookkeeping); each timed alone, compile excluded; then paused rounds of 1, 4 and 16 blocks, whose fit
  gives a block's time in the engine and what a round costs besides (its call, the host's reading of the
  lanes' sums; on 2 CPU cores at 2^15 lanes and K = 1024 a round cost about one block more).  On the
  H200 (2026-11-30) the kernel and a direct draw took ~1 and ~3 ms of a ~27 ms block (2^18 lanes,
  K = 1024, float32; the run's wall time over its slot-steps): this splits the rest;
* ``rounds`` (``--round-steps``, ``--final-call-steps``, after the breakdown): the DI at the first --lanes
  and --block for each cap of a paused round's lane-steps (``rounds.ROUND_LANE_STEPS``; it changes
  the random streams, not the law) and of a final round's call (``FINAL_CALL_LANE_STEPS``; it changes
  no number), the CPU-sized defaults first: whether GPU-sized rounds and calls pay.

    python scripts/device_check.py --lanes 65536,262144 --block 256,1024 --unroll 1,4 --n 200000

Stops starting new layouts once --budget-s seconds have passed.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from functools import partial


def emit(**kw):
    print(json.dumps(kw), flush=True)


def ints(text):
    """A comma-separated list of positive integers (None for ""); one line and exit 2 otherwise."""
    try:
        out = [int(x) for x in text.split(",")] if text else None
    except ValueError:
        out = [0]
    if out is not None and min(out) < 1:
        raise argparse.ArgumentTypeError(f"must be comma-separated positive integers (got {text!r})")
    return out


def amount(text):
    """A finite number >= 0 (1e5 allowed); one line and exit 2 otherwise (nan and inf were tracebacks)."""
    try:
        v = float(text)
    except ValueError:
        v = math.nan
    if not (math.isfinite(v) and v >= 0):
        raise argparse.ArgumentTypeError(f"must be a finite number >= 0 (got {text!r})")
    return v


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--lanes", type=ints, default="65536,262144")
    ap.add_argument("--block", type=ints, default="256")
    ap.add_argument("--unroll", type=ints, default="", help="steps per iteration of the wait layout's loop "
                    "(excursions.QUIET_UNROLL; default: the engine's)")
    ap.add_argument("--events", default="", help="event layouts to sweep, e.g. wait,fused (default: the "
                    "device's; 'fused' is the DI's quiet loop as one Pallas kernel, dryfric_jax.fused)")
    ap.add_argument("--dtypes", default="float32,float64")
    ap.add_argument("--n", type=amount, default=2e5, help="excursions per layout (at least 8 per lane)")
    ap.add_argument("--numba-n", type=int, default=16000, help="excursions per numba timing (0: skip)")
    ap.add_argument("--bench-n", type=amount, default=0, help="N of the side-by-side bench (0: skip)")
    ap.add_argument("--bound-n", type=amount, default=2**30, help="lane-steps per RNG-bound timing")
    ap.add_argument("--budget-s", type=amount, default=240)
    ap.add_argument("--kernel-tiles", type=ints, default="", help="Triton tiles of the fused kernel to time "
                    "alone first, e.g. 128,256,512 (default: none)")
    ap.add_argument("--kernel-warps", type=ints, default="4", help="Triton warps per program to time with them")
    ap.add_argument("--breakdown", action="store_true", help="time one engine block's parts first")
    ap.add_argument("--round-steps", type=ints, default="", help="caps of a paused round's lane-steps to time")
    ap.add_argument("--final-call-steps", type=ints, default="", help="caps of a final round's call to time")
    a = ap.parse_args(argv)
    dtypes, events = a.dtypes.split(","), a.events.split(",") if a.events else None
    bad = [d for d in dtypes if d not in ("float32", "float64")]
    bad += [e for e in events or [] if e not in ("wait", "fused", "branch")]
    if bad:
        ap.error(f"--dtypes must be among float32,float64 and --events among wait,fused,branch (got {bad})")
    t0 = time.perf_counter()

    import jax
    jax.config.update("jax_enable_x64", True)
    from dryfric_jax.bench import _numba_rates, run_bench, tune_layout

    emit(kind="device", devices=[str(d) for d in jax.devices()], jax=jax.__version__, cpu_count=os.cpu_count())
    from dryfric_jax import fused

    default_tile = (fused.TILE, fused.NUM_WARPS)
    runs = [(dt, default_tile) for dt in dtypes]
    first_events = events[0] if events else None  # the stages before the layouts run one layout
    if a.breakdown:
        for dt in dtypes:
            block_breakdown(dt, a.lanes[0], a.block[0], first_events)
    if a.round_steps or a.final_call_steps:
        round_sweep(dtypes[0], a.lanes[0], a.block[0], first_events, a.round_steps, a.final_call_steps, int(a.n))
    if a.kernel_tiles:
        best = kernel_sweep(dtypes[0], a.lanes[0], a.block[0], a.kernel_tiles, a.kernel_warps)
        if best != default_tile:
            runs.insert(1, (dtypes[0], best))
    d_at = {}  # (dtype, lanes, block, events) -> D at the default tile, to compare bit for bit
    for dt, (tile_, warps_) in runs:
        fused.TILE, fused.NUM_WARPS = tile_, warps_
        jax.clear_caches()  # the tile and warps are read when a kernel is traced
        left = a.budget_s - (time.perf_counter() - t0)
        if left <= 0:
            emit(kind="skipped", dtype=dt, tile=fused.TILE, warps=fused.NUM_WARPS, reason="budget")
            continue
        tile = dict(tile=fused.TILE, warps=fused.NUM_WARPS)
        try:
            b = tune_layout(a.lanes, a.block, dt, n_excursions=int(a.n), numba_excursions=0,
                            unrolls=a.unroll, events=events, budget_s=left,
                            bound_n=int(a.bound_n), on_layout=lambda row: emit(kind="layout", dtype=dt, **tile, **row))
        except ValueError as e:  # a layout or size the engine refuses (--lanes 5000000): named, exit 2
            ap.error(str(e))
        for row in b["skipped"]:
            emit(kind="skipped", dtype=dt, **{"reason": "budget", **row})  # or past the layout bound
        for row in b["failed"]:
            emit(kind="failed", dtype=dt, **row)
        emit(kind="tune", **tile, **{k: v for k, v in b.items() if k not in ("layouts", "skipped", "failed", "params")})
        for row in b["layouts"]:
            # the unroll is part of the layout: an unroll-4 row was compared with the unroll-1 one as a tile mismatch
            at = (dt, row["lanes"], row["block"], row["events"], row.get("unroll"))
            if at in d_at:
                emit(kind="tile_check", dtype=dt, **tile, lanes=row["lanes"], block=row["block"],
                     events=row["events"], unroll=row.get("unroll"), same_D=row["D"] == d_at[at], D=row["D"],
                     D_default_tile=d_at[at])
            d_at.setdefault(at, row["D"])
    fused.TILE, fused.NUM_WARPS = default_tile
    if a.numba_n > 0:
        try:
            from dryfric_jax.bench_numba import BaselineIncomplete, run_numba
        except Exception as exc:
            emit(kind="numba", error=f"{type(exc).__name__}: {exc}")
        else:
            try:
                rates = _numba_rates(run_numba, fig3_di("float64")[1], a.numba_n, 0,
                                     sorted({1, 2, os.cpu_count() or 1}))
            except BaselineIncomplete as exc:  # said; the layouts above are kept
                emit(kind="numba", error=f"BaselineIncomplete: {exc}")
            else:
                for k, v in rates.items():
                    emit(kind="numba", threads=k, steps_per_s=v)
    if a.bench_n > 0:
        emit(kind="bench", **run_bench(n_excursions=int(a.bench_n), repeat=1))
    emit(kind="done", elapsed_s=time.perf_counter() - t0)
    return 0


def fig3_di(dtype):
    """``(params, chain)``: the paper's Fig. 3 point and its DI chain at the default h, in ``dtype``."""
    import dryfric_jax as dj
    from dryfric_jax.api import default_h
    from dryfric_jax.di import make_di_model
    from dryfric_jax.params import FIG3

    p = dj.Params(**FIG3)
    return p, make_di_model(p, default_h(p), dtype)


def seconds_per_call(f, *args, reps=5):
    """Wall seconds per call of ``f(*args)`` (a jitted function), compile excluded, over ``reps`` calls."""
    import jax

    jax.block_until_ready(f(*args))  # compile
    t = time.perf_counter()
    for _ in range(reps):
        jax.block_until_ready(f(*args))
    return (time.perf_counter() - t) / reps


def kernel_sweep(dtype, lanes, block, tiles, warps, reps=5):
    """Slot-steps/s of the fused kernel alone for each (tile, warps), and of drawing its normals (the
    engine's generator, ``rng.normals``, one key per lane);
    returns the fastest (tile, warps), the default if none built; the kernel's settings are restored
    after.  The inputs are fixed (every lane starts free; a lane that meets a coin candidate idles for
    the rest of the block, as in the engine, at the same cost)."""
    import jax
    import jax.numpy as jnp

    from dryfric_jax import fused, rng

    dt, chain = jnp.dtype(dtype), fig3_di(dtype)[1]
    state = chain.init_state(lanes)
    draw = jax.jit(lambda k: rng.normals(jax.random.split(k, lanes), block, 2, dt))
    rs = jax.block_until_ready(draw(jax.random.key(0)))
    fixed = (jnp.zeros(lanes, dt), jnp.full(lanes, block, dt), jnp.full(lanes, block, dt),
             jnp.ones(lanes, bool), jnp.ones(lanes, bool))

    timed = lambda f, *args: lanes * block / seconds_per_call(f, *args, reps=reps)
    draw_rate = timed(draw, jax.random.key(1))
    rates, default = {}, (fused.TILE, fused.NUM_WARPS)
    try:
        for tile in tiles:
            for w in warps:
                fused.TILE, fused.NUM_WARPS = tile, w
                jax.clear_caches()
                f = jax.jit(lambda s, r: fused.quiet_steps(chain, block, s, *fixed, r))
                try:
                    rates[tile, w] = timed(f, state, rs)
                except Exception as exc:  # a tile the device cannot build: said, the sweep goes on
                    emit(kind="kernel", dtype=dtype, lanes=lanes, block=block, tile=tile, warps=w,
                         error=f"{type(exc).__name__}: {exc}"[:1000])
                    continue
                emit(kind="kernel", dtype=dtype, lanes=lanes, block=block, tile=tile, warps=w,
                     slot_steps_per_s=rates[tile, w], draw_slot_steps_per_s=draw_rate)
    finally:
        fused.TILE, fused.NUM_WARPS = default
    return max(rates, key=rates.get) if rates else default


def round_sweep(dtype, lanes, block, events, rounds, finals, n):
    """The DI's useful lane-steps/s for each (paused round cap, final call cap); the engine's caps are
    restored after.  One compile run first; each run on max(n, 8 lanes) excursions, seed 1."""
    import dryfric_jax as dj
    from dryfric_jax import excursions as ex
    from dryfric_jax import rounds as rd

    p = fig3_di(dtype)[0]
    saved = rd.ROUND_LANE_STEPS, rd.FINAL_CALL_LANE_STEPS, ex.DEFAULT_EVENTS
    ex.DEFAULT_EVENTS = events or ex.DEFAULT_EVENTS
    try:
        dj.estimate_diffusivity(p, 1, dtype=dtype, lanes=lanes, block=block, n_excursions=200)  # compile
        for r in rounds or [saved[0]]:
            for f in finals or [saved[1]]:
                rd.ROUND_LANE_STEPS, rd.FINAL_CALL_LANE_STEPS = r, f
                res = dj.estimate_diffusivity(p, 1, dtype=dtype, lanes=lanes, block=block,
                                              n_excursions=max(n, 8 * lanes))
                emit(kind="rounds", dtype=dtype, lanes=lanes, block=block, round_lane_steps=r, final_call_lane_steps=f,
                     lane_steps_per_s=res.lane_steps_per_s, wall_s=res.wall_s, utilization=res.lane_utilization,
                     n_excursions=res.n_excursions, D=res.D, D_ci=res.D_ci)
    finally:
        rd.ROUND_LANE_STEPS, rd.FINAL_CALL_LANE_STEPS, ex.DEFAULT_EVENTS = saved


def block_breakdown(dtype, lanes, block, events, reps=5):
    """Seconds per call of one engine block and of its parts (module docstring), from fresh lanes
    (seeking their first regeneration, as a run starts), and their share of the block."""
    import jax
    import jax.numpy as jnp
    import numpy as np

    from dryfric_jax import excursions as ex
    from dryfric_jax.rounds import Lanes

    chain = fig3_di(dtype)[1]
    events = ex._events_layout(jax.devices(), chain, events)
    lane = jax.device_put(ex.init_lanes(chain, lanes))
    keys = jax.random.split(jax.random.key(0), lanes)
    b = jnp.zeros(lanes, jnp.int64)
    big = np.int64(2**40)
    draw = jax.jit(lambda k, b: ex.draw_block(chain, k, b, block))
    rs = jax.block_until_ready(draw(keys, b))
    quiet = jax.jit(lambda ln, rs: ex._quiet_steps(chain, big, big, False, block, ln, rs, events == "fused"))
    whole = jax.jit(lambda ln, k, b: ex._block(chain, big, big, False, block, events, ln, k, b))

    timed = partial(seconds_per_call, reps=reps)
    s = dict(draw=timed(draw, keys, b), quiet=timed(quiet, lane, rs), block=timed(whole, lane, keys, b))
    s["rest"] = s["block"] - s["draw"] - s["quiet"]
    # in situ: paused rounds of 1, 4 and 16 blocks (a run's rounds are >= 4 blocks; a final round's calls
    # can be 1 block each): the slope is a block in the engine, the intercept what a round costs besides
    ln = Lanes(chain, lanes, block=block, events=events)
    ln.advance(jax.random.key(1), block)  # compile
    nbs, secs = [1, 4, 16, 1, 4, 16], []
    for i, nb in enumerate(nbs):
        t = time.perf_counter()
        ln.advance(jax.random.key(2 + i), nb * block)
        secs.append(time.perf_counter() - t)
    slope, icpt = np.polyfit(nbs, secs, 1)
    emit(kind="breakdown", dtype=dtype, lanes=lanes, block=block, events=events,
         **{f"{k}_s": v for k, v in s.items()}, **{f"{k}_share": v / s["block"] for k, v in s.items()},
         block_slot_steps_per_s=lanes * block / s["block"], round_blocks=nbs, round_s=secs,
         round_block_s=slope, round_overhead_s=icpt)


if __name__ == "__main__":
    sys.exit(main())
