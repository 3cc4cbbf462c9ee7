"""Measure the empirical coverage of the 95% delta-method CI for D against the exact white-noise D.

Sizes must be multiples of the smallest.  One long run of the DI (white-noise regime; b = 0
unless --tau-L / --gamma-bar are given) is cut into independent replicates of N excursions each
(lanes hold i.i.d. excursions, so groups of lanes are independent), for several N.  Prints
one line per N: replicates, coverage, its binomial standard error, and the mean relative
half-width.

    python scripts/ci_calibration.py --total 2000000 --sizes 500 1000 2000 5000 10000 20000
(sizes are approximate: a replicate holds about N excursions, the budget being set from a pilot)
"""
import argparse
import math

import dryfric_jax as dj
from dryfric_jax.di import make_di_model
from dryfric_jax.estimators import replicate_coverage
from dryfric_jax.excursions import STAT_NAMES
from dryfric_jax.rounds import simulate_replicates
from dryfric_jax.outfiles import dumps


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--total", type=int, default=2_000_000)
    ap.add_argument("--sizes", type=int, nargs="+", default=[500, 1000, 2000, 5000, 10000, 20000])
    ap.add_argument("--tau", type=float, default=1e-5, help="tau' (white noise: <= 1e-4)")
    ap.add_argument("--gamma-bar", type=float, default=0.0, help="gamma_bar'")
    ap.add_argument("--tau-L", type=float, default=math.inf, help="tau_L' (default inf)")
    ap.add_argument("--h", type=float, default=0.02, help="h' = h/tau0")
    ap.add_argument("--lanes-per-replicate", type=int, default=4, help="for the smallest size")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    smallest = min(a.sizes)
    # bad input: one line and exit 2 (a ZeroDivisionError or a ValueError traceback before)
    if smallest < 1 or any(n % smallest for n in a.sizes):
        ap.error(f"--sizes must be positive multiples of the smallest (got {a.sizes})")
    if a.total < smallest or a.lanes_per_replicate < 1:
        ap.error(f"--total must be >= the smallest size and --lanes-per-replicate >= 1 (got {a.total}, "
                 f"{a.lanes_per_replicate})")
    try:
        p = dj.Params.from_nondim(a.tau, a.tau_L, a.gamma_bar)
        model = make_di_model(p, a.h)
        key = dj.api._key(a.seed)[0]  # --seed -1: a traceback, exit 1
    except ValueError as e:
        ap.error(str(e))
    sim = simulate_replicates(model, key, a.total // smallest, smallest,
                              lanes_per_replicate=a.lanes_per_replicate)
    D, M = dj.theory.exact_D(p), dj.theory.exact_M0(p)
    rows = []
    for n in a.sizes:
        c = replicate_coverage(sim.stats, STAT_NAMES, a.lanes_per_replicate * n // smallest, D, M)
        reps, cD, cM, w = c["replicates"], c["coverage_D"], c["coverage_M0"], c["rel_half_width"]
        se = math.sqrt(max(cD * (1 - cD), 1e-12) / reps)
        rows.append(dict(N=n, replicates=reps, coverage_D=cD, coverage_D_se=se, coverage_M0=cM, rel_half_width=w))
        if not a.json:
            print(f"N={n:6d}  replicates={reps:5d}  coverage(D)={cD:.3f} ± {se:.3f}  coverage(M0)={cM:.3f}  "
                  f"half-width={100 * w:.1f}%", flush=True)
    if a.json:
        print(dumps(dict(params=vars(a), rows=rows)))  # strict JSON: tau_L = inf as "inf"


if __name__ == "__main__":
    main()
