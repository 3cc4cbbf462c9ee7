r"""Second mutation audit of :mod:`dryfric_jax.figures.diffusivity` (Figs. 3, 5, 8) and :mod:`dryfric_jax.noise` (the
PDMP's jump-noise grid): what the first audits (test_figure_scenes_mutants.py: 40 mutants of diffusivity.py, mostly
the JSON's numbers and settings; test_helpers_mutants.py: local_exponent; test_rng_mutants.py: 25 of noise.py;
test_internals_audit.py: the stationary law in fractions) did not target: what the panels plot (each method's own
curve and CI, the exponent's abscissae, the reference lines, the log-log axes), the seeds' documented offset, the
README's run counts, ``_affordable_n``'s catch, local_exponent's refusals, Fig. 5's bins and p_stuck, and in
noise.py the boundaries, the equivalent rewrites and the messages.

Counts (one-line mutants tried / killed by the older fast tests / equivalent / killed only here / alive):
diffusivity.py 50 / 17 / 3 / 30 / 0 (A01-A50), noise.py 38 / 29 / 7 / 2 / 0 (B01-B38); in all 88 / 46 / 10 / 32 / 0.
Older tests run against each mutant: for diffusivity.py test_figure_scenes_mutants.py, test_figure_numbers.py,
test_helpers_mutants.py and test_figures.py::test_local_exponent_of_exact_power_laws (not the figs fixture); for
noise.py the five noise tests of test_rng_mutants.py, test_plan_audit.py, test_internals_audit.py,
test_pdmp_mutants.py, test_bad_input.py and test_noise.py (test_pdmp.py, 93 s, only against B32 and B38).
Equivalent: A14 (Fig. 3's seed 1000 j -> 10 j: the 80 seeds stay distinct, no document fixes the formula), A32
(Fig. 5's ``round(0.05 / h')`` -> ``int``: its one parameter point has h' = 0.01 exactly, 5 either way), A44
(``abs`` of local_exponent's half-width, a square root over a positive step); B09 (``math.isfinite(v)`` dropped
from check_delta: nan and inf fail ``0 < v / scale < dm`` anyway), B12 (``not n <= 2**30 - 2`` -> ``n > ...``: n =
L_req / delta is never nan), B15 (grid_size's assert removed: it guards what check_delta already ensures; on the
old code it was the defect below), B20 (up_probability without ``dtype=float``: the same floats for integer k),
B23 (``log1p(-a)`` -> ``log(1 - a)``: a in [0, 1], within the 1e-13 of the fractions test), B26 (the law
normalised by its value at k = 0, which is its maximum: alpha_k / (1 - alpha_(k+1)) > 1 exactly for k < 0),
B30 (``0 < v / scale < dm`` -> ``0 < v < dm * scale``: differs within an ulp of the bound only).

Oracles: the captions (Fig. 3: both panels log-log, PDMP dots and DI lines, Gamma in [1, 10]; Fig. 5: the
exact P(v) dv as a line, the histogram at bin width 4.8e-4 m/s; Fig. 8: D against Gamma in log-log scale), the
paper's section 7.2 (the experiment's exponents 1.61 and 1.74), MODEL_NOTES section 2 (D = 10 Gamma^3 / Delta^4
for b = 0: exponent 3), the README and RESULTS.md (Fig. 3: 80 runs, 40 points, the PDMP's seeds 5000 past the
DI's; Fig. 8: 11 Gamma points, 2000 brute-force paths of 10 s, 88 points), the docstrings (local_exponent's
"of one length >= 2", D_ci >= 0; _affordable_n retries the planner's ValueError; noise: 8 SD and tau delta L_X < 2),
fake runs with known numbers (each curve checked against them), hand counts of bins and grid points, ``fractions``.

One defect, fixed in noise.grid_size (the last test): a delta that check_delta accepts, an ulp or two
below delta_max with L_req / delta just above an integer, met ``assert tau * delta * N * delta < 2.0`` as a bare
AssertionError (also through pdmp.make_pdmp_model): the exact product is 2 - 2e-16, float64 rounds it to 2.0.
The assert now allows a relative 1e-12.  The whole file runs in about 2 s.
"""
import math
from fractions import Fraction

