r"""Compiled scalar baseline for the benchmark: the same DI chain and regeneration rule as
:mod:`dryfric_jax.excursions` (and the same PDMP event algorithm as :mod:`dryfric_jax.pdmp`), one
excursion after another in a numba loop, one worker per thread, each accumulating the sums the
delta-method CI needs (:func:`dryfric_jax.estimators.long_excursion_estimates`).

The random numbers come from numpy's ``Generator`` (PCG64; normals by the ziggurat method), one per
worker, seeded from ``SeedSequence(seed).spawn(threads)``.  Not numba's ``np.random.*`` functions
(the legacy Mersenne-Twister state): measured on one core of the 2-core CI-class machine (numpy
1.26 / 2.4), those drew 6.2e7 normals/s on numba 0.61 and 3.5e7 on 0.62-0.68, where a
``Generator`` draws 2.6-2.7e8 on both; a baseline bound by them was 5x slower than this one on
numba 0.68 and its speed moved 1.7x with numba's version.  The loops run in float64 for both of
the engine's dtypes: a ``Generator``'s float32 normals are slower in numba (1.25e8/s, one core,
numba 0.68.1), so a float32 loop would be a weaker baseline.

numba is an optional extra (``pip install -e ".[bench]"``); this module is imported only by ``dryfric
bench`` (:mod:`dryfric_jax.bench`), never by ``import dryfric_jax``.
"""
from __future__ import annotations

import math
import warnings
from concurrent.futures import ThreadPoolExecutor

import numba
import numpy as np

from .limits import MAX_WORK
from .plan import MAX_STEPS, check_count, check_max_work

SEEK, PLUS, MINUS = 0, 1, 2
#: what the loops draw from (``dryfric bench`` records it with the numbers)
RNG = "numpy.random.Generator(PCG64), one per worker; normals by the ziggurat method"
#: the sums each worker returns, in this order, then :data:`TAIL`; ``t_half`` is not tracked
SUMS = ("n", "U", "U2", "U3", "U4", "t", "t2", "t3", "t4", "Ut", "U2t", "U3t", "Ut2", "U2t2", "Ut3")
#: after the sums, each worker's useful steps (events: those in an excursion), its excursions that reached
#: ``max_steps`` (closed, not in the sums) and its work (every step or event, seeks included)
TAIL = ("steps", "n_truncated", "work")
STEPS, TRUNC, WORK = (len(SUMS) + i for i in range(len(TAIL)))


class BaselineIncomplete(RuntimeError):
    """A worker reached its work bound before its excursions were done.  ``rows`` holds what every
    worker had (the sums of its complete excursions, then :data:`TAIL`)."""

    def __init__(self, message: str, rows):
        super().__init__(message)
        self.rows = rows


@numba.njit(nogil=True, cache=False)
def _add(acc, U, t):
    """Add one excursion's (U, t) to the sums ``acc`` (order: :data:`SUMS`)."""
    U2, t2 = U * U, t * t
    acc[0] += 1.0
    acc[1] += U
    acc[2] += U2
    acc[3] += U2 * U
    acc[4] += U2 * U2
    acc[5] += t
    acc[6] += t2
    acc[7] += t2 * t
    acc[8] += t2 * t2
    acc[9] += U * t
    acc[10] += U2 * t
    acc[11] += U2 * U * t
    acc[12] += U * t2
    acc[13] += U2 * t2
    acc[14] += U * t2 * t


def generators(seed: int, threads: int):
    """One numpy ``Generator`` (PCG64) per worker: ``SeedSequence(seed).spawn(threads)``."""
    return [np.random.Generator(np.random.PCG64(s)) for s in np.random.SeedSequence(seed).spawn(threads)]


