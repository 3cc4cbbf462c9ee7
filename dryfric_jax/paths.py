r"""Path scenes of the DI: the velocity (and displacement) of many independent paths on a time grid.

The D estimator stores no paths; the figures of the paper's section 7 do (histograms, first
moment, correlation, displacement paths).  Each path is one lane of the DI chain
(:mod:`dryfric_jax.di`): ``split`` per path, ``fold_in`` per recorded segment.  Everything is
nondimensional (:math:`\tau_0, u_0`); times are in steps of the model's h.

* :func:`di_transient`: paths from :math:`V_0 = v_0` with :math:`X_0 \sim \mathcal N(0, 1/\tau')`
  (stationary noise), V recorded after the given step counts (paper Figs. 6, Table 1);
* :func:`di_stationary`: paths after a burn-in, V and U recorded every ``every`` steps (Figs. 4, 5, 7);
* :func:`pdmp_stationary`: the PDMP's V on a time grid after a burn-in (Fig. 4);
* :func:`di_long_excursion`: one of the paper's long excursions step by step, from release to release (Figs.
  1-2; the PDMP's is :func:`~dryfric_jax.pdmp.excursion_skeleton`).
"""
from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from . import rng
from .api import _key, duration_text
from .di import DIModel
from .excursions import BLOCK, block_keys
from .params import check_finite, check_positive, rounded_bound, shown
from .limits import MAX_WORK, refuse_known_work
from .plan import MAX_COUNT, check_count, check_max_work
from .durations import released
from .pdmp import check_pdmp_model, flow
from .sharding import over_lanes


def _check_model(model) -> None:
    if not isinstance(model, DIModel):
        raise ValueError(f"model must be a DIModel, from dryfric_jax.make_di_model(params, h) "
                         f"(got {type(model).__name__})")
    if not float(model.ou.m2) < 1.0:  # float32 at h/tau < 6e-8: X a random walk, its stationary sd inf
        raise ValueError(f"model must have a noise decay exp(-h/tau) < 1 in its dtype (got {float(model.ou.m2)!r} in "
                         f"{model.h.dtype}: h/tau is below its resolution); build it with dtype float64")


def _record_steps(record_steps) -> list:
    """``record_steps`` as a list of ints; ``ValueError`` naming it unless it is a non-empty sequence
    of non-negative integers in non-decreasing order."""
    try:
        steps = list(record_steps)
    except TypeError:
        steps = None
    if not steps or any(isinstance(s, (bool, np.bool_)) or not isinstance(s, (int, np.integer)) for s in steps) \
            or any(s < 0 for s in steps) or any(b < a for a, b in zip(steps, steps[1:])):
        raise ValueError("record_steps must be a non-empty sequence of non-negative integers in non-decreasing "
                         f"order (step counts at which V is recorded) (got {shown(record_steps)})")
    if len(steps) > MAX_RECORD_TIMES:
        raise ValueError(f"record_steps must hold at most {MAX_RECORD_TIMES} step counts (got {len(steps)}): each "
                         "is compiled as a segment of its own (50 took 52 s to compile, 5000 did not finish: an "
                         "audit); for a fine time grid use di_stationary's records")
    return [int(s) for s in steps]


#: the most record times of :func:`di_transient` (Table 1 has 6, Fig. 6 3)
MAX_RECORD_TIMES = 32
#: the most records of :func:`di_stationary`: record i's numbers come from ``fold_in(path_key, i)`` and the
#: burn-in's from ``fold_in(path_key, n_records)``, counted in 32 bits (2^32 - 1 was an OverflowError)
MAX_RECORDS = 2**32 - 2


#: the most values one recorded array holds (n_paths x records): 2 GiB in float64; the paper's largest, Fig. 5's
#: histogram, is 4096 x 40,000 = 1.6e8.  Past it a MemoryError came from numpy after RSS passed 8 GB (an audit)
MAX_RECORDED = 2**28


def _check_recorded(n_paths: int, n_records: int) -> None:
    if n_paths * n_records > MAX_RECORDED:
        raise ValueError(f"n_paths x records must be at most 2^28 = {MAX_RECORDED} values per recorded array (each "
                         f"value 8 bytes: 2 GiB; got {n_paths} x {n_records} = {n_paths * n_records:.3g}): record "
                         "fewer paths or times, or run several seeds")


