r"""``method="auto"``: the cost model that picks the PDMP or the DI.

Both approximate the same limit (the DI driven by OU noise) at a cost per unit of
nondimensional time (:math:`\tau_0`):

* PDMP: about :math:`\Lambda' = 2/(\tau'\delta')^2` noise jumps (plus the stick/slip events,
  which do not grow as :math:`\delta \to 0`), each ``EVENT_COST`` DI steps of work;
* DI: :math:`1/h'` steps.

``EVENT_COST`` was measured when the method was added (``dryfric bench``, Fig. 3 point, float64, 2-core
CPU: DI 1.6e7 lane-steps/s, PDMP 1.6e7 events/s, so 1.0) and is kept: it picks which method ``auto`` runs, so
changing it changes results.  Both engines have been sped up since, unequally (PERFORMANCE.md: DI 1.08e8
against PDMP 3.7e7 at 0.2.5; an audit on 2026-12-07, warm: 7.1e7 against 5.2e7), but the time per result
did not follow the rates: at the Fig. 3 point the PDMP gave N = 3000 in 0.27 s against the DI's 0.50 s.
Cost per unit of simulated time is the right currency because the CI of D shrinks with the total
simulated time for both methods.  The PDMP wins when the noise is slow (large :math:`\tau'`), the DI when it
is fast: at the Fig. 3 point
(:math:`\tau' = 1.47`, default :math:`\delta' = 0.05`, :math:`h' = 0.002`) the PDMP does ~370
events per :math:`\tau_0` against 510 DI steps, so ``auto`` picks the PDMP; at
:math:`\tau = 0.05` s (:math:`\tau' = 0.15`) it needs 3.7e4 events and ``auto`` picks the DI.
"""
from __future__ import annotations

import math

from .noise import delta_max
from .params import Params

#: work of one PDMP event in DI steps (measured, see module docstring)
EVENT_COST = 1.0
#: default nondimensional grid step delta' = delta sqrt(Gamma)/Delta (delta' << 1), at most half
#: the admissible maximum
DELTA_ND = 0.05
#: and at most this fraction of the noise's stationary SD 1/sqrt(tau'): delta' sqrt(tau') =
#: delta sqrt(tau) <= 1/16, both dimensionless. Measured (README "The PDMP", bullet "Default δ"): at tau = 1 s,
#: Gamma = 1, where the stick thresholds lie 3.5 and 4.2 SD out, delta sqrt(tau) = 0.12 puts D
#: 6-7% (4 SE) below the DI and 1/16 agrees with it (-0.7 +- 1.8% SE); at Gamma = 1 and 1.29
#: halving 1/16 again moves D by -1.4 +- 1.1% (SE), no visible bias
DELTA_PER_SD = 0.0625


def default_delta(params: Params) -> float:
    r"""Default physical grid step :math:`\delta = \delta'\Delta/\sqrt\Gamma` with
    :math:`\delta' = \min(0.05,\ \tfrac{1}{16}/\sqrt{\tau'},\ \delta'_{\max}/2)`.

    The second cap keeps the grid step below 1/16 of the stationary SD of the noise
    (:math:`\delta\sqrt\tau \le 1/16`); it binds for slow noise (:math:`\tau' > 1.56`), where the
    jump chain's tail near deep stick thresholds otherwise biases D low (README "The PDMP", bullet "Default δ").
    """
    nd = params.nondim()
    d = min(DELTA_ND, DELTA_PER_SD / math.sqrt(nd.tau), 0.5 * delta_max(nd.tau, nd.gamma_bar))
    return d * params.Delta / math.sqrt(params.Gamma)


#: the deepest stick threshold, in stationary SDs of the noise, at which the default delta was
#: measured against the DI (tau = 1 s, Gamma = 1: 4.18 SD, README "The PDMP", bullet "Default δ")
DELTA_VALIDATED_SD = 4.2


def threshold_depth(params: Params) -> float:
    r"""How far the deeper stick threshold :math:`x_\pm = \pm 1 - \bar\gamma'` lies in the noise's
    stationary law, in SDs :math:`1/\sqrt{\tau'}`: :math:`(1 + |\bar\gamma'|)\sqrt{\tau'}`."""
    nd = params.nondim()
    return (1.0 + abs(nd.gamma_bar)) * math.sqrt(nd.tau)


def default_delta_note(params: Params) -> str | None:
    """The caveat for a PDMP run on the default delta beyond :data:`DELTA_VALIDATED_SD`, else None."""
    depth = threshold_depth(params)
    if depth <= DELTA_VALIDATED_SD:
        return None
    return (f"the default delta was checked against the DI only up to stick thresholds {DELTA_VALIDATED_SD:g} SD "
            f"out in the noise's law; here one lies {depth:.3g} SD out, where the jump grid's tail may bias D: "
            "compare with method 'di' or with half this delta")


def pdmp_events_per_tau0(params: Params, delta: float) -> float:
    d = delta * math.sqrt(params.Gamma) / params.Delta
    return 2.0 / (params.tau_nd * d) ** 2


def choose_method(params: Params, h: float, delta: float) -> tuple[str, str]:
    """``(method, reason)`` for ``method="auto"`` with physical step h and grid step delta: the PDMP only
    if it is strictly cheaper per tau0; at an exact tie the DI (the default method, no grid to choose)."""
    pdmp = EVENT_COST * pdmp_events_per_tau0(params, delta)
    di = params.tau0 / h
    pick = "pdmp" if pdmp < di else "di"
    why = (f"cost per tau0: PDMP {pdmp:.3g} step-equivalents (2/(tau' delta')^2 = "
           f"{pdmp / EVENT_COST:.3g} events x {EVENT_COST:g}) vs DI {di:.3g} steps (1/h'); chose {pick}")
    return pick, why
