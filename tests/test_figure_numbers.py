"""The numbers the path scenes publish (Table 1, Figs. 4-7), with their simulators replaced by
fakes that record what they were asked for and return paths whose statistics are known exactly.

test_figures.py runs the real scenes at --quick; there the SE is too large to see a plumbing
fault, and some numbers are not read at all: an x axis one record off (Fig. 7's t' shifted by
0.05), lags or rho in tau0 where seconds are meant (Fig. 4), Table 1's error taken against the
printed row or in units of 2 SE, Fig. 5's SE of E[V] in tau0 units (24x too large), a burn-in in
steps where tau0 is meant, Fig. 6's propagator 4% later than the time simulated.  Each passed
every test there; each fails here.  0.3-0.8 s per test (measured, 2-core machine).
"""
import math
from types import SimpleNamespace

import jax
import numpy as np
import pytest

from dryfric_jax import theory
from dryfric_jax.figures import covariance, diffusivity, speed_error, touchette
from dryfric_jax.figures.speed_error import fit_slope
from dryfric_jax.excursions import STAT_NAMES
from dryfric_jax.params import FIG3, Params
from dryfric_jax.paths import autocorrelation, autocovariance
from dryfric_jax.plan import default_h


def _fake_models(monkeypatch, module, made, names=("make_di_model",)):
    """Replace the scene's model builders by ones that record (kind, params, step)."""
    for name in names:
        kind = "pdmp" if "pdmp" in name else "di"
        monkeypatch.setattr(module, name, lambda p, step, kind=kind: made.append((kind, p, step)) or made[-1])


def test_table1_numbers_from_known_paths(tmp_path, monkeypatch):
    """Paths at the exact first moment of the time simulated, plus a known offset e_i and a
    +-d split: MC = exact + e, SE = d / sqrt(n - 1), the error in SE = max |e| / SE."""
    made, e, d = [], np.array([1e-3, -2e-3, 0.0, 4e-3, -1e-3, 3e-3]), 0.05

    def transient(model, key, n, record_steps, v0=1.0):
        _, p, h = model
        t = np.asarray(record_steps) * h  # the times simulated (tau0 = 1: from_nondim)
        sign = np.where(np.arange(n) % 2 == 0, 1.0, -1.0)[:, None]
        return np.array([theory.first_moment(x, v0) for x in t]) + e + d * sign

    _fake_models(monkeypatch, touchette, made)
    monkeypatch.setattr(touchette, "di_transient", transient)
    f = touchette.table1(str(tmp_path), True, 0)
    (_, p, h), n = made[0], f["n_paths"]
    assert p.tau / p.tau0 == f["tau_nd"] == 0.5e-5 and h == f["h_nd"]
    exact = [theory.first_moment(t, 1.0) for t in touchette.T_TABLE]
    assert f["exact_model"] == pytest.approx(exact, abs=1e-15)
    assert f["exact_unit_intensity"] == pytest.approx([theory.first_moment_unit_intensity(t, 1.0)
                                                       for t in touchette.T_TABLE], abs=1e-15)
    assert f["mc"] == pytest.approx(np.array(exact) + e, abs=1e-12)
    se = d / math.sqrt(n - 1)
    assert f["se"] == pytest.approx([se] * 6, rel=1e-9)
    assert f["max_abs_err"] == pytest.approx(4e-3, abs=1e-12)  # against the model, not the printed row
    assert f["max_err_in_se"] == pytest.approx(4e-3 / se, rel=1e-6)


def test_fig7_numbers_from_known_paths(tmp_path, monkeypatch):
    """The correlation is autocovariance() of the recorded paths at t' = k x (the records' spacing),
    against Touchette's C at those t'; the burn-in is BURN_TAU0 tau0 of steps."""
    made, calls = [], []

    def stationary(model, key, paths, n_records, every, burn_steps=0, record="VU"):
        calls.append((model, n_records, every, burn_steps))
        V = 10 * np.random.default_rng(len(calls)).normal(size=(paths, n_records))  # lag 0 deviates most
        return V, None

    _fake_models(monkeypatch, touchette, made)
    monkeypatch.setattr(touchette, "di_stationary", stationary)
    f = touchette.fig7(str(tmp_path), True, 0)
    assert [m[1].tau / m[1].tau0 for m in made] == list(touchette.TAUS)
    for j, ((_, _, h), n_rec, every, burn) in enumerate(calls):
        k = np.arange(len(f["t"]))
        assert f["t"] == pytest.approx(k * every * h, rel=1e-12, abs=0)  # t'[0] = 0: lag 0
        assert f["t"][-1] == pytest.approx(10.0) and burn * h == pytest.approx(touchette.BURN_TAU0, abs=h)
        V = 10 * np.random.default_rng(j + 1).normal(size=(f["n_paths"], n_rec))
        c, se = autocovariance(V, len(k) - 1)
        tau = f"{touchette.TAUS[j]:g}"
        assert np.array_equal(f["corr"][tau], c) and np.array_equal(f["se"][tau], se)
        assert f["max_dev_in_se"][tau] == pytest.approx(np.max(np.abs(c - theory.correlation(k * every * h)) / se))
    assert f["exact"] == pytest.approx(theory.correlation(np.asarray(f["t"])), rel=1e-12)


