r"""Where the DI step is: the discrete differential inclusion, in nondimensional units.

Paper section 6, with the erratum of MODEL_NOTES section 3.1: one step of length h is the
proximal (soft-threshold) step of the fresh predictor,

.. math::
    w = V_n + h\big(b(V_n) + \Xi_n\big), \qquad
    V_{n+1} = \operatorname{sign}(w)\,\max(|w| - h, 0),

with :math:`b(v) = -v/\tau_L' + \bar\gamma'` and :math:`(\Xi_n, X_{n+1})` from the exact OU step
(:mod:`dryfric_jax.ou`).  Units are :math:`\tau_0, u_0` (:math:`\Gamma = \Delta = 1`), which keeps
float32 safe for any physical Gamma.  The displacement increment is the trapezoid
:math:`h (V_n + V_{n+1})/2`.
"""
from __future__ import annotations

import math

import equinox as eqx
import jax
import jax.numpy as jnp

from . import rng
from .ou import OUStep, check_ratio, min_ratio, ou_step
from .params import Params
from .regeneration import SplitSet, split_set


class DIModel(eqx.Module):
    """Everything one DI lane needs, nondimensional, in the simulation dtype."""

    h: jnp.ndarray
    gamma_bar: jnp.ndarray
    inv_tau_L: jnp.ndarray
    ou: OUStep
    plus: SplitSet  # C_+ around x_{+Delta}: ends a -HLE
    minus: SplitSet  # C_- around x_{-Delta}: ends a +HLE
    x_plus: jnp.ndarray

    def step(self, V, Xi):
        r"""Proximal step of the velocity for the time-averaged noise ``Xi``: the soft threshold
        :math:`\operatorname{sign}(w)\max(|w| - h, 0)` written as :math:`w - \operatorname{clip}(w, -h, h)`,
        the same number in every rounding (:math:`w \mp h` for :math:`|w| > h`, exactly 0 otherwise,
        where the first form gave -0 for negative w) in 3 operations instead of ~6: the wait layout's
        quiet step 6.2 -> 5.8 ns per lane-step in float32 and 17.0 -> 16.5 in float64 (one CPU device,
        256 lanes, draws included).  Paths and events are unchanged; in float32 XLA fuses the displacement
        increments differently, so a lane's U moved in its last bits (<= 5e-9 relative, version 0.2.3)."""
        w = V + self.h * (self.gamma_bar - V * self.inv_tau_L + Xi)
        return w - jnp.clip(w, -self.h, self.h)

    def move(self, X, V, z1, z2, dtype=jnp.float64):
        """One step of the chain from two standard normals: ``(Xi, X_next, V_next, dU)``, with
        the trapezoid displacement :math:`dU = h (V_n + V_{n+1})/2` in ``dtype`` (float64 unless
        told: the lane engine asks for the simulation dtype, :meth:`advance`)."""
        Xi, Xn = self.ou.sample(X, z1, z2)
        Vn = self.step(V, Xi)
        dU = 0.5 * self.h.astype(dtype) * (V.astype(dtype) + Vn.astype(dtype))
        return Xi, Xn, Vn, dU

    # --- the lane-engine interface (dryfric_jax.excursions) ---
    start_regenerated = False  # lanes seek their first regeneration on C_+
    regen_after_step = False  # the regenerating transition belongs to the new cycle
    # block layout on a CPU (excursions._block): a lane waits at its first event of the block.
    # Against a branch per step, 2 CPU devices, Fig. 3 point, paused rounds: 512 lanes float64
    # 0.97x, float32 1.02x; 4096 lanes 1.32x and 1.63x (the branch is taken at most steps there)
    cpu_events = "wait"
    fused_quiet = True  # the "wait" loop also runs as one Pallas kernel (dryfric_jax.fused)

    @property
    def fixed_dt(self):
        """Step length in float64: excursion durations are n h with an integer n."""
        return self.h.astype(jnp.float64)

    def init_state(self, n: int):
        dt = self.h.dtype
        return (jnp.full((n,), self.x_plus, dt), jnp.zeros((n,), dt))

    @property
    def random_dtype(self):
        """The dtype the random numbers are drawn in (:meth:`draw`, :meth:`coin`): the simulation
        dtype.  A test widens float32 numbers into a float64 chain to pair the two precisions."""
        return self.h.dtype

    def draw(self, key, block: int):
        """The block's random numbers: 2 normals per step (exact OU step).  The splitting coin's
        uniform is not drawn here but only at the steps that flip a coin (:meth:`coin`)."""
        zs = rng.normal(jax.random.split(key)[0], (block, 2), self.random_dtype).astype(self.h.dtype)
        return zs[:, 0], zs[:, 1]

    def draw_lanes(self, keys, block: int):
        """:meth:`draw` of every lane at once, each leaf of shape (block, lanes): the same
        numbers, compiled faster on a CPU (:mod:`dryfric_jax.rng`)."""
        zs = rng.normals(rng.split_at(keys, 0), block, 2, self.random_dtype)
        return tuple(z.astype(self.h.dtype) for z in zs)

    def coin_key(self, key):
        """The key of the block's coins (block key as in :meth:`draw`).  A lane flips at most one
        coin per block in the engine's ``"wait"`` layout, with this key; in ``"branch"``, step
        i's coin uses ``fold_in(coin_key, i)`` (:func:`dryfric_jax.excursions._block`)."""
        return rng.split_at(key, 1)  # jax.random.split(key)[1], compiled as in draw_lanes

    def _set(self, watch_plus):
        return jax.tree_util.tree_map(lambda p, m: jnp.where(watch_plus, p, m), self.plus, self.minus)

    def advance(self, state, r, watch_plus):
        """One step.  Returns ``(state, dU, None, candidate)``: ``candidate`` marks a step that
        flips the splitting coin (stuck on C_+ and released upwards (``watch_plus``), or stuck on
        C_- and released downwards); it is a regeneration when :meth:`coin` says heads
        (:mod:`dryfric_jax.regeneration`).  Candidates are rare, so the lane engine flips coins
        only at steps where some lane has one.

        ``dU`` = :math:`h (V_n + V_{n+1})/2` is in the simulation dtype (:meth:`move`'s is float64):
        the engine adds it to its float64 U, summing at most one block of increments in the
        simulation dtype first (``excursions._quiet_steps``)."""
        X, V = state
        z1, z2 = r
        _, Xn, Vn, dU = self.move(X, V, z1, z2, V.dtype)
        released = jnp.where(watch_plus, Vn > 0, Vn < 0)
        return (Xn, Vn), dU, None, (V == 0) & released & self._set(watch_plus).contains(X)

    def coin(self, state, r, watch_plus, key):
        r"""The splitting coin of a candidate step from ``state`` with normals ``r``: heads with
        probability :math:`r(x, y) = \varepsilon\nu(y)/p(x, y)`, from a fresh uniform of ``key``."""
        X, _ = state
        z1, z2 = r
        dt = self.random_dtype
        u = rng.uniform(key, dt, minval=float(jnp.finfo(dt).tiny))  # jax.random.uniform(key, (), dt, tiny)
        return jnp.log(u.astype(self.h.dtype)) < self._set(watch_plus).log_coin(X, z1, z2)


