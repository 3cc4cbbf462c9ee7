r"""Fig. 4 (paper section 7.1): normalised stationary velocity covariance :math:`h(\rho)/h(0)`,
:math:`h(\rho) = \mathrm{Cov}(V(t), V(t+\rho))`, for tau = 0.25, 0.5, 1 s at the Fig. 3 point
(Gamma = 5, tau_L = 0.067, gamma_bar = 0.342): PDMP (delta = 0.125) solid, DI dotted.

Long stationary runs: each path starts at s_+ (PDMP) or (stationary X, V = 0) (DI)
and is discarded for a burn-in of ``BURN_TAU0`` = 50 tau0 (17-68 times the noise's correlation time
tau' = 0.74-2.95 of the scene, whose relaxation sets the law of (X, V); not several excursion durations: at
tau = 1 s the PDMP's mean excursion, 16 s, is about the burn-in's 17 s), then
V is recorded every ``DT_REC`` tau0; the covariance is the FFT autocorrelation per path around
the grand mean, averaged over paths, and normalised by its lag-0 value; the SE of that ratio
comes from the paths by the delta method (:func:`~dryfric_jax.paths.autocorrelation`).
"""
from __future__ import annotations

import math
import time

import jax
import numpy as np

from ..di import make_di_model
from ..params import FIG3, Params
from ..paths import autocorrelation, di_stationary, pdmp_stationary
from ..pdmp import make_pdmp_model
from ..plan import default_h
from .common import plt, save
from .points import report_step

TAUS = (0.25, 0.5, 1.0)
BURN_TAU0 = 50.0
#: the plot's lowest value (log axis); a band below it is drawn down to it
FLOOR = 1e-4
DT_REC = 0.05


def fig4(out_dir, quick, seed):
    t0 = time.perf_counter()
    paths, length = (128, 100.0) if quick else (2048, 1000.0)
    max_lag_s = 3.0
    fig, ax = plt.subplots(figsize=(6.5, 4.2))
    nums = dict(tau=TAUS, paths=paths, length_tau0=length, burn_in_tau0=BURN_TAU0, dt_rec_tau0=DT_REC, curves={})
    for j, tau in enumerate(TAUS):
        p = Params(FIG3["Gamma"], FIG3["Delta"], tau, FIG3["tau_L"], FIG3["gamma_bar"])
        lags = round(max_lag_s / p.tau0 / DT_REC)
        n_rec = round(length / DT_REC)
        key = jax.random.fold_in(jax.random.key(seed), j)
        report_step(f"PDMP stationary paths, tau={tau:g} s ({2 * j + 1} of {2 * len(TAUS)})")
        Vp = pdmp_stationary(make_pdmp_model(p, 0.125), key, paths, n_rec, DT_REC, BURN_TAU0)
        # the DI step: the default's, shortened to a whole fraction of DT_REC, so that the DI's lags are the
        # PDMP's (DT_REC / h rounded used to put the DI's lag k at 0.988 k DT_REC at tau = 0.25 s: 8.6 SE)
        every = math.ceil(DT_REC / (default_h(p) / p.tau0))
        h_nd = DT_REC / every
        report_step(f"DI stationary paths, tau={tau:g} s ({2 * j + 2} of {2 * len(TAUS)})")
        Vd, _ = di_stationary(make_di_model(p, h_nd * p.tau0), jax.random.fold_in(key, 1), paths, n_rec, every,
                              burn_steps=round(BURN_TAU0 / h_nd), record="V")
        # each curve at the lags it was recorded at (its interval times k), so a DI recorded at another
        # interval than the PDMP's shows in the JSON's rho instead of being plotted at the PDMP's lags
        rec_tau0 = {"pdmp": DT_REC, "di": every * h_nd}
        cur = {}
        for name, V, style in (("pdmp", Vp, "-"), ("di", Vd, ":")):
            rho = np.arange(lags + 1) * rec_tau0[name] * p.tau0
            r, se = autocorrelation(V, lags, center=True)
            # a log axis cannot show r <= 0: those lags are left out (a gap), not drawn at a floor (clipping
            # them to 1e-4 drew a flat line that looked like data); the band is the estimate +- 2 SE
            ax.semilogy(rho, np.where(r > 0, r, np.nan), style, color=f"C{j}", label=f"tau = {tau:g} s ({name})")
            # a band reaching the axis' floor: consistent with <= 0 there
            ax.fill_between(rho, np.maximum(r - 2 * se, FLOOR), np.maximum(r + 2 * se, FLOOR), color=f"C{j}",
                            alpha=0.15, lw=0)
            cur[name] = dict(rho=rho, h_over_h0=r, se=se)
        cur["di_h"], cur["di_every"] = h_nd * p.tau0, every
        diff = np.abs(cur["pdmp"]["h_over_h0"] - cur["di"]["h_over_h0"])
        se = np.hypot(cur["pdmp"]["se"], cur["di"]["se"])
        cur["max_diff_in_se"] = float(np.max(diff[1:] / se[1:]))  # lag 0 is 1 by construction
        nums["curves"][f"{tau:g}"] = cur
    ax.set_xlabel("rho (s)")
    ax.set_ylabel("h(rho) / h(0)")
    ax.set_ylim(FLOOR, 1.5)
    ax.set_title("bands: estimate +- 2 SE, pointwise; lags where the estimate is <= 0 are gaps "
                 f"(log axis, from {FLOOR:g})", fontsize=8)
    ax.legend(fontsize=7)
    return save(fig, out_dir, "fig4", nums, t0, quick=quick, seed=seed)