import numpy as np
import pytest

from dryfric_jax import theory
from dryfric_jax.figures import diffusivity
from dryfric_jax.noise import check_delta, grid_size, stationary_law, up_probability
from dryfric_jax.params import Params
from test_figure_scenes_mutants import _fake_points, _Run

# the paper's Fig. 3 / 8 constants (captions), written out here rather than read from the package
DELTA, TAU_L, GBAR = 3.84, 0.067, 0.342


# ---- diffusivity.py: what the panels show ---------------------------------------------------------------------

def _bars(container):
    """(x, y, half-width) of an errorbar call: its data line and its vertical bars' segments."""
    line, _, cols = container.lines
    x, y = np.asarray(line.get_xdata(), float), np.asarray(line.get_ydata(), float)
    seg = np.asarray(cols[0].get_segments(), float)  # one [[x, y - e], [x, y + e]] per point
    assert np.array_equal(seg[:, 0, 0], x) and np.array_equal(seg[:, 1, 0], x)
    return x, y, (seg[:, 1, 1] - seg[:, 0, 1]) / 2


def _capture(monkeypatch, store):
    """The scene's ``save``: keeps each axes' errorbar calls (x, y, half-width), its plain lines, scales and
    texts in ``store``, writes no files and returns the numbers."""
    def save(fig, out_dir, name, numbers, t0, **meta):
        bars = {id(c.lines[0]) for ax in fig.axes for c in ax.containers}
        store.append([dict(bars=[_bars(c) for c in ax.containers],
                           lines=[(np.asarray(ln.get_xdata(), float), np.asarray(ln.get_ydata(), float))
                                  for ln in ax.lines if id(ln) not in bars],
                           scales=(ax.get_xscale(), ax.get_yscale()), texts=[t.get_text() for t in ax.texts])
                      for ax in fig.axes])
        diffusivity.plt.close(fig)
        return dict(numbers)
    monkeypatch.setattr(diffusivity, "save", save)


def _fig3(tmp_path, monkeypatch, quick):
    """Fig. 3 with fake runs: the DI's D = Gamma +- 0.25, duration 3 Gamma +- 0.5, wall 7 Gamma; the PDMP's
    D = 2 Gamma +- 0.125, duration 5 Gamma +- 0.75, wall 11 Gamma (every number of a run its own)."""
    runs, figs = [], []

    def est(p, seed, kw):
        g, pdmp = p.Gamma, kw["method"] == "pdmp"
        return _Run(D=(2 if pdmp else 1) * g, D_ci=0.125 if pdmp else 0.25, mean_duration=(5 if pdmp else 3) * g,
                    mean_duration_ci=0.75 if pdmp else 0.5, wall_s=(11 if pdmp else 7) * g,
                    n_excursions=kw["n_excursions"])

    monkeypatch.setattr(diffusivity, "plan_estimate", lambda p, method="di", n_excursions=0, **kw: None)
    _fake_points(monkeypatch, runs, est)
    _capture(monkeypatch, figs)
    return diffusivity.fig3(str(tmp_path), quick, 0), runs, figs


