r"""Table 1, Fig. 6 and Fig. 7 (paper section 7.2): pure dry friction in nondimensional units,
DI with colored noise :math:`\tau' = 0.5\cdot10^{-i}` against Touchette's white-noise formulas
(MODEL_NOTES section 2; :mod:`dryfric_jax.theory`).

* Table 1: :math:`E[V'(t')]` from :math:`v'_i = 1`, :math:`x'_i \sim \mathcal N(0, 1/\tau')`,
  against the exact first moment of the model (and, for the record, of unit-intensity noise,
  the paper's printed row);
* Fig. 6: the transient velocity density at several t' against the propagator, and the atom
  :math:`P(V' = 0)` the simulation adds in the bin [0, w): the step's own :math:`2h'p(0, t')`
  (:func:`~dryfric_jax.chain_law.white_chain_atom`; it vanishes as h' -> 0) where the noise is
  white at the step, and more at :math:`\tau' = 0.05`, where the colored noise holds V' at 0;
* Fig. 7: the stationary correlation :math:`\langle V'(0)V'(t')\rangle` (burn-in of
  ``BURN_TAU0`` :math:`\tau_0` from V = 0 and stationary noise; FFT autocorrelation per path) against
  :math:`C(t')`.

Error bars are standard errors over independent paths (bands: 2 SE, pointwise: each bin or lag is covered ~95% of
the time, the whole curve much less often, ~0.88 of Fig. 7's 201 lags and none of Fig. 6's 240 bins at once in a
coverage audit; the tests' checks take the largest deviate over the points, against 4-5).
"""
from __future__ import annotations

import time

import jax
import numpy as np

from .. import theory
from ..chain_law import white_chain_atom
from ..di import make_di_model
from ..params import Params
from ..paths import autocovariance, di_stationary, di_transient
from .common import exact_steps, plt, save
from .points import report_step

T_TABLE = (0.05, 0.125, 0.25, 0.5, 1.0, 2.5)
PAPER_ROW = (0.950, 0.875, 0.757, 0.568, 0.336, 0.090)  # printed: unit-intensity noise (MODEL_NOTES 2)
TAUS = (0.5e-1, 0.5e-2, 0.5e-3, 0.5e-4)
T_DENSITY = (0.25, 1.0, 2.5)
BURN_TAU0 = 40.0


def _model(tau_nd, h_nd):
    return make_di_model(Params.from_nondim(tau_nd), h_nd)


def table1(out_dir, quick, seed):
    t0 = time.perf_counter()
    n, h, tau = (40_000, 1.25e-3, 0.5e-5) if quick else (1_000_000, 2e-4, 0.5e-5)  # t' = 0.125: 100 steps
    report_step(f"DI transient paths, tau'={tau:g}")
    V = di_transient(_model(tau, h), jax.random.key(seed), n, [exact_steps(t, h) for t in T_TABLE])
    mc, se = V.mean(0), V.std(0, ddof=1) / np.sqrt(n)
    exact = [theory.first_moment(t, 1.0) for t in T_TABLE]
    unit = [theory.first_moment_unit_intensity(t, 1.0) for t in T_TABLE]
    nums = dict(t=T_TABLE, mc=mc, se=se, exact_model=exact, exact_unit_intensity=unit, paper_row=PAPER_ROW,
                max_abs_err=float(np.max(np.abs(mc - exact))), max_err_in_se=float(np.max(np.abs(mc - exact) / se)),
                tau_nd=tau, h_nd=h, n_paths=n)
    rows = _table1_rows(nums)
    fig, ax = plt.subplots(figsize=(11, 2.6))
    ax.axis("off")
    # fixed font and a wide first column: left to itself matplotlib shrank every cell to 2 pt to fit the labels
    table = ax.table(cellText=[[r[0]] + [f"{v:.3f}" for v in r[1]] for r in rows], loc="center",
                     colWidths=[0.4] + [0.1] * len(T_TABLE))
    table.auto_set_font_size(False)
    table.set_fontsize(9)
    table.scale(1.0, 1.3)
    ax.set_title(f"Table 1: E[V'(t')] from v'=1, tau'={tau:g}, h'={h:g}, {n} paths")
    return save(fig, out_dir, "table1", nums, t0, quick=quick, seed=seed)


def _table1_rows(nums):
    return [("t'", nums["t"]), ("MC (this model)", nums["mc"]), ("MC 2 SE", 2 * np.asarray(nums["se"])),
            ("exact, this model", nums["exact_model"]),
            ("exact, unit-intensity noise (Gamma_w = Gamma)", nums["exact_unit_intensity"]),
            ("paper's printed EF row", nums["paper_row"])]


def table1_text(nums) -> str:
    """Table 1's rows as text, from the scene's numbers (its JSON): what ``dryfric figures`` prints once the
    scenes are written (the scene printed them before it wrote its files, so a closed stdout lost the scene, and
    with ``--fig all`` Figs. 7-9 too: an audit)."""
    return "\n".join(f"{r[0]:>48s} " + " ".join(f"{float(v):6.3f}" for v in r[1]) for r in _table1_rows(nums))


def freeman_tukey(count, expected):
    r"""Freeman-Tukey deviates :math:`\sqrt{c} + \sqrt{c + 1} - \sqrt{4\lambda + 1}` of Poisson
    counts c with expected counts :math:`\lambda` (*Ann. Math. Statist.* 21 (1950) 607): close to
    N(0, 1) under the null hypothesis also where :math:`\lambda` is a few counts or below, unlike
    :math:`(c - \lambda)/\sqrt{\max(c, 1)}` (the plotted bands' SE), whose largest value over the
    480 bins of the quick Fig. 6 at :math:`\tau' \le 5\cdot10^{-4}` exceeds 5 in 12% of exact Poisson
    draws (these deviates in 0.2%; ``tests/test_figure_numbers.py``)."""
    c, lam = np.asarray(count, float), np.asarray(expected, float)
    return np.sqrt(c) + np.sqrt(c + 1) - np.sqrt(4 * lam + 1)


