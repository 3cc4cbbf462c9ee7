r"""Fig. 9 (new): speed against error.

(a) RMSE of D against compute, long excursions (LE) and brute force (BF) at several horizons t,
    on a case with a known D (white noise, tau' = 1e-5, with the Fig. 3 viscous term and bias:
    D from the exact quadrature of MODEL_NOTES section 2).  Replicates are groups of lanes (LE)
    or of paths (BF) of one run each, so the RMSE at every size comes from independent
    replicates.  Section 5.3: the LE RMSE falls as cost^{-1/2}; BF at a fixed t stalls at its
    O(1/t) bias, and its best t at each budget gives the cost^{-1/3} envelope: with G paths of
    horizon t, MSE/D^2 ~ 2/G + (c/t)^2 at cost G t, least at t ~ (c^2 G t)^{1/3}.  Here c ~ 0.2 tau0
    (measured: D_t/D = 0.78, 0.89, 0.95 at t = 1, 2, 4 tau0), so the grid is t = 0.5-16 tau0 (quick;
    32 full) and G = 16-1024 paths (4096 full), where bias and spread cross.  (Until 2026-12-05 the grid was
    t = 3.75-60 tau0 and G <= 256: the bias never mattered, the RMSE was the spread of G alone, and the
    "envelope" of the noisiest points fitted -0.34 +- 0.08 by chance.)  The envelope is taken per cost
    level G t: the best (G, t) is chosen on one half of the paths and its RMSE measured on the other,
    so the minimum's selection does not bias it low.  Slopes are least-squares fits in log-log with
    their standard errors.  This case drifts (M0 = 0.016 m/s),
    where section 5.3 predicts a cost^{-1/4} envelope: its per-path variance grows as M0^2 D t
    because its statistic is not centred.  The brute force here centres U on the paths' own mean
    (:func:`~dryfric_jax.estimators.bruteforce_estimates`), whose variance does not grow with t,
    so the envelope is cost^{-1/3} with or without drift.
(b) D and its 95% CI against h (DI) and delta (PDMP) at the Fig. 3 point, with the wall time on
    a second axis: which step buys which accuracy at which cost.
"""
from __future__ import annotations

import math
import time
import warnings

import jax
import numpy as np

from .. import theory
from ..api import DryfricWarning, estimate_diffusivity
from ..di import make_di_model
from ..estimators import bruteforce_estimates, long_excursion_estimates
from ..excursions import STAT_NAMES, lanes_for
from ..rounds import abandon_on_interrupt, run_round
from ..params import FIG3, Params
from ..paths import di_stationary
from ..plan import default_h
from .common import plt, save
from .points import Points, report_step


def fit_slope(x, y, replicates=None):
    """Slope of log y on log x and its standard error.

    Each RMSE comes from R independent replicates, so log RMSE carries a sampling error of about
    1/sqrt(2R) (Gaussian errors); the fit is weighted by it and the reported standard error is
    the larger of the propagated one and the one from the residuals (which alone understates it
    when a few points happen to lie on a line).
    """
    x, y = np.asarray(x, float), np.asarray(y, float)
    r = None if replicates is None else np.asarray(replicates, float)
    if not (x.ndim == y.ndim == 1 and len(x) == len(y) >= 3 and (r is None or r.shape == x.shape)):
        raise ValueError(f"x, y (and replicates) must be 1-D of one length >= 3 (got shapes {x.shape}, {y.shape}"
                         f"{'' if r is None else ', ' + str(r.shape)})")  # 2 points: a zero SE; 1: LinAlgError
    for name, a in (("x", x), ("y", y)):
        if not np.all(np.isfinite(a) & (a > 0)):  # a zero RMSE gave a nan slope
            raise ValueError(f"{name} must be finite and > 0 (a log-log fit) (got {a.tolist()[:6]})")
    if np.all(x == x[0]):  # a singular fit: numpy's LinAlgError named no argument
        raise ValueError(f"x must take at least 2 distinct values (got {x.tolist()[:6]})")
    if r is not None and not np.all(np.isfinite(r) & (r >= 1)):
        raise ValueError(f"replicates must be finite and >= 1 (got {r.tolist()[:6]})")
    lx, ly = np.log(x), np.log(y)
    sig = np.ones_like(lx) if r is None else 1.0 / np.sqrt(2.0 * r)
    A = np.stack([lx, np.ones_like(lx)], 1)
    W = np.diag(1.0 / sig**2)
    cov_known = np.linalg.inv(A.T @ W @ A)
    coef = cov_known @ A.T @ W @ ly
    dof = max(len(lx) - 2, 1)
    chi2 = float(((ly - A @ coef) ** 2 / sig**2).sum()) / dof
    se_known = math.sqrt(cov_known[0, 0]) if replicates is not None else 0.0
    return float(coef[0]), float(max(se_known, math.sqrt(chi2 * cov_known[0, 0])))