def test_fig4_numbers_from_known_paths(tmp_path, monkeypatch):
    """rho is in seconds for both models (lag k at k DT_REC tau0, the DI's records every DT_REC tau0
    of its steps), up to 3 s; h/h0 is autocorrelation() of paths with a non-zero mean, centred; the
    burn-ins are BURN_TAU0 tau0; the difference is over lags >= 1 (largest at lag 1) in the combined SE."""
    made, calls = [], []

    def paths_(seed, paths, n):  # mean 3 (centring matters); odd seeds (the DI) MA(1): r(1) = 1/2, r(k > 1) = 0
        z = np.random.default_rng(seed).normal(size=(paths, n + 1))
        return 3.0 + (z[:, 1:] + z[:, :-1] if seed % 2 else z[:, 1:])  # the models differ most at lag 1

    def pdmp(model, key, paths, n_rec, dt_rec, burn):
        calls.append(("pdmp", model, dt_rec, burn))
        return paths_(2 * len(calls), paths, n_rec)

    def di(model, key, paths, n_rec, every, burn_steps=0, record="VU"):
        calls.append(("di", model, every, burn_steps))
        return paths_(2 * len(calls) + 1, paths, n_rec), None

    _fake_models(monkeypatch, covariance, made, ("make_di_model", "make_pdmp_model"))
    monkeypatch.setattr(covariance, "pdmp_stationary", pdmp)
    monkeypatch.setattr(covariance, "di_stationary", di)
    f = covariance.fig4(str(tmp_path), True, 0)
    for j, tau in enumerate(covariance.TAUS):
        p = Params(FIG3["Gamma"], FIG3["Delta"], tau, FIG3["tau_L"], FIG3["gamma_bar"])
        c = f["curves"][f"{tau:g}"]
        (_, (_, pp, delta), dt_rec, burn), (_, (_, pd, h), every, burn_steps) = calls[2 * j: 2 * j + 2]
        assert pp == pd == p and delta == 0.125 and burn == covariance.BURN_TAU0
        assert c["di_h"] == h <= default_h(p) and burn_steps * h / p.tau0 == pytest.approx(burn, abs=h / p.tau0)
        k = np.arange(len(c["pdmp"]["rho"]))
        for rho in (k * dt_rec * p.tau0, k * every * h):  # seconds, the PDMP's lags and the DI's
            assert c["pdmp"]["rho"] == pytest.approx(rho, rel=1e-12) and c["di"]["rho"] == pytest.approx(rho, rel=1e-12)
        assert abs(c["pdmp"]["rho"][-1] - 3.0) <= dt_rec * p.tau0 / 2  # max_lag_s
        rs = {}
        for name, seed in (("pdmp", 4 * j + 2), ("di", 4 * j + 5)):
            V = paths_(seed, f["paths"], round(f["length_tau0"] / dt_rec))
            rs[name] = autocorrelation(V, len(k) - 1, center=True)
            assert np.array_equal(c[name]["h_over_h0"], rs[name][0]) and np.array_equal(c[name]["se"], rs[name][1])
        z = np.abs(rs["pdmp"][0] - rs["di"][0])[1:] / np.hypot(rs["pdmp"][1], rs["di"][1])[1:]
        assert c["max_diff_in_se"] == pytest.approx(z.max(), rel=1e-12)


def test_fig5_numbers_from_known_paths(tmp_path, monkeypatch):
    """Path i sits at 0 (stuck), 2m, -m or 3m for its whole record (i mod 4): E[V] = m v0 with SE
    m v0 sqrt(2.5 / (P - 1)), E[V^2] = 3.5 m^2 v0^2 with SE 3.5 m^2 v0^2 / sqrt(P - 1), P(V = 0) = 1/4
    (physical units: v0 = 0.042 m/s, so an SE in tau0 units is 24x too large).  The chain law is the one at
    the simulated step; the burn-in is 40 tau0 and the records 0.05 tau0 apart."""
    made, calls, laws = [], [], []
    p = Params(0.16, diffusivity.DELTA, 1e-5, diffusivity.TAU_L, diffusivity.GBAR)
    m = theory.exact_M0(p) / p.v0

    def stationary(model, key, paths, n_records, every=1, burn_steps=0, record="VU"):
        calls.append((model, n_records, every, burn_steps))
        V = np.array([0.0, 2 * m, -m, 3 * m])[np.arange(paths) % 4, None] * np.ones(n_records)
        return V, np.zeros((paths, n_records))

    def chain_law(params, h):  # its own tests are test_chain_law.py's: here, which law is asked for
        laws.append((params, h))
        return SimpleNamespace(M0=1.0, mean_v2=2.0, p_stuck=3.0)

    _fake_models(monkeypatch, diffusivity, made)
    monkeypatch.setattr(diffusivity, "di_stationary", stationary)
    monkeypatch.setattr(diffusivity, "white_chain_law", chain_law)
    f = diffusivity.fig5(str(tmp_path), True, 0)
    (_, pm, h), ((_, n_rec, every, burn), P) = made[0], (calls[0], f["n_paths"])
    assert pm == p and h == f["h"] == default_h(p) and laws == [(p, h)]
    hn = h / p.tau0
    assert burn * hn == pytest.approx(40.0, abs=hn) and every * hn == pytest.approx(0.05, rel=1e-9)
    assert n_rec * every * hn == pytest.approx(f["length_tau0"], rel=1e-9)
    assert (f["mean_v_chain"], f["mean_v2_chain"], f["p_stuck_chain"]) == (1.0, 2.0, 3.0)
    v0 = p.v0
    assert f["mean_v"] == pytest.approx(m * v0, rel=1e-12) and f["mean_v_exact"] == theory.exact_M0(p)
    assert f["mean_v_se"] == pytest.approx(m * v0 * math.sqrt(2.5 / (P - 1)), rel=1e-9)
    assert f["mean_v2"] == pytest.approx(3.5 * (m * v0) ** 2, rel=1e-12)
    assert f["mean_v2_exact"] == theory.exact_mean_square_velocity(p)
    assert f["mean_v2_se"] == pytest.approx(3.5 * (m * v0) ** 2 / math.sqrt(P - 1), rel=1e-9)
    assert P % 4 == 0 and f["p_stuck"] == 0.25


