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

import numpy as np
import pytest

from dryfric_jax import theory
from dryfric_jax.figures import covariance, diffusivity, touchette
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

    def stationary(model, key, paths, n_records, every, burn_steps=0):
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

    def di(model, key, paths, n_rec, every, burn_steps=0):
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

    def stationary(model, key, paths, n_records, every=1, burn_steps=0):
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