def test_fig3_each_panel_plots_each_methods_own_numbers_on_log_log_axes(tmp_path, monkeypatch):
    """Fig. 3's caption: left D against Gamma, right the mean excursion duration, PDMP dots and DI lines, four
    curves (tau = 0.125 .. 1 s), both panels in log-log scale.  With the fake runs of ``_fig3`` each curve
    must be exactly its method's numbers with its own CI (the DI's durations: the paper's, its cycles dashed); the
    JSON's wall_s are the runs' own.  Kills: the PDMP
    dots at the DI's D (A01), with the DI's CI (A02), the DI line of D at the durations (A03), the PDMP
    duration dots at D (A04), the DI duration line with D's CI (A05), the DI duration line at the PDMP's
    durations (A06), the rows' wall_s the runs' durations (A07), only the left panel in log-log (A43)."""
    f, runs, figs = _fig3(tmp_path, monkeypatch, True)
    (a1, a2), = figs
    G = np.array(f["Gamma"], float)
    assert len(a1["bars"]) == len(a2["bars"]) == 2 * 4 and not a1["lines"]
    # right: PDMP dots, the DI's paper duration (fake: 4 Gamma +- 0.625) as lines, its cycle (3 Gamma) dashed
    assert len(a2["lines"]) == 4 and all(np.array_equal(x, G) and np.array_equal(y, 3 * G) for x, y in a2["lines"])
    for panel, want in ((a1, ((2, 0.125), (1, 0.25))), (a2, ((5, 0.75), (4, 0.625)))):
        assert panel["scales"] == ("log", "log")
        for j in range(4):
            for (x, y, e), (c, ci) in zip(panel["bars"][2 * j: 2 * j + 2], want):  # PDMP dots, then the DI line
                assert np.array_equal(x, G) and np.array_equal(y, c * G)
                assert e == pytest.approx([ci] * len(G), abs=1e-12)
    for tau in ("0.125", "0.25", "0.5", "1"):
        assert f["pdmp"][tau]["wall_s"] == pytest.approx(list(11 * G), rel=1e-15)
        assert f["di"][tau]["wall_s"] == pytest.approx(list(7 * G), rel=1e-15)


def test_fig3_pdmp_seeds_are_the_dis_plus_5000_and_the_full_figure_is_80_runs(tmp_path, monkeypatch):
    """RESULTS.md (Fig. 3): "from 0.2.1 the PDMP's seeds are 5000 past the DI's" (the kept runs of a points file are
    found by their seeds), and "Fig. 3 is 80 runs (40 points, PDMP and DI)": 10 Gamma over the caption's
    [1, 10] for each of the 4 taus (the quick grid inside that range too).  Kills: the offset on the DI's seeds
    instead (A09), 9 Gamma points in the full figure (A11), a quick Gamma of 20 (A48)."""
    for quick, n_gamma in ((True, 3), (False, 10)):
        f, runs, _ = _fig3(tmp_path, monkeypatch, quick)
        seed = {(p.tau, p.Gamma, kw["method"]): s for _, p, s, kw in runs}
        assert len(runs) == len(seed) == 2 * 4 * n_gamma and len(f["Gamma"]) == n_gamma
        assert 1.0 - 1e-12 <= min(f["Gamma"]) and max(f["Gamma"]) <= 10.0 + 1e-12  # the caption's range
        for (tau, g, m), s in seed.items():
            if m == "pdmp":
                assert s == seed[(tau, g, "di")] + 5000
    assert f["Gamma"][0] == pytest.approx(1.0, rel=1e-12) and f["Gamma"][-1] == pytest.approx(10.0, rel=1e-12)


def test_affordable_n_retries_only_the_planners_refusal(monkeypatch):
    """``_affordable_n`` (docstring) divides N by 4 while the planner refuses the run, and "a point refused even
    at the floor raises the planner's ValueError": any other error (here a TypeError of the planner) is no
    refusal and must reach the caller at the first ask, not after four more.  Kills A12 (``except
    Exception``: the TypeError retried down to the floor)."""
    asked = []

    def plan(p, method, n_excursions, **kw):
        asked.append(n_excursions)
        raise TypeError("not a refusal")

    monkeypatch.setattr(diffusivity, "plan_estimate", plan)
    with pytest.raises(TypeError, match="^not a refusal$"):
        diffusivity._affordable_n(None, "di", 100_000, {})
    assert asked == [100_000]


