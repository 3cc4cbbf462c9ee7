"""Compiled scalar baseline for the benchmark: the same DI chain and regeneration rule as
:mod:`dryfric_jax.excursions`, one excursion after another in a numba loop, one worker per thread.

numba is an optional extra (``pip install -e ".[bench]"``); it is never imported by the package.
"""
from __future__ import annotations

import math

import numba
import numpy as np

SEEK, PLUS, MINUS = 0, 1, 2


@numba.njit(cache=False)
def _worker(seed, n_exc, max_steps, h, gb, itl, m1, m2, L11, L21, L22, P, M, x0):
    """``n_exc`` long excursions; returns (count, sum U, sum U^2, sum t, useful steps).

    P, M: (c1, c2, a1, a2, a_sq) of C_+ and C_-.
    """
    np.random.seed(seed)
    X, V, U, n, phase = x0, 0.0, 0.0, 0, SEEK
    cnt = 0
    sU = sU2 = st = 0.0
    useful = 0
    while cnt < n_exc:
        z1 = np.random.standard_normal()
        z2 = np.random.standard_normal()
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
                u = np.random.random()  # the coin's uniform, drawn only when a coin is flipped
                heads = math.log(u) < logr if u > 0.0 else True
        if heads and phase == MINUS:
            cnt += 1
            t = n * h
            sU += U
            sU2 += U * U
            st += t
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
            U, n, phase = 0.0, 0, SEEK
    return cnt, sU, sU2, st, useful


@numba.njit(parallel=True, cache=False)
def _run(seeds, n_exc, max_steps, h, gb, itl, m1, m2, L11, L21, L22, P, M, x0):
    k = seeds.shape[0]
    out = np.zeros((k, 5))
    for i in numba.prange(k):
        c, a, b, t, s = _worker(seeds[i], n_exc, max_steps, h, gb, itl, m1, m2, L11, L21, L22, P, M, x0)
        out[i, 0], out[i, 1], out[i, 2], out[i, 3], out[i, 4] = c, a, b, t, s
    return out


def run_numba(model, n_excursions: int, threads: int, seed: int = 0, max_steps: int = 10**9):
    """Run the baseline with ``threads`` workers; returns (sums array, useful steps)."""
    f = lambda v: float(np.asarray(v))
    sset = lambda s: np.array([f(s.c1), f(s.c2), f(s.a1), f(s.a2), f(s.a_sq)])
    numba.set_num_threads(threads)
    seeds = np.arange(threads, dtype=np.int64) + 1000 * seed
    o = model.ou
    out = _run(seeds, -(-n_excursions // threads), max_steps, f(model.h), f(model.gamma_bar), f(model.inv_tau_L),
               f(o.m1), f(o.m2), f(o.L11), f(o.L21), f(o.L22), sset(model.plus), sset(model.minus), f(model.x_plus))
    return out, int(out[:, 4].sum())


# ---- PDMP: the same event algorithm as dryfric_jax.pdmp, long excursions s+ -> s- -> s+ ----
@numba.njit(cache=False)
def _pdmp_worker(seed, n_exc, N, kp, km, delta, c_alpha, rate, kappa, r_p, r_m):
    """``n_exc`` long excursions; returns (count, sum U, sum U^2, sum t, events)."""
    np.random.seed(seed)
    k, y, v = kp + 1, 1, 0.0
    U, T, phase = 0.0, 0.0, PLUS
    cnt = 0
    sU = sU2 = st = 0.0
    events = 0
    while cnt < n_exc:
        u1 = 1.0 - np.random.random()
        u2 = np.random.random()
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
            sU += U
            sU2 += U * U
            st += T
            U, T, phase = 0.0, 0.0, PLUS
    return cnt, sU, sU2, st, events


@numba.njit(parallel=True, cache=False)
def _run_pdmp(seeds, n_exc, N, kp, km, delta, c_alpha, rate, kappa, r_p, r_m):
    k = seeds.shape[0]
    out = np.zeros((k, 5))
    for i in numba.prange(k):
        c, a, b, t, s = _pdmp_worker(seeds[i], n_exc, N, kp, km, delta, c_alpha, rate, kappa, r_p, r_m)
        out[i, 0], out[i, 1], out[i, 2], out[i, 3], out[i, 4] = c, a, b, t, s
    return out


def run_numba_pdmp(model, n_excursions: int, threads: int, seed: int = 0):
    """PDMP baseline with ``threads`` workers; returns (sums array, events)."""
    f = lambda v: float(np.asarray(v))
    i = lambda v: int(np.asarray(v))
    numba.set_num_threads(threads)
    seeds = np.arange(threads, dtype=np.int64) + 1000 * seed
    out = _run_pdmp(seeds, -(-n_excursions // threads), i(model.N), i(model.kp), i(model.km), f(model.delta),
                    f(model.c_alpha), f(model.rate), f(model.inv_tau_L), f(model.r_p), f(model.r_m))
    return out, int(out[:, 4].sum())
