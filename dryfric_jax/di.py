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

from .ou import OUStep, ou_step
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
        """Proximal step of the velocity for the time-averaged noise ``Xi``."""
        w = V + self.h * (self.gamma_bar - V * self.inv_tau_L + Xi)
        return jnp.sign(w) * jnp.maximum(jnp.abs(w) - self.h, 0.0)


def make_di_model(params: Params, h: float, dtype=jnp.float64) -> DIModel:
    """Build the nondimensional DI chain for physical ``params`` and physical step ``h`` (s)."""
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

