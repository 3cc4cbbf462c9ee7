r"""The PDMP Z = (X, Y, V): exact event-driven simulation of the jump-noise model.

Paper section 3 and appendices A, B and E (printed letters; the source labels them app:genX, app:PDMP and
app:C), nondimensional units (:math:`\Gamma = \Delta = 1`), with the
errata of MODEL_NOTES section 3.  X is the jump noise of :mod:`dryfric_jax.noise` (integer
index k), Y the mode (+1 sliding up, -1 sliding down, 0 stuck), V the velocity.

Flows (appendix B) in a sliding mode y, with :math:`a = x + \bar\gamma - y` the force at v = 0
and :math:`\kappa = 1/\tau_L` (:math:`\kappa = 0` for :math:`\tau_L = \infty`, a proper case):

.. math::
    \dot v = a - \kappa v,\qquad
    v(s) = v + (a - \kappa v)\, s\,\varphi_1(-\kappa s),\qquad
    \int_0^s v = v s + (a - \kappa v)\, s^2 \varphi_2(-\kappa s),

with :math:`\varphi_1(z) = (e^z - 1)/z` and :math:`\varphi_2(z) = (e^z - 1 - z)/z^2` evaluated
stably (``expm1``, series near 0), so nothing blows up as :math:`\kappa s \to 0` or
:math:`\kappa s \to \infty` (erratum 4).  Just outside its series, :math:`\varphi_2`'s numerator
:math:`\mathrm{expm1}(z) - z \approx z^2/2` keeps a relative error of about 2 eps/|z|: 5.9e-14 at the
float64 cut |z| = 0.01 and 4.5e-6 at float32's 0.1 (audit, against 60 digits), far below the
statistical error of any estimate.  The velocity reaches 0 (only when :math:`v a < 0`) at

.. math::
    T^\star = \frac{\log(1 + \kappa\sigma)}{\kappa}\ \ (\kappa > 0),\qquad T^\star = \sigma\ \ (\kappa = 0),
    \qquad \sigma = -v/a \ge 0,

which is appendix B's :math:`\tau_L\log(1 - v/c)` (:math:`c = a\tau_L`) written with ``log1p``
of :math:`\kappa\sigma`, so that neither :math:`\kappa \to 0` nor :math:`a \to 0` cancels.  An event is
the earlier of :math:`T^\star` and the next noise jump (exponential, rate :math:`\Lambda`).  At :math:`T^\star` the
velocity is exactly 0 and the mode becomes :math:`\Theta(x, 0)`; at a noise jump the mode only
changes when stuck: leaving :math:`[k_-, k_+]` upwards gives :math:`s_+ = (x_{k_++1}, 1, 0)`,
downwards :math:`s_- = (x_{k_--1}, -1, 0)` (the kernel :math:`\mathcal Q` of appendix B).

Thresholds (section 3.3): :math:`x_{k_+} \le 1 - \bar\gamma < x_{k_++1}` and
:math:`x_{k_--1} < -1 - \bar\gamma \le x_{k_-}`.  The offsets :math:`r_\pm` of the thresholds from
the grid are computed once in float64; a threshold within :math:`10^{-9}\max(1, |q|)` grid steps of
a grid point (:math:`q` its position in grid steps, whose own rounding grows with :math:`|q|`) is
taken *on* it (:math:`r = 0`, the point is stuck, :math:`a = 0` there).  In the step the force is
:math:`a = (k - k_\pm)\delta + r_\pm`, an exact multiple plus the offset, so its sign (which
decides whether :math:`T^\star` is finite) is never a rounding accident.

Regeneration is exact: :math:`s_\pm` are hit exactly (by a noise jump out of the stuck set, or
by :math:`T^\star` at :math:`x_{k_\pm\pm1}` while sliding the other way), so a +HLE runs from
:math:`s_+` until :math:`s_-` and a -HLE back (Algorithm 1 and its mirror).
"""
from __future__ import annotations

import math
from functools import partial

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from . import rng
from .excursions import BLOCK
from .noise import check_delta, grid_size
from .params import Params, check_params, require_x64
from .sharding import over_lanes

ON_GRID_TOL = 1e-9


def _small(z):
    """|z| below 0.01 (float64) or 0.1 (float32), where phi1 and phi2 use their series, and the
    guarded argument of expm1 and its reciprocal outside it.  phi1 and phi2 of the same z build
    the same expm1 and reciprocal, so XLA computes them once per event (one division, not two)."""
    cut = 0.1 if jnp.asarray(z).dtype == jnp.float32 else 0.01
    small = jnp.abs(z) < cut
    zs = jnp.where(small, 1.0, z)
    return small, zs, 1.0 / zs


