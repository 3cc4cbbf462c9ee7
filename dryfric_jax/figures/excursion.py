r"""Figs. 1 and 2 (paper sections 3, 6): one long excursion, first HLE in black, second in red.

Rows: PDMP (delta = 0.125 s^-1/2, event skeleton: X is constant between events, V is drawn
through its values at the events) and DI (every step).  Columns: X(t), V(t), U(t), V against X.
Fig. 3 parameters (Gamma = 5, Delta = 3.84, tau = 0.5, tau_L = 0.067, gamma_bar = 0.342), SI
units.  The excursion shown is the first one a fixed seed produces; its length is random.
"""
from __future__ import annotations

import time

import jax
import numpy as np

from ..di import make_di_model
from ..params import FIG3, Params
from ..paths import di_excursion
from ..pdmp import excursion_skeleton, make_pdmp_model
from ..plan import default_h
from .common import plt, save
from .points import report_step


def fig1_2(out_dir, quick, seed):
    t0 = time.perf_counter()
    p = Params(**FIG3)
    sx = 1.0 / np.sqrt(p.Gamma) * p.Delta  # X' -> X (s^-1/2): X = X' Delta / sqrt(Gamma)
    report_step("PDMP excursion (1 of 2)")
    runs = {"PDMP (delta = 0.125)": excursion_skeleton(make_pdmp_model(p, 0.125), jax.random.key(seed))}
    report_step("DI excursion (2 of 2)")
    runs["DI (h = default)"] = di_excursion(make_di_model(p, default_h(p)), jax.random.key(seed))
    fig, axs = plt.subplots(2, 4, figsize=(16, 6.5))
    nums = {}
    for row, (name, e) in zip(axs, runs.items()):
        t, x, v, U, k = e["t"] * p.tau0, e["x"] * sx, e["v"] * p.v0, e["U"] * p.u0, e["i_half"]
        draw = "steps-post" if name.startswith("PDMP") else "default"
        for sl, col, half in ((slice(0, k + 1), "k", "first"), (slice(k, None), "r", "second")):
            row[0].plot(t[sl], x[sl], col, lw=0.7, drawstyle=draw, label=f"{half} half excursion")
            row[1].plot(t[sl], v[sl], col, lw=0.7)
            row[2].plot(t[sl], U[sl], col, lw=0.7)
            # the PDMP's X is constant between events while V follows its flow: vertical, then a jump in X
            row[3].plot(x[sl], v[sl], col, lw=0.5, drawstyle="steps-pre" if draw == "steps-post" else "default")
        for ax, yl in zip(row, ("X (s^-1/2)", "V (m/s)", "U (m)", "V (m/s)")):
            ax.set_ylabel(yl)
            ax.set_xlabel("X (s^-1/2)" if yl == "V (m/s)" and ax is row[3] else "t (s)")
        row[0].set_title(name)
        row[0].legend(fontsize=7)
        nums[name] = dict(duration_s=float(t[-1]), half_s=float(t[k]), U_m=float(U[-1]), steps_or_events=len(t) - 1,
                          complete=e["complete"], x_start=float(x[0]), x_half=float(x[k]))
    return save(fig, out_dir, "fig1_2", nums, t0, quick=quick, seed=seed)