@pytest.mark.parametrize("G,D,c,match", [
    ([1.0, 2.0], [1.0, 8.0], [[0.1], [0.2]], r"^G, D and D_ci must be 1-D sequences of one length >= 2 "
                                             r"\(got shapes \(2,\), \(2,\), \(2, 1\)\)"),
    ([1.0], [1.0], [0.1], r"^G, D and D_ci must be 1-D sequences of one length >= 2"),
    ([1.0, 2.0], [1.0, 8.0], [0.1, -0.2], r"^D_ci must be finite and >= 0 \(got \[0\.1, -0\.2\]\)"),
])
def test_local_exponent_refuses_by_name_with_the_documented_range(G, D, c, match):
    """``local_exponent``'s docstring: G, D and D_ci "finite, of one length >= 2", D_ci >= 0.  A 2-D D_ci of the
    right length, a single point (no pair: no exponent) and a negative CI are refused with a ValueError that
    states the range documented.  Kills: the D_ci shape not checked (A15: a (1, 1) half-width came back), one
    point accepted (A16: empty arrays), D_ci's message saying "> 0" where 0 is allowed (A18)."""
    with pytest.raises(ValueError, match=match):
        diffusivity.local_exponent(G, D, c)


def _fig8(tmp_path, monkeypatch, quick):
    """Fig. 8 with fake runs: long excursions D = c Gamma^3 (c = 1e5 tau / s, so each tau its own curve) with
    relative CIs 1% at Gamma = 2^(even), 3% at 2^(odd); brute force D_t = D / 2 +- D / 5; the exact white-noise
    reference 7 Gamma."""
    runs, figs = [], []
    rel = lambda g: 0.01 if round(math.log2(g)) % 2 == 0 else 0.03  # noqa: E731
    D = lambda p: 1e5 * p.tau * p.Gamma**3  # noqa: E731
    _fake_points(monkeypatch, runs, lambda p, s, kw: _Run(D=D(p), D_ci=rel(p.Gamma) * D(p)),
                 lambda p, s, kw: _Run(D_t=D(p) / 2, D_t_ci=D(p) / 5))
    monkeypatch.setattr(theory, "exact_D", lambda p: 7 * p.Gamma)
    _capture(monkeypatch, figs)
    return diffusivity.fig8(str(tmp_path), quick, 0), runs, figs, rel