def test_fig6_numbers_from_known_paths(tmp_path, monkeypatch):
    """Bin k (centre -4 + 0.1 (k + 1/2), w = 0.1) holds round(n w p_k) paths, p the propagator at
    its centre and the time simulated; the rest lie beyond 4.  The density is within half a count
    of p, so every |MC - exact| / SE is <= 1/2 (an empty bin's SE is one count); the deviation is
    exactly max_k |c_k / (n w) - p_k| / (sqrt(max(c_k, 1)) / (n w))."""
    made, calls = [], []
    w, mids = 0.1, -4 + 0.1 * (np.arange(80) + 0.5)

    def counts(t, v0, n):
        return np.round(n * w * theory.propagator(mids, t, v0)).astype(int)

    def transient(model, key, n, record_steps, v0=1.0):
        calls.append((model, np.asarray(record_steps), v0))
        cols = []
        for t in np.asarray(record_steps) * model[2]:
            v = np.repeat(mids, counts(t, v0, n))
            cols.append(np.concatenate([v, np.full(n - v.size, 10.0)]))
        return np.stack(cols, 1)

    _fake_models(monkeypatch, touchette, made)
    monkeypatch.setattr(touchette, "di_transient", transient)
    f = touchette.fig6(str(tmp_path), True, 0)
    n = f["n_paths"]
    assert [m[1].tau / m[1].tau0 for m in made] == list(touchette.TAUS)
    for j, ((_, _, h), steps, v0) in enumerate(calls):
        assert h == f["h_nd"] and steps * h == pytest.approx(touchette.T_DENSITY, rel=1e-12) and v0 == 1.0
        want = []
        for t in steps * h:
            c, ex = counts(t, 1.0, n), theory.propagator(mids, t, 1.0)
            want.append(np.max(np.abs(c / (n * w) - ex) * n * w / np.sqrt(np.maximum(c, 1))))
        got = f["max_dev_in_se"][f"{touchette.TAUS[j]:g}"]
        assert got == pytest.approx(want, rel=1e-9) and max(got) <= 0.5
        want_ft = [np.max(np.abs(np.sqrt(c) + np.sqrt(c + 1) - np.sqrt(4 * n * w * theory.propagator(mids, t, 1.0) + 1)))
                   for c, t in ((counts(t, 1.0, n), t) for t in steps * h)]
        assert f["max_ft_dev"][f"{touchette.TAUS[j]:g}"] == pytest.approx(want_ft, rel=1e-9)
        assert f["p_zero"][f"{touchette.TAUS[j]:g}"] == [0.0] * 3  # no path is at exactly 0 here
    h = f["h_nd"]
    assert f["p_zero_step"] == pytest.approx([2 * h * theory.propagator(np.zeros(1), t, 1.0)[0]
                                              for t in touchette.T_DENSITY], rel=1e-12)


def test_fig6s_freeman_tukey_deviates_are_calibrated_where_count_ses_are_not():
    """Exact Poisson counts of the quick Fig. 6's 480 bins at tau' <= 5e-4 (n = 20 000 paths, bins of
    0.1 on [-4, 4], t' = 0.25, 1, 2.5, two tau'), 4000 draws (fixed seed): the largest Freeman-Tukey
    deviate reaches the test's bound 5 in under 1% of them (0.2% expected), the largest
    |c - lambda| / sqrt(max(c, 1)) (the plotted bands' SE; what the test read up to 0.2.4) in over 5%
    (12%): that statistic would fail a correct simulation one seed in eight."""
    n, edges = 20_000, np.linspace(-4, 4, 81)
    mids, w = 0.5 * (edges[1:] + edges[:-1]), edges[1] - edges[0]
    lam = np.tile(np.concatenate([n * w * theory.propagator(mids, t, 1.0) for t in touchette.T_DENSITY]), 2)
    c = np.random.default_rng(0).poisson(lam, (4000, lam.size))
    ft = np.abs(touchette.freeman_tukey(c, lam)).max(1)
    by_count = (np.abs(c - lam) / np.sqrt(np.maximum(c, 1))).max(1)
    assert np.mean(ft >= 5) < 0.01 and np.mean(by_count >= 5) > 0.05


def test_local_exponent_with_unequal_spacing_and_unequal_cis():
    """D = 3 G^1.5 at G = 1, 2, 8 (log steps ln 2 and ln 4) with relative CIs 1%, 3%, 0: exponents
    1.5, half-widths sqrt(0.03^2 + 0.01^2) / ln 2 and 0.03 / ln 4 (each pair's own step and CIs,
    in the order the pair has them); a zero, nan or inf D is refused by name (log 0 gave -inf)."""
    G = np.array([1.0, 2.0, 8.0])
    D = 3 * G**1.5
    gm, s, ci = diffusivity.local_exponent(G, D, D * [0.01, 0.03, 0.0])
    assert s == pytest.approx([1.5, 1.5], rel=1e-12) and gm == pytest.approx([2**0.5, 4.0], rel=1e-12)
    assert ci == pytest.approx([math.hypot(0.03, 0.01) / math.log(2), 0.03 / math.log(4)], rel=1e-12)
    for bad in (0.0, math.nan, math.inf):
        with pytest.raises(ValueError, match="^D must be finite and > 0"):
            diffusivity.local_exponent(G, [1.0, bad, 2.0], [0.1] * 3)