def fig6(out_dir, quick, seed):
    t0 = time.perf_counter()
    n, h = (20_000, 2e-3) if quick else (400_000, 2e-4)
    edges = np.linspace(-4, 4, 81)
    mid, w = 0.5 * (edges[1:] + edges[:-1]), edges[1] - edges[0]
    fig, axs = plt.subplots(1, len(TAUS), figsize=(4 * len(TAUS), 3.4), sharey=True)
    k0 = int(np.searchsorted(edges, 0.0, side="right")) - 1  # the bin [0, w), where V' = 0 is counted
    # the step's atom at V' = 0 (the propagator has none): marked on top of the exact bin
    atom = white_chain_atom([theory.propagator(np.zeros(1), t, 1.0)[0] for t in T_DENSITY], h)
    nums = dict(tau_nd=TAUS, t=T_DENSITY, h_nd=h, n_paths=n, max_dev_in_se={}, max_ft_dev={},
                edges=edges.tolist(), counts={}, exact_density={},  # the plotted numbers: density = counts/(n w)
                p_zero={}, p_zero_se={}, p_zero_step=atom.tolist())  # P(V' = 0): measured, its SE, 2 h' p(0, t')
    for j, (tau, ax) in enumerate(zip(TAUS, axs)):
        report_step(f"DI transient paths, tau'={tau:g} ({j + 1} of {len(TAUS)})")
        V = di_transient(_model(tau, h), jax.random.fold_in(jax.random.key(seed), j), n,
                         [exact_steps(t, h) for t in T_DENSITY])
        devs, ft = [], []
        nums["counts"][f"{tau:g}"], nums["exact_density"][f"{tau:g}"] = [], []
        p0 = (V == 0).mean(0)
        nums["p_zero"][f"{tau:g}"], nums["p_zero_se"][f"{tau:g}"] = p0.tolist(), np.sqrt(p0 * (1 - p0) / n).tolist()
        for i, t in enumerate(T_DENSITY):
            cnt, _ = np.histogram(V[:, i], edges)
            dens, se = cnt / (n * w), np.sqrt(np.maximum(cnt, 1)) / (n * w)
            ex = theory.propagator(mid, t, 1.0)
            ax.fill_between(mid, dens - 2 * se, dens + 2 * se, color=f"C{i}", alpha=0.3)
            ax.plot(mid, ex, color=f"C{i}", lw=1, label=f"t'={t:g}")
            ax.plot([mid[k0]], [ex[k0] + atom[i] / w], "s", color=f"C{i}", mfc="none", ms=6,
                    label="+ the step's atom 2h'p(0,t')" if i == len(T_DENSITY) - 1 else None)
            devs.append(float(np.max(np.abs(dens - ex) / se)))
            ft.append(float(np.max(np.abs(freeman_tukey(cnt, n * w * ex)))))
            nums["counts"][f"{tau:g}"].append(cnt.tolist())
            nums["exact_density"][f"{tau:g}"].append(ex.tolist())
        nums["max_dev_in_se"][f"{tau:g}"] = devs
        nums["max_ft_dev"][f"{tau:g}"] = ft
        ax.set_title(f"tau' = {tau:g}")
        ax.set_xlabel("v'")
    axs[0].set_ylabel("density")  # the key in the title: on the axis it was longer than the figure and cut
    fig.suptitle("bands: MC ± 2 SE, pointwise; lines: Touchette's propagator", fontsize=9)
    axs[0].legend(fontsize=7, loc="upper left")
    return save(fig, out_dir, "fig6", nums, t0, quick=quick, seed=seed)


def fig7(out_dir, quick, seed):
    t0 = time.perf_counter()
    paths, length, h = (256, 100.0, 2e-3) if quick else (4096, 400.0, 5e-4)
    dt_rec = 0.05
    every = exact_steps(dt_rec, h)
    lags = np.arange(0, round(10 / dt_rec) + 1)
    fig, ax = plt.subplots(figsize=(6, 4))
    tl = lags * dt_rec
    ex = theory.correlation(tl)
    ax.semilogy(tl, ex, "r-", label="Touchette C(t')")
    nums = dict(tau_nd=TAUS, h_nd=h, n_paths=paths, length_tau0=length, burn_in_tau0=BURN_TAU0, t=tl, exact=ex,
                corr={}, se={}, max_dev_in_se={})
    for j, tau in enumerate(TAUS):
        report_step(f"DI stationary paths, tau'={tau:g} ({j + 1} of {len(TAUS)})")
        V, _ = di_stationary(_model(tau, h), jax.random.fold_in(jax.random.key(seed), j), paths,
                             round(length / dt_rec), every, burn_steps=round(BURN_TAU0 / h), record="V")
        c, se = autocovariance(V, len(lags) - 1)
        ax.errorbar(tl[::10], c[::10], 2 * se[::10], fmt="o", ms=3, label=f"tau' = {tau:g}")
        nums["corr"][f"{tau:g}"], nums["se"][f"{tau:g}"] = c, se
        nums["max_dev_in_se"][f"{tau:g}"] = float(np.max(np.abs(c - ex) / se))
    ax.set_xlabel("t'")
    ax.set_ylabel("<V'(0) V'(t')>")
    ax.legend(title="dots: DI, bars +- 2 SE (pointwise)", title_fontsize=8)
    return save(fig, out_dir, "fig7", nums, t0, quick=quick, seed=seed)
