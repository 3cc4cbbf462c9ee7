r"""Mutation audit of the figure helpers: :mod:`dryfric_jax.figures.points` (resumable scene runs, reused by
identity), :mod:`dryfric_jax.figures.speed_error` (Fig. 9, ``fit_slope`` excepted: test_helpers_mutants.py),
:mod:`dryfric_jax.figures.touchette` (Table 1, Figs. 6-7) and :mod:`dryfric_jax.requirements`.

Every simulator and estimator is a fake (no JAX run): the expected values come from hand arithmetic, the
printed rows of MODEL_NOTES section 2, the README's scene table (Table 1: 1e6 paths, tau' = 5e-6,
h' = 2e-4; Fig. 6: t' = 0.25, 1, 2.5 for tau' = 0.5e-i; Fig. 7: burn-in 40 tau0) and section 5.3's
slopes (-1/2 and -1/3).  Each test's docstring names the mutants (edits of those modules) it kills.

Counts (mutants tried / killed by the older tests run without the figs fixture / equivalent / killed only
here): points.py 40 / 16 / 4 / 19, speed_error.py 32 / 26 / 3 / 3, touchette.py 22 / 13 / 0 / 9,
requirements.py 10 / 5 / 2 / 2.  Equivalent: the stamp of a missing file 0 for None, the stamp not taken
again after a re-read, a run always appended (never replacing a record: under its claim none has its ident),
a computed run not put in the in-memory list (the next call re-reads the file it just wrote); Fig. 9's
``int(x) + 1`` for ``round(x)`` (same step here), ``<=`` for ``<`` in the envelope (no ties), ``int`` for
``round`` of t / horizons[0] (exactly 1, 4, 16); ``release`` without ``\s*`` or with ``re.search`` (no
installed version has a leading space or text).  Two survivors were the better behaviour: ``_canon``
returning floats as they are (a numpy float64 setting, which ``_canon`` wrote as ``'np.float64(0.1)'`` under
numpy 2, was then the same run as 0.1; ``_canon`` now writes the value, and
test_points_identity_names_values_not_numpy_types pins it), and the floors' pattern without its closing quote
(``"numpy>=1.26,<3"`` is then a floor; now it is silently none: no test, pyproject has no such floor).  Points'
Ctrl-C check and Table 1's times and printed row were tested before only on test_figures.py's figs fixture
(every scene run, minutes)."""
import dataclasses
import json
import math
import warnings

import jax
import numpy as np
import pytest

from dryfric_jax import requirements as rq
from dryfric_jax import theory
from dryfric_jax.api import BruteForceResult, DryfricWarning, EstimateResult
from dryfric_jax.excursions import STAT_NAMES
from dryfric_jax.figures import points, speed_error, touchette
from dryfric_jax.params import FIG3, Params


# ---- points.py ----------------------------------------------------------------------------------------------

def _result(cls, **values):
    """A result of ``cls`` with every required field 0 except ``values``."""
    req = {f.name: 0.0 for f in dataclasses.fields(cls)
           if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING}
    return cls(**dict(req, **values))


def _fake_kinds(monkeypatch, calls):
    """Both kinds of run replaced by fakes that record (kind, seed, kw): D (D_t) = seed, wall_s = 1.5 + seed."""
    def est(params, seed, **kw):
        calls.append(("estimate", int(seed), kw))
        return _result(EstimateResult, D=float(seed), wall_s=1.5 + seed, params=params.as_dict())

    def bf(params, seed, **kw):
        calls.append(("bruteforce", int(seed), kw))
        return _result(BruteForceResult, D_t=float(seed), wall_s=1.5 + seed, params=params.as_dict())

    for kind, fn in (("estimate", est), ("bruteforce", bf)):  # the result classes stay the module's
        monkeypatch.setitem(points._KINDS, kind, (fn, points._KINDS[kind][1]))


