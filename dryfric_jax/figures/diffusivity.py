r"""Figs. 3, 5 and 8 (paper sections 7.1, 7.2): D against Gamma with 95% CI bars, and the
stationary velocity law.

* Fig. 3: D and the paper's mean long-excursion duration for tau = 0.125, 0.25, 0.5, 1 s (tau_L = 0.067 s,
  Delta = 3.84, gamma_bar = 0.342): PDMP (delta = 0.125 s^-1/2) dots, DI lines; N = 1e5 (full)
  or 1e3 (quick), lowered by 4x steps (not below 1e3) where the run would exceed the default
  ``max_work`` (the N used is in the JSON).  The PDMP's durations are its excursions'; the DI's come
  from counting releases (:mod:`dryfric_jax.durations`, with its bridge correction, at its default step),
  since its regeneration cycles (thin dashed lines) span one or more of the paper's excursions.  At the
  paper's delta the PDMP's durations are 0.6-13% long at tau <= 0.5 s, more at 1 s (its delta-grid, which
  releases one level past each threshold: ``pdmp_grid_widening`` in the JSON; RESULTS.md);
* Fig. 8: D for b = 0 and for b = -v/tau_L + gamma_bar, tau = 1e-5 .. 1e-2 s: brute force
  (t = 10 s) dots, long excursions lines, the exact white-noise D as reference, and the local
  exponent d ln D / d ln Gamma (finite differences of the long-excursion D, delta-method CI);
* Fig. 5: the DI's stationary velocity histogram (Gamma = 0.16, tau = 1e-5 s) against the exact
  white-noise density and the discrete chain's law at the same h, and 10 displacement paths U(t).
"""
from __future__ import annotations

import math
import time

import jax
import numpy as np

from .. import theory
from ..chain_law import white_chain_law
from ..di import make_di_model
from ..durations import NoCountError, default_duration_h, di_long_excursion_duration, max_steps_for
from ..params import Params, real_or_none
from ..paths import di_stationary
from ..pdmp import pdmp_grid_info, threshold_widening
from ..plan import default_h, plan_estimate
from .common import plt, save
from .points import Points, report_step

DELTA, TAU_L, GBAR = 3.84, 0.067, 0.342


#: smallest N a figure point is lowered to; below it the CI bars would say little
N_FLOOR = 1000
#: lane-steps a DI duration point may take (long excursions planned from the D run's cycle duration); the floor of
#: 32 excursions can exceed it (full tau = 1 s, Gamma = 1: 62 counted in 32 lanes, 326 s on 2 cores, CI +-21%)
DUR_WORK = {True: 3e7, False: 1e9}
#: the fewest and the most long excursions a DI duration point counts
DUR_N = (32, 8192)


def _di_durations(p, seed, cycle_s, quick, pts=None):
    """The paper's mean long-excursion duration of the DI at ``p`` (:mod:`dryfric_jax.durations`), with as many
    excursions (within :data:`DUR_N`) as keep the expected steps within ``DUR_WORK``: a cycle spans at least one
    long excursion, so one takes at most ``cycle_s``; the lanes are the count's default.  None (counted in
    ``le_dur_missing``) where there is no plan (a cycle duration that is not a finite number > 0) or fewer than 2
    excursions ended within the bound: a missing point, not a lost figure.  Through ``pts`` (the scene's
    :class:`~dryfric_jax.figures.points.Points`) a finished count is kept in the points file, so a resumed or
    repeated Fig. 3 reuses it (they ran again before 2026-12-05: ~3.5 min of the full figure)."""
    c = real_or_none(cycle_s)
    if c is None or not math.isfinite(c) or c <= 0:
        return None
    h = default_duration_h(p)
    le_steps = max(c / h, 1.0)
    n = int(min(DUR_N[1], max(DUR_N[0], DUR_WORK[quick] / le_steps)))
    run = di_long_excursion_duration if pts is None else pts.duration
    try:
        return run(p, seed, h=h, n_excursions=n, max_steps=max_steps_for(n, le_steps))
    except NoCountError:  # fewer than 2 excursions within the bound (a progress callback's error goes on up)
        return None