def test_fit_slope_weighted_and_from_residuals():
    """log x = 0, 1, 2 and log y = 0, 3, 3, by hand.  Replicates 1, 1, 4 (weights 2 R = 2, 2, 8):
    weighted slope 9/7, propagated SE sqrt(1/7) = 0.38, residual SE sqrt(chi2 / (3 - 2) / 7) =
    3 sqrt(8 / 147) = 0.70, the larger reported.  Without replicates: slope 3/2, SE from the residuals
    alone, sqrt(3/2 / 2) (and 0 on an exact line).  Fewer than one replicate is refused."""
    x = np.exp([0.0, 1.0, 2.0])
    y = np.exp([0.0, 3.0, 3.0])
    slope, se = fit_slope(x, y, [1, 1, 4])
    assert slope == pytest.approx(9 / 7, rel=1e-12) and se == pytest.approx(3 * math.sqrt(8 / 147), rel=1e-12)
    assert fit_slope(x, y) == pytest.approx((1.5, math.sqrt(1.5 / 2)), rel=1e-12)
    assert fit_slope(x, x**-0.5) == pytest.approx((-0.5, 0.0), abs=1e-12)
    with pytest.raises(ValueError, match="^replicates must be finite and >= 1"):
        fit_slope(x, y, [1, 0.5, 1])


def _fake_plan(calls, fits):
    """plan_estimate that records (method, N, settings) and refuses (ValueError) what ``fits`` rejects."""
    def plan(p, method="di", n_excursions=20_000, **kw):
        calls.append((method, n_excursions, kw))
        if not fits(p, method, n_excursions, kw):
            raise ValueError("max_work")
    return plan


def test_affordable_n_divides_by_4_asking_with_the_runs_settings(monkeypatch):
    """N = 1e5 refused above 3000: asked at 1e5, 25000, 6250, 1562, which fits; the method and delta
    are the run's.  N = 1000 (quick) is asked too, once."""
    calls, p = [], Params(1.0, 3.84, 1.0, 0.067, 0.342)
    monkeypatch.setattr(diffusivity, "plan_estimate", _fake_plan(calls, lambda p, m, n, kw: n <= 3000))
    assert diffusivity._affordable_n(p, "pdmp", 100_000, dict(delta=0.125)) == 1562
    assert calls == [("pdmp", n, dict(delta=0.125)) for n in (100_000, 25_000, 6250, 1562)]
    calls.clear()
    assert diffusivity._affordable_n(p, "di", 1000, {}) == 1000 and calls == [("di", 1000, {})]


def test_affordable_n_stops_at_the_floor_and_raises_the_planners_refusal(monkeypatch):
    """A point the planner refuses at every N: 1562 is followed by the floor 1000 (not 390), and the
    refusal at the floor reaches the caller instead of an unasked N <= 1000 being run."""
    calls, p = [], Params(1.0, 3.84, 1.0, 0.067, 0.342)
    monkeypatch.setattr(diffusivity, "plan_estimate", _fake_plan(calls, lambda p, m, n, kw: n <= 500))
    with pytest.raises(ValueError, match="max_work"):
        diffusivity._affordable_n(p, "di", 100_000, {})
    assert [c[1] for c in calls] == [100_000, 25_000, 6250, 1562, 1000]
    calls.clear()
    monkeypatch.setattr(diffusivity, "plan_estimate", _fake_plan(calls, lambda p, m, n, kw: n <= 1000))
    assert diffusivity._affordable_n(p, "di", 2000, {}) == 1000 and [c[1] for c in calls] == [2000, 1000]


def _fake_points(module, monkeypatch, estimate, bruteforce=None):
    """Replace the scene's Points by one whose runs are ``estimate`` / ``bruteforce`` (params, seed, kw)."""
    runs = []

    class FakePoints:
        def __init__(self, out_dir, scene):
            pass

        def estimate(self, params, seed, **kw):
            runs.append(("estimate", params, seed, kw))
            return estimate(params, seed, kw)

        def bruteforce(self, params, seed, **kw):
            runs.append(("bruteforce", params, seed, kw))
            return bruteforce(params, seed, kw)

        def kept(self, params, seed, **kw):
            return False

        def summary(self):
            return {}

    monkeypatch.setattr(module, "Points", FakePoints)
    return runs


def _no_files(module, monkeypatch, figs):
    """The scene's ``save`` keeps the figure's plotted lines in ``figs`` and returns its numbers, writing no
    files (PNG and PDF of many points took 2-8 s here; the files are test_figures.py's)."""
    def save(fig, out_dir, name, numbers, t0, **meta):
        figs.append([[(np.asarray(ln.get_xdata(), float), np.asarray(ln.get_ydata(), float)) for ln in ax.lines]
                     for ax in fig.axes])
        module.plt.close(fig)
        return dict(numbers)
    monkeypatch.setattr(module, "save", save)