def test_points_identity_is_kind_params_seed_and_settings_not_their_spelling(tmp_path, monkeypatch):
    """A run is reused exactly when its kind, parameters, seed and settings are those of a kept run:
    settings given in another order, or a numpy integer seed, are the same run (reused); a brute-force
    run with an estimate's seed and settings, other parameters or other settings are other runs
    (computed, by their own function).  Kills: ident without sort_keys (P07: kw order mattered), without
    int(seed) (P08: a numpy seed was a TypeError), without the kind (P02: the brute force reused the
    estimate), without the parameters (P06), without the settings (P04); bruteforce() running the
    estimate (P37)."""
    calls = []
    _fake_kinds(monkeypatch, calls)
    p, q = Params(**FIG3), Params(**dict(FIG3, Gamma=2 * FIG3["Gamma"]))
    first = points.Points(str(tmp_path), "s")
    a = first.estimate(p, 1, h=0.01, n_excursions=64)
    assert calls == [("estimate", 1, dict(h=0.01, n_excursions=64))]
    again = points.Points(str(tmp_path), "s")
    assert again.estimate(p, np.int64(1), n_excursions=64, h=0.01) == a
    assert (again.reused, again.computed) == (1, 0) and len(calls) == 1
    b = again.bruteforce(p, 1, h=0.01, n_excursions=64)
    assert isinstance(b, BruteForceResult) and b.D_t == 1.0
    again.estimate(q, 1, h=0.01, n_excursions=64)
    again.estimate(p, 1, h=0.02, n_excursions=64)
    assert calls[1:] == [("bruteforce", 1, dict(h=0.01, n_excursions=64)),
                         ("estimate", 1, dict(h=0.01, n_excursions=64)), ("estimate", 1, dict(h=0.02, n_excursions=64))]
    assert (again.reused, again.computed) == (1, 3)


def test_a_kept_bruteforce_run_is_read_back_as_one(tmp_path, monkeypatch):
    """A brute-force run written by one Points is a valid record for the next (its result has
    BruteForceResult's fields) and comes back as the same BruteForceResult, from its record of kind
    "bruteforce".  Kills: every record written as kind "estimate" (P35: the next Points refused the file
    as "not a finished-run record"), the brute force's result class EstimateResult (P36)."""
    calls = []
    _fake_kinds(monkeypatch, calls)
    p = Params(**FIG3)
    b = points.Points(str(tmp_path), "s").bruteforce(p, 7, t=10.0, n_paths=100)
    again = points.Points(str(tmp_path), "s")
    assert again.bruteforce(p, 7, t=10.0, n_paths=100) == b and type(b) is BruteForceResult
    assert (again.reused, again.computed, len(calls)) == (1, 0, 1)
    rec, = [json.loads(x) for x in (tmp_path / "s.points.jsonl").read_text().splitlines()]
    assert rec["kind"] == "bruteforce" and rec["result"]["D_t"] == 7.0


def test_points_summary_counts_and_wall_time(tmp_path, monkeypatch):
    """Runs of wall 1.5 + seed s: seeds 1 and 2 computed by one Points; the next reuses seed 1 and computes
    seed 3, so its summary is the file's name, 1 reused, 1 computed and 2.5 + 4.5 = 7 s of runs (the reused
    one included).  Kills: the computed run's wall time not added (P27), the reused one's not added (P28),
    the file's full path instead of its name (P31), reused and computed swapped (P32), runs_wall_s 0 (P40)."""
    _fake_kinds(monkeypatch, [])
    p = Params(**FIG3)
    first = points.Points(str(tmp_path), "s")
    first.estimate(p, 1)
    first.estimate(p, 2)
    assert first.summary() == dict(file="s.points.jsonl", reused=0, computed=2, runs_wall_s=2.5 + 3.5, n_truncated=0,
                                   other_versions={})
    again = points.Points(str(tmp_path), "s")
    again.estimate(p, 1)
    again.estimate(p, 3)
    assert again.summary() == dict(file="s.points.jsonl", reused=1, computed=1, runs_wall_s=2.5 + 4.5, n_truncated=0,
                                   other_versions={})


