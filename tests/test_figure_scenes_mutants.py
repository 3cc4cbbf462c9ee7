r"""Mutation audit of the figure scenes' numbers: :mod:`dryfric_jax.figures.excursion` (Figs. 1-2),
:mod:`dryfric_jax.figures.covariance` (Fig. 4), :mod:`dryfric_jax.figures.diffusivity` (Figs. 3, 5, 8) and
:mod:`dryfric_jax.figures.common` (``save``, ``exact_steps``).

Every simulator, model builder and estimator is a fake that records what it was given (no JAX run, no
quadrature).  The expected values come from the paper's captions (Figs. 1-2: Gamma = 5, Delta = 3.84,
tau = 0.5 s, tau_L = 0.067 s, gamma_bar = 0.342, delta = 0.125 s^-1/2; Fig. 3: tau = 0.125 .. 1 s,
Gamma in [1, 10]; Fig. 4: tau = 0.25, 0.5, 1 s, i.e. tau' = 0.74, 1.47, 2.95; Fig. 8: tau = 10^-i s,
i = 5 .. 2, t = 10 s), the README's scene table and its Fig. 4 note (burn-in 50 tau0, records every
0.05 tau0, 177 lags up to 3 s and a DI step of 6.5e-4 s at tau = 0.25 s), unit conversions by hand
(tau0 = Gamma / Delta^2, v0 = Gamma / Delta, u0 = Gamma^2 / Delta^3, X = X' Delta / sqrt(Gamma)) and the
PNG / PDF magic numbers.  Each test's docstring names the mutants (edits of those modules) it kills.

Counts (mutants tried / killed by the older fast tests, test_figure_numbers.py, test_helpers_mutants.py and
test_figure_helpers_mutants.py, without test_figures.py's figs fixture / equivalent / killed only here):
covariance.py 26 / 17 / 2 / 7, excursion.py 17 / 0 / 1 / 16, diffusivity.py 40 / 27 / 2 / 11 (one of the 27,
``_affordable_n`` going on at the floor, hung until a timeout; the last test here kills it at once), common.py 12 /
2 / 2 / 8; in all 95 / 46 / 7 / 42. Equivalent: Fig. 4's quick path count 128 -> 64 and full length 1000 -> 100 tau0
(C24, C19: settings no caption or README line fixes), the DI of Figs. 1-2 drawn from key(seed + 1) (E15: one sample
either way), Fig. 5's histogram range at the 1e-3 quantiles for 1e-4 (D25: a display range) and Fig. 8's full Gamma
grid from 0.5 for 0.25 (D38: the paper gives no grid), ``exact_steps`` refusing n < 0 for n < 1 (M08: n = 0 leaves
|0 h - t| = t, refused by the tolerance anyway) and its bound 2^64 for 2^62 (M10: far beyond any count the scenes
ask). No defect found in these modules.
"""
import json
import math
import time

import jax
import numpy as np
import pytest

from dryfric_jax import theory
from dryfric_jax.figures import common, covariance, diffusivity, excursion
from dryfric_jax.params import Params
from test_figure_numbers import _no_files  # the scene's save, writing no files

# the paper's Fig. 1-4 point (captions), written out here rather than read from the package
G5, DELTA, TAU_L, GBAR = 5.0, 3.84, 0.067, 0.342


def _key(key):
    return tuple(np.asarray(jax.random.key_data(key)).ravel().tolist())


# ---- excursion.py (Figs. 1-2) -------------------------------------------------------------------------------

# one nondimensional excursion (t', X', V', U'), second half from index 2; the DI's flagged incomplete
_T, _X = np.array([0.0, 0.5, 1.2, 2.0, 3.1]), np.array([0.91, 1.2, 0.3, -0.9, -1.0])
_V, _U = np.array([0.0, 0.4, 0.1, -0.2, 0.05]), np.array([0.0, 0.1, 0.3, 0.2, 0.25])


