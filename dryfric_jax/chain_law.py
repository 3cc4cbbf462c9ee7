r"""The exact stationary law, mobility and diffusivity of the DI chain at a finite step, for
white noise: what the simulation converges to at fixed ``h`` as :math:`\tau/h \to 0`.

As :math:`\tau/h \to 0` the step's noise :math:`h\,\Xi_n` (:mod:`dryfric_jax.ou`) becomes
:math:`\sqrt{2h}\,Z_n` with i.i.d. standard normals (its variance is
:math:`2h - 2\tau(1 - e^{-h/\tau})` and successive ones correlate by :math:`O(\tau/h)`), and the
velocity alone is a Markov chain (nondimensional units, :mod:`dryfric_jax.di`):

.. math::
    w = V_n + h\,b(V_n) + \sqrt{2h}\,Z_n, \qquad V_{n+1} = \operatorname{sign}(w)\max(|w| - h, 0),
    \qquad b(v) = -v/\tau_L' + \bar\gamma'.

From :math:`v` it lands at 0 with probability :math:`\Phi((h - m)/s) - \Phi((-h - m)/s)` and
elsewhere with density :math:`\varphi((y \pm h - m)/s)/s` for :math:`y \gtrless 0`, where
:math:`m = v + h b(v)`, :math:`s = \sqrt{2h}`.  Its stationary law :math:`\pi` (an atom at 0 and
a density on each half line) is the fixed point of that kernel, computed here by Nystrom's
method: trapezoid nodes on :math:`[-L, 0^-]` and :math:`[0^+, L]` plus the atom, each column of
the transition matrix renormalised to a probability.  With :math:`dU_n = h(V_n + V_{n+1})/2`
(the simulation's trapezoid displacement), :math:`M_0 = E_\pi V` and, from the Poisson equation
:math:`g - Pg = \bar f - h M_0` with :math:`\bar f(v) = E[dU_n \mid V_n = v]`, the martingale
decomposition of :math:`\sum dU_n` gives

.. math::
    D = \frac1h\,E_\pi\big[(dU_n - h M_0 - g(V_n) + g(V_{n+1}))^2\big]

(:math:`D = \lim \mathrm{Var}\,U(t)/t`, MODEL_NOTES section 1).  The grid error is
:math:`O(dv^2)`: 12 nodes per noise sd instead of the default 8 change D and :math:`E[V^2]` by
~1e-4 relative.  As
:math:`h \to 0` all three tend to the white-noise values of :mod:`dryfric_jax.theory`, to first
order in ``h``: at Fig. 5's point and the default step (h' = 0.01) :math:`E[V^2]` is 0.40% below
the continuum value, which is most of the gap Fig. 5 shows.
"""
from __future__ import annotations

import math
import sys
import warnings
from dataclasses import dataclass

import numpy as np
from scipy import linalg, special

from .params import Params, check_params, check_positive, real_or_none, refuse_traced, rounded_bound, shown
from .plan import H_MIN_REL, check_count, check_h, h_max
from .theory import _nd, _scale

MAX_NODES = 6001  # dense Nystrom: O(n^3) solves; at 6001 nodes 0.29 GB per n x n array, ~2 GB peak, ~15 s
#: fewest grid nodes per step-noise sd: the O(dv^2) grid error of D and E[V^2] is 5e-4 relative at 4
#: (measured at Fig. 5's point and b = 0, h' = 0.1, against 24), 1e-4 at the default 8, 8e-3 at 1
MIN_NODES_PER_SD = 4
#: narrowest grid, in widths of the continuum law on each side of 0: the tails beyond 15 widths
#: (exponential at worst, b = 0) change D by 6e-6 at h' = 0.1 (where the 10 sds of padding add ~4.5
#: widths) but by 5e-5, 8e-5 and 1.1e-4 at h' = 0.02, 0.01, 0.005, and by 6e-5 to 1.5e-4 at gamma_bar' = 0.5
#: (h' = 0.1, 0.03; a chain-law audit against 45 widths): about the default grid's own error; beyond the
#: default 30, by < 1e-10
MIN_WIDTH = 15.0
#: the grid spans at least MIN_WIDTH widths plus 10 step-noise sds on each side of 0, and a width is at
#: least sqrt(5) sds at any admissible h (h' <= 0.1 min(1, tau_L')), so more nodes per sd than this always
#: exceed MAX_NODES: (MAX_NODES - 3) / 2 / (10 + 15 sqrt(5)) = 68.9 (it was 299, from the 10 sds alone:
#: 69-299 passed the check and were refused later as "the law is too wide")
MAX_NODES_PER_SD = int((MAX_NODES - 3) / 2 / (10 + MIN_WIDTH * math.sqrt(5)))
#: below this mean against the law's sd, :math:`|E V|/\mathrm{sd}\,V`, the solve's round-off in
#: :math:`\pi` (about 1.5e3 eps / that ratio, relative: 0.7% at tau_L' = 1e-20, a factor 460 at 1e-30,
#: gamma_bar' = 0.5; a chain-law audit) makes M0 unreliable to 1e-4: a warning says so
M0_MIN_RATIO = 1.5e3 * sys.float_info.epsilon / 1e-4
#: the grid's defaults (:func:`white_chain_law`); a refusal past them names the caller's grid
DEFAULT_NODES_PER_SD, DEFAULT_WIDTH = 8, 30.0