def make_di_model(params: Params, h: float, dtype=jnp.float64) -> DIModel:
    """Build the nondimensional DI chain for physical ``params`` and physical step ``h`` (s).

    The arguments are checked as the planner checks them (:mod:`dryfric_jax.plan`), ``ValueError``
    naming the one that is wrong: ``params`` a :class:`~dryfric_jax.Params`, ``h`` in
    [1e-12, 0.1]*min(tau0, tau_L) s (None: the default step, :func:`~dryfric_jax.plan.default_h`),
    ``dtype`` float32 or float64 (a name or a dtype).  Unlike a planned run, float32 is used as asked
    where it is not safe (:func:`~dryfric_jax.limits.float32_unsafe_reason`).  An h/tau below
    :func:`~dryfric_jax.ou.min_ratio` is refused (:func:`~dryfric_jax.ou.ou_step`: the step's covariance underflows),
    and so is a tau too long for any allowed h."""
    from .params import check_params, require_x64  # the planner's own checks (imported here: plan is a layer above)
    from .plan import DTYPES, check_h, dtype_name, h_max

    require_x64()  # with it off, the default float64 built a float32 model
    check_params(params)
    if h_max(params) / params.tau < min_ratio(jnp.float64):  # no step would do: said so, not of the default h alone
        raise ValueError(f"tau = {params.tau:.3g} s is too long for any step h <= {h_max(params):.3g} s (the largest "
                         f"allowed): h/tau would be below {min_ratio(jnp.float64):.2g}, where the OU step underflows")
    h = check_h(params, h)
    check_ratio(h, params.tau, jnp.float64)  # named in the user's h and tau
    dtype = DTYPES[dtype_name(dtype)]
    nd = params.nondim()
    h_nd = h / params.tau0
    ou64 = ou_step(h_nd, nd.tau, jnp.float64)
    x_plus, x_minus = nd.x_thresholds
    plus = split_set(ou64, x_plus, nd.tau)
    minus = split_set(ou64, x_minus, nd.tau)
    cast = lambda tree: jax.tree_util.tree_map(lambda a: jnp.asarray(a, dtype), tree)
    itl = 0.0 if math.isinf(nd.tau_L) else 1.0 / nd.tau_L
    return DIModel(jnp.asarray(h_nd, dtype), jnp.asarray(nd.gamma_bar, dtype), jnp.asarray(itl, dtype),
                   cast(ou64), cast(plus), cast(minus), jnp.asarray(x_plus, dtype))