def test_fig3_numbers_from_known_runs(tmp_path, monkeypatch):
    """Full settings (N = 1e5, cut by 4 while the planner refuses: DI above 7000 at Gamma < 2, PDMP
    above 30000 where it is asked with delta = 0.125).  Fake runs: DI D = Gamma, CI 0.3; PDMP
    D = Gamma - 0.5, CI 0.4, so every agreement |difference| / hypot(CIs) is exactly 1; durations
    are 2 Gamma +- 0.1 Gamma.  Every run has its own seed (the PDMP's are not the DI's)."""
    calls = []

    def fits(p, m, n, kw):
        return n <= (30_000 if m == "pdmp" and kw == dict(delta=0.125) else 7000 if p.Gamma < 2 else math.inf)

    def est(p, seed, kw):
        pdmp = kw.get("method") == "pdmp"
        return SimpleNamespace(D=p.Gamma - 0.5 * pdmp, D_ci=0.3 + 0.1 * pdmp, mean_duration=2 * p.Gamma,
                               mean_duration_ci=0.1 * p.Gamma, wall_s=1.0, n_excursions=kw["n_excursions"])

    monkeypatch.setattr(diffusivity, "plan_estimate", _fake_plan(calls, fits))
    runs = _fake_points(diffusivity, monkeypatch, est)
    _no_files(diffusivity, monkeypatch, [])
    durs = []

    def dur(p, seed, cycle_s, quick, pts=None):  # the paper's duration: half the cycle; none at Gamma = 1, tau = 1 s
        durs.append((p.Gamma, p.tau, seed, cycle_s, quick))
        assert pts is not None  # through the scene's points file (kept, reused when resumed)
        return None if (p.Gamma, p.tau) == (1.0, 1.0) else SimpleNamespace(
            mean=cycle_s / 2, ci=0.05 * p.Gamma, h=1e-4, n_lanes=64, n_excursions=128, n_truncated=1)

    monkeypatch.setattr(diffusivity, "_di_durations", dur)
    f = diffusivity.fig3(str(tmp_path), False, 0)
    assert len({d[2] for d in durs}) == len(durs) == len(f["Gamma"]) * 4 and all(d[4] is False for d in durs)
    assert all(d[3] == pytest.approx(2 * d[0]) for d in durs)  # planned from the DI run's cycle
    assert f["le_dur_missing"] == 1 and f["le_dur_truncated"] == len(durs) - 1
    assert f["di"]["1"]["le_dur"][0] is None and f["agree_dur"]["1"][0] is None
    # PDMP durations 2 Gamma +- 0.1 Gamma against the DI's Gamma +- 0.05 Gamma: |diff| / hypot = 1 / hypot(0.1, 0.05)
    assert f["agree_dur"]["0.5"] == pytest.approx([1 / math.hypot(0.1, 0.05)] * len(f["Gamma"]))
    G = f["Gamma"]
    assert len(runs) == 2 * len(G) * len(f["tau"]) and len({r[2] for r in runs}) == len(runs)
    assert {(p.tau, p.Gamma, kw["method"]) for _, p, _, kw in runs} == {(t, g, m) for t in f["tau"] for g in G
                                                                        for m in ("pdmp", "di")}
    for _, p, _, kw in runs:
        assert (p.Delta, p.tau_L, p.gamma_bar) == (diffusivity.DELTA, diffusivity.TAU_L, diffusivity.GBAR)
        want = dict(method="pdmp", delta=0.125) if kw["method"] == "pdmp" else dict(method="di")
        n = 25_000 if kw["method"] == "pdmp" else 6250 if p.Gamma < 2 else 100_000
        assert kw == dict(want, n_excursions=n)
    for tau in f["tau"]:
        for m, off, ci in (("pdmp", 0.5, 0.4), ("di", 0.0, 0.3)):
            r = f[m][f"{tau:g}"]
            assert r["D"] == pytest.approx([g - off for g in G], abs=1e-12) and r["D_ci"] == [ci] * len(G)
            assert r["dur"] == pytest.approx([2 * g for g in G]) and r["dur_ci"] == pytest.approx([0.1 * g for g in G])
        assert f["agree"][f"{tau:g}"] == pytest.approx([1.0] * len(G), rel=1e-12)
    # the PDMP grid's widening of the stuck set per Gamma (pdmp.threshold_widening; test_pdmp checks it by hand)
    from dryfric_jax.pdmp import threshold_widening

    gb = diffusivity.GBAR / diffusivity.DELTA
    assert f["pdmp_grid_widening"] == pytest.approx([sum(threshold_widening(0.125 * math.sqrt(g) / diffusivity.DELTA,
                                                                            gb)) for g in G], rel=1e-9)
    assert max(f["pdmp_grid_widening"]) == pytest.approx(1.92, abs=0.005)



@pytest.mark.parametrize("cycle", [float("nan"), float("inf"), None, 0.0, -1.0, "x"])
def test_fig3_duration_plan_without_a_cycle_is_a_missing_point(monkeypatch, cycle):
    """A D run with no finite cycle duration gave _di_durations' plan a NaN (ValueError outside its try),
    an inf (OverflowError) or None (TypeError) and lost the figure (an audit): no plan, no run, a missing point."""
    monkeypatch.setattr(diffusivity, "di_long_excursion_duration", lambda *a, **k: pytest.fail("ran"))
    assert diffusivity._di_durations(Params(**FIG3), 0, cycle, True) is None


def test_fig3_duration_only_the_counts_own_failure_is_a_missing_point(monkeypatch):
    """A count with fewer than 2 LEs (``NoCountError``) is a missing point; any other ``ValueError``, such as one
    raised by a progress callback (``points.reporting``) within the count, goes up (it was a missing point too,
    silently: an audit)."""
    from dryfric_jax.durations import NoCountError

    def fails(cls):
        def run(*a, **k):
            raise cls("x")
        return run

    monkeypatch.setattr(diffusivity, "di_long_excursion_duration", fails(NoCountError))
    assert diffusivity._di_durations(Params(**FIG3), 0, 4.0, True) is None
    monkeypatch.setattr(diffusivity, "di_long_excursion_duration", fails(ValueError))
    with pytest.raises(ValueError, match="^x$"):
        diffusivity._di_durations(Params(**FIG3), 0, 4.0, True)


@pytest.mark.parametrize("quick,cycle,n,lanes", [(True, 4.0, 5025, 256), (True, 40.0, 502, 128),
                                                  (False, 4.0, 8192, 256), (False, 1e9, 32, 32)])