def test_fig8_panels_plot_the_runs_the_exact_d_the_exponents_and_the_reference_lines(tmp_path, monkeypatch):
    """Fig. 8 (caption and section 7.2): top, D against Gamma in log-log scale, long-excursion lines with their CI,
    brute-force dots with theirs, the exact white-noise D over every Gamma; bottom, the local exponent at the
    geometric midpoints sqrt(G_i G_(i+1)) (Gamma doubles in the quick grid 0.5 .. 4, so by hand 3 exactly, with
    half-width hypot(r_i, r_(i+1)) / ln 2), and horizontal references at 3 (D = 10 Gamma^3 / Delta^4 for b = 0,
    MODEL_NOTES section 2) and at the experiment's 1.61 and 1.74 (section 7.2).  Kills: the exponent plotted at
    Gamma[1:] (A19), its bars the exponent itself (A20), the LE bars D itself (A21), the BF dots at the LE's D
    (A22), the references at 2 (A23), 1.71 (A24), 1.47 (A25), the exact D without its first point (A27), the D
    panel's y axis linear (A41), the exponent panel's x axis linear (A42: shared, so the D panel's x too)."""
    f, runs, figs, rel = _fig8(tmp_path, monkeypatch, True)
    axes, = figs
    G = np.array([0.5, 1.0, 2.0, 4.0])
    assert f["Gamma"] == pytest.approx(list(G), rel=1e-15) and len(axes) == 4
    for k in range(2):  # the two cases, left and right; fig.axes is row by row
        top, bottom = axes[k], axes[2 + k]
        assert top["scales"] == ("log", "log") and bottom["scales"][0] == "log"
        assert len(top["lines"]) == 2 - k and np.array_equal(top["lines"][0][0], G)
        assert top["lines"][0][1] == pytest.approx(7 * G, rel=1e-15)
        if k == 0:  # b = 0: the exact white-noise D^t at t = 10 s, D (1 - 27/5 tau0/t), where t >= 20 tau0
            keep = 10.0 >= 20 * G / 3.84**2  # all of the quick grid's Gamma <= 4 (t/tau0 = 36.9 at 4)
            assert keep.all() and np.array_equal(top["lines"][1][0], G[keep])
            assert top["lines"][1][1] == pytest.approx(10 * G**3 / 3.84**4 * (1 - 5.4 * G / 3.84**2 / 10.0), rel=1e-14)
            assert f["cases"]["b = 0"]["exact_bf"] == pytest.approx(list(top["lines"][1][1]), rel=1e-15)
        # 3 is the white-noise exponent of b = 0 only: the viscous panel (k = 1) has the experiment's two
        three = [pytest.approx([3.0, 3.0])] if k == 0 else []
        assert [y for _, y in bottom["lines"]] == three + [pytest.approx([1.61, 1.61]), pytest.approx([1.74, 1.74])]
        assert bottom["texts"] == ["3 (white noise, b = 0)"][:len(three)] + ["1.61 (experiment)", "1.74 (experiment)"]
        r = np.array([rel(g) for g in G])
        for j, tau in enumerate((1e-5, 1e-2)):
            D = 1e5 * tau * G**3
            (x, y, e), (xb, yb, eb) = top["bars"][2 * j: 2 * j + 2]
            assert np.array_equal(x, G) and np.array_equal(xb, G)
            assert y == pytest.approx(D, rel=1e-15) and e == pytest.approx(r * D, rel=1e-9)
            assert yb == pytest.approx(D / 2, rel=1e-15) and eb == pytest.approx(D / 5, rel=1e-9)
            gm, s, sc = bottom["bars"][j]
            assert gm == pytest.approx(np.sqrt(G[1:] * G[:-1]), rel=1e-15) and s == pytest.approx([3.0] * 3, rel=1e-12)
            assert sc == pytest.approx(np.hypot(r[1:], r[:-1]) / math.log(2), rel=1e-9)


def test_fig8_full_settings_are_the_readmes_88_points(tmp_path, monkeypatch):
    """README: "Fig. 8: 11 Gamma points", and RESULTS.md: its full run "N = 10^5, 2000 brute-force paths of 10 s,
    88 points" (11 Gamma x 4 tau x 2 cases), Gamma from 0.25 to 8 (the scene's grid, a geometric one, so the ratio of
    neighbours is 32^(1/10)).  Kills: 10 Gamma points (A26), 200 brute-force paths (A28)."""
    f, runs, _, _ = _fig8(tmp_path, monkeypatch, False)
    G = f["Gamma"]
    assert len(G) == 11 and G[0] == pytest.approx(0.25, rel=1e-12) and G[-1] == pytest.approx(8.0, rel=1e-12)
    assert np.diff(np.log(G)) == pytest.approx([math.log(32) / 10] * 10, rel=1e-9)
    est = [kw for kind, _, _, kw in runs if kind == "estimate"]
    bf = [kw for kind, _, _, kw in runs if kind == "bruteforce"]
    assert len(est) == len(bf) == 88 and f["n_paths_bf"] == 2000 and f["n_excursions"] == 100_000
    assert all(kw == dict(n_excursions=100_000) for kw in est)
    assert all(kw == dict(t=10.0, n_paths=2000) for kw in bf)