def test_fig1_2_caption_parameters_units_and_the_excursions_numbers(tmp_path, monkeypatch):
    """Figs. 1-2's captions: Gamma = 5, Delta = 3.84, tau = 0.5 s, tau_L = 0.067 s, gamma_bar = 0.342, the PDMP
    at delta = 0.125 s^-1/2, the DI at the default step (in seconds: 0.01 min(tau0, tau_L)).  A fake
    excursion (t', X', V', U', i_half = 2) is put in SI units by hand: t = t' Gamma / Delta^2, X = X' Delta /
    sqrt(Gamma), V = V' Gamma / Delta, U = U' Gamma^2 / Delta^3; the JSON has the duration, half time, final U,
    the step or event count, the excursion's own ``complete``, X at the start and at the half, under the
    rows' names.  Kills: X scaled by sqrt(Gamma) / Delta (E01), V in u0 (E02, plotted), U in v0 (E03), t in
    tau0 (E04), delta = 0.25 (E05), the DI step in tau0 units (E06), tau = 1 s (E07), the half time one
    event late (E08), U at the half (E09), len(t) steps (E10), X one before the half (E11), complete always
    True (E12), X at the second record (E13), the duration one record short (E14), the rows' names cut (E16),
    the duration in tau0 (E17).  The DI row is ``paths.di_long_excursion`` (the paper's long excursion from release
    to release, not ``di_excursion``'s regeneration cycle: an audit), whose last state is the one after the next
    release, so its duration, U and steps end one state before the last (its ``duration``); the JSON says which
    definition each row plots and holds the plotted arrays (t, X, V, U in SI units, i_half), the same numbers as
    the figure's lines."""
    made, keys, figs = [], [], []
    exc = lambda complete: dict(t=_T, x=_X, v=_V, U=_U, i_half=2, complete=complete)  # noqa: E731
    di = dict(exc(False), duration=_T[-2])
    monkeypatch.setattr(excursion, "make_pdmp_model", lambda p, d: made.append(("pdmp", p, d)) or "pdmp")
    monkeypatch.setattr(excursion, "make_di_model", lambda p, h: made.append(("di", p, h)) or "di")
    monkeypatch.setattr(excursion, "excursion_skeleton", lambda m, k: keys.append((m, _key(k))) or exc(True))
    monkeypatch.setattr(excursion, "di_long_excursion", lambda m, k: keys.append((m, _key(k))) or di)
    assert not hasattr(excursion, "di_excursion")  # the cycle is not what the figure plots
    _no_files(excursion, monkeypatch, figs)
    f = excursion.fig1_2(str(tmp_path), True, 3)
    tau0, v0, u0, sx = G5 / DELTA**2, G5 / DELTA, G5**2 / DELTA**3, DELTA / math.sqrt(G5)
    p = Params(G5, DELTA, 0.5, TAU_L, GBAR)
    assert made == [("pdmp", p, 0.125), ("di", p, pytest.approx(0.01 * min(tau0, TAU_L), rel=1e-12))]
    assert [m for m, _ in keys] == ["pdmp", "di"]
    assert sorted(f) == ["DI (h = default)", "PDMP (delta = 0.125)"]
    for name, complete, end in (("PDMP (delta = 0.125)", True, 4), ("DI (h = default)", False, 3)):
        path = f[name].pop("path")
        d = f[name].pop("definition")  # the PDMP's s_+ -> s_- -> s_+, the DI's releases (section 6.1)
        assert ("section 3" if complete else "section 6.1") in d and ("release" in d) is not complete, d
        assert f[name] == pytest.approx(dict(duration_s=_T[end] * tau0, half_s=1.2 * tau0, U_m=_U[end] * u0,
                                             steps_or_events=end, complete=complete, x_start=0.91 * sx,
                                             x_half=0.3 * sx), rel=1e-12)
        assert type(f[name]["steps_or_events"]) is int and f[name]["complete"] is complete
        want = dict(t_s=_T * tau0, X=_X * sx, V_m_s=_V * v0, U_m=_U * u0)
        assert sorted(path) == sorted([*want, "i_half"]) and path["i_half"] == 2
        for k, a in want.items():
            assert path[k] == pytest.approx(list(a), rel=1e-12), k
        assert type(path["i_half"]) is int and all(type(a) is list for k, a in path.items() if k != "i_half")
    for row in (figs[0][0:4], figs[0][4:8]):  # X, V, U (each in two halves), V against X
        (tx, x), _ = row[0]
        (tv, v), _ = row[1]
        (tu, u), _ = row[2]
        (xv, vx), _ = row[3]
        for t in (tx, tv, tu):
            assert t == pytest.approx(_T[:3] * tau0, rel=1e-12)
        assert x == pytest.approx(_X[:3] * sx, rel=1e-12) and xv == pytest.approx(_X[:3] * sx, rel=1e-12)
        assert v == pytest.approx(_V[:3] * v0, rel=1e-12) and vx == pytest.approx(_V[:3] * v0, rel=1e-12)
        assert u == pytest.approx(_U[:3] * u0, rel=1e-12)
        (tx2, x2), (tv2, v2), (tu2, u2) = row[0][1], row[1][1], row[2][1]  # the second halves, from i_half on
        for t in (tx2, tv2, tu2):
            assert t == pytest.approx(_T[2:] * tau0, rel=1e-12)
        assert x2 == pytest.approx(_X[2:] * sx, rel=1e-12)
        assert v2 == pytest.approx(_V[2:] * v0, rel=1e-12) and u2 == pytest.approx(_U[2:] * u0, rel=1e-12)


