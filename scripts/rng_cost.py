"""Where a normal's cost lies: the engine's threefry hash alone, the hash plus the engine's Box-Muller
transform with its vectorised log, cosine and sine (the engine's normals: the bench's RNG bound,
``bench.rng_bound_timer``), ``jax.random.normal`` (the same key's bits through the inverse error
function, twice as many in float64 since 0.3.0, with XLA:CPU's scalar float64 logarithm: the
engine's transform up to version 0.2.3), the same Box-Muller pairs with XLA's ``jnp.log``,
``jnp.cos`` and ``jnp.sin`` (for comparison: why the engine evaluates its own), and numpy's
``Generator`` (PCG64, ziggurat) inside a numba loop, the bench's compiled baseline
(``dryfric_jax.bench_numba``). The JAX rates are timed the way the bench times its RNG bound
(``bench._device_timer``: every lane draws a block from ``fold_in(lane_key, block)`` and reads it
row by row), with the CLI's XLA flags. Run it pinned to
one core (one XLA device)::

    taskset -c 1 python scripts/rng_cost.py

It prints numbers per second (best of 5 timings) and their ratios to numba's normals; numba draws
1e7 normals in one loop.  Needs the ``bench`` extra (numba).
"""
import time

from dryfric_jax.xla_flags import use_all_cpu_cores

use_all_cpu_cores(vector_width=True)  # as the CLI (dryfric bench), before JAX starts

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numba  # noqa: E402
import numpy as np  # noqa: E402

from dryfric_jax import rng  # noqa: E402
from dryfric_jax.bench import _device_timer, rng_bound_timer  # noqa: E402
from dryfric_jax.excursions import BLOCK, UNROLL, block_keys  # noqa: E402

LANES, N = 512, 1 << 23  # the bench's RNG-bound defaults


def _pair_bits(keys, b, dtype):
    """A block's two words of bits per step, what :func:`rng.normals` transforms (``rng._bits``): in float64
    one hash's two 32-bit words (since 0.3.0), in float32 two 32-bit numbers."""
    return rng._bits(jax.random.key_data(block_keys(keys, b)), BLOCK, 2, dtype, pairs=True)


def hash_timer(dtype):
    """A timer of the hash alone: lane-steps/s if drawing a step's two words of bits were all the lanes did."""
    def body(keys, b, acc):
        w1, w2 = _pair_bits(keys, b, dtype)
        return jax.lax.fori_loop(0, BLOCK, lambda i, a: a + w1[i] + w2[i], acc, unroll=UNROLL)

    return _device_timer(body, lambda m: jnp.zeros((m,), jnp.uint32), LANES, BLOCK, N, 5)


def box_muller_timer(dtype):
    r"""A timer of Box-Muller normals from the same bits through XLA's ``jnp.log``, ``jnp.cos`` and
    ``jnp.sin`` (for comparison with the engine's, which evaluates its own), a step's pair
    :math:`\sqrt{-2\ln u_1}\,(\cos 2\pi u_2, \sin 2\pi u_2)` with :math:`u_1 \in (0, 1]`."""
    def unit(w):  # on [0, 1): all 32 bits of a float64 pair's word, else jax.random.uniform's
        return w.astype(dtype) * np.array(2.0 ** -32, dtype) if dtype == np.float64 else rng._unit(w, dtype, 0.0, 1.0)

    def body(keys, b, acc):
        w1, w2 = _pair_bits(keys, b, dtype)
        u1 = np.array(1.0, dtype) - unit(w1)
        r = jnp.sqrt(np.array(-2.0, dtype) * jnp.log(u1))
        th = np.array(2 * np.pi, dtype) * unit(w2)
        z1, z2 = r * jnp.cos(th), r * jnp.sin(th)
        return jax.lax.fori_loop(0, BLOCK, lambda i, a: a + z1[i] + z2[i], acc, unroll=UNROLL)

    return _device_timer(body, lambda m: jnp.zeros((m,), dtype), LANES, BLOCK, N, 5)


@numba.njit(nogil=True)
def _numba_normals(gen, n):
    s = 0.0
    for _ in range(n):
        s += gen.standard_normal()
    return s


def _numba_rate(n: int = 10**7) -> float:
    gen = np.random.Generator(np.random.PCG64(1))
    _numba_normals(gen, 10)  # compile
    best = float("inf")
    for _ in range(5):
        t0 = time.perf_counter()
        _numba_normals(gen, n)
        best = min(best, time.perf_counter() - t0)
    return n / best


def main() -> None:
    jax.config.update("jax_enable_x64", True)
    nb = _numba_rate()
    print(f"{jax.device_count()} XLA device(s); numba Generator(PCG64) normals: {nb:.3e}/s")
    for dtype in (np.float32, np.float64):
        # two numbers per lane-step; the best of 5 timings of each
        timers = (hash_timer(dtype), rng_bound_timer(dtype, LANES, BLOCK, N),
                  rng_bound_timer(dtype, LANES, BLOCK, N, via="jax"), box_muller_timer(dtype))
        b, z, zj, bm = (2 * max(t() for _ in range(5)) for t in timers)
        print(f"{np.dtype(dtype).name}: hash words {b:.3e}/s ({b / nb:.2f}x numba's normals), "
              f"normals {z:.3e}/s ({z / nb:.2f}x), jax.random.normal {zj:.3e}/s ({zj / nb:.2f}x); "
              f"Box-Muller with XLA's log, cos, sin {bm:.3e}/s ({bm / nb:.2f}x)")


if __name__ == "__main__":
    main()
