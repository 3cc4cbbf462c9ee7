"""Side-by-side throughput (``dryfric bench``, ``scripts/bench.py``).

One run, one device, the paper's Fig. 3 point:

* useful lane-steps/s of the DI engine, float32 and float64;
* the device's raw normal-generation rate (the engine's generator, :mod:`dryfric_jax.rng`, drawn
  per lane and per block as the lanes draw them), as a lane-step bound at 2 normals per step,
  and the rate of ``jax.random.normal`` (JAX's own normals, another transform of jax.random's bits: of
  the same bits in float32, of twice as many in float64, whose pairs read one hash since 0.3.0; slower on
  a CPU, where its inverse error function takes a scalar float64 log);
* the chain floor: the same draws and transitions without the excursion bookkeeping (DI
  lane-steps/s, PDMP events/s), which splits the gap to the RNG bound into the chain's own
  arithmetic (floor / bound) and the engine's (engine / floor);
* PDMP events/s (default delta), float32 and float64;
* the duration count's lane-steps/s (:func:`~dryfric_jax.di_long_excursion_duration`, float64, its own h
  and default lanes; steps computed, the idle lanes' included), against the float64 chain floor (the count
  also computes its bridge's crossing chance at every step, ~1.4x the raw count's cost): it once froze a
  stopped lane's X and V with a select per step, which ran it at 0.27 of its speed on 2 CPU cores, unseen
  by any test;
* compiled scalar baselines of the same DI chain and of the same PDMP event loop (numba, 1 and 2
  threads, normals from numpy's ``Generator``: :mod:`dryfric_jax.bench_numba`), if numba is
  installed;
* the ratios, and the time to a 1% CI on D extrapolated from the measured CI width and rate
  (the CI half-width scales as N^{-1/2}).

``dryfric bench --lanes ... --block ...`` runs :func:`tune_layout` instead: the DI's lane-steps/s
for each engine layout, to choose one on a new device.
"""
from __future__ import annotations

import contextlib
import os
import time
import warnings

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh, PartitionSpec

from .api import DryfricWarning, default_h, estimate_diffusivity
from .durations import di_long_excursion_duration
from .cost import default_delta
from .di import make_di_model
from . import rng
from .excursions import BLOCK, MAX_LAYOUT, UNROLL, block_keys, draw_block, increment_dtype, numbers_at
from .pdmp import make_pdmp_model
from .plan import check_count, check_layout, plan_estimate
from .params import FIG3, Params


#: how to get the compiled baseline (an installed package has no checkout for ``pip install -e '.[bench]'``)
NUMBA_HINT = "pip install numba (the bench extra; in a checkout pip install -e '.[bench]')"