# ---- covariance.py (Fig. 4) ---------------------------------------------------------------------------------

def _fig4(tmp_path, monkeypatch, quick):
    made, calls = [], []

    def pdmp(model, key, paths, n_rec, dt_rec, burn):
        calls.append(("pdmp", model, _key(key), paths, n_rec, dt_rec, burn))
        return 1.0 + np.random.default_rng(len(calls)).normal(size=(paths, n_rec))

    def di(model, key, paths, n_rec, every, burn_steps=0, record="VU"):
        calls.append(("di", model, _key(key), paths, n_rec, every, burn_steps))
        return 1.0 + np.random.default_rng(len(calls)).normal(size=(paths, n_rec)), None

    monkeypatch.setattr(covariance, "make_pdmp_model", lambda p, d: made.append(("pdmp", p, d)) or made[-1])
    monkeypatch.setattr(covariance, "make_di_model", lambda p, h: made.append(("di", p, h)) or made[-1])
    monkeypatch.setattr(covariance, "pdmp_stationary", pdmp)
    monkeypatch.setattr(covariance, "di_stationary", di)
    _no_files(covariance, monkeypatch, [])
    return covariance.fig4(str(tmp_path), quick, 0), made, calls


def test_fig4_caption_taus_and_the_readme_lags_burn_in_and_step(tmp_path, monkeypatch):
    """Fig. 4's caption: tau = 0.25, 0.5, 1 s, i.e. tau' = 0.74, 1.47, 2.95 (to its 2 digits), at Gamma = 5,
    Delta = 3.84, tau_L = 0.067, gamma_bar = 0.342, the PDMP at delta = 0.125; the curves are keyed by tau in
    seconds.  The README and RESULTS.md: burn-in 50 tau0 for both models (the DI's in its steps: 50 / h' of them),
    records every 0.05 tau0 (the PDMP's dt_rec, the DI's every h'), 177 lags up to 3 s at tau = 0.25 s, the DI step
    6.5e-4 s there; the JSON's settings are those the runs were given.  Kills: tau = 2 s (C01), BURN_TAU0 5
    (C02), DT_REC 0.1 (C03), the JSON's burn-in not the one run (C23), its dt_rec not the one run (C26), the
    curves keyed by tau' (C22)."""
    f, made, calls = _fig4(tmp_path, monkeypatch, True)
    assert sorted(f["curves"]) == ["0.25", "0.5", "1"] and list(f["tau"]) == [0.25, 0.5, 1.0]
    ps = [p for kind, p, _ in made if kind == "pdmp"]
    assert [(p.Gamma, p.Delta, p.tau_L, p.gamma_bar) for p in ps] == [(G5, DELTA, TAU_L, GBAR)] * 3
    assert [p.tau * DELTA**2 / G5 for p in ps] == pytest.approx([0.74, 1.47, 2.95], abs=0.006)
    assert [d for kind, _, d in made if kind == "pdmp"] == [0.125] * 3
    tau0 = G5 / DELTA**2
    for j, tau in enumerate((0.25, 0.5, 1.0)):
        (_, _, _, paths, n_rec, dt_rec, burn), (_, (_, pd, h), _, paths_d, n_rec_d, every, burn_steps) = \
            calls[2 * j: 2 * j + 2]
        assert (dt_rec, burn, f["dt_rec_tau0"], f["burn_in_tau0"]) == (0.05, 50.0, 0.05, 50.0)
        assert every * h / tau0 == pytest.approx(0.05, rel=1e-12)
        assert burn_steps * h / tau0 == pytest.approx(50.0, abs=h / tau0)
        assert (paths, paths_d, n_rec_d) == (f["paths"], f["paths"], n_rec)
        assert n_rec * dt_rec == pytest.approx(f["length_tau0"], rel=1e-12)
        c = f["curves"][f"{tau:g}"]
        assert c["di_h"] == h
        if tau == 0.25:
            assert len(c["pdmp"]["rho"]) == 177 + 1 and c["pdmp"]["rho"][-1] == pytest.approx(3.0, abs=0.01)
            assert h == pytest.approx(6.5e-4, abs=0.05e-4)