def phi1(z):
    """(e^z - 1)/z, 1 at z = 0 (series near 0: the omitted term is below z^6/5040)."""
    small, zs, inv = _small(z)
    series = 1.0 + z * (0.5 + z * (1 / 6 + z * (1 / 24 + z * (1 / 120 + z / 720))))
    return jnp.where(small, series, jnp.expm1(zs) * inv)


def phi2(z):
    """(e^z - 1 - z)/z^2, 1/2 at z = 0 (series near 0)."""
    small, zs, inv = _small(z)
    series = 0.5 + z * (1 / 6 + z * (1 / 24 + z * (1 / 120 + z * (1 / 720 + z / 5040))))
    return jnp.where(small, series, (jnp.expm1(zs) - zs) * inv * inv)


def flow(v, a, kappa, s):
    """Velocity after sliding for a time s from v (force a at v = 0, viscous rate kappa)."""
    return v + (a - kappa * v) * s * phi1(-kappa * s)


def displacement(v, a, kappa, s):
    r"""Displacement :math:`\int_0^s v` while sliding (appendix B's U(T_1), appendix E's displacement(), stable form)."""
    return v * s + (a - kappa * v) * s * s * phi2(-kappa * s)


def hitting_time(v, a, kappa, y=None):
    """T*: time for the velocity, sliding in mode ``y`` (default sign(v)), to reach 0; +inf when
    it never does (a of the same sign as y, or a = 0).  v = 0 against the force gives 0."""
    y = jnp.sign(v) if y is None else y
    hits = ((y > 0) & (a < 0)) | ((y < 0) & (a > 0))
    sigma = jnp.where(hits, -v / jnp.where(hits, a, 1.0), 0.0)  # >= 0: the time without viscosity
    # log(1 + kappa sigma)/kappa (= sigma at kappa = 0): log1p keeps kappa sigma -> 0 exact, and
    # kappa is one number per model, so its reciprocal is computed once, not per lane
    viscous = jnp.abs(kappa) >= jnp.finfo(jnp.result_type(kappa, sigma)).tiny  # 1/kappa is finite
    t = jnp.where(viscous, jnp.log1p(kappa * sigma) * (1.0 / jnp.where(viscous, kappa, 1.0)), sigma)
    return jnp.where(hits, t, jnp.inf)