def test_fig3_duration_plan(monkeypatch, quick, cycle, n, lanes):
    """Long excursions from DUR_WORK and the cycle (an excursion takes at most a cycle), within DUR_N = [32, 8192],
    the count's default lanes and step (durations.default_duration_h), a bound of 50x the expected steps of a lane's
    excursions plus 2 (>= 1e4); a cycle so long that the bound passes durations.MAX_STEPS is clipped to it (it was
    refused: a missing point).  By hand: at Fig. 3's point (h = 6.7e-4 s, tau/h = 746 >= 700, cycle 4 s) an
    excursion takes 5970 steps: 3e7 (quick) is 5025 of them, lanes the power of 2 nearest 1675, within [32, 256]:
    256; at a 40 s cycle 502.5 -> 502, in 128 lanes (167 -> 128); 1e9 (full) 1.7e5, capped at 8192, in 256 lanes;
    a 1e9 s cycle: the floor 32, in 32 lanes."""
    from dryfric_jax.durations import MAX_STEPS, default_lanes

    seen = {}
    monkeypatch.setattr(diffusivity, "di_long_excursion_duration", lambda p, seed, **kw: seen.update(kw) or "run")
    p = Params(**FIG3)
    assert diffusivity._di_durations(p, 0, cycle, quick) == "run"
    h = 6.7e-4
    assert seen["h"] == h and seen["n_excursions"] == n and "n_lanes" not in seen and default_lanes(n) == lanes
    assert seen["max_steps"] == min(max(int(50 * (n / lanes + 2) * cycle / h), 10_000), MAX_STEPS)


def test_fig8_numbers_from_known_runs(tmp_path, monkeypatch):
    """Fake long-excursion runs D = 2 Gamma^3 tau^0.1 with relative CIs 1% at even, 3% at odd points:
    exponents exactly 3 at the geometric midpoints, half-widths hypot(0.01, 0.03) / ln 2 (Gamma doubles);
    brute force D_t = D / 2 with CI 0.1 D at t = 10 s, N' = 100.  The reference is the exact white-noise D
    of each case (b = 0: no viscous term, gamma_bar = 0; asked at tau = 1e-9 s), t / tau0 is in the case's
    tau0; every run has its own seed (brute force and long excursions are independent)."""
    rel = lambda p: 0.01 if round(math.log2(p.Gamma)) % 2 == 0 else 0.03  # noqa: E731

    def est(p, seed, kw):
        assert kw == dict(n_excursions=1000)
        D = 2 * p.Gamma**3 * p.tau**0.1
        return SimpleNamespace(D=D, D_ci=rel(p) * D)

    def bf(p, seed, kw):
        assert kw == dict(t=10.0, n_paths=100)
        return SimpleNamespace(D_t=p.Gamma**3 * p.tau**0.1, D_t_ci=0.2 * p.Gamma**3 * p.tau**0.1)

    runs = _fake_points(diffusivity, monkeypatch, est, bf)
    monkeypatch.setattr(theory, "exact_D", lambda p: (p.Gamma, p.Delta, p.tau, p.tau_L, p.gamma_bar))
    _no_files(diffusivity, monkeypatch, [])
    f = diffusivity.fig8(str(tmp_path), True, 0)
    G = f["Gamma"]
    assert len(runs) == 2 * 2 * len(G) * len(f["tau"]) and len({(r[0], r[2]) for r in runs}) == len(runs)
    assert len({r[2] for r in runs}) == len(runs)
    for name, (tl, gb) in (("b = 0", (math.inf, 0.0)), ("b = -v/tau_L + gamma_bar", (0.067, 0.342))):
        c = f["cases"][name]
        assert c["exact"] == [(g, diffusivity.DELTA, 1e-9, tl, gb) for g in G]  # theory.exact_D's parameters
        if tl == math.inf:  # what its brute force estimates, D (1 - 27/5 tau0/t) (all quick points: t >= 20 tau0)
            assert c["exact_bf"] == pytest.approx([10 * g**3 / 3.84**4 * (1 - 5.4 * g / 3.84**2 / 10) for g in G])
        else:
            assert "exact_bf" not in c
        for tau in f["tau"]:
            ps = [Params(g, diffusivity.DELTA, tau, tl, gb) for g in G]
            for kind in ("estimate", "bruteforce"):
                assert [r[1] for r in runs if r[0] == kind and r[1] in ps] == ps
            r = c[f"{tau:g}"]
            D = [2 * g**3 * tau**0.1 for g in G]
            assert r["D"] == pytest.approx(D, rel=1e-12)
            assert r["D_ci"] == pytest.approx([rel(q) * d for q, d in zip(ps, D)])
            assert r["D_bf"] == pytest.approx([d / 2 for d in D])
            assert r["D_bf_ci"] == pytest.approx([0.1 * d for d in D])
            assert r["t_over_tau0"] == pytest.approx([10.0 / q.tau0 for q in ps], rel=1e-12)
            assert r["exponent"] == pytest.approx([3.0] * (len(G) - 1), rel=1e-9)
            assert r["exponent_at"] == pytest.approx([math.sqrt(a * b) for a, b in zip(G, G[1:])], rel=1e-12)
            assert r["exponent_ci"] == pytest.approx([math.hypot(0.01, 0.03) / math.log(2)] * (len(G) - 1), rel=1e-9)