def test_a_runs_notes_are_not_shown_by_the_scene(tmp_path, monkeypatch):
    """A run's DryfricWarning (its notes stay in its result) is not shown while a scene runs; other warnings
    are.  Kills: the DryfricWarning filter dropped (P34)."""
    def est(params, seed, **kw):
        warnings.warn("few excursions", DryfricWarning)
        warnings.warn("something else", RuntimeWarning)
        return _result(EstimateResult, D=1.0, warnings=["few excursions"])

    monkeypatch.setitem(points._KINDS, "estimate", (est, points._KINDS["estimate"][1]))
    with warnings.catch_warnings(record=True) as ws:
        warnings.simplefilter("always")
        r = points.Points(str(tmp_path), "s").estimate(Params(**FIG3), 1)
    assert [w.category for w in ws] == [RuntimeWarning] and r.warnings == ["few excursions"]


@pytest.mark.parametrize("change", [dict(ident=["estimate", 1]), dict(kind="walk"), dict(result=[1.0, 2.0])])
def test_a_record_of_another_shape_is_refused_by_name(tmp_path, change):
    """A line whose ident is not text, whose kind is none of the two, or whose result is not an object is
    not a finished-run record, whatever version wrote it (here another one, whose results are not checked
    field by field): the file is refused by name (ValueError), not half-read.  Kills: the ident's type
    unchecked (P10: a TypeError traceback, unhashable list), the kind unchecked (P09: accepted), the
    result's type unchecked (P11: accepted)."""
    rec = dict(ident="x", kind="estimate", version="0.0.1", result={"D": 1.0})
    (tmp_path / "s.points.jsonl").write_text(json.dumps(dict(rec, **change)) + "\n")
    with pytest.raises(ValueError, match=r"s\.points\.jsonl'? line 1 is not a finished-run record"):
        points.Points(str(tmp_path), "s")


# ---- speed_error.py (Fig. 9) --------------------------------------------------------------------------------

def _no_files(module, monkeypatch, lines):
    """The scene's ``save`` keeps its plotted lines (label, x, y) in ``lines`` and returns its numbers."""
    def save(fig, out_dir, name, numbers, t0, **meta):
        lines.extend((ln.get_label(), np.asarray(ln.get_xdata(), float), np.asarray(ln.get_ydata(), float))
                     for ax in fig.axes for ln in ax.lines)
        module.plt.close(fig)
        return dict(numbers)
    monkeypatch.setattr(module, "save", save)


def test_fig9_streams_reference_line_and_theory_slopes(tmp_path, monkeypatch):
    """Fake lanes and paths (errors N(0, 0.05) about the exact D, brute force biased by 0.001 t):
    the long excursions and the brute-force paths are drawn from two different keys (independent
    replicates of the two methods); the N^-1/2 guide starts at the first LE point and falls by 10 over
    a 100-fold cost (slope -1/2 in log-log); the JSON's theory slopes are section 5.3's, -1/2 and -1/3.
    Kills: the paths drawn with the lanes' key (S23), the guide falling by 100 (S27, slope -1), bf's
    theory slope -1/2 (S21); and D_true left in m^2/s (S19, test_figure_numbers.py's too)."""
    keys = []
    rng = np.random.default_rng(5)
    e, Ub = rng.normal(0, 0.05, 1024), rng.normal(0, 0.05, (2**16, 32))
    G, Dl = FIG3["Gamma"], FIG3["Delta"]
    p = Params(G, Dl, 1e-5 * G / Dl**2, FIG3["tau_L"], FIG3["gamma_bar"])
    D_true = 0.3 / p.D0

    def run_round(model, key, lanes, budget):
        keys.append(jax.random.key_data(key).tolist())
        stats = np.zeros((lanes, len(STAT_NAMES)))
        stats[:, 0], stats[:, 1] = 1.0, D_true + e[:lanes]
        return type("R", (), dict(stats=stats, lane_steps=np.full(lanes, 100.0)))

    def stationary(model, key, paths, n_records, every=1, burn_steps=0, record="VU"):
        keys.append(jax.random.key_data(key).tolist())
        return None, Ub[:paths, :n_records]

    class FakePoints:
        def __init__(self, out_dir, scene):
            pass

        def estimate(self, params, seed, **kw):
            return _result(EstimateResult, D=1.0, D_ci=0.1, wall_s=1.0)

        def kept(self, params, seed, **kw):  # every run kept: no warm-up (estimate_diffusivity below would fail)
            return True

        def summary(self):
            return {}

    lines = []
    for name, fake in (("run_round", run_round), ("di_stationary", stationary), ("Points", FakePoints),
                       ("estimate_diffusivity", None),
                       ("long_excursion_estimates", lambda T: dict(D=T["U"] / T["n"])),
                       ("bruteforce_estimates", lambda U, t: dict(D_t=D_true + np.mean(U) + 0.001 * t, D_t_ci=0.01)),
                       ("make_di_model", lambda params, h: None)):
        monkeypatch.setattr(speed_error, name, fake)
    monkeypatch.setattr(theory, "exact_D", lambda params: 0.3)
    _no_files(speed_error, monkeypatch, lines)
    f = speed_error.fig9(str(tmp_path), True, 0)
    assert len(keys) == 2 and keys[0] != keys[1]
    assert f["theory_slopes"] == dict(le=-0.5, bf=-1 / 3)
    # one lane a replicate: its error e_i; RMSE over the 1024 in m^2/s
    assert f["le"][0]["rmse"] == pytest.approx(math.sqrt(np.mean(e**2)) * p.D0, rel=1e-9)
    (x, y), = [(x, y) for lab, x, y in lines if lab == "N^-1/2"]
    assert (x[0], y[0]) == pytest.approx((f["le"][0]["cost"], f["le"][0]["rmse"]), rel=1e-12)
    assert math.log(y[1] / y[0]) / math.log(x[1] / x[0]) == pytest.approx(-0.5, rel=1e-12)