class PDMPModel(eqx.Module):
    """Everything one PDMP lane needs, nondimensional (simulation dtype for v and times)."""

    delta: jnp.ndarray
    c_alpha: jnp.ndarray  # tau delta^2 / 4: alpha_k = 1/2 - c_alpha k
    rate: jnp.ndarray  # Lambda = 2 / (tau delta)^2
    inv_tau_L: jnp.ndarray
    N: jnp.ndarray  # grid |k| <= N
    kp: jnp.ndarray  # k_+
    km: jnp.ndarray  # k_-
    r_p: jnp.ndarray  # x_{k+} + gamma_bar - 1 in (-delta, 0]
    r_m: jnp.ndarray  # x_{k-} + gamma_bar + 1 in [0, delta)

    start_regenerated = True  # lanes start at s_+, a regeneration state
    regen_after_step = True  # the event that lands on s_+ or s_- closes the cycle
    fixed_dt = None  # durations are float64 sums of event times
    coin = None  # s_+ and s_- are hit exactly: an event that lands on them is a regeneration
    # block layout on a CPU (excursions._block): a branch per event.  Waiting at events makes
    # XLA:CPU recompute the event (log, expm1, log1p) for each array the step writes: 0.85x
    # events/s at 512 lanes, 1.01x at 4096 (2 CPU devices, Fig. 3 point, paused rounds)
    cpu_events = "branch"

    # ---- one event ----
    def force(self, k, y):
        """a = x_k + gamma_bar - y (the acceleration at v = 0 in mode y = +-1)."""
        dt = self.delta.dtype
        kk = jnp.where(y > 0, k - self.kp, k - self.km).astype(dt)
        return kk * self.delta + jnp.where(y > 0, self.r_p, self.r_m)

    def event(self, state, r):
        """The next event from ``state = (k, y, v)`` with uniforms ``r = (u1, u2)``.

        Returns ``(dt, a, new_state, to_plus, to_minus)``: the time to the event, the force of
        the sliding segment, the state after it, and whether it lands exactly on s_+ / s_-.
        """
        k, y, v = state
        u1, u2 = r
        moving = y != 0
        a = self.force(k, y)
        t_star = hitting_time(v, a, self.inv_tau_L, y)  # +inf when stuck (y = 0)
        e = -jnp.log(u1) * (1.0 / self.rate)
        jump = e < t_star
        dt = jnp.where(jump, e, t_star)
        vn = jnp.where(moving & jump, flow(v, a, self.inv_tau_L, dt), 0.0).astype(v.dtype)
        # the side: toward 0 with probability beta = 1/2 + c |k| (alpha_k = 1/2 - c k up), drawn the same way
        # on both sides: up iff u2 < beta for k <= 0, down iff the mirrored uniform 1 - 2^-m - u2 (the same
        # grid of values, j -> 2^m - 1 - j) is < beta for k > 0.  The law is then exactly symmetric under
        # k -> -k whatever the uniforms' resolution: with 'u2 < alpha_k' on both sides, P(up) was
        # ceil(alpha 2^m)/2^m >= alpha, a drift up that gave float32 a stationary E[X] of 2.9e-6 (delta' =
        # 0.05) to 5e-4 (3e-4) at tau' = 1, gamma_bar = 0 (a PDMP audit, from the exact law of the chain
        # with the model's float32 alpha_k); float64's 2^-52 made it ~1e-14
        ud = u2.dtype
        beta = jnp.where(jnp.abs(k) >= self.N, 1.0, 0.5 + self.c_alpha * jnp.abs(k).astype(ud))
        mirrored = jnp.asarray(1.0 - float(jnp.finfo(self.random_dtype).eps), ud) - u2  # exact: 2^-m grid
        up = jnp.where(k > 0, mirrored >= beta, u2 < beta)
        kn = jnp.where(jump, k + jnp.where(up, 1, -1), k).astype(k.dtype)
        stuck = y == 0
        theta = lambda kk: jnp.where(kk > self.kp, 1, jnp.where(kk < self.km, -1, 0)).astype(y.dtype)
        yn = jnp.where(jump, jnp.where(stuck, theta(kn), y), theta(k))
        to_plus = jnp.where(jump, stuck & (kn == self.kp + 1), (y == -1) & (k == self.kp + 1))
        to_minus = jnp.where(jump, stuck & (kn == self.km - 1), (y == 1) & (k == self.km - 1))
        return dt, a, (kn, yn, vn), to_plus, to_minus

    # ---- the lane-engine interface (dryfric_jax.excursions) ----
    def s_plus(self, n: int):
        return (jnp.full((n,), self.kp + 1, jnp.int32), jnp.ones((n,), jnp.int32),
                jnp.zeros((n,), self.delta.dtype))

    def init_state(self, n: int):
        return self.s_plus(n)

    @property
    def random_dtype(self):
        """The dtype the uniforms are drawn in: the simulation dtype.  A test widens float32
        numbers into a float64 chain to pair the two precisions (as for the DI)."""
        return self.delta.dtype

    def draw(self, key, block: int):
        """The block's random numbers: 2 uniforms in (0, 1) per event (waiting time, jump side)."""
        dt = self.random_dtype
        u = jax.random.uniform(key, (block, 2), dt, minval=jnp.finfo(dt).tiny).astype(self.delta.dtype)
        return u[:, 0], u[:, 1]

    def draw_lanes(self, keys, block: int):
        """:meth:`draw` of every lane at once, each leaf of shape (block, lanes): the same
        numbers, compiled faster on a CPU (:mod:`dryfric_jax.rng`)."""
        dt = self.random_dtype
        us = rng.uniforms(keys, block, 2, dt, minval=float(jnp.finfo(dt).tiny))
        return tuple(u.astype(self.delta.dtype) for u in us)

    def advance(self, state, r, watch_plus):
        """One event; ``heads`` when it lands on s_+ (``watch_plus``) or s_-."""
        k, y, v = state
        dt, a, new, to_plus, to_minus = self.event(state, r)
        dU = jnp.where(y != 0, displacement(v, a, self.inv_tau_L, dt), 0.0).astype(jnp.float64)
        return new, dU, dt.astype(jnp.float64), jnp.where(watch_plus, to_plus, to_minus)