def _affordable_n(p, method, n, kw):
    """N, divided by 4 (not below :data:`N_FLOOR`) until the planner accepts the run under the default
    max_work (slow noise at small Gamma makes excursions exponentially long: the paper's tau = 1 s,
    Gamma = 1 point needs ~6e4 tau0 each).  Every N used is asked; a point refused even at the floor
    raises the planner's ``ValueError``, which names max_work and the parameters."""
    while True:
        try:
            plan_estimate(p, method=method, n_excursions=n, **kw)
            return n
        except ValueError:
            if n <= N_FLOOR:
                raise
            n = max(n // 4, N_FLOOR)


def fig3(out_dir, quick, seed):
    t0 = time.perf_counter()
    gammas = [2.5, 5.0, 10.0] if quick else list(np.geomspace(1, 10, 10))
    taus = (0.125, 0.25, 0.5, 1.0)
    n = 1000 if quick else 100_000
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4))
    delta = 0.125  # the PDMP's grid step (s^-1/2), the paper's
    nums = dict(Gamma=gammas, tau=taus, n_excursions=n, delta=delta, pdmp={}, di={}, agree={})
    # the PDMP's grid releases a stuck particle one level past each threshold: s_+ + s_- grid steps wider than the
    # DI's stuck set (pdmp.threshold_widening; it depends on Gamma alone), which lengthens its excursions
    nums["pdmp_grid_widening"] = [sum(threshold_widening(pdmp_grid_info(p, delta)["delta_nd"], p.nondim().gamma_bar))
                                  for p in (Params(G, DELTA, 0.5, TAU_L, GBAR) for G in gammas)]
    pts = Points(out_dir, "fig3")  # finished runs are kept: an interrupted figure resumes
    for j, tau in enumerate(taus):
        rows = {}
        ps = [Params(G, DELTA, tau, TAU_L, GBAR) for G in gammas]
        for m in ("pdmp", "di"):
            kw = dict(delta=delta) if m == "pdmp" else {}
            # the PDMP's seeds 5000 past the DI's (they shared one per point: the same key's bits, used
            # otherwise, may correlate the two estimates that the agreement z compares as independent)
            off = 5000 if m == "pdmp" else 0
            rs = [pts.estimate(p, seed + off + 17 * i + 1000 * j, method=m, n_excursions=_affordable_n(p, m, n, kw),
                               **kw) for i, p in enumerate(ps)]
            rows[m] = dict(D=[r.D for r in rs], D_ci=[r.D_ci for r in rs], dur=[r.mean_duration for r in rs],
                           dur_ci=[r.mean_duration_ci for r in rs], wall_s=[r.wall_s for r in rs],
                           n_excursions=[r.n_excursions for r in rs])
            nums[m][f"{tau:g}"] = rows[m]
        # the DI's paper-excursion durations (its cycles' are rows["di"]["dur"]): seeds past the estimates'
        ds = [_di_durations(p, seed + 9000 + 17 * i + 1000 * j, c, quick, pts=pts) for i, (p, c) in
              enumerate(zip(ps, rows["di"]["dur"]))]
        rows["di"].update({f"le_dur{k}": [getattr(r, a) if r else None for r in ds] for k, a in (
            ("", "mean"), ("_ci", "ci"), ("_h", "h"), ("_lanes", "n_lanes"), ("_n", "n_excursions"),
            ("_truncated", "n_truncated"))})
        nums["le_dur_truncated"] = nums.get("le_dur_truncated", 0) + sum(r.n_truncated for r in ds if r)
        nums["le_dur_missing"] = nums.get("le_dur_missing", 0) + sum(r is None for r in ds)
        p, d = rows["pdmp"], rows["di"]
        a1.errorbar(gammas, p["D"], p["D_ci"], fmt="o", color=f"C{j}", ms=4)
        a1.errorbar(gammas, d["D"], d["D_ci"], fmt="-", color=f"C{j}", label=f"tau = {tau:g} s")
        a2.errorbar(gammas, p["dur"], p["dur_ci"], fmt="o", color=f"C{j}", ms=4)
        ok = [i for i, r in enumerate(ds) if r]
        a2.errorbar([gammas[i] for i in ok], [d["le_dur"][i] for i in ok], [d["le_dur_ci"][i] for i in ok], fmt="-",
                    color=f"C{j}", label=f"tau = {tau:g} s")
        a2.plot(gammas, d["dur"], "--", color=f"C{j}", lw=0.7)
        # PDMP (delta > 0) and DI approximate the same D: difference in units of the combined CI
        nums["agree"][f"{tau:g}"] = [abs(a - b) / math.hypot(c, e) for a, b, c, e in
                                     zip(p["D"], d["D"], p["D_ci"], d["D_ci"])]
        nums.setdefault("agree_dur", {})[f"{tau:g}"] = [abs(a - b) / math.hypot(c, e) if b is not None else None
                                                        for a, b, c, e in
                                                        zip(p["dur"], d["le_dur"], p["dur_ci"], d["le_dur_ci"])]
    for ax, lab in ((a1, "D (m^2/s)"), (a2, "mean duration (s)")):
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("Gamma (m^2 s^-3)")
        ax.set_ylabel(lab)
    a1.legend(title="dots PDMP, lines DI")
    # the DI's cycle runs from one Nummelin regeneration to the next (regeneration.py), a coin at each release near a
    # threshold, so a cycle spans a random number (>= 1) of the paper's excursions and is about 2-4x longer here (D
    # and M0 do not depend on the rule); the solid lines count the paper's excursions by their releases (durations.py)
    a2.set_title("the paper's long excursion: dots PDMP, lines DI (releases counted, bridged)\n"
                 "dashed: the DI's regeneration cycle, >= 1 such excursion each", fontsize=8)
    nums["runs"] = pts.summary()
    return save(fig, out_dir, "fig3", nums, t0, quick=quick, seed=seed)