def _check_path_work(n_paths: int, steps: int, max_work) -> None:
    """Refuse (``ValueError``) ``n_paths`` paths of ``steps`` steps each beyond ``max_work`` lane-steps (default
    :data:`~dryfric_jax.limits.MAX_WORK`, the estimator's): 10^12 paths ran on and on (an audit).  The paper's
    largest path scene, Table 1, is 1.25e10."""
    max_work = check_max_work(max_work)
    work = float(n_paths) * float(steps)
    refuse_known_work(work, max_work, "lane-steps", f"{n_paths} paths of {steps} steps",
                      "lower n_paths or the steps, or raise max_work",
                      hint=f"; at ~1e8 lane-steps/s on 2 CPU cores that is {duration_text(work / 1e8)}")


#: the longest stretch of steps between records: its numbers are one draw of 2 per step, counted in uint32
MAX_SEGMENT = 2**31 - 1
SEGMENT_WHY = " (steps between records: their normals are counted in 32 bits)"


def _segment(model: DIModel, carry, keys, n_steps: int, block: int = BLOCK):
    """``n_steps`` DI steps of every lane (``carry = (X, V, U)``, arrays over lanes; U in float64,
    trapezoid).  Lane l's step j uses row j of ``rng.normal(keys[l], (n_steps, 2))``,
    drawn a block of rows at a time for all lanes (:func:`dryfric_jax.rng.normals` with
    ``start``): the numbers of the per-path definition, without holding a segment's numbers
    in memory.  Keys of another generator draw the segment at once."""
    dt = model.h.dtype
    if not rng.is_threefry(keys):
        block = n_steps
    if n_steps > MAX_SEGMENT:  # the public functions name their argument first
        raise ValueError(f"a recorded segment must have fewer than 2**31 steps (got {n_steps})")

    def run(c, start, size):
        z1, z2 = rng.normals(keys, size, 2, dt, start=start)

        def step(i, c2):
            X, V, U = c2
            _, Xn, Vn, dU = model.move(X, V, z1[i], z2[i])
            return Xn, Vn, U + dU

        return jax.lax.fori_loop(0, size, step, c)

    n_blocks, rest = divmod(n_steps, block)
    if n_blocks == 1 and rest == 0:
        return run(carry, None, block)
    carry = jax.lax.fori_loop(0, n_blocks, lambda b, c: run(c, b * block, block), carry)
    return run(carry, n_blocks * block, rest) if rest else carry


def _transient(model, keys, x0, v0, *, segments):
    c = (x0, jnp.full(x0.shape, v0, model.h.dtype), jnp.zeros(x0.shape, jnp.float64))
    out = []
    for i, n in enumerate(segments):  # few, static: unrolled
        c = _segment(model, c, block_keys(keys, i), n) if n else c
        out.append(c[1])
    return jnp.stack(out, axis=1)


