r"""Figs. 1 and 2 (paper sections 3, 6): one long excursion, first HLE in black, second in red.

Rows: PDMP (delta = 0.125 s^-1/2, event skeleton: X is constant between events, V is drawn
through its values at the events; s_+ through s_- back to s_+, :func:`~dryfric_jax.pdmp.excursion_skeleton`)
and DI (every step; from a release towards V > 0 through the first release towards V < 0 to the next release
towards V > 0, :func:`~dryfric_jax.paths.di_long_excursion`: the paper's long excursion of section 6.1 as
:mod:`dryfric_jax.durations` counts them.  Until 2026-12-07 the DI row was one Nummelin regeneration cycle,
the D estimator's, which spans one or more of them: ~3 at seed 0).  Columns: X(t), V(t),
U(t), V against X.  Fig. 3 parameters (Gamma = 5, Delta = 3.84, tau = 0.5, tau_L = 0.067, gamma_bar = 0.342), SI
units.  The excursion shown is the first one a fixed seed produces; its length is random.

The JSON holds, per row, the definition plotted, the summary numbers, and the plotted arrays (``path``: t, X, V, U
in SI units, the halves split at ``i_half``, the state both halves share).
"""
from __future__ import annotations

import time

import jax
import numpy as np

from ..di import make_di_model
from ..params import FIG3, Params
from ..paths import di_long_excursion
from ..pdmp import excursion_skeleton, make_pdmp_model
from ..plan import default_h
from .common import plt, save
from .points import report_step


#: what each row plots (its JSON says it)
DEFINITION = {
    "PDMP (delta = 0.125)": "long excursion of the PDMP (paper section 3): from s_+ through s_- back to s_+, its "
                            "event skeleton (pdmp.excursion_skeleton)",
    "DI (h = default)": "long excursion of the DI (paper section 6.1): from a release towards V > 0 (stuck a whole "
                        "step, then moving; the first after a release towards V < 0) through the first release "
                        "towards V < 0 (i_half) to the next release towards V > 0, the plain release rule of "
                        "dryfric_jax.durations without its bridge correction (paths.di_long_excursion); the "
                        "path's last state is after that release, the duration ends a step before it",
}


def fig1_2(out_dir, quick, seed):
    t0 = time.perf_counter()
    p = Params(**FIG3)
    sx = 1.0 / np.sqrt(p.Gamma) * p.Delta  # X' -> X (s^-1/2): X = X' Delta / sqrt(Gamma)
    report_step("PDMP excursion (1 of 2)")
    runs = {"PDMP (delta = 0.125)": excursion_skeleton(make_pdmp_model(p, 0.125), jax.random.key(seed))}
    report_step("DI excursion (2 of 2)")
    runs["DI (h = default)"] = di_long_excursion(make_di_model(p, default_h(p)), jax.random.key(seed))
    if not len(runs["DI (h = default)"]["t"]):  # its seek for a start ran out (50 x 200 000 steps: ~1e3 LEs)
        raise RuntimeError("Figs. 1-2: the DI found no release towards V > 0 after one towards V < 0 in 1e7 steps")
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
        # the DI's last state is the one after the release that starts the next +HLE: its excursion ends a step
        # before (paths.di_long_excursion), the PDMP's at its last event (s_+)
        end = len(t) - 2 if "duration" in e else len(t) - 1
        nums[name] = dict(duration_s=float(t[end]), half_s=float(t[k]), U_m=float(U[end]), steps_or_events=end,
                          complete=e["complete"], x_start=float(x[0]), x_half=float(x[k]), definition=DEFINITION[name],
                          path=dict(t_s=t.tolist(), X=x.tolist(), V_m_s=v.tolist(), U_m=U.tolist(), i_half=k))
    return save(fig, out_dir, "fig1_2", nums, t0, quick=quick, seed=seed)