def grid_offsets(delta: float, gamma_bar: float) -> tuple[int, int, float, float]:
    """k_+, k_- and the offsets r_+ = x_{k+} + gamma_bar - 1, r_- = x_{k-} + gamma_bar + 1 (float64);
    a threshold q grid steps from 0 and within ON_GRID_TOL * max(1, |q|) steps of a grid point is on it
    (r = 0): the tolerance is relative beyond one step, as q's own float64 rounding is.  ``ValueError`` unless
    ``delta`` is a finite number > 0 and ``gamma_bar`` finite (delta = 0 was a ZeroDivisionError; the public
    functions check delta first)."""
    if not (math.isfinite(delta) and delta > 0 and math.isfinite(gamma_bar)):
        raise ValueError(f"delta must be a finite number > 0 and gamma_bar finite (got delta = {delta!r}, "
                         f"gamma_bar = {gamma_bar!r})")
    qp, qm = (1.0 - gamma_bar) / delta, (-1.0 - gamma_bar) / delta
    if abs(qp - round(qp)) < ON_GRID_TOL * max(1.0, abs(qp)):
        kp, r_p = int(round(qp)), 0.0
    else:
        kp = math.floor(qp)
        r_p = min(kp * delta + gamma_bar - 1.0, 0.0)
    if abs(qm - round(qm)) < ON_GRID_TOL * max(1.0, abs(qm)):
        km, r_m = int(round(qm)), 0.0
    else:
        km = math.ceil(qm)
        r_m = max(km * delta + gamma_bar + 1.0, 0.0)
    return kp, km, r_p, r_m


def threshold_widening(delta: float, gamma_bar: float) -> tuple[float, float]:
    """How far past each threshold the grid's first level lies, in grid steps, each in (0, 1]: a stuck particle
    is released at :math:`x_{k_+ + 1}` and :math:`x_{k_- - 1}` (:func:`grid_offsets`; nondimensional ``delta``,
    ``gamma_bar``), where the DI is released at the thresholds themselves, so the grid widens the stuck set by
    their sum and lengthens the excursions (at Fig. 3's delta by up to 13% at tau <= 0.5 s: RESULTS.md)."""
    _, _, r_p, r_m = grid_offsets(delta, gamma_bar)
    return 1.0 + r_p / delta, 1.0 - r_m / delta


def pdmp_grid_info(params: Params, delta: float) -> dict:
    """The noise grid for physical ``delta`` (s^-1/2): delta, delta', L_X (s^-1/2), N and the jump
    rate per tau0; ValueError if delta is outside its admissible range (:mod:`dryfric_jax.noise`), or if
    ``params`` is not a :class:`~dryfric_jax.Params` (a dict was an AttributeError)."""
    check_params(params)
    nd = params.nondim()
    scale = params.Delta / math.sqrt(params.Gamma)  # delta = delta' Delta / sqrt(Gamma)
    # delta' = delta / scale, the very number check_delta tests: a delta within an ulp of the bound is
    # refused here in physical units, not by grid_size's check of a delta' rounded the other way
    check_delta(delta, nd.tau, nd.gamma_bar, scale=scale)
    d = float(delta) / scale
    N = grid_size(d, nd.tau, nd.gamma_bar, shown_as=f"delta = {float(delta):.4g} s^-1/2 (delta' = {d:.4g})",
                  scale=scale)
    return dict(delta=float(delta), delta_nd=d, L_X=N * d * scale, N=N, rate_nd=2.0 / (nd.tau * d) ** 2)


def make_pdmp_model(params: Params, delta: float, dtype=jnp.float64) -> PDMPModel:
    """Build the nondimensional PDMP for physical ``params`` and physical grid step ``delta``
    (s^-1/2), validated by :func:`pdmp_grid_info`; ``dtype`` float32 or float64 (a name or a dtype; others, e.g.
    int32 or float16, are refused by name: an audit found them built into a model of zeros).  As for
    :func:`~dryfric_jax.make_di_model`, float32 is used as asked where a planned run would not use it
    (:func:`~dryfric_jax.limits.pdmp_float32_unsafe_reason`), except where a number of the model overflows it
    (1/tau_L' beyond 3.4e38: the model's numbers would be inf), which is refused by name."""
    from .plan import DTYPES, dtype_name  # plan is a layer above

    require_x64()
    g = pdmp_grid_info(params, delta)  # checks params, then delta
    dtype = DTYPES[dtype_name(dtype)]
    nd = params.nondim()
    d = g["delta_nd"]
    kp, km, r_p, r_m = grid_offsets(d, nd.gamma_bar)
    itl = 0.0 if math.isinf(nd.tau_L) else 1.0 / nd.tau_L
    reals = (d, 0.25 * nd.tau * d * d, g["rate_nd"], itl, r_p, r_m)
    big = float(jnp.finfo(dtype).max)
    if any(abs(x) > big for x in reals):
        raise ValueError(f"dtype {jnp.dtype(dtype).name} cannot hold this PDMP's numbers (1/tau_L' = {itl:.3g}, jump "
                         f"rate {g['rate_nd']:.3g} per tau0; at most {big:.3g}): use float64")
    f = lambda x: jnp.asarray(x, dtype)
    i = lambda x: jnp.asarray(x, jnp.int32)
    return PDMPModel(*(f(x) for x in reals[:4]), i(g["N"]), i(kp), i(km), f(r_p), f(r_m))