def test_fig4_every_run_has_its_own_key(tmp_path, monkeypatch):
    """The three taus and the two models are six independent runs: six different keys (the DI's PDMP-DI
    difference in combined SE assumes independent curves).  Kills: the DI run from the PDMP's key (C09),
    one key for every tau (C10)."""
    _, _, calls = _fig4(tmp_path, monkeypatch, True)
    assert [c[0] for c in calls] == ["pdmp", "di"] * 3 and len({c[2] for c in calls}) == 6


# ---- diffusivity.py (Figs. 3, 5, 8) -------------------------------------------------------------------------

class _Run:
    def __init__(self, **kw):
        self.__dict__.update(kw)


def _fake_points(monkeypatch, runs, est, bf=None):
    """The scenes' Points, each run recorded in ``runs`` and answered by ``est`` / ``bf`` (params, seed, kw)."""
    def recorder(kind, answer):
        def run(self, params, seed, **kw):
            runs.append((kind, params, seed, kw))
            return answer(params, seed, kw)
        return run

    FakePoints = type("FakePoints", (), dict(
        __init__=lambda self, out_dir, scene: setattr(self, "scene", scene),
        estimate=recorder("estimate", est), bruteforce=recorder("bruteforce", bf),
        summary=lambda self: dict(file=f"{self.scene}.points.jsonl", reused=0, computed=len(runs), runs_wall_s=0.0)))
    monkeypatch.setattr(diffusivity, "Points", FakePoints)
    # Fig. 3's DI duration runs: planned from the fake runs' cycle durations they would run for real (an 18-min
    # test), so they are fake too: the paper's duration 4 Gamma +- 0.625 (none of the fake runs' numbers)
    monkeypatch.setattr(diffusivity, "_di_durations", lambda p, seed, cycle_s, quick, pts=None: _Run(
        mean=4 * p.Gamma, ci=0.625, h=1e-4, n_lanes=64, n_excursions=128, n_truncated=0))