def local_exponent(G, D, D_ci):
    r"""Local exponent :math:`d\ln D/d\ln\Gamma` between neighbouring points, at their geometric
    midpoints, and its 95% half-width :math:`\sqrt{(c_1/D_1)^2 + (c_0/D_0)^2}/\Delta\ln\Gamma`
    (independent points; paper section 7.2 discusses the experiment's 1.61 and 1.74).

    ``G`` (increasing, > 0), ``D`` (> 0) and ``D_ci`` (>= 0): finite, of one length >= 2;
    ``ValueError`` naming the argument (a repeated Gamma gave inf, a negative D nan)."""
    G, D, c = (np.asarray(a, float) for a in (G, D, D_ci))
    if not (G.ndim == D.ndim == c.ndim == 1 and len(G) == len(D) == len(c) >= 2):
        raise ValueError(f"G, D and D_ci must be 1-D sequences of one length >= 2 (got shapes {G.shape}, {D.shape}, "
                         f"{c.shape})")
    for name, a, ok in (("G", G, np.all(G > 0) and np.all(np.diff(G) > 0)), ("D", D, np.all(D > 0)),
                        ("D_ci", c, np.all(c >= 0))):
        if not (np.all(np.isfinite(a)) and ok):
            what = {"G": "> 0 and increasing", "D": "> 0", "D_ci": ">= 0"}[name]
            raise ValueError(f"{name} must be finite and {what} (got {a.tolist()[:6]})")
    dl = np.diff(np.log(G))
    s = np.diff(np.log(D)) / dl
    ci = np.sqrt((c[1:] / D[1:]) ** 2 + (c[:-1] / D[:-1]) ** 2) / dl
    return np.sqrt(G[1:] * G[:-1]), s, ci