def test_fig5_histogram_total_variation_and_u_paths(tmp_path, monkeypatch):
    """Even paths at -x, odd ones at +x (2x = 10.5 bins of the paper's 4.8e-4 m/s), except path 1 at 2x
    (1/256 of the samples: inside the 1e-4 quantiles) and one sample at 10 x (beyond them: out of the
    histogram, in its denominator).  The bins run from -x in steps of 4.8e-4 past 2x: 16 bins, their
    centres asked of the density; with a flat density of e = 0.9 / 16 per bin the total variation is
    (|n0/N - e| + |n10/N - e| + |n15/N - e| + 13 e) / 2 exactly.  The U(t) panel: 10 paths at records
    1..n of the step h, over 2 s, in metres, and the JSON's ``U_paths`` the same arrays."""
    p = Params(0.16, diffusivity.DELTA, 1e-5, diffusivity.TAU_L, diffusivity.GBAR)
    bw, x = 4.8e-4, 10.5 * 4.8e-4 / 2
    calls, mids, figs = [], [], []

    def stationary(model, key, paths, n_records, every=1, burn_steps=0, record="VU"):
        calls.append((jax.random.key_data(key).tolist(), paths, n_records, every, burn_steps))
        V = np.where(np.arange(paths)[:, None] % 2, x, -x) / p.v0 * np.ones(n_records)
        V[1], V[0, 0] = 2 * x / p.v0, 10 * x / p.v0
        return V, np.arange(paths)[:, None] * np.ones(n_records)

    def density(v, params):
        assert params == p
        mids.append(np.asarray(v))
        return np.full(len(v), 0.9 / 16 / bw)

    _fake_models(monkeypatch, diffusivity, [])
    monkeypatch.setattr(diffusivity, "di_stationary", stationary)
    monkeypatch.setattr(diffusivity, "white_chain_law", lambda params, h: SimpleNamespace(M0=1, mean_v2=2, p_stuck=3))
    monkeypatch.setattr(theory, "stationary_density", density)
    for name in ("exact_M0", "exact_mean_square_velocity"):  # quadratures (5 s), test_fig5_numbers_from_known_paths'
        monkeypatch.setattr(theory, name, lambda params: 0.0)
    _no_files(diffusivity, monkeypatch, figs)
    f = diffusivity.fig5(str(tmp_path), True, 0)
    (k0, P, n, _, _), (k1, ten, n_rec, every, burn) = calls
    N = P * n
    assert f["bin_width"] == bw and mids[0] == pytest.approx(-x + bw * (np.arange(16) + 0.5), rel=0, abs=1e-12)
    e, cnt = 0.9 / 16, np.array([N / 2 - 1, N / 2 - n, n])
    assert f["total_variation"] == pytest.approx((np.abs(cnt / N - e).sum() + 13 * e) / 2, rel=1e-12)
    h = f["h"]
    assert k1 != k0 and (ten, every) == (10, 1) and n_rec * h == pytest.approx(2.0, abs=h) and burn * h / p.tau0 > 39
    lines = figs[0][1]
    assert len(lines) == 10
    for i, (t, u) in enumerate(lines):
        assert t == pytest.approx(np.arange(1, n_rec + 1) * h, rel=1e-12) and u == pytest.approx(i * p.u0, rel=1e-12)
    # the JSON holds the panel's paths as plotted (an audit: it held none of them): the same numbers
    up = f["U_paths"]
    assert type(up["t_s"]) is list and len(up["U_m"]) == 10 and all(type(u) is list for u in up["U_m"])
    np.testing.assert_array_equal(up["t_s"], lines[0][0])
    for u, (_, line) in zip(up["U_m"], lines):
        np.testing.assert_array_equal(u, line)