def _on_threads(worker, seed: int, threads: int, n_excursions: int, args):
    """``worker(generator, n_each, *args)`` on ``threads`` threads (numba releases the GIL: nogil),
    ``n_each = ceil(n_excursions / threads)``; one row per worker: the sums, then :data:`TAIL`."""
    n_each = -(-n_excursions // threads)
    with ThreadPoolExecutor(threads) as ex:
        rows = list(ex.map(lambda g: worker(g, n_each, *args), generators(seed, threads)))
    return np.array(rows)


def _work_each(threads, max_work) -> int:
    """Each worker's work bound, ``ceil(max_work / threads)``, after the planner's checks of ``threads``
    (an integer >= 1) and ``max_work`` (a finite number >= 1e3), and at most 2^62 here: a worker counts
    its steps in an int64.  ``ValueError`` names the one out of range."""
    threads = check_count("threads", threads, 1)
    max_work = check_max_work(max_work)
    if max_work > 2.0**62:
        raise ValueError(f"max_work must be <= 2^62 for the numba baseline (its workers count in int64) "
                         f"(got {max_work:.3g})")
    return math.ceil(max_work / threads)


def _finished(out, n_excursions: int, threads: int, each: int, what: str, unit: str):
    """``out`` and its useful steps (events), after the checks: every worker ran its excursions (else
    :class:`BaselineIncomplete`, the rows kept), and the truncated ones are reported (a warning)."""
    n_each = -(-n_excursions // threads)
    short = [i for i in range(len(out)) if out[i, 0] < n_each]
    if short:
        i = short[0]
        raise BaselineIncomplete(
            f"numba {what} baseline: worker {i} reached its work bound of {each} {unit} after "
            f"{int(out[i, 0])} of its {n_each} excursions ({len(short)} of {len(out)} workers stopped short; "
            f"raise max_work, or the baseline is broken)", out)
    n_trunc = int(out[:, TRUNC].sum())
    if n_trunc:
        from .api import DryfricWarning

        warnings.warn(f"numba {what} baseline: {n_trunc} excursions reached max_steps and were closed without "
                      f"entering the sums", DryfricWarning, stacklevel=3)
    return out, int(out[:, STEPS].sum())


def sums(out) -> dict:
    """The workers' rows (:func:`run_numba`, :func:`run_numba_pdmp`) as one dict of sums, which
    :func:`dryfric_jax.estimators.long_excursion_estimates` takes (nondimensional units)."""
    total = np.asarray(out)[:, :len(SUMS)].sum(axis=0)
    return dict(zip(SUMS, map(float, total)), t_half=0.0)


@numba.njit(nogil=True, cache=False)
def _worker(g, n_exc, max_steps, max_work, h, gb, itl, m1, m2, L11, L21, L22, P, M, x0):
    """``n_exc`` long excursions drawn from the Generator ``g``, in at most ``max_work`` steps; returns
    the sums (:data:`SUMS`), then :data:`TAIL`.  An excursion reaching ``max_steps`` steps is closed,
    counted and left out of the sums, and the worker seeks again (as the engine does).

    P, M: (c1, c2, a1, a2, a_sq) of C_+ and C_-.
    """
    X, V, U, n, phase = x0, 0.0, 0.0, 0, SEEK
    cnt = 0
    acc = np.zeros(len(SUMS) + len(TAIL))
    useful = trunc = work = 0
    while cnt < n_exc and work < max_work:
        work += 1
        z1 = g.standard_normal()
        z2 = g.standard_normal()
        Xi = X * m1 + L11 * z1
        Xn = X * m2 + L21 * z1 + L22 * z2
        w = V + h * (gb - V * itl + Xi)
        Vn = math.copysign(max(abs(w) - h, 0.0), w)
        heads = False
        if V == 0.0:
            S = M if phase == PLUS else P
            released = Vn < 0.0 if phase == PLUS else Vn > 0.0
            if released and S[0] <= X <= S[1]:
                za = z1 * S[2] + z2 * S[3]
                d1, d2 = X - S[0], X - S[1]
                logr = min(-d1 * za - 0.5 * d1 * d1 * S[4], -d2 * za - 0.5 * d2 * d2 * S[4])
                u = g.random()  # the coin's uniform, drawn only when a coin is flipped
                heads = math.log(u) < logr if u > 0.0 else True
        if heads and phase == MINUS:
            cnt += 1
            _add(acc, U, n * h)
        if heads and phase != PLUS:
            U, n, phase = 0.0, 0, PLUS
        elif heads:
            phase = MINUS
        if phase != SEEK:
            U += 0.5 * h * (V + Vn)
            n += 1
            useful += 1
        X, V = Xn, Vn
        if n >= max_steps:
            trunc += 1
            U, n, phase = 0.0, 0, SEEK
    acc[STEPS], acc[TRUNC], acc[WORK] = useful, trunc, work
    return acc


def run_numba(model, n_excursions: int, threads: int, seed: int = 0, max_steps: int = 10**9,
              max_work: float = MAX_WORK):
    """Run the DI baseline on ``threads`` threads, ``ceil(n_excursions / threads)`` excursions each, in
    at most ``max_work`` steps in all (``max_work / threads`` each; the engine's default bound);
    returns (one row per worker: :data:`SUMS` then :data:`TAIL`, useful steps).  Raises
    :class:`BaselineIncomplete` where a worker reached its bound first."""
    max_steps = check_count("max_steps", max_steps, 1, hi=MAX_STEPS)
    each = _work_each(threads, max_work)
    f = lambda v: float(np.asarray(v))
    sset = lambda s: np.array([f(s.c1), f(s.c2), f(s.a1), f(s.a2), f(s.a_sq)])
    o = model.ou
    out = _on_threads(_worker, seed, threads, n_excursions,
                      (max_steps, each, f(model.h), f(model.gamma_bar), f(model.inv_tau_L), f(o.m1), f(o.m2),
                       f(o.L11), f(o.L21), f(o.L22), sset(model.plus), sset(model.minus), f(model.x_plus)))
    return _finished(out, n_excursions, threads, each, "DI", "steps")


# ---- PDMP: the same event algorithm as dryfric_jax.pdmp, long excursions s+ -> s- -> s+ ----
@numba.njit(nogil=True, cache=False)
def _pdmp_worker(g, n_exc, max_work, N, kp, km, delta, c_alpha, rate, kappa, r_p, r_m):
    """``n_exc`` long excursions drawn from the Generator ``g``, in at most ``max_work`` events;
    returns the sums (:data:`SUMS`), then :data:`TAIL`.  It starts on s_+ and seeks nothing, so every
    event is in an excursion (the events are the work) and none is truncated: the work bound is the
    only one (a per-excursion bound cost ~10% of its speed, one core)."""
    k, y, v = kp + 1, 1, 0.0
    U, T, phase = 0.0, 0.0, PLUS
    cnt = 0
    acc = np.zeros(len(SUMS) + len(TAIL))
    events = 0
    while cnt < n_exc and events < max_work:
        u1 = 1.0 - g.random()
        u2 = g.random()
        a = 0.0
        t_star = math.inf
        if y != 0:
            a = ((k - kp) * delta + r_p) if y > 0 else ((k - km) * delta + r_m)
            if (y > 0 and a < 0.0) or (y < 0 and a > 0.0):
                sig = -v / a
                x = kappa * sig
                t_star = sig * (math.log1p(x) / x if x > 0.0 else 1.0)
        e = -math.log(u1) / rate
        jump = e < t_star
        dt = e if jump else t_star
        if y != 0:
            z = -kappa * dt
            p1 = math.expm1(z) / z if z != 0.0 else 1.0
            if abs(z) < 0.01:
                p2 = 0.5 + z * (1 / 6 + z * (1 / 24 + z * (1 / 120 + z * (1 / 720 + z / 5040))))
            else:
                p2 = (math.expm1(z) - z) / (z * z)
            U += v * dt + (a - kappa * v) * dt * dt * p2
            vn = v + (a - kappa * v) * dt * p1 if jump else 0.0
        else:
            vn = 0.0
        T += dt
        events += 1
        to_plus = to_minus = False
        if jump:
            alpha = 0.0 if k >= N else (1.0 if k <= -N else 0.5 - c_alpha * k)
            kn = k + 1 if u2 < alpha else k - 1
            if y == 0:
                to_plus, to_minus = kn == kp + 1, kn == km - 1
                y = 1 if kn > kp else (-1 if kn < km else 0)
            k = kn
        else:
            to_plus, to_minus = (y == -1 and k == kp + 1), (y == 1 and k == km - 1)
            y = 1 if k > kp else (-1 if k < km else 0)
        v = vn
        if phase == PLUS and to_minus:
            phase = MINUS
        elif phase == MINUS and to_plus:
            cnt += 1
            _add(acc, U, T)
            U, T, phase = 0.0, 0.0, PLUS
    acc[STEPS], acc[WORK] = events, events
    return acc


def run_numba_pdmp(model, n_excursions: int, threads: int, seed: int = 0, max_work: float = MAX_WORK):
    """The PDMP baseline on ``threads`` threads, in at most ``max_work`` events in all, as
    :func:`run_numba`; returns (rows as in :func:`run_numba`, events)."""
    each = _work_each(threads, max_work)
    f = lambda v: float(np.asarray(v))
    i = lambda v: int(np.asarray(v))
    out = _on_threads(_pdmp_worker, seed, threads, n_excursions,
                      (each, i(model.N), i(model.kp), i(model.km), f(model.delta), f(model.c_alpha),
                       f(model.rate), f(model.inv_tau_L), f(model.r_p), f(model.r_m)))
    return _finished(out, n_excursions, threads, each, "PDMP", "events")