def fig8(out_dir, quick, seed):
    t0 = time.perf_counter()
    gammas = [0.5, 1.0, 2.0, 4.0] if quick else list(np.geomspace(0.25, 8, 11))
    taus = (1e-5, 1e-2) if quick else (1e-5, 1e-4, 1e-3, 1e-2)
    n, n_bf, t_bf = (1000, 100, 10.0) if quick else (100_000, 2000, 10.0)
    cases = {"b = 0": (math.inf, 0.0), "b = -v/tau_L + gamma_bar": (TAU_L, GBAR)}
    fig, axs = plt.subplots(2, 2, figsize=(11, 7), sharex=True)
    nums = dict(Gamma=gammas, tau=taus, n_excursions=n, n_paths_bf=n_bf, t_bf=t_bf, cases={})
    pts = Points(out_dir, "fig8")
    for k, (name, (tl, gb)) in enumerate(cases.items()):
        ax, ax2 = axs[0, k], axs[1, k]
        exact = [theory.exact_D(Params(G, DELTA, 1e-9, tl, gb)) for G in gammas]
        ax.plot(gammas, exact, "k--", lw=1, label="white noise, exact")
        cnum = dict(exact=exact)
        if k == 0:  # what brute force from rest estimates: D^t = D (1 - b/t), b exact for white noise and b = 0
            # (theory.horizon_bias, 27/5 tau0), to exponentially small terms where t >= 20 tau0 (0.23% of D there)
            cnum["exact_bf"] = [theory.D_pure_dry(G, DELTA) * (1.0 - theory.horizon_bias(G, DELTA) / t_bf)
                                if t_bf >= 20.0 * G / DELTA**2 else None for G in gammas]
            shown_bf = [(G, d) for G, d in zip(gammas, cnum["exact_bf"]) if d is not None]
            ax.plot(*zip(*shown_bf), "k:", lw=1, label=f"white noise, exact D^t (t = {t_bf:g} s, from rest)")
        for j, tau in enumerate(taus):
            ps = [Params(G, DELTA, tau, tl, gb) for G in gammas]
            le = [pts.estimate(p, seed + 31 * i + 1000 * j + 7 * k, n_excursions=n) for i, p in enumerate(ps)]
            bf = [pts.bruteforce(p, seed + 31 * i + 1000 * j + 7 * k + 1, t=t_bf, n_paths=n_bf)
                  for i, p in enumerate(ps)]
            D, Dc = [r.D for r in le], [r.D_ci for r in le]
            ax.errorbar(gammas, D, Dc, fmt="-", color=f"C{j}", label=f"tau = {tau:g} s")
            ax.errorbar(gammas, [r.D_t for r in bf], [r.D_t_ci for r in bf], fmt="o", color=f"C{j}", ms=4)
            gm, s, sc = local_exponent(gammas, D, Dc)
            ax2.errorbar(gm, s, sc, fmt="-o", color=f"C{j}", ms=3)
            # brute force has an O(tau_c / t) bias (section 5.3): t / tau0 says where it is small
            cnum[f"{tau:g}"] = dict(D=D, D_ci=Dc, D_bf=[r.D_t for r in bf], D_bf_ci=[r.D_t_ci for r in bf],
                                    t_over_tau0=[t_bf / p.tau0 for p in ps], exponent_at=gm, exponent=s,
                                    exponent_ci=sc)
        # 3 is the exact white-noise exponent of b = 0 only (D = 10 Gamma^3 / Delta^4); with the viscous term
        # and the bias the white-noise exponent varies with Gamma
        refs = ((3.0, "3 (white noise, b = 0)"),) if k == 0 else ()
        for y, lab in refs + ((1.61, "1.61 (experiment)"), (1.74, "1.74 (experiment)")):
            ax2.axhline(y, color="gray", lw=0.7, ls=":")
            ax2.text(gammas[0], y, lab, fontsize=7, va="bottom")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_title(name)
        ax.set_ylabel("D (m^2/s)")
        ax2.set_xscale("log")
        ax2.set_xlabel("Gamma (m^2 s^-3)")
        ax2.set_ylabel("d ln D / d ln Gamma")
        ax.legend(fontsize=7, title="lines LE, dots BF (t = 10 s)", title_fontsize=7)
        nums["cases"][name] = cnum
    nums["runs"] = pts.summary()
    return save(fig, out_dir, "fig8", nums, t0, quick=quick, seed=seed)