def di_transient(model: DIModel, key, n_paths: int, record_steps, v0: float = 1.0, chunk: int = 8192,
                 max_work: float = MAX_WORK):
    """V after each of ``record_steps`` (non-decreasing step counts) for ``n_paths`` paths from
    :math:`(X_0, V_0) = (\\mathcal N(0, 1/\\tau'), v_0)`.  Returns ``(n_paths, len(record_steps))``.

    Path p of chunk c has key ``split(fold_in(key, c)[1])[p]``; its segment i (up to
    ``record_steps[i]``) uses ``rng.normal(fold_in(path_key, i), (steps, 2))``.  ``key`` is
    a ``jax.random`` key or an integer seed in [0, 2^62] (as :func:`~dryfric_jax.estimate_diffusivity`
    takes it); ``n_paths`` and ``chunk`` are integers >= 1; at most :data:`MAX_RECORD_TIMES` record steps; the
    lane-steps ``n_paths`` x the last record step at most ``max_work`` (default 1e11, as the estimator's).
    ``ValueError`` naming the argument."""
    _check_model(model)
    key = _key(key)[0]
    n_paths, chunk = check_count("n_paths", n_paths, 1), check_count("chunk", chunk, 1)
    steps = _record_steps(record_steps)
    _check_path_work(n_paths, steps[-1], max_work)
    _check_recorded(n_paths, len(steps))
    check_finite("v0", v0)
    v0 = float(v0)
    segments = tuple(np.diff([0] + steps).tolist())
    if max(segments) > MAX_SEGMENT:
        raise ValueError(f"record_steps must be at most {MAX_SEGMENT} apart{SEGMENT_WHY} "
                         f"(got a gap of {max(segments)})")
    sd = model.ou.stationary_sd()  # finite: _check_model refuses m2 = 1
    out = []
    for c in range(-(-n_paths // chunk)):
        m = min(chunk, n_paths - c * chunk)
        kx, kp = jax.random.split(jax.random.fold_in(key, c))
        x0 = sd * jax.random.normal(kx, (m,), model.h.dtype)
        args = (model, jax.random.split(kp, m), x0, jnp.asarray(v0, model.h.dtype))
        out.append(np.asarray(over_lanes(_transient, args, (False, True, True, False), segments=segments)))
    return np.concatenate(out)


def _stationary(model, keys, *, n_records, every, burn, record="VU"):
    dt = model.h.dtype
    x0 = jax.vmap(lambda k: jax.random.normal(jax.random.fold_in(k, n_records + 1), (), dt))(keys)
    c = (x0 * model.ou.stationary_sd(), jnp.zeros(x0.shape, dt), jnp.zeros(x0.shape, jnp.float64))
    if burn:
        c = _segment(model, c, block_keys(keys, n_records), burn)
    c = (c[0], c[1], jnp.zeros(x0.shape, jnp.float64))  # U counted from the end of the burn-in

    def rec(cc, i):  # only the recorded arrays are stacked: Fig. 5's 4096 x 40,000 V alone is 1.3 GB
        cc = _segment(model, cc, block_keys(keys, i), every)
        return cc, tuple(cc[1 + "VU".index(r)] for r in record)

    _, out = jax.lax.scan(rec, c, jnp.arange(n_records))
    return tuple(o.T for o in out)


#: what :func:`di_stationary` records: V and U, V only, or U only
RECORDS = ("VU", "V", "U")


def di_stationary(model: DIModel, key, n_paths: int, n_records: int, every: int = 1, burn_steps: int = 0,
                  max_work: float = MAX_WORK, record: str = "VU"):
    """V and U (from the end of the burn-in) every ``every`` steps: two ``(n_paths, n_records)``
    arrays.  The noise starts stationary; ``burn_steps`` lets the velocity relax too.  ``record``
    ``"V"`` or ``"U"`` returns the other as None and never holds it: the same numbers for half
    the memory (Fig. 5's histogram needs V only; with both it peaked at 5.5 GB).

    Path p has key ``split(key)[p]``; its burn-in uses ``rng.normal(fold_in(path_key,
    n_records), (burn_steps, 2))``, record i the numbers of ``fold_in(path_key, i)``.  ``key`` is a
    ``jax.random`` key or an integer seed in [0, 2^62]; ``n_paths``, ``n_records`` and ``every`` are
    integers >= 1 (``n_records`` <= :data:`MAX_RECORDS`; ``every`` and ``burn_steps`` <= 2^31 - 1,
    :data:`MAX_SEGMENT`; ``burn_steps`` >= 0); the lane-steps ``n_paths`` x (``burn_steps`` + ``n_records`` x
    ``every``) at most ``max_work`` (default 1e11, as the estimator's).  ``ValueError`` naming the argument."""
    _check_model(model)
    key = _key(key)[0]
    n_paths = check_count("n_paths", n_paths, 1)
    n_records = check_count("n_records", n_records, 1, MAX_RECORDS, " (records are folded into the keys in 32 bits)")
    every = check_count("every", every, 1, MAX_SEGMENT, SEGMENT_WHY)
    burn_steps = check_count("burn_steps", burn_steps, 0, MAX_SEGMENT, SEGMENT_WHY)
    _check_path_work(n_paths, burn_steps + n_records * every, max_work)
    if not isinstance(record, str) or record not in RECORDS:
        raise ValueError(f"record must be one of 'VU', 'V' or 'U' (got {shown(record)})")
    _check_recorded(n_paths, n_records)
    out = list(over_lanes(_stationary, (model, jax.random.split(key, n_paths)), (False, True),
                          n_records=n_records, every=every, burn=burn_steps, record=record))
    for i in range(len(out)):  # each device array released as soon as it is on the host
        out[i] = np.asarray(out[i])
    got = dict(zip(record, out))
    return got.get("V"), got.get("U")


def autocovariance(V: np.ndarray, max_lag: int, center: bool = False) -> tuple[np.ndarray, np.ndarray]:
    r"""Stationary autocovariance :math:`\langle V(t)V(t+k)\rangle` and its standard error over
    paths, by FFT per path.  ``center=True`` subtracts the grand mean first (Cov, the paper's
    :math:`h(\rho)`); the pure dry friction case has mean 0 and uses the raw moment.

    ``V`` is ``(paths, samples)``, finite, with at least 2 paths (the standard error is their
    spread); returns two arrays of length ``max_lag + 1``, ``max_lag`` an integer in
    [0, samples - 1].
    """
    V, max_lag = _acf_args(V, max_lag, center)
    acf = _per_path_acf(V, max_lag, center)
    return acf.mean(0), acf.std(0, ddof=1) / np.sqrt(V.shape[0])


#: largest |V| the autocovariance takes: its products (V^2) and their spread (V^4, the SE) stay inside float64
ACF_MAX_ABS = 1e75


def _acf_args(V, max_lag, center):
    """``(V as a float64 array, max_lag as an int)``; ``ValueError`` naming the argument that is wrong
    (a max_lag beyond the series gave numpy's broadcast error, -1 an IndexError, one path an
    all-NaN standard error)."""
    try:
        a = None if isinstance(V, (str, bytes)) else np.asarray(V)
    except Exception:  # noqa: BLE001  (a ragged list, say)
        a = None
    if a is None or a.dtype.kind not in "iuf" or a.ndim != 2 or a.shape[0] < 2 or a.shape[1] < 1:
        what = f"an array of shape {a.shape} and dtype {a.dtype}" if a is not None else shown(V)
        raise ValueError(f"V must be a real array of shape (paths, samples) with at least 2 paths (the standard "
                         f"error is their spread) and 1 sample (got {what})")
    if not np.all(np.isfinite(a)):
        raise ValueError("V must be finite (got a NaN or an inf)")
    top = float(np.max(np.abs(a))) if a.size else 0.0
    if top > ACF_MAX_ABS:  # products of 1e200s overflowed to inf and NaN, silently
        raise ValueError(f"V must have |V| <= {ACF_MAX_ABS:g} (its products overflow float64; got |V| up to "
                         f"{top:.3g}): rescale it")
    lag = check_count("max_lag", max_lag, 0, a.shape[1] - 1, " (samples - 1 of V)")
    if not isinstance(center, (bool, np.bool_)):
        raise ValueError(f"center must be True or False (got {shown(center)})")
    return a.astype(np.float64), lag


def _per_path_acf(V, max_lag, center):
    if center:
        V = V - V.mean()
    n = V.shape[1]
    f = np.fft.rfft(V, 2 * n, axis=1)
    return np.fft.irfft(f * np.conj(f), axis=1)[:, : max_lag + 1] / (n - np.arange(max_lag + 1))


def autocorrelation(V: np.ndarray, max_lag: int, center: bool = True) -> tuple[np.ndarray, np.ndarray]:
    r"""Normalised autocovariance :math:`r(k) = \bar c(k)/\bar c(0)` (the paper's :math:`h(\rho)/h(0)`,
    Fig. 4) and its standard error, a ratio estimator over paths:

    .. math::
        \mathrm{SE}\,r(k) = \frac{\operatorname{sd}_i\big(c_i(k) - r(k)\,c_i(0)\big)}{\sqrt{n}\;\bar c(0)},

    :math:`c_i` the FFT autocovariance of path i (delta method).  ``se(c(k))/c(0)`` ignores that
    :math:`c_i(k)` and :math:`c_i(0)` move together from path to path: it overstated the SE by up
    to ~20x at short lags, where r is close to 1.  Arguments as :func:`autocovariance`'s; the
    series must not be constant (r is c(k)/c(0)).
    """
    V, max_lag = _acf_args(V, max_lag, center)
    acf = _per_path_acf(V, max_lag, center)
    a, b = acf.mean(0), acf[:, 0].mean()
    if not b > 0:
        raise ValueError("V must vary: its mean autocovariance at lag 0 is 0, and r(k) = c(k)/c(0) is undefined")
    r = a / b
    resid = acf - r[None, :] * acf[:, :1]
    return r, resid.std(0, ddof=1) / (np.sqrt(V.shape[0]) * b)


#: largest ``max_steps`` of :func:`di_long_excursion`: its three buffers of max_steps + 1 states are allocated
#: whole, 1.6 GB at this bound (2^31 - 1 passed 6 GB in 5 s and was killed: an audit)
MAX_EXCURSION_STEPS = 2**26


@partial(jax.jit, static_argnames=("max_steps",))
def _long_excursion(model: DIModel, key, max_seek, *, max_steps: int):
    """The loop of :func:`di_long_excursion`: returns the recorded states' last index n, the phase (4: complete,
    5: stopped by ``max_steps``; below 2: the seek ran out), i_half, the buffers.  V before the first step is NaN,
    "not stuck", so the first step is no release, as in the count's lanes (:func:`~dryfric_jax.durations._lane_start`:
    a V_{-1} of 0 made a move at step 0 one, starting 8-18% of the seeds' excursions elsewhere: a review)."""
    dt = model.h.dtype
    buf = dict(X=jnp.zeros(max_steps + 1, dt), V=jnp.zeros(max_steps + 1, dt), U=jnp.zeros(max_steps + 1))
    k_start, k_steps = jax.random.split(key)
    x0 = model.ou.stationary_sd() * jax.random.normal(k_start, (), dt)
    put = lambda bb, j, vals: {k: bb[k].at[j].set(vals[k]) for k in bb}  # noqa: E731

    def cond(c):
        i, phase = c[0], c[2]
        # phase 0: seeking a release towards V < 0; 1: then one towards V > 0 (the start); 2: +HLE; 3: -HLE;
        # 4: done; 5: stopped by max_steps.  The seek (phases 0, 1) is bounded by max_seek steps, the HLEs by
        # the buffers (max_steps recorded steps)
        return (phase < 4) & ((phase >= 2) | (i < max_seek))

    def body(c):
        i, n, phase, n_half, X, V, V_prev, U, b = c
        z1, z2 = model.draw(jax.random.fold_in(k_steps, i.astype(jnp.uint32)), 1)
        _, Xn, Vn, dU = model.move(X, V, z1[0], z2[0])
        release = released(V_prev == 0, V, Vn)
        up, down = release & (Vn > 0), release & (Vn < 0)
        start = (phase == 1) & up
        # the start's step records the state before it (index 0, U = 0) and after it (index 1); in the HLEs each
        # step records the state after it, the end's too (the release that starts the next +HLE)
        b = jax.lax.cond(start, lambda bb: put(bb, 0, dict(X=X, V=V, U=0.0)), lambda bb: bb, b)
        U = jnp.where(start, 0.0, U) + dU
        rec = start | (phase == 2) | (phase == 3)
        full = rec & (n + 1 > max_steps)
        rec = rec & ~full
        b = jax.lax.cond(rec, lambda bb: put(bb, n + 1, dict(X=Xn, V=Vn, U=U)), lambda bb: bb, b)
        n_half = jnp.where((phase == 2) & down & ~full, n, n_half)  # the state before the release towards V < 0
        phase = jnp.where(full, 5, jnp.where((phase == 0) & down, 1, jnp.where(start, 2, jnp.where(
            (phase == 2) & down, 3, jnp.where((phase == 3) & up, 4, phase)))))
        return i + 1, n + rec, phase, n_half, Xn, Vn, V, U, b

    z = jnp.asarray(0.0, dt)
    init = (jnp.asarray(0, jnp.int64), jnp.asarray(0, jnp.int64), jnp.asarray(0), jnp.asarray(-1, jnp.int64),
            x0, z, jnp.asarray(jnp.nan, dt), jnp.asarray(0.0, jnp.float64), buf)
    _, n, phase, n_half, *_, b = jax.lax.while_loop(cond, body, init)
    return n, phase, n_half, b


#: the default bound of :func:`di_long_excursion`'s seek for a start, in units of ``max_steps``
SEEK_FACTOR = 50


def di_long_excursion(model: DIModel, key, max_steps: int = 200_000, max_seek: int | None = None) -> dict:
    r"""One of the paper's long excursions of the DI (section 6.1, Figs. 1-2), step by step: a +HLE from a
    release towards :math:`V > 0` to the first release towards :math:`V < 0`, then the -HLE to the next release
    towards :math:`V > 0`.

    A *release* is the rule of :mod:`dryfric_jax.durations`: step n releases the particle when it was stuck a
    whole step and then moves,

    .. math::
        V_{n-1} = V_n = 0 \ne V_{n+1}, \qquad \text{towards } \operatorname{sign}(V_{n+1}),

    so that a V passing through 0 for one step is not one.  In continuous time a release towards
    :math:`V > 0` happens only where X crosses :math:`x_{\Delta}` (the state is then :math:`(x_{\Delta}, 0)`),
    one towards :math:`V < 0` only at :math:`x_{-\Delta}`; an HLE therefore ends where the direction of release
    changes.  This is not the D estimator's Nummelin cycle (C_+ to C_- to C_+, cut by a coin:
    :mod:`dryfric_jax.regeneration`), which spans a random number >= 1 of these long excursions.

    The chain (:meth:`~dryfric_jax.di.DIModel.move`) starts as the durations count's lanes do: X from its stationary
    law, :math:`V_0 = 0`, not stuck before its first step (which is thus no release).  It runs until a release
    towards :math:`V < 0` and then until the next release towards :math:`V > 0`: that step, a change of direction as
    the count's excursions start at, starts the +HLE.  Index 0 of the returned arrays is the state before it
    (:math:`t = 0`, :math:`V = 0`, :math:`U = 0`), index 1 the state after it; ``i_half`` is the index of the state
    before the first release towards :math:`V < 0` (the -HLE's start: the halves are ``[0, i_half]`` and ``[i_half,
    end]``), and the last index is the state *after* the next release towards :math:`V > 0`, so that the first and
    the last recorded moves are both releases towards :math:`V > 0`.  The excursion's duration, between its two
    releases towards :math:`V > 0`, is therefore

    .. math::
        t_{\mathrm{le}} = (\texttt{len(t)} - 2)\,h = t_{-2},

    returned as ``duration`` (the count's :math:`d\,h`; NaN where ``complete`` is False), and
    :math:`U = \sum h (V_n + V_{n+1})/2` (trapezoid) from index 0.  The release is the plain rule: the count's
    bridge correction (crossings of the opposite threshold between two steps of a stuck particle,
    :func:`~dryfric_jax.durations.bridge_crossing`) is random and moves nothing in the path, so a plotted path
    uses the raw rule; its mean duration is the raw count's (``bridge=False``; tested), biased like
    :math:`\sqrt h` against the continuum (+0.5% or less at Fig. 3's point and default step, more at small
    tau/h: :mod:`dryfric_jax.durations`).

    Keys: ``split(key)`` gives the start's key (X_0 = its normal times the stationary sd) and the steps' key
    ``k``; step i (counted from the start of the run, the seek included) uses ``model.draw(fold_in(k, i), 1)``.

    Returns nondimensional numpy arrays ``t, x, v, U`` (``t`` = index x h), ``i_half``, ``duration`` and
    ``complete`` (False if ``max_steps`` recorded steps stopped it, or if no start was found within ``max_seek``
    steps: the arrays are then empty and ``i_half`` is -1).  ``key`` is a ``jax.random`` key or an integer seed in
    [0, 2^62]; ``max_steps`` an integer in [1, 2^26] (its buffers hold max_steps + 1 states); ``max_seek`` an
    integer >= 1 with ``max_seek + max_steps`` < 2^32 (the steps are folded into the key in 32 bits), default
    :data:`SEEK_FACTOR` x ``max_steps`` (as far as that bound allows).  ``ValueError`` naming the argument.
    """
    _check_model(model)
    key = _key(key)[0]
    max_steps = check_count("max_steps", max_steps, 1, MAX_EXCURSION_STEPS, " (its buffers hold max_steps + 1 states)")
    most_seek = 2**32 - 1 - max_steps
    if max_seek is None:
        max_seek = min(SEEK_FACTOR * max_steps, most_seek)
    max_seek = check_count("max_seek", max_seek, 1, most_seek,
                           " (2^32 - 1 - max_steps: the steps are folded into the key in 32 bits)")
    n, phase, n_half, b = jax.device_get(
        _long_excursion(model, key, jnp.asarray(max_seek, jnp.int64), max_steps=max_steps))
    n, phase = int(n), int(phase)
    m = n + 1 if phase >= 2 else 0
    out = {k: np.asarray(v)[:m].astype(np.float64) for k, v in b.items()}
    h = float(model.h)
    complete = phase == 4
    return dict(t=np.arange(m) * h, x=out["X"], v=out["V"], U=out["U"], i_half=int(n_half) if phase >= 3 else -1,
                duration=(n - 1) * h if complete else float("nan"), complete=complete)


def _pdmp_sampled(model, keys, t_burn, dt_rec, max_events, *, n_records: int):
    """A ``lax.scan`` over the grid times; for each, a bounded ``while_loop`` runs the events up
    to it.  Only the current segment is carried (state at its start, its drift, its end), so
    the record is the scan's output and no buffer is copied per event.  Run by :func:`over_lanes`, the paths split
    over the devices (it ran on one core of two: an audit)."""
    vdt = model.delta.dtype

    def path(key):
        def draw(i, state):
            u = jax.random.uniform(jax.random.fold_in(key, i), (2,), vdt, minval=jnp.finfo(vdt).tiny)
            dt, a, new, _, _ = model.event(state, (u[0], u[1]))
            return dt.astype(jnp.float64), a, new

        def record(c, j):
            tj = t_burn + j * dt_rec

            def cond(cc):  # the segment [T, T + dt] ends before the grid time
                i, _, T, dt, _, _ = cc
                return (T + dt < tj) & (i < max_events)

            def body(cc):
                i, _, T, dt, _, new = cc
                dt1, a1, new1 = draw(i, new)
                return i + 1, new, T + dt, dt1, a1, new1

            c = jax.lax.while_loop(cond, body, c)
            i, (k, y, v), T, dt, a, _ = c
            val = jnp.where(y != 0, flow(v, a, model.inv_tau_L, jnp.maximum(tj - T, 0).astype(vdt)), 0.0)
            return c, (val, T + dt >= tj)  # False: stopped by max_events, not a grid time

        s0 = jax.tree_util.tree_map(lambda a: a[0], model.s_plus(1))
        dt0, a0, new0 = draw(jnp.asarray(0, jnp.int64), s0)
        init = (jnp.asarray(1, jnp.int64), s0, jnp.asarray(0.0, jnp.float64), dt0, a0, new0)
        _, (V, ok) = jax.lax.scan(record, init, jnp.arange(n_records))
        return V, jnp.all(ok)

    return jax.vmap(path)(keys)


def pdmp_stationary(model, key, n_paths: int, n_records: int, dt_rec: float, burn: float,
                    max_events: int | None = None):
    """V of the PDMP at times ``burn + j dt_rec`` (nondimensional), ``(n_paths, n_records)``.

    Paths start at s_+; every event is bounded by ``max_events`` per path (default 10x the
    expected jump count); a path stopped by it raises ``RuntimeError`` rather than returning
    a short record.  ``key`` is a seed or a ``jax.random`` key, as elsewhere.
    """
    # checked as the DI's path functions check theirs (an int seed was a TypeError, a DIModel an
    # AttributeError, dt_rec < 0 repeated values, n_paths = 0 an empty array)
    check_pdmp_model(model)
    key = _key(key)[0]
    n_paths, n_records = check_count("n_paths", n_paths, 1), check_count("n_records", n_records, 1)
    _check_recorded(n_paths, n_records)
    check_positive("dt_rec", dt_rec)
    check_finite("burn", burn)
    if not burn >= 0:
        raise ValueError(f"burn must be >= 0 (got {shown(burn)})")
    if max_events is not None:
        max_events = check_count("max_events", max_events, 1, MAX_COUNT)
    t_end = burn + n_records * dt_rec
    # the event times are summed in float64: past this the rounding of T exceeds a thousandth of the mean
    # time between events and T stalls (an audit: burn ~7e12 tau0 ran on to max_events, ~7e16 events)
    t_most = 1e-3 * 2.0**52 / float(model.rate)
    if not t_end <= t_most:
        raise ValueError(f"burn + n_records * dt_rec must be at most {rounded_bound(t_most, lower=False, digits=3)} "
                         f"(tau0) for this model (got {t_end:.3g}): beyond it float64 cannot resolve the time "
                         f"between its events (1/rate = {1 / float(model.rate):.3g} tau0)")
    if max_events is None:  # 10x the expected jumps, < 2^62 by the bound on t_end above (< 4.6e13 jumps)
        max_events = int(10 * float(model.rate) * t_end + 10_000)
    V, ok = over_lanes(_pdmp_sampled, (model, jax.random.split(key, n_paths), jnp.asarray(burn, jnp.float64),
                                       jnp.asarray(dt_rec, jnp.float64), jnp.asarray(max_events, jnp.int64)),
                       (False, True, False, False, False), n_records=int(n_records))
    if not bool(np.all(ok)):
        raise RuntimeError(f"{int((~np.asarray(ok)).sum())} PDMP paths hit max_events = {max_events}")
    return np.asarray(V, np.float64)