# ---- touchette.py (Table 1, Figs. 6-7) ----------------------------------------------------------------------

def _fake_model(monkeypatch, made):
    monkeypatch.setattr(touchette, "make_di_model", lambda p, h: made.append((p, h)) or (p, h))


def _table1(tmp_path, monkeypatch, quick, offsets):
    """table1 on paths at Touchette's mean of the time simulated plus offsets[i mod len] for path i."""
    made, asked = [], []

    def transient(model, key, n, record_steps, v0=1.0):
        asked.append((n, list(record_steps), v0))
        t = np.asarray(record_steps) * model[1]  # tau0 = 1: from_nondim
        off = np.asarray(offsets)[np.arange(n) % len(offsets), None]
        return np.array([theory.first_moment(x, v0) for x in t]) + off

    _fake_model(monkeypatch, made)
    monkeypatch.setattr(touchette, "di_transient", transient)
    _no_files(touchette, monkeypatch, [])
    return touchette.table1(str(tmp_path), quick, 0), made, asked


def test_table1_rows_are_model_notes_rows(tmp_path, monkeypatch):
    """MODEL_NOTES section 2: at t' = 0.05, 0.125, 0.25, 0.5, 1, 2.5 the model's exact first moment is
    0.950 0.877 0.773 0.618 0.428 0.182, the paper printed 0.950 0.875 0.757 0.568 0.336 0.090, which is the
    unit-intensity row (to its 3 digits).  Kills: another last time (T01), the printed row replaced by the
    model's (T02)."""
    f, _, _ = _table1(tmp_path, monkeypatch, True, [0.0])
    assert list(f["t"]) == [0.05, 0.125, 0.25, 0.5, 1.0, 2.5]
    assert f["exact_model"] == pytest.approx([0.950, 0.877, 0.773, 0.618, 0.428, 0.182], abs=6e-4)
    assert list(f["paper_row"]) == [0.950, 0.875, 0.757, 0.568, 0.336, 0.090]
    assert f["exact_unit_intensity"] == pytest.approx(f["paper_row"], abs=6e-4)