# ---------------------------------------------------------------------------------------------
# brute force on [0, t] (Algorithm 2, corrected: U adds the displacement, and Y = 1 at s_+)
# ---------------------------------------------------------------------------------------------
def _bruteforce_paths(model: PDMPModel, keys, t_start, t_end, max_events, *, block: int):
    """The paths of ``keys`` (run by :func:`~dryfric_jax.sharding.over_lanes`, split over the devices): each its own
    ``while_loop`` to ``t_end`` or ``max_events``."""
    def lane(key):
        def cond(c):
            b, state, T, U, n = c
            return (T < t_end) & (n < max_events)

        def body(c):
            b, state, T, U, n = c
            rs = model.draw(jax.random.fold_in(key, b), block)

            def ev(i, cc):
                state, T, U, n = cc
                live = T < t_end
                k, y, v = state
                dt, a, new, _, _ = model.event(state, (rs[0][i], rs[1][i]))
                dt64 = dt.astype(jnp.float64)
                # count the part of [T, T + dt] inside [t_start, t_end]
                lo = jnp.clip(t_start - T, 0.0, dt64)
                hi = jnp.clip(t_end - T, 0.0, dt64)
                seg = lambda s: displacement(v.astype(jnp.float64), a.astype(jnp.float64),
                                             model.inv_tau_L.astype(jnp.float64), s)
                dU = jnp.where(live & (y != 0), seg(hi) - seg(lo), 0.0)
                state = jax.tree_util.tree_map(lambda nw, od: jnp.where(live, nw, od), new, state)
                return state, jnp.where(live, T + dt64, T), U + dU, n + live

            state, T, U, n = jax.lax.fori_loop(0, block, ev, (state, T, U, n))
            return b + 1, state, T, U, n

        s0 = jax.tree_util.tree_map(lambda a: a[0], model.s_plus(1))
        init = (jnp.asarray(0, jnp.int64), s0, jnp.asarray(0.0, jnp.float64), jnp.asarray(0.0, jnp.float64),
                jnp.asarray(0, jnp.int64))
        _, _, T, U, n = jax.lax.while_loop(cond, body, init)
        return U, n, T >= t_end

    return jax.vmap(lane)(keys)