def fig5(out_dir, quick, seed):
    """Stationary velocity histogram against the exact white-noise density, and 10 U(t) paths."""
    t0 = time.perf_counter()
    p = Params(0.16, DELTA, 1e-5, TAU_L, GBAR)
    h = default_h(p)
    m = make_di_model(p, h)
    paths, length = (256, 200.0) if quick else (4096, 2000.0)  # in tau0
    h_nd = h / p.tau0
    every = max(1, round(0.05 / h_nd))
    report_step("DI stationary paths for the histogram (1 of 2)")
    # V only, in m/s (the scaled copy made once, briefly beside the unscaled one), then no array of its size but
    # np.quantile's copy: at full settings V is 4096 x 40,000 (1.3 GB), and the scene peaked at 5.6 GB when it kept
    # U, V * v0 and V^2 beside it (3.0 GB now)
    V = di_stationary(m, jax.random.key(seed), paths, round(length / (every * h_nd)), every,
                      burn_steps=round(40 / h_nd), record="V")[0] * p.v0
    v = V.ravel()
    bw = 4.8e-4  # the paper's bin width
    lo, hi = np.quantile(v, [1e-4, 1 - 1e-4])
    edges = np.arange(lo, hi + bw, bw)
    cnt, _ = np.histogram(v, edges)
    mid = 0.5 * (edges[1:] + edges[:-1])
    prob, exact = cnt / v.size, theory.stationary_density(mid, p) * bw
    # paths of U on [0, 2] s
    n_rec = round(2.0 / p.tau0 / h_nd)
    report_step("10 paths of U (2 of 2)")
    _, U = di_stationary(m, jax.random.key(seed + 1), 10, n_rec, 1, burn_steps=round(40 / h_nd), record="U")
    # the step's own share of any gap: the exact law of the white-noise chain at this h
    # (tau/h -> 0); at h = 0.01 tau0 its E[V^2] is 0.40% below the continuum value
    law = white_chain_law(p, h)
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4))
    a1.plot(mid, exact, "k-",
            label="exact white-noise density x bin width\n(MODEL_NOTES §2: 2 Gamma tau_L, Delta/Gamma)")
    a1.plot(mid, prob, "r^", ms=3, label=f"DI, tau = 1e-5 s ({paths} paths)")
    # the discrete chain sticks at V = 0 with positive probability (the continuum law has no atom): the
    # bin holding v = 0 gets that atom on top of the density, which the chain's exact law predicts
    k0 = int(np.searchsorted(edges, 0.0, side="right")) - 1
    has_zero = 0 <= k0 < len(mid)  # v = 0 among the bins (the 1e-4 quantiles could leave it out)
    if has_zero:
        a1.plot([mid[k0]], [exact[k0] + law.p_stuck], "ks", mfc="none", ms=7,
                label=f"+ the chain's atom P(V = 0) = {law.p_stuck:.2g} (h = {h:.2g} s)")
    a1.set_xlabel("v (m/s)")
    a1.set_ylabel(f"probability per bin ({bw:g} m/s)")
    a1.legend(fontsize=7)
    tt = np.arange(1, n_rec + 1) * h
    for u in U:
        a2.plot(tt, u * p.u0, lw=0.8)
    a2.set_xlabel("t (s)")
    a2.set_ylabel("U(t) (m)")
    # samples along a path are correlated, paths are independent: standard errors of the first
    # two moments from the per-path means, compared with their exact values
    mean_exact = theory.exact_M0(p)
    V2 = np.einsum("ij,ij->i", V, V) / V.shape[1]  # each path's mean V^2
    nums = dict(params=p.as_dict(), h=h, bin_width=bw, n_paths=paths, length_tau0=length,
                mean_v=float(v.mean()), mean_v_exact=mean_exact,
                mean_v_se=float(V.mean(1).std(ddof=1) / math.sqrt(paths)),
                mean_v2=float(V2.mean()), mean_v2_exact=theory.exact_mean_square_velocity(p),
                mean_v2_se=float(V2.std(ddof=1) / math.sqrt(paths)),
                mean_v_chain=law.M0, mean_v2_chain=law.mean_v2, p_stuck=np.count_nonzero(V == 0) / V.size,
                p_stuck_chain=law.p_stuck,
                total_variation=float(0.5 * np.abs(prob - exact).sum()),
                histogram=dict(edges=edges.tolist(), measured=prob.tolist(), exact=exact.tolist()),  # as plotted
                # the right panel's 10 paths as plotted, in float64 (10 x 18 432 points: 5.4 MB of the JSON)
                U_paths=dict(t_s=tt.tolist(), U_m=(U * p.u0).tolist()),
                zero_bin=dict(v=float(mid[k0]), measured=float(prob[k0]), exact_density=float(exact[k0]),
                              with_chain_atom=float(exact[k0] + law.p_stuck)) if has_zero else None)
    return save(fig, out_dir, "fig5", nums, t0, quick=quick, seed=seed)