def test_table1_full_settings_and_a_skewed_sample(tmp_path, monkeypatch):
    """Full settings are the README's: 1e6 paths, tau' = 5e-6, h' = 2e-4, from v' = 1.  Paths at the exact
    mean plus d (3, -1, -1, -1) (i mod 4): MC = exact (the mean, while the median is exact - d), SE =
    d sqrt(3 n / (n - 1)) / sqrt(n) = d sqrt(3 / (n - 1)).  Kills: the full run's tau' 5e-5 (T04), the
    median for the mean (T20)."""
    d = 0.01
    f, made, asked = _table1(tmp_path, monkeypatch, False, [3 * d, -d, -d, -d])
    (p, h), = made
    (n, steps, v0), = asked
    assert (n, f["n_paths"], p.tau / p.tau0, h, f["h_nd"], v0) == (10**6, 10**6, 5e-6, 2e-4, 2e-4, 1.0)
    assert np.asarray(steps) * h == pytest.approx([0.05, 0.125, 0.25, 0.5, 1.0, 2.5], rel=1e-12)
    assert f["mc"] == pytest.approx(f["exact_model"], abs=1e-9)  # sums of 1e6 terms
    assert f["se"] == pytest.approx([d * math.sqrt(3 / (n - 1))] * 6, rel=1e-9)


def test_fig6_and_fig7_panels_times_and_burn_in(tmp_path, monkeypatch):
    """Fig. 6: tau' = 0.05, 5e-3, 5e-4, 5e-5, each from its own key, recorded at t' = 0.25, 1, 2.5 (README);
    Fig. 7: the same tau', each from its own key, after a burn-in of 40 tau0 (README).  Kills: one key for
    every tau' of Fig. 6 (T12) and of Fig. 7 (T16), the burn-in 4 tau0 (T15), t' = 2 for 2.5 (T19), the
    last tau' 5e-6 (T22)."""
    made, keys6, keys7, burns = [], [], [], []

    def transient(model, key, n, record_steps, v0=1.0):
        keys6.append(jax.random.key_data(key).tolist())
        assert np.asarray(record_steps) * model[1] == pytest.approx([0.25, 1.0, 2.5], rel=1e-12)
        return np.zeros((n, len(record_steps)))

    def stationary(model, key, paths, n_records, every, burn_steps=0, record="VU"):
        keys7.append(jax.random.key_data(key).tolist())
        burns.append(burn_steps * model[1])
        return np.random.default_rng(len(keys7)).normal(size=(paths, n_records)), None

    _fake_model(monkeypatch, made)
    monkeypatch.setattr(touchette, "di_transient", transient)
    monkeypatch.setattr(touchette, "di_stationary", stationary)
    _no_files(touchette, monkeypatch, [])
    touchette.fig6(str(tmp_path), True, 0)
    touchette.fig7(str(tmp_path), True, 0)
    taus = [p.tau / p.tau0 for p, _ in made]
    assert taus == pytest.approx([0.05, 5e-3, 5e-4, 5e-5] * 2, rel=1e-12)
    assert len(set(map(str, keys6))) == 4 and len(set(map(str, keys7))) == 4
    assert burns == pytest.approx([40.0] * 4, abs=made[-1][1])


# ---- requirements.py ----------------------------------------------------------------------------------------

def test_a_package_without_metadata_is_not_checked(monkeypatch):
    """A package whose metadata is missing (PackageNotFoundError) is reported as None and not checked
    (module docstring): with jax at its floor and no equinox metadata, nothing is too old; with jax 0.5.3,
    only jax is named.  Kills: a missing package reported as version "0" (R05: "equinox 0" too old)."""
    def version(name):
        if name == "equinox":
            raise rq.metadata.PackageNotFoundError(name)
        return {"jax": "0.6.2", "jaxlib": "0.6.2"}[name]

    monkeypatch.setattr(rq.metadata, "version", version)
    assert rq.installed_versions() == {"jax": "0.6.2", "jaxlib": "0.6.2", "equinox": None}
    assert rq.requirement_error() is None
    monkeypatch.setattr(rq.metadata, "version", lambda name: version(name) if name == "equinox" else "0.5.3")
    assert "installed: jax 0.5.3, jaxlib 0.5.3." in rq.requirement_error()


def test_pyproject_floors_past_a_bracket_inside_the_list():
    """A ']' inside the dependencies list (here in a comment) does not end it: the list ends at the ']'
    that starts a line.  Kills: the list ended at the first ']' (R06: numpy's floor lost)."""
    text = 'dependencies = [\n    "jax>=0.6.2",  # see [1]\n    "numpy>=1.26",\n]\n'
    assert rq.pyproject_floors(text) == {"jax": "0.6.2", "numpy": "1.26"}