def _rmse_le(model, key, lanes, budget, D_true, sizes):
    res = run_round(model, key, lanes, budget)
    steps = np.asarray(res.lane_steps, float)
    out = []
    for g in sizes:  # lanes per replicate
        errs, cost, n = [], [], []
        for r in range(lanes // g):
            blk = res.stats[r * g:(r + 1) * g].sum(0)
            errs.append(long_excursion_estimates(dict(zip(STAT_NAMES, blk)))["D"] - D_true)
            cost.append(steps[r * g:(r + 1) * g].sum())
            n.append(blk[0])
        out.append(dict(lanes=g, n_excursions=float(np.mean(n)), cost=float(np.mean(cost)),
                        rmse=float(np.sqrt(np.mean(np.square(errs)))), replicates=lanes // g))
    return out


#: Fig. 9(a) brute force (quick, full): paths, records every 0.5 tau0, paths per replicate
BF_GRID = {True: (2**16, 32, (16, 64, 256, 1024)), False: (2**18, 64, (16, 64, 256, 1024, 4096))}


def _rmse_bf(model, key, quick, h_nd, D_true, unit):
    """Fig. 9(a)'s brute force (module docstring): stationary paths recorded every 0.5 tau0; at the
    horizons t = 0.5 * 2^k tau0 the RMSE of D_t over replicates of G paths (D_t = Var U(t) / t,
    :func:`~dryfric_jax.estimators.bruteforce_estimates`'s y2 - y1^2, per replicate), the bias of D_t
    from all paths with its 95% CI, and the envelope over cost levels G t with >= 2 candidates: the
    best (G, t) by the RMSE on the first half of the replicates, its RMSE on the second half.  ``D_true``
    nondimensional, the RMSEs in units of ``unit`` (D0 in m^2/s: the JSON's), the costs in lane-steps."""
    n_paths, n_records, groups = BF_GRID[bool(quick)]
    every = round(0.5 / h_nd)
    _, U = di_stationary(model, key, n_paths, n_records, every, record="U")
    bf, bias, levels = {}, [], {}
    for k in range(int(math.log2(n_records)) + 1):
        j = 2**k - 1
        tt = (j + 1) * every * h_nd
        e = bruteforce_estimates(U[:, j], tt)
        bias.append(dict(t=tt, D_t_over_D=e["D_t"] / D_true, ci=e["D_t_ci"] / D_true))
        rows = []
        for g in groups:
            err = U[:, j].reshape(-1, g).var(1) / tt - D_true
            half, cost = err.size // 2, g * (j + 1) * every
            ms = [float(np.sqrt(np.mean(np.square(x)))) * unit for x in (err, err[:half], err[half:])]
            rows.append(dict(paths=g, cost=cost, rmse=ms[0], replicates=err.size))
            levels.setdefault(cost, []).append((ms[1], ms[2], half, cost, tt, g))
        bf[f"{(j + 1) * 0.5:g}"] = rows  # the nominal horizon in tau0
    env = []
    for lv in sorted(levels):
        if len(levels[lv]) >= 2:
            _, e_b, half, cost, tt, g = min(levels[lv])
            env.append(dict(cost=cost, rmse=e_b, replicates=half, t=tt, paths=g, candidates=len(levels[lv])))
    return bf, bias, env


def _warm_up(params, n, **kw):
    """An untimed run with the timed runs' layout (``lanes_for(n)`` lanes, N = lanes), so that their wall
    times exclude compiling: the first run of a shape in a process compiles it (measured, quick DI at the
    coarsest h: 2.85 s before, 0.054 s after; the PDMP at its coarsest delta 2.04 s and 0.038 s)."""
    lanes = lanes_for(n)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DryfricWarning)
        with abandon_on_interrupt():
            r = estimate_diffusivity(params, 0, n_excursions=lanes, lanes=lanes, **kw)
    if r.stopped_by == "interrupted":
        raise KeyboardInterrupt


def fig9(out_dir, quick, seed):
    t0 = time.perf_counter()
    # (a) -------------------------------------------------------------------------------------
    p = Params(FIG3["Gamma"], FIG3["Delta"], 1e-5 * FIG3["Gamma"] / FIG3["Delta"] ** 2, FIG3["tau_L"],
               FIG3["gamma_bar"])
    D_true = theory.exact_D(p) / p.D0
    h = default_h(p)
    model = make_di_model(p, h)
    h_nd = h / p.tau0
    # quick: 80 000 steps per lane, ~77 excursions in the smallest replicate (one lane).  With
    # 20 000 (~19 per lane) the ratio estimator is not yet in its N^{-1/2} regime: over 9 seeds the
    # fitted slope was -0.46 +- 0.03, 1.4 of its SE off -1/2, and the 3-SE check failed for ~1 in
    # 10 random streams; at 80 000 it is -0.48 +- 0.02 (9 seeds, all within 3 SE)
    lanes, budget = (1024, 80_000) if quick else (8192, 100_000)
    # RMSEs in m^2/s, like D_true in the JSON (they were in units of D0 = 0.57 m^2/s, 1.74x too large)
    report_step(f"(a) long excursions, {lanes} lanes x {budget} steps")
    le = [dict(r, rmse=r["rmse"] * p.D0) for r in _rmse_le(model, jax.random.key(seed), lanes, budget, D_true,
                                                            [1, 4, 16, 64])]
    report_step(f"(a) brute force, {BF_GRID[bool(quick)][0]} paths")
    bf, bias, env = _rmse_bf(model, jax.random.key(seed + 1), quick, h_nd, D_true, p.D0)
    le_slope = fit_slope([r["cost"] for r in le], [r["rmse"] for r in le], [r["replicates"] for r in le])
    bf_slope = fit_slope(*zip(*[(r["cost"], r["rmse"], r["replicates"]) for r in env]))
    # (b) -------------------------------------------------------------------------------------
    pf = Params(**FIG3)
    n = 2000 if quick else 100_000
    h_rel = (0.1, 0.03, 0.01, 0.003) if quick else (0.1, 0.03, 0.01, 0.003, 0.001)
    d_nd = (0.15, 0.1, 0.05, 0.025)  # delta'_max = 0.19 here
    pts = Points(out_dir, "fig9")  # (b)'s runs are kept: an interrupted figure resumes them
    hs = [hr * min(pf.tau0, pf.tau_L) for hr in h_rel]
    ds = [d * pf.Delta / math.sqrt(pf.Gamma) for d in d_nd]
    runs = ([(seed + i, dict(h=hh, n_excursions=n)) for i, hh in enumerate(hs)]
            + [(seed + 10 + i, dict(method="pdmp", delta=dd, n_excursions=n)) for i, dd in enumerate(ds)])
    for method, step in (("di", dict(h=hs[0])), ("pdmp", dict(delta=ds[0]))):
        if not all(pts.kept(pf, s, **kw) for s, kw in runs if kw.get("method", "di") == method):
            report_step(f"(b) an untimed {method.upper()} run, so that the timed runs exclude compiling")
            _warm_up(pf, n, method=method, **step)
    rs = [pts.estimate(pf, s, **kw) for s, kw in runs]
    di, pd = rs[:len(hs)], rs[len(hs):]
    fig, axs = plt.subplots(1, 3, figsize=(15, 4))
    a = axs[0]
    a.loglog([r["cost"] for r in le], [r["rmse"] for r in le], "ko-",
             label=f"LE, slope {le_slope[0]:.2f} ± {le_slope[1]:.2f}")
    for i, (t, rows) in enumerate(bf.items()):
        a.loglog([r["cost"] for r in rows], [r["rmse"] for r in rows], "s--", color=f"C{i}",
                 label=f"BF t = {t} tau0")
    a.loglog([r["cost"] for r in env], [r["rmse"] for r in env], "r:", lw=2,
             label=f"BF best t, slope {bf_slope[0]:.2f} ± {bf_slope[1]:.2f}")
    c0 = le[0]["cost"]
    a.loglog([c0, c0 * 100], [le[0]["rmse"], le[0]["rmse"] / 10], "k:", lw=0.7, label="N^-1/2")
    a.set_xlabel("lane-steps per estimate")
    a.set_ylabel("RMSE of D (m^2/s)")
    a.set_title("(a) tau' = 1e-5 (white-noise limit), exact white-noise D known", fontsize=9)
    a.legend(fontsize=7)
    for ax, xs, rs, lab in ((axs[1], hs, di, "h (s)"), (axs[2], ds, pd, "delta (s^-1/2)")):
        ax.errorbar(xs, [r.D for r in rs], [r.D_ci for r in rs], fmt="o-")
        ax.set_xscale("log")
        ax.set_xlabel(lab)
        ax.tick_params(axis="x", which="both", labelsize=7, labelrotation=30)
        ax.set_ylabel("D (m^2/s), 95% CI")
        ax2 = ax.twinx()
        ax2.loglog(xs, [r.wall_s for r in rs], "r^--")
        ax2.set_ylabel("wall time (s)", color="r")
    axs[1].set_title(f"(b) DI at the Fig. 3 point, N = {n}", fontsize=9)
    axs[2].set_title(f"(b) PDMP at the Fig. 3 point, N = {n}", fontsize=9)
    nums = dict(D_true=D_true * p.D0, le=le, bf=bf, bf_bias=bias, le_slope=le_slope[0], le_slope_se=le_slope[1],
                bf_envelope=env, bf_slope=bf_slope[0], bf_slope_se=bf_slope[1], theory_slopes=dict(le=-0.5, bf=-1 / 3),
                # each run's own step (its result's h or delta), not the one asked for
                di=[dict(h=r.h, D=r.D, D_ci=r.D_ci, wall_s=r.wall_s) for r in di],
                pdmp=[dict(delta=r.delta, D=r.D, D_ci=r.D_ci, wall_s=r.wall_s) for r in pd],
                runs=pts.summary())
    return save(fig, out_dir, "fig9", nums, t0, quick=quick, seed=seed)