def test_fig3_caption_parameters_and_the_json_of_the_runs(tmp_path, monkeypatch):
    """Fig. 3's caption: tau = 0.125, 0.25, 0.5, 1 s, tau_L = 0.067 s, Delta = 3.84, gamma_bar = 0.342, Gamma
    over [1, 10] (full settings), the PDMP at delta = 0.125 (so the JSON says); the quick N is 1e3 (module
    docstring).  Each row's n_excursions is the N each run was given (here the planner cuts the DI's N by 4
    at Gamma < 5, so it differs from the nominal N), and the JSON keeps the runs' summary.  Kills: tau = 2 s
    (D01), Delta 3.48 (D03, also by the two tests below), the JSON's delta 0.25 (D05), quick N 100 (D07), Gamma
    up to 20 (D08), the rows' n_excursions the nominal N (D09), the runs' summary dropped (D40)."""
    runs = []

    def plan(p, method="di", n_excursions=0, **kw):
        if method == "di" and p.Gamma < 5 and n_excursions in (1000, 100_000):
            raise ValueError("max_work")

    def est(p, seed, kw):
        return _Run(D=1.0, D_ci=0.1, mean_duration=2.0, mean_duration_ci=0.2, wall_s=0.5,
                    n_excursions=kw["n_excursions"])

    monkeypatch.setattr(diffusivity, "plan_estimate", plan)
    monkeypatch.setattr(diffusivity, "N_FLOOR", 100)
    _fake_points(monkeypatch, runs, est)
    _no_files(diffusivity, monkeypatch, [])
    q = diffusivity.fig3(str(tmp_path), True, 0)
    assert q["n_excursions"] == 1000 and {kw["n_excursions"] for *_, kw in runs} == {1000, 250}
    runs.clear()
    f = diffusivity.fig3(str(tmp_path), False, 0)
    assert list(f["tau"]) == [0.125, 0.25, 0.5, 1.0] and f["delta"] == 0.125
    assert min(f["Gamma"]) == pytest.approx(1.0) and max(f["Gamma"]) == pytest.approx(10.0)
    assert {(p.Delta, p.tau_L, p.gamma_bar) for _, p, _, _ in runs} == {(DELTA, TAU_L, GBAR)}
    assert {p.tau for _, p, _, _ in runs} == {0.125, 0.25, 0.5, 1.0}
    for tau in ("0.125", "0.25", "0.5", "1"):
        for m in ("pdmp", "di"):
            want = [25_000 if m == "di" and g < 5 else 100_000 for g in f["Gamma"]]
            assert f[m][tau]["n_excursions"] == want
    assert f["runs"] == dict(file="fig3.points.jsonl", reused=0, computed=len(runs), runs_wall_s=0.0)


def test_fig8_full_settings_are_the_captions(tmp_path, monkeypatch):
    """Fig. 8's caption at full settings: tau = 10^-i s for i = 5 .. 2 and brute force at t = 10 s (t / tau0
    in the JSON is 10 s over each point's tau0 = Gamma / Delta^2).  Kills: the full taus without 1e-2 (D19),
    the full brute-force horizon 1 s (D37); the quick taus 1e-5, 1e-3 (D18: the quick run's last tau is the
    caption's 1e-2)."""
    runs = []
    _fake_points(monkeypatch, runs, lambda p, s, kw: _Run(D=p.Gamma**2, D_ci=0.01 * p.Gamma**2),
                 lambda p, s, kw: _Run(D_t=p.Gamma**2, D_t_ci=0.1))
    monkeypatch.setattr(theory, "exact_D", lambda p: 1.0)
    _no_files(diffusivity, monkeypatch, [])
    f = diffusivity.fig8(str(tmp_path), False, 0)
    assert list(f["tau"]) == pytest.approx([1e-5, 1e-4, 1e-3, 1e-2], rel=1e-12) and f["t_bf"] == 10.0
    assert {kw["t"] for kind, _, _, kw in runs if kind == "bruteforce"} == {10.0}
    G = f["Gamma"]
    for c in f["cases"].values():
        assert c["1e-05"]["t_over_tau0"] == pytest.approx([10.0 * DELTA**2 / g for g in G], rel=1e-12)
    runs.clear()
    q = diffusivity.fig8(str(tmp_path), True, 0)
    assert q["tau"][0] == pytest.approx(1e-5) and q["tau"][-1] == pytest.approx(1e-2)