def test_a_run_stopped_by_ctrl_c_is_not_kept(tmp_path, monkeypatch):
    """A run that returns what its rounds reached after a Ctrl-C (stopped_by "interrupted") is no finished
    point: the scene stops (KeyboardInterrupt) and nothing is written; the next run of the scene computes
    it.  Only test_figures.py's figs-fixture test (minutes) saw this before.  Kills: the check dropped
    (P21: the interrupted run was kept and reused as if finished)."""
    stopped = ["interrupted", "n_excursions"]

    def est(params, seed, **kw):
        return _result(EstimateResult, D=float(seed), stopped_by=stopped.pop(0))

    monkeypatch.setitem(points._KINDS, "estimate", (est, points._KINDS["estimate"][1]))
    with pytest.raises(KeyboardInterrupt):
        points.Points(str(tmp_path), "s").estimate(Params(**FIG3), 1)
    assert not (tmp_path / "s.points.jsonl").exists()
    again = points.Points(str(tmp_path), "s")
    assert again.estimate(Params(**FIG3), 1).stopped_by == "n_excursions" and again.computed == 1


def test_a_ctrl_c_in_a_run_stops_it_at_once(tmp_path, monkeypatch):
    """The real engine, Ctrl-C in its second paused round: the scene keeps finished runs only, so the run
    is dropped at once (no final round, which finished the excursions in flight for up to 20 s and was then
    thrown away; a sweep audit) and nothing is written."""
    from dryfric_jax import rounds

    calls = {"advance": 0, "finish": 0}
    real = {m: getattr(rounds.Lanes, m) for m in calls}

    def wrap(m):
        def f(self, *a, **k):
            calls[m] += 1
            if m == "advance" and calls[m] == 2:
                raise KeyboardInterrupt
            return real[m](self, *a, **k)
        return f

    for m in calls:
        monkeypatch.setattr(rounds.Lanes, m, wrap(m))
    with pytest.raises(KeyboardInterrupt):
        points.Points(str(tmp_path), "s").estimate(Params(**FIG3), 1, n_excursions=3000)
    assert calls == {"advance": 2, "finish": 0} and not (tmp_path / "s.points.jsonl").exists()


def test_a_kept_result_with_an_extra_key_is_reused(tmp_path, monkeypatch):
    """A kept result with a key its class lacks (a hand-added note) is reused with the class's fields only.
    Kills: the result's keys not filtered by the class's fields (P30: a TypeError traceback)."""
    _fake_kinds(monkeypatch, [])
    a = points.Points(str(tmp_path), "s").estimate(Params(**FIG3), 4)
    path = tmp_path / "s.points.jsonl"
    rec = json.loads(path.read_text())
    path.write_text(json.dumps(dict(rec, result=dict(rec["result"], note="checked by hand"))) + "\n")
    again = points.Points(str(tmp_path), "s")
    assert again.estimate(Params(**FIG3), 4) == a and again.reused == 1


def test_points_identity_names_values_not_numpy_types():
    """A setting given as a numpy float64 or int64 (read from an array) is the run of the Python number it
    holds, and -inf is not inf.  Before, numpy 2 wrote ``np.float64(0.1)`` into the identity (a run at
    h = np.float64(0.1) was not reused for h = 0.1, nor the reverse), a numpy int64 setting made json.dumps
    fail, and -inf was written "inf"; plain Python values keep the identity they had (kept files are reused)."""
    p = Params(**FIG3)
    ident = lambda **kw: points._ident("estimate", p, 1, kw)  # noqa: E731
    assert ident(h=np.float64(0.1), n_excursions=np.int64(64)) == ident(h=0.1, n_excursions=64)
    assert ident(h=np.float32(0.5)) == ident(h=0.5)
    assert ident(max_time=-math.inf) != ident(max_time=math.inf)
    assert json.loads(ident(h=0.1, max_time=math.inf))[3] == {"h": "0.1", "max_time": "inf"}
