"""The accelerator check, as one prepared run (a lent GPU has minutes, not hours).

Prints one JSON line per measurement as soon as it is made (a run stopped at its time limit
keeps what it printed), at the paper's Fig. 3 point:

* ``layout``: DI useful lane-steps/s for each (dtype, lanes, block K, unroll), N = max(--n, 8 lanes)
  excursions after a compile run, with D +- CI (the layouts change the streams, not the law:
  their D must agree within their CIs);
* ``rng_bound``, ``chain_floor``: the engine's generator alone, and the chain without the excursion
  bookkeeping, at the best layout of each dtype;
* ``numba``: the compiled CPU loop of the same DI chain with 1, 2 and all host threads;
* ``bench``: the side-by-side ``dryfric bench`` (the plan's own lanes), when --bench-n > 0.

    python scripts/device_check.py --lanes 65536,262144 --block 256,1024 --unroll 1,4 --n 200000

Stops starting new layouts once --budget-s seconds have passed.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time
import warnings


def emit(**kw):
    print(json.dumps(kw), flush=True)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--lanes", default="65536,262144")
    ap.add_argument("--block", default="256")
    ap.add_argument("--unroll", default="", help="steps per iteration of the wait layout's loop "
                    "(excursions.QUIET_UNROLL; default: the engine's)")
    ap.add_argument("--dtypes", default="float32,float64")
    ap.add_argument("--n", type=float, default=2e5, help="excursions per layout (at least 8 per lane)")
    ap.add_argument("--numba-n", type=int, default=4000, help="excursions per numba timing (0: skip)")
    ap.add_argument("--bench-n", type=float, default=0, help="N of the side-by-side bench (0: skip)")
    ap.add_argument("--bound-n", type=float, default=2**30, help="lane-steps per RNG-bound timing")
    ap.add_argument("--budget-s", type=float, default=240)
    a = ap.parse_args(argv)
    t0 = time.perf_counter()

    import jax
    jax.config.update("jax_enable_x64", True)
    import jax.numpy as jnp
    import dryfric_jax as dj
    from dryfric_jax.api import default_h
    from dryfric_jax.bench import chain_floor, rng_bound, run_bench
    from dryfric_jax.di import make_di_model
    from dryfric_jax.params import FIG3

    emit(kind="device", devices=[str(d) for d in jax.devices()], jax=jax.__version__, cpu_count=os.cpu_count())
    p = dj.Params(**FIG3)
    from dryfric_jax import excursions
    lanes_list = [int(x) for x in a.lanes.split(",")]
    blocks = [int(x) for x in a.block.split(",")]
    unrolls = [int(x) for x in a.unroll.split(",")] if a.unroll else [excursions.QUIET_UNROLL]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", dj.DryfricWarning)
        for dt in a.dtypes.split(","):
            best = None
            for lanes, block, unroll in [(x, y, z) for x in lanes_list for y in blocks for z in unrolls]:
                if time.perf_counter() - t0 > a.budget_s:
                    emit(kind="skipped", dtype=dt, lanes=lanes, block=block, unroll=unroll, reason="budget")
                    continue
                if unroll != excursions.QUIET_UNROLL:  # traced into the loop: compile afresh
                    excursions.QUIET_UNROLL = unroll
                    jax.clear_caches()
                tc = time.perf_counter()
                dj.estimate_diffusivity(p, 0, n_excursions=200, dtype=dt, lanes=lanes, block=block)
                compile_s = time.perf_counter() - tc
                r = dj.estimate_diffusivity(p, 1, n_excursions=int(max(a.n, 8 * lanes)), dtype=dt,
                                            lanes=lanes, block=block)
                row = dict(kind="layout", dtype=dt, lanes=lanes, block=block, unroll=unroll,
                           n_excursions=r.n_excursions,
                           lane_steps_per_s=r.lane_steps_per_s, utilization=r.lane_utilization,
                           wall_s=r.wall_s, compile_and_200_s=compile_s, D=r.D, D_ci=r.D_ci,
                           n_truncated=r.n_truncated, stopped_by=r.stopped_by)
                emit(**row)
                if best is None or row["lane_steps_per_s"] > best["lane_steps_per_s"]:
                    best = row
            if best is not None:
                bound = rng_bound(jnp.dtype(dt), best["lanes"], best["block"], n=int(a.bound_n))
                emit(kind="rng_bound", dtype=dt, lanes=best["lanes"], block=best["block"],
                     lane_steps_per_s=bound, ratio_best_to_bound=best["lane_steps_per_s"] / bound)
                floor = chain_floor(make_di_model(p, default_h(p), dt), best["lanes"], best["block"],
                                    n=int(a.bound_n))
                emit(kind="chain_floor", dtype=dt, lanes=best["lanes"], block=best["block"], lane_steps_per_s=floor,
                     ratio_floor_to_bound=floor / bound, ratio_best_to_floor=best["lane_steps_per_s"] / floor)
        if a.numba_n > 0:
            try:
                from dryfric_jax.bench_numba import run_numba
            except Exception as exc:
                emit(kind="numba", error=f"{type(exc).__name__}: {exc}")
            else:
                model = make_di_model(p, default_h(p))
                run_numba(model, 20, 1)  # compile
                for k in sorted({1, 2, os.cpu_count() or 1}):
                    t = time.perf_counter()
                    _, steps = run_numba(model, a.numba_n, k, 0)
                    emit(kind="numba", threads=k, steps_per_s=steps / (time.perf_counter() - t))
        if a.bench_n > 0:
            emit(kind="bench", **run_bench(n_excursions=int(a.bench_n), repeat=1))
    emit(kind="done", elapsed_s=time.perf_counter() - t0)
    return 0


if __name__ == "__main__":
    sys.exit(main())
