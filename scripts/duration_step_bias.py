"""Measure how the DI's mean long-excursion duration (dryfric_jax.durations) moves with the step h.

At one point (nondimensional: Gamma = Delta = 1, so tau0 = 1 s and tau' = --tau; tau_L = inf, gamma_bar = 0 unless
given) it counts --n-excursions long excursions at each tau/h of --ratios (seed --seed) and prints the mean, its
95% CI and the step's X variance against the stuck band's half-width squared,
q = Var(X_{n+1} | X_n) = (1 - exp(-2h/tau)) / tau' (durations.step_band_variance).  The bias of the count is a
function of q (durations.MAX_BAND_VARIANCE): compare the rows of one tau' with its finest, and rows of equal q
across tau'.

    python scripts/duration_step_bias.py --tau 0.03 --ratios 175 700 2800 --n-excursions 16384
"""
import argparse
import json
import time
import warnings

import dryfric_jax as dj
from dryfric_jax.durations import di_long_excursion_duration as duration
from dryfric_jax.durations import step_band_variance


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tau", type=float, required=True, help="tau' (= tau in s, with Gamma = Delta = 1)")
    ap.add_argument("--tau-L", type=float, default=float("inf"))
    ap.add_argument("--gamma-bar", type=float, default=0.0)
    ap.add_argument("--ratios", type=float, nargs="+", required=True, help="tau/h for each run")
    ap.add_argument("--n-excursions", type=int, default=4096)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    if not a.tau > 0 or min(a.ratios) <= 0 or a.n_excursions < 2:
        ap.error("--tau and --ratios must be > 0, --n-excursions >= 2")
    p = dj.Params(Gamma=1.0, Delta=1.0, tau=a.tau, tau_L=a.tau_L, gamma_bar=a.gamma_bar)
    warnings.simplefilter("ignore", dj.DryfricWarning)
    for ratio in a.ratios:
        h = a.tau / ratio
        t = time.perf_counter()
        r = duration(p, a.seed, h=h, n_excursions=a.n_excursions, max_work=1e13)
        row = dict(tau=a.tau, tau_L=a.tau_L, gamma_bar=a.gamma_bar, ratio=ratio, q=step_band_variance(p, h),
                   mean=r.mean, ci=r.ci, n=r.n_excursions, truncated=r.n_truncated, seed=a.seed,
                   wall_s=time.perf_counter() - t)
        print(json.dumps(row) if a.json else
              f"tau'={a.tau:g} tau/h={ratio:g} q={row['q']:.4g}: {r.mean:.4f} +- {r.ci:.4f} "
              f"({100 * r.ci / r.mean:.1f}%), {r.n_excursions} LEs, {r.n_truncated} truncated, "
              f"{row['wall_s']:.0f} s", flush=True)


if __name__ == "__main__":
    main()