def test_fig5_histogram_panel_plots_the_bin_probabilities_and_the_exact_density_at_the_bin_centres(
        tmp_path, monkeypatch):
    """Fig. 5 (caption): the exact P(v) dv as a solid line and the histogram (bin width 4.8e-4 m/s) as
    triangles, both at the bins' centres.  Half the paths sit at v = -x, half at +x, 2x = 10.5 bins: the bins
    run from -x (the 1e-4 quantile) in steps of 4.8e-4 to -x + 11 bins, so 11 bins, centres -x + (i + 1/2) bw,
    probabilities 1/2 in the first and the last, 0 between (by hand); a fake density 1 + 100 v gives the exact
    line (1 + 100 mid) bw.  Kills: the exact line drawn at the histogram's values (A30), the histogram drawn at
    the bins' left edges (A31)."""
    p = Params(0.16, DELTA, 1e-5, TAU_L, GBAR)
    bw = 4.8e-4
    x = 10.5 * bw / 2
    figs = []

    def stationary(model, key, paths, n_records, every=1, burn_steps=0, record="VU"):
        if paths == 10:  # the U(t) panel
            return None, np.zeros((paths, n_records))
        return np.where(np.arange(16)[:, None] % 2, x, -x) / p.v0 * np.ones((16, 4)), None

    monkeypatch.setattr(diffusivity, "make_di_model", lambda params, h: None)
    monkeypatch.setattr(diffusivity, "di_stationary", stationary)
    monkeypatch.setattr(diffusivity, "white_chain_law", lambda params, h: _Run(M0=0.0, mean_v2=0.0, p_stuck=0.125))
    for name in ("exact_M0", "exact_mean_square_velocity"):
        monkeypatch.setattr(theory, name, lambda params: 0.0)
    monkeypatch.setattr(theory, "stationary_density", lambda v, params: 1 + 100 * np.asarray(v))
    _capture(monkeypatch, figs)
    diffusivity.fig5(str(tmp_path), True, 0)
    (exact_x, exact_y), (hist_x, hist_y), (atom_x, atom_y) = figs[0][0]["lines"]
    mid = -x + bw * (np.arange(11) + 0.5)
    assert exact_x == pytest.approx(mid, rel=0, abs=1e-15) and hist_x == pytest.approx(mid, rel=0, abs=1e-15)
    assert exact_y == pytest.approx((1 + 100 * mid) * bw, rel=1e-12)
    assert hist_y == pytest.approx([0.5] + [0.0] * 9 + [0.5], rel=0, abs=1e-15)
    # the chain's atom at V = 0 on top of the density, in the bin holding v = 0 ([-x + 5 bw, -x + 6 bw))
    assert atom_x == pytest.approx([mid[5]], rel=0, abs=1e-15)
    assert atom_y == pytest.approx([(1 + 100 * mid[5]) * bw + 0.125], rel=1e-12)


def test_fig5_p_stuck_counts_exact_zeros_only(tmp_path, monkeypatch):
    """Fig. 5's ``p_stuck`` is compared with the chain law's probability of V = 0 (the DI's proximal step puts a
    stuck particle at 0 exactly, MODEL_NOTES erratum 1): a velocity 1e-9 v0 is sliding, not stuck.  Paths at 0,
    1e-9, -1e-9 and 0.5 (nondimensional) give p_stuck = 1/4 by hand.  Kills A35 (|V| < 1e-3 counted as stuck:
    3/4)."""
    def stationary(model, key, paths, n_records, every=1, burn_steps=0, record="VU"):
        if paths == 10:
            return None, np.zeros((paths, n_records))
        return np.array([0.0, 1e-9, -1e-9, 0.5])[np.arange(16) % 4, None] * np.ones((16, 3)), None

    monkeypatch.setattr(diffusivity, "make_di_model", lambda params, h: None)
    monkeypatch.setattr(diffusivity, "di_stationary", stationary)
    monkeypatch.setattr(diffusivity, "white_chain_law", lambda params, h: _Run(M0=0.0, mean_v2=0.0, p_stuck=0.0))
    for name in ("exact_M0", "exact_mean_square_velocity"):
        monkeypatch.setattr(theory, name, lambda params: 0.0)
    monkeypatch.setattr(theory, "stationary_density", lambda v, params: np.ones(len(v)))
    _capture(monkeypatch, [])
    assert diffusivity.fig5(str(tmp_path), True, 0)["p_stuck"] == 0.25