def test_fig5_full_length_and_the_u_panel_in_seconds(tmp_path, monkeypatch):
    """Fig. 5 (caption: tau = 1e-5 s, Gamma = 0.16; 10 U(t) paths on [0, 2] s): the U paths run 2 s, i.e.
    2 / tau0 = 2 Delta^2 / Gamma tau0 of steps h; the full histogram run is 4096 paths of 2000 tau0 (the
    scene's docstring and JSON), so 2000 / 0.05 records 0.05 tau0 apart.  Kills: the full length 200 tau0
    while the JSON says 2000 (D35); also the U paths 2 tau0 long (D34, killed before)."""
    calls = []
    tau0 = 0.16 / DELTA**2

    def stationary(model, key, paths, n_records, every=1, burn_steps=0, record="VU"):
        calls.append((paths, n_records, every))
        if paths == 10:  # the U(t) panel
            return None, np.zeros((paths, n_records))
        return np.random.default_rng(1).normal(0, 0.05, (16, 4)), None

    monkeypatch.setattr(diffusivity, "make_di_model", lambda p, h: (p, h))
    monkeypatch.setattr(diffusivity, "di_stationary", stationary)
    monkeypatch.setattr(diffusivity, "white_chain_law", lambda p, h: _Run(M0=0.0, mean_v2=0.0, p_stuck=0.0))
    for name in ("exact_M0", "exact_mean_square_velocity"):
        monkeypatch.setattr(theory, name, lambda p: 0.0)
    monkeypatch.setattr(theory, "stationary_density", lambda v, p: np.zeros(len(v)))
    _no_files(diffusivity, monkeypatch, [])
    f = diffusivity.fig5(str(tmp_path), False, 0)
    (paths, n_rec, every), (ten, n_u, one) = calls
    h_nd = 0.01  # the default step: 0.01 min(tau0, tau_L), tau0 = 0.0109 s < tau_L
    assert (paths, f["n_paths"], f["length_tau0"]) == (4096, 4096, 2000.0)
    assert f["h"] == pytest.approx(h_nd * tau0, rel=1e-12)
    assert n_rec * every * h_nd == pytest.approx(2000.0, rel=1e-9) and every * h_nd == pytest.approx(0.05, rel=1e-9)
    assert (ten, one) == (10, 1) and n_u * h_nd * tau0 == pytest.approx(2.0, abs=h_nd * tau0)


# ---- common.py ----------------------------------------------------------------------------------------------