def simulate_pdmp_bruteforce(model: PDMPModel, key, n_paths: int, t: float, *, burn_in: float = 0.0,
                             max_events: int = 10**9, block: int = BLOCK, chunk_lanes: int = 4096):
    """U(t) of ``n_paths`` PDMP paths from s_+ (nondimensional t, burn_in).

    Returns:
        ``(U, events, n_unfinished)``: displacements over [burn_in, burn_in + t], total events,
        and the number of paths stopped by ``max_events`` (reported, never hidden).
    """
    from .bruteforce import path_keys  # (bruteforce imports the DI; the PDMP's chain needs none of it)

    lanes = min(chunk_lanes, n_paths)
    Us, ev, unf = [], 0, 0
    for c in range(-(-n_paths // lanes)):
        # the last chunk runs only its paths; path k's key does not depend on the chunking (as the DI's brute force)
        keys = path_keys(key, c * lanes, min((c + 1) * lanes, n_paths))
        # split over the devices (it ran on one core of two: an audit); a path's numbers do not depend on the device
        # count, up to the last bits (sharding module docstring)
        U, n, fin = over_lanes(_bruteforce_paths, (model, keys, jnp.asarray(burn_in, jnp.float64),
                                                   jnp.asarray(burn_in + t, jnp.float64),
                                                   jnp.asarray(max_events, jnp.int64)),
                               (False, True, False, False, False), block=block)
        Us.append(np.asarray(U))
        ev += int(np.asarray(n).sum())
        unf += int((~np.asarray(fin)).sum())
    return np.concatenate(Us), ev, unf


# ---------------------------------------------------------------------------------------------
# one long excursion's event skeleton (for sample-path figures)
# ---------------------------------------------------------------------------------------------
@partial(jax.jit, static_argnames=("max_events",))
def _skeleton(model: PDMPModel, key, *, max_events: int):
    dt_ = model.delta.dtype
    buf = dict(t=jnp.zeros(max_events + 1), k=jnp.zeros(max_events + 1, jnp.int32),
               y=jnp.zeros(max_events + 1, jnp.int32), v=jnp.zeros(max_events + 1, dt_), U=jnp.zeros(max_events + 1))
    s0 = jax.tree_util.tree_map(lambda a: a[0], model.s_plus(1))
    buf = {n: a.at[0].set(x) for (n, a), x in zip(buf.items(), (0.0, s0[0], s0[1], s0[2], 0.0))}

    def cond(c):
        i, phase, i_half, state, T, U, b = c
        return (i < max_events) & (phase < 2)

    def body(c):
        i, phase, i_half, state, T, U, b = c
        r = jax.random.uniform(jax.random.fold_in(key, i), (2,), dt_, minval=jnp.finfo(dt_).tiny)
        new, dU, dt, heads = model.advance(state, (r[0], r[1]), phase == 1)  # s_- first, then s_+
        T, U = T + dt, U + dU
        i = i + 1
        b = {n: b[n].at[i].set(x) for n, x in zip(("t", "k", "y", "v", "U"), (T, new[0], new[1], new[2], U))}
        half = (phase == 0) & heads
        phase = jnp.where(half, 1, jnp.where((phase == 1) & heads, 2, phase))
        return i, phase, jnp.where(half, i, i_half), new, T, U, b

    init = (jnp.asarray(0), jnp.asarray(0), jnp.asarray(-1), s0, jnp.asarray(0.0, jnp.float64),
            jnp.asarray(0.0, jnp.float64), buf)
    i, phase, i_half, _, _, _, b = jax.lax.while_loop(cond, body, init)
    return i, phase, i_half, b


#: the most events :func:`excursion_skeleton` records
MAX_SKELETON_EVENTS = 2**26


def check_pdmp_model(model) -> None:
    """``ValueError`` unless ``model`` is a :class:`PDMPModel` (the path functions' check: a DIModel was an
    AttributeError deep inside)."""
    if not isinstance(model, PDMPModel):
        raise ValueError(f"model must be a PDMPModel, from dryfric_jax.make_pdmp_model(params, delta) "
                         f"(got {type(model).__name__})")


def excursion_skeleton(model: PDMPModel, key, max_events: int = 200_000) -> dict:
    """One long excursion from s_+ (through s_-, back to s_+) as its event skeleton.

    Returns nondimensional numpy arrays ``t, x, y, v, U`` at the event times (index 0 is s_+),
    ``i_half`` (index of s_-) and ``complete`` (False if ``max_events`` stopped it first).
    Between events v follows :func:`flow` and X is constant.  ``RuntimeError`` with JAX's 64-bit mode off
    (:func:`~dryfric_jax.params.require_x64`; it returned float32 times and int32 levels: a review).  ``key`` is a
    ``jax.random`` key or an integer seed in [0, 2^62], as elsewhere; ``max_events`` an integer in [1, 2^26] (its
    buffers, of max_events + 1 events, are allocated whole: 2^31 passed 6 GB, 1e10 ran out of memory, -5 was a
    TypeError from JAX and 2.5 was taken as 2: an audit).  ``ValueError`` naming the argument.
    """
    from .api import _key  # the API imports this module
    from .plan import check_count

    require_x64()
    check_pdmp_model(model)
    key = _key(key)[0]
    max_events = check_count("max_events", max_events, 1, MAX_SKELETON_EVENTS, " (its buffers are allocated whole)")
    n, phase, i_half, b = jax.device_get(_skeleton(model, key, max_events=max_events))
    n = int(n)
    out = {k: np.asarray(v)[: n + 1] for k, v in b.items()}
    out["x"] = out.pop("k") * float(model.delta)
    out.update(i_half=int(i_half), complete=bool(phase == 2))
    return out