def test_fig9_numbers_from_known_runs(tmp_path, monkeypatch):
    """(a) Lane i closes 1 + i mod 3 excursions of mean D_true + e_i (e_i known, N(0, 0.05)) in 100 + i steps;
    a replicate of g lanes has D = its excursion-weighted mean, its cost the sum of its steps.  Brute force:
    2^16 known paths recorded every 0.5 tau0 (32 records, quick); at horizon t = (j + 1) 0.5 tau0 a replicate of
    G paths has D_t = Var U(t) / t (numpy's, ddof 0), its error D_t - D_true, and bruteforce_estimates of all
    paths gives the bias row.  The RMSEs over the replicates, in m^2/s like D_true (D0 = 0.57 m^2/s here), the
    costs, the envelope (per cost level G (j + 1), chosen on the first half of the replicates, measured on the
    second) and the slopes (fit_slope, weighted by the replicates) follow.  (b) h in min(tau0, tau_L), delta in
    Delta / sqrt(Gamma), one seed per run, the PDMP's runs are PDMP runs, each method warmed up once first."""
    made, rounds, recs, bfs, warm = [], [], [], [], []
    rng = np.random.default_rng(3)
    e = rng.normal(0, 0.05, 1024)
    n_paths, n_rec, groups = 2**16, 32, (16, 64, 256, 1024)
    Ub = rng.normal(0, 1.0, (n_paths, n_rec)) * np.sqrt(np.arange(1, n_rec + 1))
    G, Dl = FIG3["Gamma"], FIG3["Delta"]
    p = Params(G, Dl, 1e-5 * G / Dl**2, FIG3["tau_L"], FIG3["gamma_bar"])
    D_true = 0.3 / p.D0  # exact_D is faked at 0.3 m^2/s: nondimensional

    def run_round(model, key, lanes, budget):
        rounds.append((model, lanes, budget))
        n = 1.0 + np.arange(lanes) % 3
        stats = np.zeros((lanes, len(STAT_NAMES)))
        stats[:, 0], stats[:, 1] = n, n * (D_true + e[:lanes])
        return SimpleNamespace(stats=stats, lane_steps=100 + np.arange(lanes))

    def le_est(T):
        assert list(T) == list(STAT_NAMES)
        return dict(D=T["U"] / T["n"])

    def stationary(model, key, paths, n_records, every=1, burn_steps=0, record="VU"):
        recs.append((model, paths, n_records, every))
        return None, Ub[:paths, :n_records]

    def bf_est(U, t):
        bfs.append(t)
        return dict(D_t=np.var(U) / t + 0.01, D_t_ci=0.02)

    _fake_models(monkeypatch, speed_error, made)
    for name, fake in (("run_round", run_round), ("long_excursion_estimates", le_est), ("di_stationary", stationary),
                       ("bruteforce_estimates", bf_est)):
        monkeypatch.setattr(speed_error, name, fake)
    monkeypatch.setattr(speed_error, "estimate_diffusivity",
                        lambda q, seed, **kw: warm.append((q, seed, kw)) or SimpleNamespace(stopped_by="n_excursions"))
    monkeypatch.setattr(theory, "exact_D", lambda params: 0.3 if params == p else math.nan)
    # a run reports the step it simulated (its result's h, delta): here 1.5x the one asked, so the JSON's are seen
    # to be the results' (the scene recorded the steps it asked for: a test audit)
    runs = _fake_points(speed_error, monkeypatch, lambda q, seed, kw: SimpleNamespace(
        D=1.0 + seed, D_ci=0.1 * seed, wall_s=2.0 + seed, h=1.5 * kw["h"] if "h" in kw else None,
        delta=1.5 * kw["delta"] if "delta" in kw else None))
    _no_files(speed_error, monkeypatch, [])
    f = speed_error.fig9(str(tmp_path), True, 0)
    (_, pm, h), = made
    hn = h / p.tau0
    every = round(0.5 / hn)
    assert pm == p and h == default_h(p) and f["D_true"] == pytest.approx(0.3, rel=1e-12)
    assert rounds == [(made[0], 1024, 80_000)] and recs == [(made[0], n_paths, n_rec, every)]
    want = []
    for g in (1, 4, 16, 64):
        n = (1.0 + np.arange(1024) % 3).reshape(-1, g)
        err = (n * e.reshape(-1, g)).sum(1) / n.sum(1)
        cost = (100 + np.arange(1024)).reshape(-1, g).sum(1).mean()
        want.append(dict(lanes=g, n_excursions=n.sum(1).mean(), cost=cost,
                         rmse=np.sqrt(np.mean(err**2)) * p.D0, replicates=1024 // g))
    assert f["le"] == [pytest.approx(w, rel=1e-9) for w in want]
    levels, js = {}, [0, 1, 3, 7, 15, 31]
    assert list(f["bf"]) == ["0.5", "1", "2", "4", "8", "16"]
    for t, j in zip(f["bf"], js):
        tt = (j + 1) * every * hn
        rows = []
        for g in groups:
            err = np.var(Ub[:, j].reshape(-1, g), axis=1) / tt - D_true
            rows.append(dict(paths=g, cost=g * (j + 1) * every, rmse=np.sqrt(np.mean(err**2)) * p.D0,
                             replicates=n_paths // g))
            a, b = np.sqrt(np.mean(err[:err.size // 2] ** 2)), np.sqrt(np.mean(err[err.size // 2:] ** 2))
            levels.setdefault(g * (j + 1), []).append((a, b * p.D0, err.size // 2, rows[-1]["cost"], tt, g))
        assert f["bf"][t] == [pytest.approx(r, rel=1e-9) for r in rows]
    assert bfs == pytest.approx([(j + 1) * every * hn for j in js], rel=1e-12)
    assert f["bf_bias"] == [pytest.approx(dict(t=(j + 1) * every * hn, D_t_over_D=(np.var(Ub[:, j]) / ((j + 1) * every * hn)
                                                                                  + 0.01) / D_true, ci=0.02 / D_true),
                                          rel=1e-9) for j in js]
    env = [min(c) for lv, c in sorted(levels.items()) if len(c) >= 2]
    assert len(env) >= 3 and f["bf_envelope"] == [pytest.approx(dict(cost=c, rmse=b, replicates=r, t=tt, paths=g,
                                                                     candidates=len(levels[c / every])), rel=1e-9)
                                                  for _, b, r, c, tt, g in env]
    assert (f["bf_slope"], f["bf_slope_se"]) == pytest.approx(fit_slope(*zip(*[(c, b, r) for _, b, r, c, _, _ in env])),
                                                              rel=1e-9)
    le = [(w["cost"], w["rmse"], w["replicates"]) for w in want]
    assert (f["le_slope"], f["le_slope_se"]) == pytest.approx(fit_slope(*zip(*le)), rel=1e-9)
    pf = Params(**FIG3)
    hs = [r * min(pf.tau0, pf.tau_L) for r in (0.1, 0.03, 0.01, 0.003)]
    ds = [d * pf.Delta / math.sqrt(pf.Gamma) for d in (0.15, 0.1, 0.05, 0.025)]
    assert [(q, kw) for _, q, _, kw in runs] == ([(pf, dict(h=x, n_excursions=2000)) for x in hs]
                                                 + [(pf, dict(method="pdmp", delta=d, n_excursions=2000)) for d in ds])
    seeds = [r[2] for r in runs]
    assert len(set(seeds)) == 8
    lanes = speed_error.lanes_for(2000)
    assert warm == [(pf, 0, dict(n_excursions=lanes, lanes=lanes, method="di", h=hs[0])),
                    (pf, 0, dict(n_excursions=lanes, lanes=lanes, method="pdmp", delta=ds[0]))]
    assert f["di"] + f["pdmp"] == [dict(D=1.0 + s, D_ci=0.1 * s, wall_s=2.0 + s, **x) for s, x in
                                   zip(seeds, [dict(h=1.5 * x) for x in hs] + [dict(delta=1.5 * d) for d in ds])]
