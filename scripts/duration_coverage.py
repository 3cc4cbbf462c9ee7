"""Measure the coverage and bias of the DI's mean long-excursion duration (dryfric_jax.durations).

At one point (default Gamma = 10, tau = 0.125 s, Fig. 3's other constants, h = the D estimator's default, where
excursions are short) a reference run of --ref-excursions long excursions gives the mean; then, for each size N,
--replicates runs of N excursions (default lanes, seeds from 1) give the share of 95% CIs that hold the reference
(and its binomial SE) and the mean of the estimates against it.  --horizon-cut also runs the biased design that
the stopping rule avoids: all lanes run a fixed horizon (--horizon mean durations) and the excursions in flight
there are dropped.

    python scripts/duration_coverage.py --sizes 32 128 2048 --replicates 1000
"""
import argparse
import json
import math
import time
import warnings

import dryfric_jax as dj
from dryfric_jax.durations import MAX_STEPS
from dryfric_jax.durations import di_long_excursion_duration as duration
from dryfric_jax.params import FIG3
from dryfric_jax.plan import default_h


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--Gamma", type=float, default=10.0)
    ap.add_argument("--tau", type=float, default=0.125)
    ap.add_argument("--sizes", type=int, nargs="+", default=[32, 128, 2048])
    ap.add_argument("--replicates", type=int, default=1000)
    ap.add_argument("--ref-excursions", type=int, default=2**20)
    ap.add_argument("--horizon", type=float, default=3.0, help="mean durations per lane, for --horizon-cut")
    ap.add_argument("--horizon-cut", action="store_true")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    if min(a.sizes) < 2 or a.replicates < 2 or a.ref_excursions < 2 or not a.horizon > 0:
        ap.error("--sizes, --replicates and --ref-excursions must be >= 2, --horizon > 0")
    p = dj.Params(**{**FIG3, "Gamma": a.Gamma, "tau": a.tau})
    h = default_h(p)
    warnings.simplefilter("ignore", dj.DryfricWarning)
    t0 = time.perf_counter()
    ref = duration(p, 10**9, h=h, n_excursions=a.ref_excursions, max_steps=MAX_STEPS)
    out = dict(Gamma=a.Gamma, tau=a.tau, h=h, ref=ref.mean, ref_se=ref.ci / 1.96, ref_n=ref.n_excursions,
               ref_wall_s=time.perf_counter() - t0, sizes={})
    for n in a.sizes:
        rs = [duration(p, s, h=h, n_excursions=n) for s in range(1, a.replicates + 1)]
        cov = sum(abs(r.mean - ref.mean) <= r.ci for r in rs) / len(rs)
        mean = sum(r.mean for r in rs) / len(rs)
        sd = math.sqrt(sum((r.mean - mean) ** 2 for r in rs) / (len(rs) - 1))
        out["sizes"][n] = dict(lanes=rs[0].n_lanes, coverage=cov, coverage_se=math.sqrt(cov * (1 - cov) / len(rs)),
                               mean_excursions=sum(r.n_excursions for r in rs) / len(rs), rel_bias=mean / ref.mean - 1,
                               rel_bias_se=sd / math.sqrt(len(rs)) / ref.mean,
                               rel_halfwidth=sum(r.ci for r in rs) / len(rs) / ref.mean,
                               steps_ratio=sum(r.loop_steps for r in rs) / sum(r.lane_steps for r in rs))
    if a.horizon_cut:  # no stop: every lane runs the horizon, the excursions in flight there are dropped
        cut = [duration(p, s, h=h, n_excursions=10**9, n_lanes=256, max_steps=int(a.horizon * ref.mean / h),
                        max_work=1e18)
               for s in range(1, 21)]
        m = sum(r.mean for r in cut) / len(cut)
        out["horizon_cut"] = dict(horizon=a.horizon, runs=len(cut), rel_bias=m / ref.mean - 1,
                                  rel_bias_se=math.sqrt(sum((r.mean - m) ** 2 for r in cut) / (len(cut) - 1)
                                                        / len(cut)) / ref.mean)
    out["wall_s"] = time.perf_counter() - t0
    print(json.dumps(out, indent=1) if a.json else "\n".join(f"{k}: {v}" for k, v in out.items()))


if __name__ == "__main__":
    main()