@dataclass(frozen=True)
class ChainLaw:
    """Exact white-noise limit of the DI chain at step ``h`` (physical units, like the estimators)."""

    h: float
    M0: float  # = E_pi[V]
    mean_v2: float  # E_pi[V^2]
    D: float
    p_stuck: float  # pi({0})
    n_nodes: int


def _norm_pdf(z):
    return np.exp(-0.5 * z * z) / math.sqrt(2 * math.pi)


def _norm_cdf(z):
    return 0.5 * special.erfc(-z / math.sqrt(2))


def _law_span(width: float, itl: float, g: float) -> float:
    r"""The grid's span past 0 (nondimensional) less its 10 step-noise sds: ``width`` widths of the continuum law,
    or past a bump of sd :math:`\sqrt{\tau_L'}` at :math:`|v^*| = (|g| - 1)\tau_L'` (theory._mode_points)."""
    law = width * _scale(itl, g)
    if itl > 0 and abs(g) > 1:
        law = max(law, (abs(g) - 1) / itl + width / math.sqrt(itl))
    return law


def _least_h(params: Params, law: float, nodes_per_sd: int) -> float:
    """The least h (s) whose grid fits ``MAX_NODES``, h-free (it may underflow): nodes ~ 2 L / dv with
    dv^2 = 2 h' / nodes_per_sd^2, exactly ceil(law nps / s + 10 nps) <= (MAX_NODES - 3) / 2 (``law``:
    :func:`_law_span`); room > 0 as nodes_per_sd <= MAX_NODES_PER_SD; inf for a huge width (no OverflowError)."""
    room = (MAX_NODES - 3) // 2 - 10 * nodes_per_sd
    span = law * nodes_per_sd / room
    return 0.5 * span * span * params.tau0 if span < 1e150 else math.inf


def _check_chain_h(params: Params, h, nodes_per_sd: int, law: float) -> float:
    """``h`` checked against the range the chain law takes: :func:`~dryfric_jax.plan.check_h`'s, its lower end
    raised 1% above the least h whose grid fits ``MAX_NODES`` (:func:`_least_h`), so that the range a refusal
    prints is the one accepted (an audit: h = 0 was told [6.7e-14, 0.0067] s, then 1e-12 was refused for its
    grid).  Where no admissible h fits, the grid's own refusal in :func:`white_chain_law` says so."""
    refuse_traced("h", h, "the chain law")  # before the range test, which took a tracer for a bad number
    need = 1.01 * _least_h(params, law, nodes_per_sd)
    hm = h_max(params)
    lo = max(H_MIN_REL * min(params.tau0, params.tau_L), need)
    v = None if h is None else real_or_none(h)
    # a NaN, an inf or a non-number too: they were told check_h's wider range, which the chain law refuses in part
    if h is not None and need <= hm and not (v is not None and lo <= v <= hm):
        finite = v is not None and math.isfinite(v) and v > 0
        raise ValueError(f"h must be in [{rounded_bound(lo, lower=True)}, {rounded_bound(hm, lower=False)}] s for the "
                         f"chain law (got {shown(h)})" + ("" if not finite else ": " + (
                             f"below it its grid of nodes_per_sd = {nodes_per_sd} per step-noise sd would exceed "
                             f"{MAX_NODES} nodes" if v < lo else "above it the step is coarse against min(tau0, "
                             "tau_L), the range every DI step is held to")))
    return check_h(params, h)


