r"""Where the GPU's fused quiet loop is: the ``"fused"`` event layout, one Pallas kernel per block.

The ``"wait"`` layout (:func:`dryfric_jax.excursions._quiet_steps`) runs a block's K quiet steps
as a ``fori_loop`` of whole-lane array operations: XLA launches at least one kernel per step and
each step reads and writes every lane's state in device memory.  On an H200 that engine reached
0.09 of the RNG bound (PERFORMANCE.md "On a GPU"): a step of 2^18 lanes took ~43 us where its memory
traffic needs ~3 us.  Here the loop is turned inside out: one GPU thread runs its lane's K steps
in registers, reading only the two normals of each step (Pallas, Triton backend), so a block is
one kernel.

The kernel is the same arithmetic as the ``"wait"`` loop, step by step: for each step i of the
block, a lane that has not yet met an event takes the DI step
(:meth:`~dryfric_jax.di.DIModel.advance`) unless the step is an event (a coin to flip, or the
step index reaches ``first``, the lane's budget stop or work bound), where it stops and records
``at = i``; the engine then runs that pending step with the full bookkeeping, as for ``"wait"``.
So the law is that of ``"wait"``, and on a CPU the numbers are too, up to rounding: bit for bit
at 48 lanes per device in both dtypes (tested, in Pallas's interpreter), but in float32 with 6 or
7 lanes on one device a lane's U differed by 3e-8 relative, with the same events, steps and slots
(the two programs are compiled apart, and XLA:CPU's code depends on the shape).  Only the DI has
it (a chain with ``fused_quiet = True``).

On a CPU the kernel runs in Pallas's interpreter (slow: for the tests only), and ``"fused"`` is
the DI's default only on an NVIDIA GPU (:func:`dryfric_jax.excursions._events_layout`).  On an
H100 (jax 0.11.2, Fig. 3 point, 2026-11-27; PERFORMANCE.md "On an H100") its estimates equalled the
``"wait"`` layout's bit for bit at all five layouts run (2^16 and 2^18 lanes, K = 256 and 1024,
float32 and float64), and it ran 3.0x (2^16 lanes, K = 256), 1.6x (2^18, 256) and 1.9x (2^18,
1024) faster in float32, up to 8.8e9 useful lane-steps/s; in float64 it ran as fast as ``"wait"``.
On an H200 (2026-11-30) the kernel alone ran 2.8e11 slot-steps/s (2^18 lanes, K = 1024, float32;
:data:`TILE` 256 with 4 warps the fastest of 12 pairs), while the engine's run made ~1e10 slot-steps/s
in all: the rest of the block, not this kernel, is where the time goes (PERFORMANCE.md "On an H200").
"""
from __future__ import annotations

import jax
import jax.numpy as jnp
from jax import lax

#: lanes per kernel instance (one Triton program), at most; a power of two dividing the lanes (256 and
#: 4 warps: the fastest of tiles 128-1024 x warps 2-8 on an H200, scripts/device_check.py --kernel-tiles)
TILE = 256
#: Triton warps per program
NUM_WARPS = 4


def tile_for(n_lanes: int) -> int:
    """The largest power of two <= :data:`TILE` that divides ``n_lanes``."""
    t = TILE
    while n_lanes % t:
        t //= 2
    return t


def _compiler_params():
    from jax.experimental.pallas import triton as pltriton

    return pltriton.CompilerParams(num_warps=NUM_WARPS)


def quiet_steps(chain, block: int, state, U0, at0, first, watch, counted, rs):
    r"""The ``"wait"`` layout's quiet loop as one kernel (module docstring).

    Args:
        chain: the DI chain (its leaves are passed to the kernel as scalars).
        block: K, steps of the block.
        state: ``(X, V)``, each (lanes,) in the simulation dtype.
        U0: (lanes,) displacement sum to add to (the dtype of the increments).
        at0: (lanes,) ``block`` for a lane that is free, -1 for a done lane (dtype of ``U0``).
        first: (lanes,) step index at which a lane's counters make an event (dtype of ``U0``).
        watch: (lanes,) bool, the lane watches :math:`C_+` (phase is not PLUS).
        counted: (lanes,) bool, the lane's steps count (phase is not SEEK).
        rs: ``(z1, z2)``, each (block, lanes): the block's normals.

    Returns:
        ``(state, U, at)`` after the block: ``at`` is each lane's pending step (``block``: none,
        -1: done), as :func:`dryfric_jax.excursions._quiet_steps`'s loop returns them.
    """
    from jax.experimental import pallas as pl

    X0, V0 = state
    z1, z2 = rs
    n = X0.shape[0]
    tile = tile_for(n)
    leaves, treedef = jax.tree_util.tree_flatten(chain)
    consts = [jnp.reshape(c, (1,)) for c in leaves]
    nc = len(consts)
    flags = (watch.astype(jnp.int32), counted.astype(jnp.int32))

    def kernel(*refs):
        chain_k = jax.tree_util.tree_unflatten(treedef, [r[0] for r in refs[:nc]])
        x_ref, v_ref, u_ref, at_ref, first_ref, w_ref, c_ref, z1_ref, z2_ref = refs[nc:nc + 9]
        xo, vo, uo, ato = refs[nc + 9:]
        fst, wat, cnt = first_ref[...], w_ref[...] != 0, c_ref[...] != 0

        def body(i, c):
            X, V, U, at = c
            (Xn, Vn), dU, _, cand = chain_k.advance((X, V), (z1_ref[i, :], z2_ref[i, :]), wat)
            fi = i.astype(at.dtype)
            free = at == block
            event = free & (cand | (fi >= fst))
            go = free & ~event
            return (jnp.where(go, Xn, X), jnp.where(go, Vn, V), U + jnp.where(go & cnt, dU, 0.0),
                    jnp.where(event, fi, at))

        X, V, U, at = lax.fori_loop(0, block, body, (x_ref[...], v_ref[...], u_ref[...], at_ref[...]))
        xo[...], vo[...], uo[...], ato[...] = X, V, U, at

    lane_spec = pl.BlockSpec((tile,), lambda j: (j,))
    row_spec = pl.BlockSpec((block, tile), lambda j: (0, j))
    const_spec = pl.BlockSpec((1,), lambda j: (0,))
    in_specs = [const_spec] * nc + [lane_spec] * 7 + [row_spec] * 2
    out_shape = [jax.ShapeDtypeStruct((n,), a.dtype) for a in (X0, V0, U0, at0)]
    args = (*consts, X0, V0, U0, at0, first, *flags, z1, z2)

    def call(interpret: bool):
        kw = dict(interpret=True) if interpret else dict(compiler_params=_compiler_params())
        return lambda *a: tuple(pl.pallas_call(kernel, out_shape=out_shape, grid=(n // tile,), in_specs=in_specs,
                                               out_specs=[lane_spec] * 4, **kw)(*a))

    X, V, U, at = lax.platform_dependent(*args, cpu=call(True), default=call(False))
    return (X, V), U, at