def test_save_writes_png_pdf_and_the_json_it_returns(tmp_path):
    """``save`` writes name.png (PNG magic), name.pdf (PDF magic) and name.json, the numbers plus their wall
    time since t0 (between 0 and the time measured around the call), the JSON the same as what it returns;
    the figure is closed.  Kills: no wall_s (M01), a negative wall_s (M02), the figure left open (M03), no
    PDF (M04), the JSON's wall_s not the returned one (M05), the returned wall_s not the JSON's (M06), the PNG
    written as name.pdf (M12)."""
    fig, ax = common.plt.subplots()
    ax.plot([0, 1], [1, 2])
    t0 = time.perf_counter()
    out = common.save(fig, str(tmp_path), "scene", dict(a=1.5, b=[1, 2], c="x"), t0, quick=True, seed=0)
    after = time.perf_counter() - t0
    assert fig.number not in common.plt.get_fignums()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scene.json", "scene.pdf", "scene.png"]
    assert (tmp_path / "scene.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert (tmp_path / "scene.pdf").read_bytes()[:5] == b"%PDF-"
    got = json.loads((tmp_path / "scene.json").read_text())
    assert got == out and {k: out[k] for k in "abc"} == dict(a=1.5, b=[1, 2], c="x")
    assert 0 < out["wall_s"] <= after


@pytest.mark.parametrize("t,h,n", [(0.3, 0.1, 3), (0.7, 0.1, 7), (0.5, 0.5, 1)])
def test_exact_steps_counts_by_hand(t, h, n):
    """t / h steps, by hand.  Kills (as test_helpers_mutants.py does): int for round (M09: 0.3 / 0.1 =
    2.9999999999999996 -> 2, 0.7 / 0.1 -> 6)."""
    assert common.exact_steps(t, h) == n


@pytest.mark.parametrize("t,h", [(1.0 + 1e-8, 1e-3), (0.0, 0.1), (0.4, 0.5), (0.1, 0.0)])
def test_exact_steps_refuses_a_near_miss_and_no_time(t, h):
    """t = 1 + 1e-8 is 1e-8 off a whole number of steps 1e-3 (the scenes' rounding fault); t = 0 is no time,
    0.4 / 0.5 not one step, h = 0 no step (a ValueError, not a ZeroDivisionError).  Kills: tolerance 1e-6 t
    (M07, killed before), h >= 0 accepted (M11)."""
    with pytest.raises(ValueError):
        common.exact_steps(t, h)


def test_affordable_n_divides_by_4_down_to_the_floor_then_says_why(monkeypatch):
    """``_affordable_n`` (docstring): N divided by 4, not below N_FLOOR = 1000, until the planner accepts; a point
    refused at the floor raises the planner's ValueError.  By hand from 100000: 100000, 25000, 6250, 1562, 1000
    (the floor), and a planner that accepts from 1562 on stops there.  Kills D12 (``n < N_FLOOR``: the floor asked
    for ever, which only a 120-s timeout stopped before; the fake stops it after 20 asks)."""
    asked = []

    def planner(limit):
        def plan(p, method, n_excursions, **kw):
            asked.append(n_excursions)
            if len(asked) > 20:
                raise RuntimeError("asked for ever")
            if n_excursions > limit:
                raise ValueError(f"max_work must be >= ... (n = {n_excursions})")
        return plan

    monkeypatch.setattr(diffusivity, "plan_estimate", planner(0))
    with pytest.raises(ValueError, match=r"^max_work must be >= \.\.\. \(n = 1000\)"):
        diffusivity._affordable_n(None, "di", 100_000, {})
    assert asked == [100_000, 25_000, 6250, 1562, 1000]
    asked.clear()
    monkeypatch.setattr(diffusivity, "plan_estimate", planner(2000))
    assert diffusivity._affordable_n(None, "di", 100_000, {}) == 1562 and asked == [100_000, 25_000, 6250, 1562]


def test_table1_is_drawn_in_a_readable_font(monkeypatch, tmp_path):
    """Table 1's PNG had every cell shrunk to 2 pt: matplotlib's automatic font size fitted the long row label
    into an equal-width first column (found by a user audit).  The table now has a fixed 9 pt font and a first
    column four times as wide as the others.  The simulator is a fake (V = 1 - t' on 8 paths)."""
    from dryfric_jax.figures import touchette

    drawn = {}
    monkeypatch.setattr(touchette, "di_transient",
                        lambda model, key, n, steps: np.tile(1.0 - np.asarray(touchette.T_TABLE), (8, 1)))
    monkeypatch.setattr(touchette, "save", lambda fig, out, name, nums, t0, **meta: drawn.update(fig=fig) or {})
    touchette.table1(str(tmp_path), True, 0)
    (ax,) = drawn["fig"].axes
    cells = ax.tables[0].get_celld()
    assert {c.get_text().get_fontsize() for c in cells.values()} == {9}
    assert cells[0, 0].get_width() == pytest.approx(4 * cells[0, 1].get_width())
    common.plt.close(drawn["fig"])
