r"""Path scenes of the DI: the velocity (and displacement) of many independent paths on a time grid.

The D estimator stores no paths; the figures of the paper's section 7 do (histograms, first
moment, correlation, displacement paths).  Each path is one lane of the DI chain
(:mod:`dryfric_jax.di`): ``split`` per path, ``fold_in`` per recorded segment.  Everything is
nondimensional (:math:`\tau_0, u_0`); times are in steps of the model's h.

* :func:`di_transient`: paths from :math:`V_0 = v_0` with :math:`X_0 \sim \mathcal N(0, 1/\tau')`
  (stationary noise), V recorded after the given step counts (paper Figs. 6, Table 1);
* :func:`di_stationary`: paths after a burn-in, V and U recorded every ``every`` steps (Figs. 5, 7).
"""
from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from .di import DIModel


def _advance(model: DIModel, carry, key, n_steps: int):
    """``n_steps`` DI steps of one path; U accumulates in float64 (trapezoid)."""
    dt = model.h.dtype
    h64 = model.h.astype(jnp.float64)
    z = jax.random.normal(key, (n_steps, 2), dt)

    def step(c, zz):
        X, V, U = c
        Xi, Xn = model.ou.sample(X, zz[0], zz[1])
        Vn = model.step(V, Xi)
        return (Xn, Vn, U + 0.5 * h64 * (V.astype(jnp.float64) + Vn.astype(jnp.float64))), None

    return jax.lax.scan(step, carry, z)[0]


def _stationary_sd(model: DIModel):
    """Standard deviation of the stationary law of the discrete X chain (1/sqrt(tau') exactly)."""
    return jnp.sqrt((model.ou.L21**2 + model.ou.L22**2) / (1.0 - model.ou.m2**2))


@partial(jax.jit, static_argnames=("segments",))
def _transient(model, keys, x0, v0, *, segments):
    def path(key, x):
        c = (x, jnp.asarray(v0, model.h.dtype), jnp.asarray(0.0, jnp.float64))
        out = []
        for i, n in enumerate(segments):  # few, static: unrolled
            c = _advance(model, c, jax.random.fold_in(key, i), n) if n else c
            out.append(c[1])
        return jnp.stack(out)

    return jax.vmap(path)(keys, x0)


def di_transient(model: DIModel, key, n_paths: int, record_steps, v0: float = 1.0, chunk: int = 8192):
    """V after each of ``record_steps`` (increasing step counts) for ``n_paths`` paths from
    :math:`(X_0, V_0) = (\\mathcal N(0, 1/\\tau'), v_0)`.  Returns ``(n_paths, len(record_steps))``."""
    steps = [int(s) for s in record_steps]
    if any(b < a for a, b in zip(steps, steps[1:])) or steps[0] < 0:
        raise ValueError(f"record_steps must be non-negative and increasing (got {record_steps})")
    segments = tuple(np.diff([0] + steps).tolist())
    sd = _stationary_sd(model)
    out = []
    for c in range(-(-n_paths // chunk)):
        m = min(chunk, n_paths - c * chunk)
        kx, kp = jax.random.split(jax.random.fold_in(key, c))
        x0 = sd * jax.random.normal(kx, (m,), model.h.dtype)
        out.append(np.asarray(_transient(model, jax.random.split(kp, m), x0, v0, segments=segments)))
    return np.concatenate(out)


@partial(jax.jit, static_argnames=("n_records", "every", "burn"))
def _stationary(model, keys, *, n_records, every, burn):
    def path(key):
        dt = model.h.dtype
        x0 = jax.random.normal(jax.random.fold_in(key, n_records + 1), (), dt) * _stationary_sd(model)
        c = (x0, jnp.asarray(0.0, dt), jnp.asarray(0.0, jnp.float64))
        if burn:
            c = _advance(model, c, jax.random.fold_in(key, n_records), burn)
        c = (c[0], c[1], jnp.asarray(0.0, jnp.float64))  # U counted from the end of the burn-in

        def rec(cc, i):
            cc = _advance(model, cc, jax.random.fold_in(key, i), every)
            return cc, (cc[1], cc[2])

        _, (V, U) = jax.lax.scan(rec, c, jnp.arange(n_records))
        return V, U

    return jax.vmap(path)(keys)


def di_stationary(model: DIModel, key, n_paths: int, n_records: int, every: int = 1, burn_steps: int = 0):
    """V and U (from the end of the burn-in) every ``every`` steps: two ``(n_paths, n_records)``
    arrays.  The noise starts stationary; ``burn_steps`` lets the velocity relax too."""
    V, U = _stationary(model, jax.random.split(key, n_paths), n_records=int(n_records), every=int(every),
                       burn=int(burn_steps))
    return np.asarray(V), np.asarray(U)


def autocovariance(V: np.ndarray, max_lag: int) -> tuple[np.ndarray, np.ndarray]:
    r"""Stationary autocovariance :math:`\langle V(t)V(t+k)\rangle` (not centred: the paper's pure
    dry friction case has mean 0) and its standard error over paths, by FFT per path.

    ``V`` is ``(paths, samples)``; returns two arrays of length ``max_lag + 1``.
    """
    n = V.shape[1]
    f = np.fft.rfft(V, 2 * n, axis=1)
    acf = np.fft.irfft(f * np.conj(f), axis=1)[:, : max_lag + 1] / (n - np.arange(max_lag + 1))
    return acf.mean(0), acf.std(0, ddof=1) / np.sqrt(V.shape[0])