# ---- noise.py ---------------------------------------------------------------------------------------------------

def test_a_refused_grid_counts_its_points_from_the_grid_size():
    """The refusal of a too fine grid prints its point count 2N + 1 = 2n + 3 (N = n + 1 for an integer n =
    L_req / delta) to three digits.  delta = 2^-30, tau = 100 (the thresholds set the reach) and L_req = 1 +
    |gamma_bar| = 1082499999 * 2^-30 (exact: 31 significant bits) give n = 1082499999 > 2^30 - 2, hence
    2165000001 points: "2.17e+09" by hand (2165000000 would print 2.16e+09, half to even).  Kills B32 (2n + 2
    points), which every older count let through."""
    n = 1082499999
    assert n > 2**30 - 2 and f"{2 * (n + 1) + 1:.3g}" == "2.17e+09" and f"{2 * n + 2:.3g}" == "2.16e+09"
    gb = n * 2.0**-30 - 1.0
    assert 1.0 + gb == n * 2.0**-30
    with pytest.raises(ValueError, match=r"^delta' = .* too small: the noise grid would have 2\.17e\+09 points"):
        grid_size(2.0**-30, 100.0, gb)


def test_the_refusal_of_delta_states_the_documented_coverage():
    """The module docstring: the grid covers 8 standard deviations of N(0, 1/tau) and both stick thresholds,
    with tau delta L_X < 2; the refusal of a delta says so.  Kills B38 (the message saying 6 SD)."""
    with pytest.raises(ValueError, match=r"the noise grid must cover 8 standard deviations of N\(0, 1/tau\) "
                                         r"and the stick thresholds while keeping tau\*delta\*L_X < 2"):
        check_delta(0.3, 1.0)


@pytest.mark.parametrize("tau,gb,d,n", [(804.0207389678485, 0.6443598976241491, 0.0015099723577815876, 1089),
                                        (882.164127519208, 0.8679273314557276, 0.001212152713468999, 1541),
                                        (11.40313839338702, 13.681800379076867, 0.011926726546772433, 1231)])
def test_a_delta_just_below_delta_max_gets_its_grid_not_an_assertion_error(tau, gb, d, n):
    """DEFECT (fixed in noise.grid_size): a delta that check_delta accepts (1-2 ulp below delta_max), with L_req /
    delta just above an integer n, met grid_size's ``assert tau * delta * N * delta < 2.0``: a bare
    AssertionError.  In exact rationals (``fractions``) the grid is fine: L_req = 1 + |gamma_bar| (8 / sqrt(tau)
    < 2.5 here), N = ceil(L_req / delta) + 1 = n + 2, and tau delta^2 N < 2 (the product is 1 - 1e-16 below 2,
    the float one rounds to 2.0).  So grid_size must return n + 2, and the chain's up-probabilities lie in
    [0, 1] with a finite stationary law.  The points came from a search over tau and delta near delta_max (122
    of 130086 accepted near-bound deltas failed with 0 <= gamma_bar' < 1); make_pdmp_model(Params(1, 1, 804.02..,
    gamma_bar=0.644..), 0.00151..) reached the same assert."""
    check_delta(d, tau, gb)  # accepted
    L, D, T = Fraction(1) + abs(Fraction(gb)), Fraction(d), Fraction(tau)
    assert 8 / math.sqrt(tau) < 2.5 and math.ceil(L / D) == n + 1 and T * D * D * (n + 2) < 2
    N = grid_size(d, tau, gb)
    assert N == n + 2
    a = up_probability(np.arange(-N, N + 1), N, d, tau)
    assert np.all((a >= 0) & (a <= 1))
    x, pi = stationary_law(N, d, tau)
    assert np.all(np.isfinite(pi)) and abs(pi.sum() - 1) < 1e-12