def _device_timer(per_lane_block, init, lanes: int, block: int, n: int, reps: int):
    """Compile ``per_lane_block(keys, b, carry) -> carry`` run for ``b = 0, 1, ...`` on every local
    device (``lanes`` split evenly, ``n`` lane-steps in all) and return a function that times it:
    each call runs it ``reps`` times and returns lane-steps/s, compile excluded."""
    devs = jax.local_devices()
    mesh = Mesh(np.array(devs), ("d",))
    per_dev = max(1, lanes // len(devs))
    n_blocks = max(1, n // (len(devs) * per_dev * block))

    def run(k):
        keys = jax.random.split(jax.random.fold_in(k[0], jax.lax.axis_index("d")), per_dev)
        out = jax.lax.fori_loop(0, n_blocks, lambda b, c: per_lane_block(keys, b, c), init(per_dev))
        return sum(jnp.sum(a).astype(jnp.float64) for a in jax.tree_util.tree_leaves(out))[None]

    f = jax.jit(jax.shard_map(run, mesh=mesh, in_specs=PartitionSpec(), out_specs=PartitionSpec("d"),
                              check_vma=False))
    f(jax.random.key(0)[None]).block_until_ready()

    def rate() -> float:
        t = time.perf_counter()
        for i in range(reps):
            f(jax.random.key(i + 1)[None]).block_until_ready()
        return n_blocks * block * per_dev * len(devs) * reps / (time.perf_counter() - t)

    return rate


def rng_bound(dtype, lanes: int = 512, block: int = BLOCK, n: int = 1 << 23, reps: int = 5,
              via: str = "engine") -> float:
    """Lane-steps/s of :func:`rng_bound_timer`, measured once."""
    return rng_bound_timer(dtype, lanes, block, n, reps, via)()


def rng_bound_timer(dtype, lanes: int = 512, block: int = BLOCK, n: int = 1 << 23, reps: int = 5,
                    via: str = "engine"):
    """A timer (see :func:`_device_timer`) of the lane-steps/s the local devices could do if
    drawing 2 normals per step were all they did.

    Drawn the way the lanes draw them: each device loops over blocks, and in each block every
    one of its lanes draws ``(block, 2)`` normals from ``fold_in(lane_key, block_index)``, so the
    numbers stay in cache as in the engine (one huge array would measure memory bandwidth).
    ``via="engine"``: through :func:`dryfric_jax.rng.normals`, the engine's generator (the
    bound); ``via="jax"``: through ``jax.random.normal`` (the same key's bits, JAX's transform and CPU
    lowering; twice the engine's bits in float64; not the engine's numbers, :mod:`dryfric_jax.rng`).
    """
    def body(keys, b, acc):
        bk = block_keys(keys, b)
        if via == "jax":
            z1, z2 = rng.per_lane(lambda k: jax.random.normal(k, (block, 2), dtype), bk, 2)
        else:
            z1, z2 = rng.normals(bk, block, 2, dtype)
        # read row by row as the steps do (3-7% faster than summing the block at once)
        return jax.lax.fori_loop(0, block, lambda i, a: a + z1[i] + z2[i], acc, unroll=UNROLL)

    return _device_timer(body, lambda m: jnp.zeros((m,), dtype), lanes, block, n, reps)


def chain_floor(chain, lanes: int = 512, block: int = BLOCK, n: int = 1 << 23, reps: int = 5) -> float:
    """Lane-steps (events) per second of :func:`chain_floor_timer`, measured once."""
    return chain_floor_timer(chain, lanes, block, n, reps)()


def chain_floor_timer(chain, lanes: int = 512, block: int = BLOCK, n: int = 1 << 23, reps: int = 5):
    """A timer (see :func:`_device_timer`) of the lane-steps (events) per second of the chain
    alone: the engine's draws and transitions
    (``chain.draw``, ``chain.advance`` with its regeneration test; for the DI the test for a
    coin to flip, the coins themselves being flipped in the bookkeeping) and the float64 sum of
    U (a block's increments summed in their own dtype first, as the engine does), without the
    excursion bookkeeping, refills or idle lanes.  Engine / floor is what the bookkeeping costs;
    floor / RNG bound is what the chain's own arithmetic costs."""
    def body(keys, b, carry):
        rs = draw_block(chain, keys, b, block)
        state, U = carry

        def step(i, c):
            state, S = c
            new, dU, _, heads = chain.advance(state, numbers_at(rs, i), True)
            return new, S + jnp.where(heads, 0.0, dU).astype(S.dtype)

        dU_dtype = increment_dtype(chain.advance, state, rs, True)
        state, S = jax.lax.fori_loop(0, block, step, (state, jnp.zeros(U.shape, dU_dtype)), unroll=UNROLL)
        return state, U + S.astype(U.dtype)

    init = lambda m: (chain.init_state(m), jnp.zeros((m,), jnp.float64))
    return _device_timer(body, init, lanes, block, n, reps)


def _numba_rates(run, model, n_excursions: int, seed: int, threads=(1, 2)) -> dict:
    """Steps (or events) per second of a numba baseline ``run`` with each number of ``threads``,
    compiled first (numba caches the compiled loop, so a second call compiles nothing)."""
    run(model, 20, 1)  # compile
    rates = {}
    for k in threads:
        t = time.perf_counter()
        _, steps = run(model, n_excursions, k, seed)
        rates[k] = steps / (time.perf_counter() - t)
    return rates


def _ratios(m: dict) -> dict:
    """The ratios of one round of measurements ``m`` (all measured within seconds of each other)."""
    out = {}
    if "numba_2t_steps_per_s" in m:
        for dt in ("float64", "float32"):
            out[f"ratio_pdmp_{dt}_to_numba_2t"] = m[f"pdmp_{dt}_events_per_s"] / m["numba_pdmp_2t_events_per_s"]
            out[f"ratio_di_{dt}_to_numba_2t"] = m[f"di_{dt}_lane_steps_per_s"] / m["numba_2t_steps_per_s"]
    for dt in ("float64", "float32"):
        bound, floor = m[f"rng_bound_{dt}_lane_steps_per_s"], m[f"di_chain_floor_{dt}_lane_steps_per_s"]
        out[f"ratio_di_{dt}_to_rng_bound"] = m[f"di_{dt}_lane_steps_per_s"] / bound
        out[f"ratio_rng_bound_{dt}_to_jax_random_normal"] = bound / m[f"jax_random_normal_{dt}_lane_steps_per_s"]
        out[f"ratio_di_{dt}_to_chain_floor"] = m[f"di_{dt}_lane_steps_per_s"] / floor
        out[f"ratio_di_chain_floor_{dt}_to_rng_bound"] = floor / bound
        out[f"ratio_pdmp_{dt}_to_event_floor"] = m[f"pdmp_{dt}_events_per_s"] / m[f"pdmp_event_floor_{dt}_events_per_s"]
    out["ratio_di_duration_to_chain_floor"] = (m["di_duration_lane_steps_per_s"]
                                               / m["di_chain_floor_float64_lane_steps_per_s"])
    return out


#: most rounds of a bench or a layout sweep (each ~1-2 min on 2 CPU cores at the default N): 10^23 was taken and
#: ran until killed, with nothing printed (an audit)
MAX_REPEAT = 1000


def run_bench(n_excursions: int = 10_000, numba_excursions: int = 10_000, seed: int = 0, repeat: int = 1) -> dict:
    """The side-by-side bench (module docstring), ``repeat`` rounds.

    Everything is compiled first; then each round measures every number once, one after the
    other (DI float64, its RNG bound, ``jax.random.normal``, chain floor; the same in float32;
    PDMP; numba), with the same seeds, and computes its ratios.  A 2-core machine's speed drifts
    by up to +-25% from minute to minute, so a ratio is only meaningful between numbers measured
    close together: the result gives each rate and each ratio as the **median over the rounds of
    that round's value** (a ratio is not recomputed from the medians), and with ``repeat > 1``
    also ``ranges`` (min, max over the rounds) and ``rounds`` (every round's numbers).
    """
    check_count("repeat", repeat, lo=1, hi=MAX_REPEAT)
    # a small bench (the tests) is small throughout: the floors' and numba's work scale with N
    # below the default N = 1e4 (2**23 lane-steps per timing, 1e4 numba excursions: ~1 s per timing)
    floor_n = int(min(1 << 23, max(1 << 20, 840 * n_excursions)))
    numba_excursions = int(min(numba_excursions, max(20, n_excursions)))
    p = Params(**FIG3)
    out = dict(device=str(jax.devices()[0]), n_devices=jax.device_count(), cpu_count=os.cpu_count(),
               params=p.as_dict(), n_excursions=n_excursions, repeat=repeat, numba_excursions=numba_excursions,
               jax_version=jax.__version__)
    timers = []  # each returns a dict of this round's numbers

    def di_timer(dt, lanes):
        def f():
            r = estimate_diffusivity(p, seed + 1, n_excursions=n_excursions, dtype=dt, lanes=lanes)
            m = {f"di_{dt}_lane_steps_per_s": r.lane_steps_per_s, f"di_{dt}_utilization": r.lane_utilization}
            if dt == "float64":
                rel = r.D_ci / r.D
                n1 = r.n_excursions * (rel / 0.01) ** 2
                m.update(D=r.D, D_ci=r.D_ci, excursions_for_1pct=n1, time_to_1pct_ci_s=r.wall_s * n1 / r.n_excursions)
            return m
        return f

    def pdmp_timer(dt, lanes):
        def f():
            r = estimate_diffusivity(p, seed + 1, method="pdmp", n_excursions=n_excursions, dtype=dt, lanes=lanes)
            return {f"pdmp_{dt}_events_per_s": r.events_per_s, "pdmp_delta": r.delta}
        return f

    def duration_timer(n):
        def f():
            r = di_long_excursion_duration(p, seed + 1, n_excursions=n)
            return {"di_duration_lane_steps_per_s": r.loop_steps / r.wall_s}
        return f

    named = lambda name, timer: (lambda: {name: timer()})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DryfricWarning)
        plan = plan_estimate(p, n_excursions=n_excursions)  # the run's layout, also for the compile
        lanes, block = plan.lanes, plan.block
        out.update(block=block, di_lanes=lanes)
        for dt in ("float64", "float32"):
            estimate_diffusivity(p, seed, n_excursions=200, dtype=dt, lanes=lanes)  # compile, same shapes
            timers += [di_timer(dt, lanes),
                       named(f"rng_bound_{dt}_lane_steps_per_s",
                             rng_bound_timer(jnp.dtype(dt), lanes, block, n=floor_n)),
                       named(f"jax_random_normal_{dt}_lane_steps_per_s",
                             rng_bound_timer(jnp.dtype(dt), lanes, block, n=floor_n, via="jax")),
                       named(f"di_chain_floor_{dt}_lane_steps_per_s",
                             chain_floor_timer(make_di_model(p, default_h(p), dt), lanes, block, n=floor_n))]
        dur_n = max(32, n_excursions // 2)  # 5000 long excursions at the default N, ~1 s on 2 cores
        out["di_duration_excursions"] = dur_n
        di_long_excursion_duration(p, seed, n_excursions=dur_n)  # compile, same lanes
        timers.append(duration_timer(dur_n))
        pdmp_lanes = plan_estimate(p, method="pdmp", n_excursions=n_excursions).lanes
        out["pdmp_lanes"] = pdmp_lanes
        for dt in ("float64", "float32"):  # PDMP events/s at the default delta
            estimate_diffusivity(p, seed, method="pdmp", n_excursions=200, dtype=dt, lanes=pdmp_lanes)  # compile
            timers += [pdmp_timer(dt, pdmp_lanes),
                       named(f"pdmp_event_floor_{dt}_events_per_s",
                             chain_floor_timer(make_pdmp_model(p, default_delta(p), dt), pdmp_lanes, n=floor_n))]
        try:
            from .bench_numba import RNG, BaselineIncomplete, run_numba, run_numba_pdmp
        except Exception as exc:  # not installed, or broken in this environment: say so, go on
            out["numba"] = f"unavailable ({type(exc).__name__}: {exc}); {NUMBA_HINT}"
        else:
            import numba

            # recorded with the numbers: the baseline draws from numpy's Generator (bench_numba), whose
            # speed did not move between numba 0.61 and 0.68; numba's legacy np.random did (1.8x)
            out["numba_version"] = numba.__version__
            out["numba_rng"] = RNG
            pm, dm = make_pdmp_model(p, default_delta(p)), make_di_model(p, default_h(p))

            timers.append(lambda: _numba_round(out, (run_numba_pdmp, pm), (run_numba, dm), numba_excursions, seed,
                                               BaselineIncomplete))
        rounds = []
        for _ in range(repeat):
            m = {}
            for f in timers:
                m.update(f())
            m.update(_ratios(m))
            rounds.append(m)
    return _medians(out, rounds)


def _numba_round(out: dict, pdmp, di, n_excursions: int, seed: int, stopped=()) -> dict:
    """One round's numba rates: ``pdmp`` and ``di`` are (run, model).  A baseline that stops at its work
    bound (the exception ``stopped``: it is broken) is said in ``out["numba"]`` and gives no rates, in
    this round and the later ones; the other numbers are kept."""
    if "numba" in out:
        return {}
    try:
        m = {f"numba_pdmp_{k}t_events_per_s": v for k, v in _numba_rates(*pdmp, n_excursions, seed).items()}
        m.update({f"numba_{k}t_steps_per_s": v for k, v in _numba_rates(*di, n_excursions, seed).items()})
    except stopped as exc:
        out["numba"] = f"stopped ({exc})"
        return {}
    return m


def _medians(out: dict, rounds: list) -> dict:
    """``out`` with each number of the rounds as its median over them, taken over the numbers every round
    has (a baseline that stopped in a later round has none); with several rounds, also ``ranges`` and
    ``rounds``."""
    keys = [k for k in rounds[0] if all(k in r for r in rounds)]
    for k in keys:
        out[k] = float(np.median([r[k] for r in rounds]))
    if len(rounds) > 1:
        out["ranges"] = {k: [min(r[k] for r in rounds), max(r[k] for r in rounds)] for k in keys}
        out["rounds"] = rounds
    return out


def tune_layout(lanes_list, blocks, dtype: str = "float32", n_excursions: int = 10_000, seed: int = 0,
                numba_excursions: int = 10_000, repeat: int = 1, *, unrolls=None, events=None,
                budget_s: float | None = None, on_layout=None, bound_n: int = 1 << 23) -> dict:
    """DI useful lane-steps/s at the Fig. 3 point for every engine layout (lanes, block K) in
    ``lanes_list`` x ``blocks`` (``dryfric bench --lanes ... --block ...``): the sweep that
    picks the layout on a new device (a GPU needs far more lanes than the CPU default).

    Each layout is compiled by a short run first, then timed on ``max(n_excursions, 8 * lanes)``
    excursions (every lane runs several, so the final round's tail does not dominate), the i-th
    (lanes, K) with seed ``seed + 1 + i``, in ``repeat`` rounds that each time every layout once
    (interleaved, so a drift of the machine's speed hits all layouts alike); a layout's rate is
    the median of its rounds, with ``lane_steps_per_s_range`` (min, max).  The layout changes the
    random streams but not the law, so the D of all layouts must agree within their CIs:
    ``max_z`` is the largest |D_i - pooled others| / SE of the difference, each row against the
    inverse-variance pool of the other rows (a check, not a speed number).  At the best layout,
    on the same device: the RNG bound and the chain floor (``bound_n`` lane-steps each), and on
    the host CPU the numba 2-thread DI loop (``numba_excursions`` = 0 skips it).

    For a lent accelerator's few minutes (``scripts/device_check.py``): ``unrolls`` also sweeps
    the wait loop's unroll (:data:`~dryfric_jax.excursions.QUIET_UNROLL`, traced into the loop,
    so each value compiles afresh; restored at the end); ``events`` the engine's event layouts
    (``"wait"``, ``"fused"``, ``"branch"``; None: the device's default; :mod:`dryfric_jax.fused`),
    each (lanes, K) running every one in turn; ``budget_s`` starts no new layout after that many
    seconds (the first always runs; the rest are listed under ``skipped``); ``on_layout(row)``
    receives each layout's row as soon as its rounds are done.  A layout whose compile run raises
    (a kernel the device cannot build) is listed under ``failed`` with its error, and the sweep
    goes on.
    """
    from . import excursions

    lanes_list = [check_layout(lanes, 1)[0] for lanes in lanes_list]
    blocks = [check_layout(1, block)[1] for block in blocks]
    # a grid's layouts past lanes * K <= 2^28 are listed as skipped (2^19 lanes at K = 1024 refused a
    # whole device check); a grid with none within it is refused, naming the first
    fits = [(la, bl) for la in lanes_list for bl in blocks if la * bl <= MAX_LAYOUT]
    if not fits:
        raise ValueError(f"lanes * block must be <= 2^28 for some layout (a block's normals are drawn at once) "
                         f"(got lanes {lanes_list}, block {blocks})")
    if dtype not in ("float32", "float64"):
        raise ValueError(f"dtype must be 'float32' or 'float64' (got {dtype!r})")
    check_count("repeat", repeat, lo=1, hi=MAX_REPEAT)
    unrolls = [excursions.QUIET_UNROLL] if not unrolls else [int(u) for u in unrolls]
    for u in unrolls:
        check_count("unroll", u, lo=1)
    events = [excursions.DEFAULT_EVENTS] if not events else list(events)
    for ev in events:
        if ev not in excursions.EVENTS:
            raise ValueError(f"events must be among {list(excursions.EVENTS)} (got {ev!r})")
    p = Params(**FIG3)
    out = dict(device=str(jax.devices()[0]), n_devices=jax.device_count(), cpu_count=os.cpu_count(),
               params=p.as_dict(), dtype=dtype, repeat=repeat, layouts=[], skipped=[], failed=[])
    t0 = time.perf_counter()
    over = lambda: budget_s is not None and time.perf_counter() - t0 > budget_s
    attempted = 0  # layouts compiled or tried: the first always runs, later ones only within budget_s
    combos = [(lanes, block, ev) for lanes, block in fits for ev in events]
    out["skipped"] += [dict(lanes=la, block=bl, unroll=u, events=ev, reason="lanes * K > 2^28")
                       for la in lanes_list for bl in blocks if la * bl > MAX_LAYOUT for u in unrolls for ev in events]
    # each (lanes, K) its own seed: the first lanes of 32 and 64 lanes from one seed share their keys
    # (split(key, 32) is split(key, 64)[:32]), which made their D agree for free; the unrolls and the
    # event layouts of one (lanes, K) keep its seed (they differ by rounding only)
    pair_seed = {lb: seed + 1 + i for i, lb in enumerate(dict.fromkeys((la, bl) for la, bl, _ in combos))}
    timed = lambda lanes, block: estimate_diffusivity(p, pair_seed[lanes, block], dtype=dtype, lanes=lanes,
                                                      block=block, n_excursions=max(int(n_excursions), 8 * lanes))
    with _engine_settings_restored(), warnings.catch_warnings():
        warnings.simplefilter("ignore", DryfricWarning)
        for unroll in unrolls:
            _set_quiet_unroll(unroll)
            runs = {}  # (lanes, block, events) -> compile time and the timed runs; None: skipped or failed
            for rnd in range(repeat):  # interleaved rounds; the first compiles each layout just before
                for lanes, block, ev in combos:
                    at = (lanes, block, ev)
                    excursions.DEFAULT_EVENTS = ev  # read when a run builds its lanes
                    if rnd == 0:
                        runs[at] = _compile_layout(p, seed, dtype, at, unroll, out, attempted > 0 and over())
                        attempted += 1
                    if runs[at] is None:
                        continue
                    runs[at]["rs"].append(timed(lanes, block))
                    if rnd == repeat - 1:
                        out["layouts"].append(_layout_row(at, unroll, **runs[at]))
                        if on_layout is not None:
                            on_layout(out["layouts"][-1])
        if not out["layouts"]:
            raise ValueError(f"no layout ran: {out['failed']}")
        best = _summarise_layouts(out)
        bound = rng_bound(jnp.dtype(dtype), best["lanes"], best["block"], n=bound_n)
        floor = chain_floor(make_di_model(p, default_h(p), dtype), best["lanes"], best["block"], n=bound_n)
        out.update(rng_bound_lane_steps_per_s=bound, ratio_best_to_rng_bound=best["lane_steps_per_s"] / bound,
                   chain_floor_lane_steps_per_s=floor, ratio_chain_floor_to_rng_bound=floor / bound,
                   ratio_best_to_chain_floor=best["lane_steps_per_s"] / floor)
    if numba_excursions > 0:
        try:
            from .bench_numba import BaselineIncomplete, run_numba
        except Exception as exc:
            out["numba"] = f"unavailable ({type(exc).__name__}: {exc}); {NUMBA_HINT}"
        else:
            try:
                rate = _numba_rates(run_numba, make_di_model(p, default_h(p)), numba_excursions, seed, (2,))[2]
            except BaselineIncomplete as exc:
                out["numba"] = f"stopped ({exc})"
            else:
                out.update(numba_2t_steps_per_s=rate, ratio_best_to_numba_2t=best["lane_steps_per_s"] / rate)
    return out


@contextlib.contextmanager
def _engine_settings_restored():
    """Restore the engine's module-level layout settings (event layout, wait-loop unroll) on exit."""
    from . import excursions

    events0, unroll0 = excursions.DEFAULT_EVENTS, excursions.QUIET_UNROLL
    try:
        yield
    finally:
        excursions.DEFAULT_EVENTS = events0
        _set_quiet_unroll(unroll0)


def _set_quiet_unroll(unroll: int) -> None:
    """Set the wait loop's unroll; it is traced into the loop, so a change compiles afresh."""
    from . import excursions

    if unroll != excursions.QUIET_UNROLL:
        excursions.QUIET_UNROLL = unroll
        jax.clear_caches()


def _compile_layout(p, seed, dtype, at, unroll, out, skip: bool):
    """A layout's compile run (200 excursions): ``dict(compile_s, rs=[])``, or None after listing
    it under ``out["skipped"]`` (``skip``: past the time budget) or ``out["failed"]`` (it raised:
    a kernel the device cannot build)."""
    lanes, block, ev = at
    where = dict(lanes=lanes, block=block, unroll=unroll, events=ev)
    if skip:
        out["skipped"].append(where)
        return None
    tc = time.perf_counter()
    try:
        estimate_diffusivity(p, seed, n_excursions=200, dtype=dtype, lanes=lanes, block=block)
    except Exception as exc:  # a layout this device cannot run: say so, go on
        out["failed"].append(dict(where, error=f"{type(exc).__name__}: {exc}"[:2000]))
        return None
    return dict(compile_s=time.perf_counter() - tc, rs=[])


def _layout_row(at, unroll, compile_s, rs) -> dict:
    """A layout's row: the median rate of its rounds and its range; the rounds share a seed, so
    they share D."""
    lanes, block, ev = at
    r, rates = rs[0], [x.lane_steps_per_s for x in rs]
    return dict(lanes=lanes, block=block, unroll=unroll, events=ev, n_excursions=r.n_excursions,
                lane_steps_per_s=float(np.median(rates)), lane_steps_per_s_range=[min(rates), max(rates)],
                utilization=r.lane_utilization, wall_s=float(np.median([x.wall_s for x in rs])),
                compile_and_200_s=compile_s, D=r.D, D_ci=r.D_ci, n_truncated=r.n_truncated, stopped_by=r.stopped_by)


def _summarise_layouts(out: dict) -> dict:
    """Add the best layout, the inverse-variance pooled D and ``max_z`` to ``out``; return the best row."""
    best = max(out["layouts"], key=lambda row: row["lane_steps_per_s"])
    # the wait and fused layouts and the unrolls of one (lanes, K) run the same excursions (its seed, the numbers
    # used alike; up to rounding): one row of them, or a row's twin in the pool of the others pulls that pool
    # towards it (wait and fused: max_z shrank by sqrt(2/3)).  "branch" uses the numbers otherwise
    rows = list({(row["lanes"], row["block"], row["events"] == "branch"): row for row in out["layouts"]}.values())
    w = [(1.96 / row["D_ci"]) ** 2 for row in rows]
    pooled = sum(wi * row["D"] for wi, row in zip(w, rows)) / sum(w)

    def z(i):  # row i against the pool of the others (a pool holding row i pulls towards it)
        wo = sum(w) - w[i]
        if wo <= 0:
            return 0.0
        rest = (sum(wi * row["D"] for wi, row in zip(w, rows)) - w[i] * rows[i]["D"]) / wo
        return abs(rows[i]["D"] - rest) / (1 / w[i] + 1 / wo) ** 0.5
    out.update(best_lanes=best["lanes"], best_block=best["block"], best_unroll=best["unroll"],
               best_events=best["events"], best_lane_steps_per_s=best["lane_steps_per_s"], D_pooled=pooled,
               max_z=max(z(i) for i in range(len(rows))))
    return best


def format_layouts(b: dict) -> str:
    """The table of :func:`tune_layout`."""
    head = f"device {b['device']} (x{b['n_devices']}, {b['cpu_count']} CPU cores), DI {b['dtype']}, Fig. 3 point"
    if b.get("repeat", 1) > 1:
        head += f"; medians of {b['repeat']} interleaved rounds [min-max]"
    lines = [head, f"{'lanes':>8} {'K':>5} {'unroll':>6} {'events':>7} {'N':>9} {'lane-steps/s':>13} {'util':>6} "
                   f"{'wall s':>8}  D (95% CI)"]
    ev = lambda r: str(r["events"] or "default")
    for r in b["layouts"]:
        lo, hi = r["lane_steps_per_s_range"]
        spread = f"  [{lo:.4g}-{hi:.4g}]" if b.get("repeat", 1) > 1 else ""
        lines.append(f"{r['lanes']:>8} {r['block']:>5} {r['unroll']:>6} {ev(r):>7} {r['n_excursions']:>9} "
                     f"{r['lane_steps_per_s']:>13.4g} {r['utilization']:>6.3f} {r['wall_s']:>8.2f}  "
                     f"{r['D']:.5g} ± {r['D_ci']:.2g}{spread}")
    for r in b.get("skipped", []):
        lines.append(f"{r['lanes']:>8} {r['block']:>5} {r['unroll']:>6} {ev(r):>7}  skipped "
                     f"({r.get('reason', 'budget_s')})")
    for r in b.get("failed", []):
        lines.append(f"{r['lanes']:>8} {r['block']:>5} {r['unroll']:>6} {ev(r):>7}  failed: {r['error'][:200]}")
    lines.append(f"best: lanes = {b['best_lanes']}, K = {b['best_block']}, {b['best_lane_steps_per_s']:.4g} "
                 f"lane-steps/s = {b['ratio_best_to_rng_bound']:.3g} x the RNG bound ({b['rng_bound_lane_steps_per_s']:.4g})")
    lines.append(f"       {b['ratio_best_to_chain_floor']:.3g} x the chain floor ({b['chain_floor_lane_steps_per_s']:.4g}; "
                 f"floor / bound = {b['ratio_chain_floor_to_rng_bound']:.3g})")
    if "ratio_best_to_numba_2t" in b:
        lines.append(f"       {b['ratio_best_to_numba_2t']:.3g} x the numba 2-thread CPU loop "
                     f"({b['numba_2t_steps_per_s']:.4g} steps/s)")
    lines.append(f"layouts agree: largest |D - pooled others| = {b['max_z']:.2f} SE (pooled D = {b['D_pooled']:.5g})")
    return "\n".join(lines)


def format_table(b: dict) -> str:
    """:func:`run_bench`'s numbers, one per line; with several rounds, medians and [min-max]."""
    rows = [("device", b["device"] + f" (x{b['n_devices']}, {b['cpu_count']} CPU cores)")]
    ranges = b.get("ranges", {})
    for k, v in b.items():
        if k in ("device", "n_devices", "cpu_count", "params", "ranges", "rounds"):
            continue
        text = f"{v:.4g}" if isinstance(v, float) else str(v)
        if k in ranges and ranges[k][0] != ranges[k][1]:
            text += f"  [{ranges[k][0]:.4g}-{ranges[k][1]:.4g}]"
        rows.append((k, text))
    if ranges:
        rows.insert(1, ("", f"medians of {b['repeat']} rounds [min-max]; each ratio is taken within its round"))
    w = max(len(k) for k, _ in rows)
    return "\n".join(f"{k:<{w}}  {v}" for k, v in rows)