def white_chain_law(params: Params, h: float, *, nodes_per_sd: int = DEFAULT_NODES_PER_SD,
                    width: float = DEFAULT_WIDTH) -> ChainLaw:
    r"""Stationary :math:`E[V]`, :math:`E[V^2]`, :math:`P(V = 0)` and the diffusivity of the
    white-noise DI chain at step ``h`` (s), by Nystrom's method (module docstring).

    ``nodes_per_sd`` grid nodes per standard deviation :math:`\sqrt{2h'}` of one step's noise (an
    integer in [:data:`MIN_NODES_PER_SD`, :data:`MAX_NODES_PER_SD`]), the grid reaching ``width``
    widths of the continuum law past the origin on each side (a finite number >= :data:`MIN_WIDTH`):
    fewer would cost the result its accuracy (a width of -1 gave D 25 times too small).
    ``tau`` is not used: this is the :math:`\tau/h \to 0` limit, which the name says (unlike
    :func:`~dryfric_jax.theory.exact_D`, no warning where ``params`` carry a larger tau: the figures and
    ``dryfric theory --h`` ask for this chain at their own h whatever the tau).  Raises ``ValueError`` where
    the grid would exceed ``MAX_NODES`` (``h`` small against the law's width: small h, or a wide
    law, :math:`|\bar\gamma| \to \Delta` with :math:`\tau_L = \infty`, or a bump far from 0,
    :math:`|\bar\gamma'| > 1` with a large :math:`\tau_L'`: its sd :math:`\sqrt{\tau_L'}` at
    :math:`(|\bar\gamma'| - 1)\tau_L'`, which the grid covers too), for an ``h`` outside
    :func:`~dryfric_jax.plan.check_h`'s range and for a law that is not recurrent.
    """
    check_params(params)
    nodes_per_sd = check_count("nodes_per_sd", nodes_per_sd, MIN_NODES_PER_SD, MAX_NODES_PER_SD,
                               f" (grid nodes per step-noise sd: the grid error is 5e-4 relative at "
                               f"{MIN_NODES_PER_SD}, 8e-3 at 1; more than {MAX_NODES_PER_SD} always exceed "
                               f"MAX_NODES = {MAX_NODES})")
    w = real_or_none(width)
    if w is None or not (math.isfinite(w) and w >= MIN_WIDTH):
        raise ValueError(f"width must be a finite number >= {MIN_WIDTH:g} (widths of the law on each side of 0: "
                         f"the tails beyond {MIN_WIDTH:g} change D by ~1e-5 to 1.5e-4 relative, about the default "
                         f"grid's error) (got {shown(width)})")
    width = w
    itl, g = _nd(params)
    law = _law_span(width, itl, g)
    h = _check_chain_h(params, h, nodes_per_sd, law)
    hn = h / params.tau0
    s = math.sqrt(2 * hn)
    dv = s / nodes_per_sd
    L = law + 10 * s
    ratio = L / dv if dv > 0 else math.inf  # h near 5e-324: dv underflows
    kf = math.ceil(ratio) if ratio < 1e300 else math.inf
    if 2 * kf + 3 > MAX_NODES:
        nodes = 2.0 * kf + 3  # a float: one readable number, not 150 digits
        need = _least_h(params, law, nodes_per_sd)  # 1% up below: the message prints 3 digits
        if need <= h_max(params):
            fix = f"use h >= {min(1.01 * need, h_max(params)):.3g} s or fewer nodes_per_sd"
        elif width > DEFAULT_WIDTH or nodes_per_sd > DEFAULT_NODES_PER_SD:  # the caller's grid does not fit
            fix = (f"no admissible h (<= {h_max(params):.3g} s) is large enough at width = {width:g} and "
                   f"nodes_per_sd = {nodes_per_sd}: lower them (defaults {DEFAULT_WIDTH:g} and {DEFAULT_NODES_PER_SD})")
        else:
            fix = f"no admissible h (<= {h_max(params):.3g} s) is large enough: the law is too wide"
        raise ValueError(f"h = {h:.4g} s: the dense chain law would need {nodes:.3g} grid nodes > {MAX_NODES} (the "
                         f"law spans +-{L:.3g} against a step noise sd of {s:.3g}, nondimensional); {fix}")
    k = int(kf)
    half = np.arange(k + 1) * dv  # 0+ ... L
    hw = np.full(k + 1, dv)
    hw[0] = hw[-1] = dv / 2
    y = np.concatenate([-half[::-1], [0.0], half])  # node k + 1 is the atom at 0
    w = np.concatenate([hw[::-1], [1.0], hw])
    atom = k + 1
    side = np.concatenate([-np.ones(k + 1), [0.0], np.ones(k + 1)])  # 0- and 0+ are two nodes
    m = y + hn * (g - y * itl)  # predictor mean from each node
    shift = hn * side[:, None]  # y = w -+ h on the two half lines
    P = _norm_pdf((y[:, None] + shift - m[None, :]) / s) / s * w[:, None]  # P[i, j]: j -> cell i
    P[atom] = _norm_cdf((hn - m) / s) - _norm_cdf((-hn - m) / s)
    P /= P.sum(0, keepdims=True)
    n = y.size
    # pi = P pi, sum pi = 1: replace one (redundant) balance equation by the normalisation
    A = P - np.eye(n)
    A[0] = 1.0
    rhs = np.zeros(n)
    rhs[0] = 1.0
    pi = linalg.solve(A, rhs)
    mean_v = pi @ y
    mean_v2 = float(pi @ (y * y))
    sd_v = math.sqrt(max(mean_v2 - float(mean_v) ** 2, 0.0))
    if g != 0.0 and abs(float(mean_v)) < M0_MIN_RATIO * sd_v:
        from .api import DryfricWarning  # (api imports the package's modules; this one is imported by it)

        ratio = abs(float(mean_v)) / sd_v
        warnings.warn(f"the chain law's M0 is unreliable here: E[V] is {ratio:.2g} sds of V from 0, "
                      f"below {M0_MIN_RATIO:.2g}, and the solve's round-off is ~1.5e3 eps / that, relative (D and "
                      "E[V^2] are not affected; theory.exact_M0 gives the continuum's)", DryfricWarning, stacklevel=2)
    mu = hn * mean_v  # E_pi[dU]
    dU = 0.5 * hn * (y[None, :] + y[:, None])  # [i, j]: step j -> i
    fbar = (P * dU).sum(0)
    # Poisson equation g - P^T g = fbar - mu, pinned by pi . g = 0: (I - P^T + 1 pi^T) g = fbar - mu
    gsol = linalg.solve(np.eye(n) - P.T + np.outer(np.ones(n), pi), fbar - mu)
    a = dU - mu - gsol[None, :] + gsol[:, None]
    D_nd = float(((P * a * a).sum(0) @ pi) / hn)
    return ChainLaw(h=h, M0=float(mean_v) * params.v0, mean_v2=mean_v2 * params.v0**2,
                    D=D_nd * params.D0, p_stuck=float(pi[atom]), n_nodes=n)


