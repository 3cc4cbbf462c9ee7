"""Where a normal's cost lies, on one CPU core: the engine's threefry hash alone, the hash plus
``jax.random``'s inverse-erf transform (the engine's normals, ``dryfric_jax.rng``), and numpy's
``Generator`` (PCG64, ziggurat) inside a numba loop, the bench's compiled baseline
(``dryfric_jax.bench_numba``).  Run it pinned to one core::

    taskset -c 1 python scripts/rng_cost.py

It prints numbers per second (best of 5 timings) and their ratios to numba's normals.  The
engine draws a block of 256 lanes x 128 rows x 2 columns per call, the way the lane engine does;
numba draws 1e7 normals in one loop.  Needs the ``bench`` extra (numba).
"""
import time

import jax
import numba
import numpy as np

from dryfric_jax import rng

LANES, BLOCK = 256, 128


def _best(f, *args, reps: int = 100) -> float:
    """The best of 5 timings of ``reps`` calls, per call (seconds)."""
    jax.block_until_ready(f(*args))
    times = []
    for _ in range(5):
        t0 = time.perf_counter()
        for _ in range(reps):
            out = f(*args)
        jax.block_until_ready(out)
        times.append((time.perf_counter() - t0) / reps)
    return min(times)


@numba.njit(nogil=True)
def _numba_normals(gen, n):
    s = 0.0
    for _ in range(n):
        s += gen.standard_normal()
    return s


def main() -> None:
    jax.config.update("jax_enable_x64", True)
    gen = np.random.Generator(np.random.PCG64(1))
    _numba_normals(gen, 10)  # compile
    n = 10**7
    nb = n / min(_timed(lambda: _numba_normals(gen, n)) for _ in range(5))
    print(f"numba Generator(PCG64) normals: {nb:.3e}/s")
    kd = jax.random.key_data(jax.random.split(jax.random.key(0), LANES))
    per_call = LANES * BLOCK * 2
    for dtype in (np.dtype(np.float32), np.dtype(np.float64)):
        bits = jax.jit(lambda kd, dt=dtype: rng._bits(kd, BLOCK, 2, dt))
        normals = jax.jit(lambda kd, dt=dtype: tuple(rng._normal(b, dt) for b in rng._bits(kd, BLOCK, 2, dt)))
        b, z = per_call / _best(bits, kd), per_call / _best(normals, kd)
        print(f"{dtype.name}: hash words {b:.3e}/s ({b / nb:.2f}x numba's normals), "
              f"normals {z:.3e}/s ({z / nb:.2f}x)")


def _timed(f) -> float:
    t0 = time.perf_counter()
    f()
    return time.perf_counter() - t0


if __name__ == "__main__":
    main()
