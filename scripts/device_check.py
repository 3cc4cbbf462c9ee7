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
* ``bench``: the side-by-side ``dryfric bench`` (the plan's own lanes), when --bench-n > 0.

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
    a = ap.parse_args(argv)
    bad = [d for d in a.dtypes.split(",") if d not in ("float32", "float64")]
    bad += [e for e in (a.events.split(",") if a.events else []) if e not in ("wait", "fused", "branch")]
    if bad:
        ap.error(f"--dtypes must be among float32,float64 and --events among wait,fused,branch (got {bad})")
    t0 = time.perf_counter()

    import jax
    jax.config.update("jax_enable_x64", True)
    import dryfric_jax as dj
    from dryfric_jax.api import default_h
    from dryfric_jax.bench import _numba_rates, run_bench, tune_layout
    from dryfric_jax.di import make_di_model
    from dryfric_jax.params import FIG3

    emit(kind="device", devices=[str(d) for d in jax.devices()], jax=jax.__version__, cpu_count=os.cpu_count())
    for dt in a.dtypes.split(","):
        left = a.budget_s - (time.perf_counter() - t0)
        if left <= 0:
            emit(kind="skipped", dtype=dt, reason="budget")
            continue
        try:
            b = tune_layout(a.lanes, a.block, dt, n_excursions=int(a.n), numba_excursions=0,
                            unrolls=a.unroll, events=a.events.split(",") if a.events else None, budget_s=left,
                            bound_n=int(a.bound_n), on_layout=lambda row: emit(kind="layout", dtype=dt, **row))
        except ValueError as e:  # a layout or size the engine refuses (--lanes 5000000): named, exit 2
            ap.error(str(e))
        for row in b["skipped"]:
            emit(kind="skipped", dtype=dt, **{"reason": "budget", **row})  # or past the layout bound
        for row in b["failed"]:
            emit(kind="failed", dtype=dt, **row)
        emit(kind="tune", **{k: v for k, v in b.items() if k not in ("layouts", "skipped", "failed", "params")})
    if a.numba_n > 0:
        try:
            from dryfric_jax.bench_numba import BaselineIncomplete, run_numba
        except Exception as exc:
            emit(kind="numba", error=f"{type(exc).__name__}: {exc}")
        else:
            p = dj.Params(**FIG3)
            try:
                rates = _numba_rates(run_numba, make_di_model(p, default_h(p)), a.numba_n, 0,
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


if __name__ == "__main__":
    sys.exit(main())