def white_chain_atom(density_at_zero, h_nd: float):
    r"""Leading-order mass of the white-noise chain's atom at :math:`V = 0` (nondimensional step
    :math:`h`, module docstring): the chain lands at 0 when :math:`|w| \le h`, so from a law whose
    density near 0 is :math:`p(0)` it does so with probability

    .. math::
        P(V_{n+1} = 0) \approx 2h\,p(0)

    (the atom is renewed every step, so at a time t it is :math:`2h\,p(0, t)` of the law at t).
    It vanishes as :math:`h \to 0`, as the continuum law has no atom.  The next order is
    :math:`O(h^{3/2})`: the chain's density is depleted near 0, and its exact stationary atom
    (:func:`white_chain_law`, ``p_stuck``, b = 0, where :math:`p(0) = 1/2`) is 0.94, 0.92, 0.89 and
    0.83 of :math:`2h\,p(0)` at :math:`h' = 0.005, 0.01, 0.02, 0.05`, about :math:`1 - 0.8\sqrt{h'}`
    (``tests/test_chain_law.py``).  Fig. 6 marks it in the bin at :math:`v' = 0`.

    Args:
        density_at_zero: :math:`p(0)` (nondimensional), a number or array of finite numbers >= 0.
        h_nd: the step :math:`h' = h/\tau_0`, finite and > 0.

    ``ValueError`` naming the argument otherwise (NaN, inf and a negative density gave a NaN, an inf and a
    negative probability: an audit).
    """
    check_positive("h_nd", h_nd)
    try:
        p = np.asarray(density_at_zero, float)
    except (TypeError, ValueError):
        p = None
    if p is None or not (np.isfinite(p).all() and (p >= 0).all()):
        raise ValueError(f"density_at_zero must hold finite numbers >= 0 (got {shown(density_at_zero)})")
    return 2.0 * float(h_nd) * p
