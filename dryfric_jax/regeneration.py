r"""Where excursions end: exact regeneration of the discrete DI chain by Nummelin splitting.

Why not a reset
---------------
In continuous time a half-long excursion (HLE) ends when the particle is stuck (V = 0) and X
crosses the far threshold :math:`x_{\mp\Delta}`; the state is then exactly
:math:`(x_{\mp\Delta}, 0)`.  A discrete chain never lands on a threshold, and resetting X to it
perturbs the chain (MODEL_NOTES section 3.1): the "V = 0 and X beyond" rule gives large
overshoots for :math:`\tau \gg h`, the "was stuck, now crosses" rule never fires for
:math:`\tau \ll h`.  We do not reset anything.

The rule
--------
From a stuck state :math:`(X_n, V_n) = (x, 0)` the next pair :math:`y = (\Xi, X_{n+1})` is
:math:`\mathcal N(x\,m, \Sigma)` (module :mod:`dryfric_jax.ou`), and the next state
:math:`(X_{n+1}, V_{n+1})` is a function of :math:`y` alone.  On an interval
:math:`C = [c_1, c_2]` the kernel has the minorisation

.. math::
    p(x, y) \ge \varepsilon\,\nu(y) := \min\{\varphi_\Sigma(y - c_1 m), \varphi_\Sigma(y - c_2 m)\},
    \qquad x \in C,

because :math:`\log\varphi_\Sigma(y - xm)` is concave in :math:`x`.  After every ordinary step
from :math:`(x, 0)` with :math:`x \in C` we flip a coin with probability
:math:`r(x,y) = \varepsilon\nu(y)/p(x,y)` (retrospective splitting, Mykland, Tierney & Yu 1995).
Conditionally on heads, :math:`y \sim \nu` independently of the past, so the chain
*regenerates* at that step; the coin never changes the path.  Hence:

* the cycles between regenerations are i.i.d. and the long-excursion estimator targets the
  asymptotic variance of exactly the chain that brute force simulates (no bias at any h/tau);
* the +HLE runs until a regeneration on :math:`C_-` (around :math:`x_{-\Delta}`), the -HLE
  until one on :math:`C_+` (around :math:`x_{\Delta}`); a lane finds its first start by running
  the chain until a regeneration on :math:`C_+` (:mod:`dryfric_jax.excursions`).

Direction of release.  As in the paper's definition, a half excursion ends only when the stuck
particle is released towards the far side: the coin on :math:`C_-` is only flipped when
:math:`V_{n+1} < 0`, on :math:`C_+` when :math:`V_{n+1} > 0`.  Restricting :math:`\nu` to such
y is still a minorisation (:math:`\varepsilon\nu(y)1_A(y) \le p(x, y)`), so exactness is kept;
it makes the cycles the physical ones and the D interval better calibrated (README).

In whitened coordinates :math:`y - x m = L z` and with :math:`a = L^{-1} m`,

.. math::
    \log r = \min_{c \in \{c_1, c_2\}} \big[-(x-c)\, a\cdot z - \tfrac12 (x-c)^2 |a|^2\big],

one dot product per step, and :math:`\varepsilon = 2\Phi(-w|a|)` for half-width :math:`w`.

Choice of C
-----------
:math:`C_\pm = [x_{\pm\Delta} - w, x_{\pm\Delta} + w]` with
:math:`w = \min(\kappa/|a|,\ 4/\sqrt{\tau})`, :math:`\kappa = 1`.  For :math:`\tau \gg h`,
:math:`|a|^2 \approx 2\tau^2/h`, so :math:`w \approx \sqrt{h/2}/\tau`, half the one-step standard
deviation :math:`\sqrt{2h}/\tau` of X, and
:math:`\varepsilon = 2\Phi(-1) \approx 0.32` per stuck step: C shrinks to the threshold as
:math:`h \to 0`, so a regeneration happens only where the continuous-time rule ends a half excursion.
It does not happen at every such release (the coin's chance does not tend to 1 as :math:`h \to 0`),
so a cycle spans a random number (>= 1) of the paper's threshold-to-threshold excursions and its mean
duration is about 2-4 times theirs at Fig. 3's parameters (1.9 at its point; RESULTS.md, "Where the
reproduction and the paper's text differ"); D and M0, ratios over i.i.d. cycles, do not depend on that.

For :math:`\tau \ll h`, :math:`|a|^2 \approx \tau^2/(2h) \to 0`: C covers :math:`\pm 4` stationary
standard deviations and :math:`\varepsilon \to 1`, so every stuck step is a regeneration chance.  Either way the
expected wait is a few stuck visits, so no excursion is astronomically long.
"""
from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
from jax.scipy.special import ndtr

from .ou import OUStep

KAPPA = 1.0
COVER_SD = 4.0


class SplitSet(eqx.Module):
    """Small set C = [c1, c2] of the noise value for stuck states, with its minorisation."""

    c1: jnp.ndarray
    c2: jnp.ndarray
    a1: jnp.ndarray  # a = L^{-1} m
    a2: jnp.ndarray
    a_sq: jnp.ndarray  # |a|^2
    half_d: jnp.ndarray  # w |a|; epsilon = 2 Phi(-half_d)

    @property
    def epsilon(self):
        return 2.0 * ndtr(-self.half_d)

    def log_coin(self, x, z1, z2):
        """log r(x, y) for y = x m + L z; only meaningful for x in [c1, c2]."""
        za = z1 * self.a1 + z2 * self.a2
        d1, d2 = x - self.c1, x - self.c2
        return jnp.minimum(-d1 * za - 0.5 * d1 * d1 * self.a_sq, -d2 * za - 0.5 * d2 * d2 * self.a_sq)

    def contains(self, x):
        return (x >= self.c1) & (x <= self.c2)

    @property
    def center(self):
        return 0.5 * (self.c1 + self.c2)


def split_set(ou: OUStep, x_threshold, tau, kappa: float = KAPPA, cover_sd: float = COVER_SD) -> SplitSet:
    """The set C around ``x_threshold`` for the step ``ou`` (module docstring)."""
    a1 = ou.m1 / ou.L11
    a2 = (ou.m2 - ou.L21 * a1) / ou.L22
    a_sq = a1 * a1 + a2 * a2
    w = jnp.minimum(kappa / jnp.sqrt(a_sq), cover_sd / jnp.sqrt(tau))
    dt = ou.m1.dtype
    c = jnp.asarray(x_threshold, dt)
    return SplitSet(c - w, c + w, a1, a2, a_sq, jnp.asarray(w * jnp.sqrt(a_sq), dt))
