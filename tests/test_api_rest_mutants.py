"""Mutation audit of the rest of ``dryfric_jax/api.py`` (what tests/test_api_audit.py did not target) and of
``plan.check_h`` / ``plan.dtype_name``: the seed and key checks, the texts (``_fmt``, ``duration_text``,
``summary``, ``str`` of the results), ``time_left`` and ``_ratio``, ``missing_fields``, and in
``estimate_diffusivity`` the progress reports, the early ``ProjectionWarning`` and what the result records.

140 one-line mutants tried (tried against the existing tests that touch each part: test_api_audit, test_bad_input,
test_targets, and per part test_reproducibility / test_figures / test_sweep (seeds, keys), test_cli's text and
projection tests, test_combine / test_combine_limits_mutants (missing fields), test_paths / test_plan_audit /
test_stress / test_ou / test_chain_law (h, dtype)): 50 killed before, 7 equivalent (a numpy bool is no Integral;
max_work or max_time tying exactly with N changes only the label of a tie; ``_ratio`` ``<=`` at exactly 2^32;
a zero D so far divides to nan either way; a nan or inf h fails the range without isfinite; numpy refuses
np.dtype(array) itself), 83 killed here, none left.  One DEFECT found and fixed (the last test): a limit
already passed was projected to end a run that reaches its N in that very round, and the ProjectionWarning said
"short of N excursions" for a run that then ended by N.

Oracles: hand arithmetic on the documented definitions (the docstrings and the README's "--rtol", "--max-time",
progress display and "Predicted work" parts): the projection is (N wanted - closed - running) x work per excursion /
rate, the work per excursion counting each running excursion as one, N wanted = max(N, closed (rel/rtol)^2) with a
target, capped by what max_work and max_time leave (never below 0); seeds are integers in [0, 2^62] (figures:
2^62 - 2^20); h in [1e-12, 0.1] x min(tau0, tau_L).  Every formatted number below is written out by hand from the
format the docstring names (6 significant digits for D, 2 for a CI, ...).  The engine and the clock are fakes
(as in test_api_audit): no simulation, nothing depends on the machine's speed.
"""
import math
import sys
import types
import warnings

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import dryfric_jax as dj
from dryfric_jax import api
from dryfric_jax.api import (
    MAX_FIGURE_SEED, MAX_SEED, BruteForceResult, EstimateResult, _fmt, _key, _ratio, check_progress, check_seed,
    duration_text, missing_fields, time_left,
)
from dryfric_jax.plan import check_h, dtype_name

from test_api_audit import P, T40, U40, _stats  # the audit's point, its 40 excursions and their engine record

H = 0.02 * P.tau0


# ---- seeds, keys, progress ----------------------------------------------------------------------------------------

def test_seed_range_edges_and_what_comes_back():
    """[0, 2^62] both ends included, a Python int back (a numpy one was returned as is), the message naming the
    range from 0 (mutants: 0 or 2^62 refused, ``return seed``, "[1, 2^62]", MAX_SEED 2^63, MAX_FIGURE_SEED off)."""
    assert MAX_SEED == 2**62 and MAX_FIGURE_SEED == 2**62 - 2**20
    assert check_seed(0) == 0 and check_seed(2**62) == 2**62
    got = check_seed(np.int64(5))
    assert got == 5 and type(got) is int
    for bad in (-1, 2**62 + 1, True, np.bool_(False), 1.0):
        with pytest.raises(ValueError, match=r"^seed must be an integer in \[0, 2\^62\] \(got "):
            check_seed(bad)
    assert check_seed(2**62 - 2**20, MAX_FIGURE_SEED, "x") == 2**62 - 2**20
    with pytest.raises(ValueError, match=r"^seed must be an integer in \[0, x\] \(got 4611686018426339329\)$"):
        check_seed(2**62 - 2**20 + 1, MAX_FIGURE_SEED, "x")


def test_a_huge_seed_or_progress_is_shown_short():
    """The refusal shows a 401-digit int as its head and length (mutants: ``{seed}``, ``{progress}``)."""
    for call, name in ((check_seed, "seed"), (check_progress, "progress")):
        with pytest.raises(ValueError, match=f"^{name} must be") as e:
            call(10**400)
        assert "(401 characters)" in str(e.value) and len(str(e.value)) < 200


def test_progress_may_be_none_any_callable_or_a_bool():
    """None, a callable, True and False pass; anything else is refused saying what passes; without ``live`` (the
    figures') True and False are refused too (mutants: None refused, "or None" dropped, 1 taken for True)."""
    assert check_progress(None) is None and check_progress(print) is None
    assert check_progress(True) is None and check_progress(False) is None
    for bad in (5, 1, "yes"):
        with pytest.raises(ValueError, match=r"^progress must be a callable, True \(a live status line\), False or "
                                             r"None \(got "):
            check_progress(bad)
    with pytest.raises(ValueError, match=r"^progress must be a callable or None \(got True\)$"):
        check_progress(True, live=False)


def test_keys_seeds_and_their_recorded_seed():
    """None is seed 0 (key(0), recorded 0); a seed s is key(s), recorded s; a legacy PRNGKey and a typed key are
    used as they are, recorded None (mutants: None -> seed None or key(1), seed -> None, PRNGKey -> seed 0)."""
    data = lambda k: np.asarray(jax.random.key_data(k))
    k, s = _key(None)
    assert s == 0 and (data(k) == data(jax.random.key(0))).all()
    k, s = _key(np.int64(5))
    assert s == 5 and type(s) is int and (data(k) == data(jax.random.key(5))).all()
    k, s = _key(jax.random.PRNGKey(3))
    assert s is None and (data(k) == data(jax.random.key(3))).all()
    typed = jax.random.key(9)
    assert _key(typed)[0] is typed and _key(typed)[1] is None


@pytest.mark.parametrize("key,got", [
    (np.zeros((3, 2), np.uint32), "an array of shape (3, 2) and dtype uint32"),  # a batch of raw keys
    (np.zeros(2, np.int32), "an array of shape (2,) and dtype int32"),  # not a PRNGKey's dtype
    (jax.random.split(jax.random.key(0)), "an array of shape (2,) and dtype key<fry>"),  # a batch of typed keys
    (True, "True"), (np.True_, "an array of shape () and dtype bool"),  # not seeds
])
def test_what_is_not_one_key_is_refused_by_name(key, got):
    """Only a () typed key or a uint32[2] PRNGKey is a key (mutants: shape or dtype not checked, the message's
    dtype dropped, its seed range misnamed, a numpy bool taken for a seed)."""
    with pytest.raises(ValueError) as e:
        _key(key)
    msg = str(e.value)
    assert msg.startswith("key must be a seed (an integer in [0, 2^62]) or one jax.random key (got ")
    assert msg.endswith(f"(got {got})")


# ---- texts ---------------------------------------------------------------------------------------------------------

def test_fmt_value_ci_and_relative_width():
    """6 significant digits, a 2-digit CI, the relative width in % of |x| to 0.1; for x = 0 no relative width
    (mutants: 5 digits, a 3-digit CI, a negative %, 2 decimals, ``if ci``, the zero branch's CI)."""
    # 0.126 / 3.14159265 = 4.0107%
    assert _fmt(-3.14159265, 0.126) == "-3.14159 ± 0.13  (4.0%)"
    assert _fmt(0.0, 0.123) == "0 ± 0.12"
    assert _fmt(0.0, 0.0) == "0 ± 0"


@pytest.mark.parametrize("s,text", [(45.4, "45 s"), (60.0, "60 s"), (89.4, "89 s"), (90.0, "1.5 min"),
                                    (150.0, "2.5 min"), (3600.0, "60.0 min"), (5399.0, "90.0 min"),
                                    (5400.0, "1.5 h"), (9000.0, "2.5 h")])
def test_duration_text_units_and_edges(s, text):
    """Seconds below 90 s, minutes (one decimal) below 90 min, else hours (one decimal): the README's "45 s",
    "12.5 min", "3.2 h" (mutants: each edge moved or made inclusive, the decimals changed, hours as s/60)."""
    assert duration_text(s) == text


def _estimate(**kw):
    d = dict(D=2.5e-3, D_ci=1.0e-4, M0=-0.0314159265, M0_ci=0.00126, mean_duration=0.123456, n_excursions=20000,
             n_truncated=3, method="di", h=0.00066666, dtype="float64", seed=7, wall_s=12.34,
             lane_steps_per_s=1.23456e8, params={}, stopped_by="target")
    return EstimateResult(**{**d, **kw})


def test_estimate_summary_written_out():
    """Every line of ``summary()`` by hand from its documented fields (mutants: the CI level as a fraction,
    4 -> 3 digits of the duration, 0.1 -> 0.01 s of wall time, 3 -> 2 digits of the speed, stopped_by replaced,
    M0 with D's CI, the resolution's digits)."""
    want = ("D  = 0.0025 ± 0.0001  (4.0%) m^2/s   (95% CI)\n"
            "M0 = -0.0314159 ± 0.0013  (4.0%) m/s\n"  # 0.00126 / 0.0314159 = 4.01%
            "mean excursion duration = 0.1235 s (DI: regeneration cycles, each >= 1 of the paper's excursions)\n"
            "N = 20000 excursions, 3 truncated, h = 0.000667 s, float64, seed 7\n"
            "wall 12.3 s, 1.23e+08 lane-steps/s, stopped by: target")
    assert _estimate().summary() == want
    # the DI's cycle is not the paper's excursion (2-4x longer at Fig. 3's point; an audit read the two
    # methods' "mean excursion duration" as one quantity); the PDMP's is
    pdmp = _estimate(method="pdmp", h=None, delta=0.0625, L_X=6.0).summary()
    assert "\nmean excursion duration = 0.1235 s\n" in pdmp and "cycles" not in pdmp


def test_pooled_pdmp_summary_names_its_seeds_the_grid_and_events():
    """A pooled PDMP result: "seeds [...]", the grid step (s^-1/2, 3 digits) and L_X, events/s (mutants: the seed
    shown for a pool, the labels swapped, L_X shown as delta, the delta's unit)."""
    r = _estimate(h=None, delta=0.123456, L_X=7.891, combined_from=[1, 2], seed=None, ci_level=0.9)
    lines = r.summary().splitlines()
    assert lines[0].endswith("(90% CI)")
    assert lines[3] == "N = 20000 excursions, 3 truncated, PDMP delta = 0.123 s^-1/2, L_X = 7.89, float64, seeds [1, 2]"
    assert lines[4] == "wall 12.3 s, 1.23e+08 events/s, stopped by: target"


def _bruteforce(**kw):
    d = dict(D_t=1.5, D_t_ci=0.03, M0_t=0.25, M0_t_ci=0.0123, t=12.3456, n_paths=500, method="di", h=0.001,
             dtype="float32", seed=3, wall_s=2.26, lane_steps_per_s=1e6, params={})
    return BruteForceResult(**{**d, **kw})


def test_bruteforce_summary_written_out():
    """(mutants: the horizon's digits, N' off by one, M0_t with D_t's CI, its CI level, the wall time's digits)"""
    want = ("D_t  = 1.5 ± 0.03  (2.0%) m^2/s   (t = 12.35 s, 95% CI)\n"
            "M0_t = 0.25 ± 0.012  (4.9%) m/s\n"  # 0.0123 / 0.25 = 4.92%
            "N' = 500 paths, h = 0.001 s, wall 2.3 s")
    assert _bruteforce().summary() == want
    assert "(t = 12.35 s, 80% CI)" in _bruteforce(ci_level=0.8).summary()


@pytest.mark.parametrize("make", [_estimate, _bruteforce])
def test_str_is_the_summary_then_each_warning_on_its_line(make):
    """Two warnings, each on its own "warning: " line, none lost, none doubled, nothing between them; to_dict
    keeps them (mutants: "\\n".join, a trailing newline, the first warning only, str without warnings, to_dict
    without warnings)."""
    r = make(warnings=["first note", "second note"])
    assert str(r) == r.summary() + "\nwarning: first note\nwarning: second note"
    assert r.to_dict()["warnings"] == ["first note", "second note"]


def test_results_default_to_95_percent_cis():
    """The class docstrings: "CIs are 95% half-widths"; a result that does not say what stopped it reached its N
    (mutants: ci_level default 0.9, either class; stopped_by default "target")."""
    assert _estimate().ci_level == 0.95 and _bruteforce().ci_level == 0.95
    assert EstimateResult(**{k: v for k, v in _estimate().to_dict().items() if k != "stopped_by"}).stopped_by \
        == "n_excursions"


# ---- missing_fields ------------------------------------------------------------------------------------------------

EST_REQUIRED = ["D", "D_ci", "M0", "M0_ci", "mean_duration", "n_excursions", "n_truncated", "method", "h", "dtype",
                "seed", "wall_s", "lane_steps_per_s", "params"]
BF_REQUIRED = ["D_t", "D_t_ci", "M0_t", "M0_t_ci", "t", "n_paths", "method", "h", "dtype", "seed", "wall_s",
               "lane_steps_per_s", "params"]


def test_missing_fields_are_the_fields_without_a_default():
    """From an empty dict every field without a default, in order (none with a default or a default factory);
    from a full to_dict() none; a dict lacking params names it (mutants: defaulted fields named, factory fields
    named, the first field skipped, params skipped)."""
    assert missing_fields(EstimateResult, {}) == EST_REQUIRED
    assert missing_fields(BruteForceResult, {}) == BF_REQUIRED
    d = _estimate().to_dict()
    assert missing_fields(EstimateResult, d) == []
    assert missing_fields(EstimateResult, {k: v for k, v in d.items() if k not in ("params", "warnings", "sums")}) \
        == ["params"]


# ---- time_left and _ratio ------------------------------------------------------------------------------------------

def test_time_left_is_unknown_without_time_or_work():
    """(None, None) before any time or work has passed, not a ZeroDivisionError (mutants: ``elapsed < 0``,
    ``work < 0``); and with a precision target whose half-width is not a finite number yet (mutant: only None)."""
    assert time_left(0.0, 1e6, 10, 0, 100) == (None, None)
    assert time_left(10.0, 0.0, 10, 0, 100) == (None, None)
    for rel in (math.nan, math.inf):
        assert time_left(10.0, 1e6, 100, 0, 50, rtol=0.01, rel=rel) == (None, None)


def test_time_left_by_hand():
    """1e6 lane-steps paid in 10 s (1e5 per s unless ``rate``), 1e4 or 1e5 per excursion (mutants: ``rate`` ignored,
    N wanted not at least the target, running ones counted in N (rel/rtol)^2, a negative time left for a passed
    N, max_work or max_time, max_time compared whole, not what is left of it)."""
    assert time_left(10.0, 1e6, 10, 0, 100, rate=2e5) == (45.0, "n_excursions")  # 90 x 1e5 / 2e5
    # N (rel/rtol)^2 = 100 / 4 = 25 < 200 asked: 100 more, 1e4 each at 1e5 per s
    assert time_left(10.0, 1e6, 100, 0, 200, rtol=0.01, rel=0.005)[0] == pytest.approx(10.0, rel=1e-12)
    # 90 closed (in flight not counted in N): 90 x 4 = 360 wanted, 360 - 100 = 260 more at 1e4 / 1e5 s
    assert time_left(10.0, 1e6, 90, 10, 50, rtol=0.01, rel=0.02) == (pytest.approx(26.0, rel=1e-12), "target")
    assert time_left(10.0, 1e6, 120, 0, 100) == (0.0, "n_excursions")  # N passed: nothing left
    assert time_left(10.0, 1e6, 10, 0, 100, max_work=5e5) == (0.0, "max_work")  # already past max_work
    assert time_left(10.0, 1e6, 10, 0, 100, max_time=5.0) == (0.0, "max_time")  # already past max_time
    assert time_left(10.0, 1e6, 10, 0, 100, max_time=95.0) == (85.0, "max_time")  # 85 s of it left < 90


def test_ratio_is_capped_at_2_to_the_32():
    """rel/rtol, at most 2^32, also for inf and nan (mutants: the cap at 2^31 or 2^16)."""
    assert _ratio(3.0, 1.5) == 2.0 and _ratio(1e5, 1.0) == 1e5 and _ratio(2.0**32 - 1, 1.0) == 2.0**32 - 1
    assert _ratio(1e300, 1e-10) == _ratio(math.inf, 1.0) == _ratio(math.nan, 1.0) == 2.0**32


# ---- estimate_diffusivity: reports, the ProjectionWarning, the result's record ---------------------------------------

def _fake(monkeypatch, rounds, stopped, clock=None):
    """The engine reports each round to ``progress`` itself (as the real one does: the warning's stack depth is
    the real one) and returns the last; the clock reads 1, 2, 3, ... or the readings given."""
    ticks = [0.0]

    def tick():
        ticks[0] += 1.0
        return ticks[0]

    now = tick if clock is None else iter(clock).__next__

    def engine(model, key, n, *, progress, **kw):
        for st in rounds:
            progress(st)
        return rounds[-1], stopped

    monkeypatch.setattr(api, "simulate_long_excursions", engine)
    monkeypatch.setattr(api, "time", types.SimpleNamespace(perf_counter=now))


def _rounds(*slots, closed=100):
    """Rounds of the 40 excursions' sums, ``closed`` closed (truncated ones count), paid ``slots`` lane-steps."""
    return [_stats(U40, T40, slot=s, truncated=closed - 40) for s in slots]


def _recorded(call):
    with warnings.catch_warnings(record=True) as ws:
        warnings.simplefilter("always")
        r = call()
    return r, [w for w in ws if issubclass(w.category, dj.DryfricWarning)]


def test_a_max_time_projection_is_reported_not_warned(monkeypatch):
    """Round 2: 2e9 lane-steps for 100 excursions (2e7 each) at 1e9 per s; 300 more want 6 s, but max_time = 4 s
    at 3 s elapsed leaves 1 s: ``left_to`` "max_time", 1 s; no ProjectionWarning (that is max_work's); the
    report's N is the complete excursions (40), its rtol the one given (mutants: max_time not passed to the
    projection, a ProjectionWarning for max_time too, N counting truncated ones, rtol not reported)."""
    seen = []
    _fake(monkeypatch, _rounds(1e9, 2e9), "max_time")
    r, ws = _recorded(lambda: dj.estimate_diffusivity(P, 7, h=H, n_excursions=400, max_time=4.0,
                                                      progress=seen.append))
    assert [(d["left_s"], d["left_to"]) for d in seen] == [(None, None), (1.0, "max_time"), (None, None)]
    assert not any(w.category is dj.ProjectionWarning for w in ws)
    assert [(d["n_excursions"], d["target"], d["rtol"]) for d in seen] == [(40, 400, None)] * 3
    seen.clear()
    _fake(monkeypatch, _rounds(1e9, 2e9), "max_time")
    r, ws = _recorded(lambda: dj.estimate_diffusivity(P, 7, h=H, n_excursions=400, rtol=0.05, max_time=4.0,
                                                      progress=seen.append))
    assert [(d["rtol"], d["left_s"], d["left_to"]) for d in seen] == [(0.05, None, None), (0.05, 1.0, "max_time"),
                                                                     (0.05, None, None)]
    assert r.rtol == 0.05 and r.stopped_by == "max_time"


def test_a_precision_run_without_progress_still_warns_early_and_names_its_target(monkeypatch):
    """rtol = 0.05 at a half-width of 39%: ~6000 excursions wanted; round 2 paid 2.46e9 lane-steps for 100
    (2.46e7 each, 3 digits) at 1.46e9 per s; max_work = 2.5e9 ends the run in 0.03 s: one ProjectionWarning, of
    that class, said "short of rtol = 0.05", the predicted work per excursion the plan's over N; raised at the
    caller's line (mutants: no projection without a progress callback, the target not named, 2 digits, the whole
    predicted work, a DryfricWarning, stacklevel 2)."""
    _fake(monkeypatch, _rounds(1e9, 2.46e9), "work_bound")
    pred = dj.plan_estimate(P, h=H, n_excursions=40, max_work=2.5e9).predicted_work
    line = sys._getframe().f_lineno + 1
    r, ws = _recorded(lambda: dj.estimate_diffusivity(P, 7, h=H, n_excursions=40, rtol=0.05, max_work=2.5e9))
    early = [w for w in ws if "projected" in str(w.message)]
    assert len(early) == 1 and early[0].category is dj.ProjectionWarning
    assert str(early[0].message) == (
        "max_work = 2.5e+09 steps is projected to end the run in ~0 s, short of rtol = 0.05: the rounds so far paid "
        f">= 2.46e+07 steps per excursion (predicted >= {pred / 40:.3g}).  Lower n_excursions, raise max_work, or "
        "coarsen h or delta")
    assert (early[0].filename, early[0].lineno) == (__file__, line)
    # the notes are warned at the caller's line too
    assert {(w.filename, w.lineno) for w in ws} == {(__file__, line)} and len(ws) > 1


def test_the_bruteforce_notes_are_warned_at_the_callers_line(monkeypatch):
    """(mutant: stacklevel 3)"""
    monkeypatch.setattr(api, "simulate_bruteforce", lambda model, key, n, steps, **kw: (np.arange(6.0), 1.0))
    line = sys._getframe().f_lineno + 1
    r, ws = _recorded(lambda: dj.bruteforce_diffusivity(P, 3, h=H, t=H * 50, n_paths=6))
    assert ws and {(w.filename, w.lineno) for w in ws} == {(__file__, line)}


def test_a_clock_that_stands_still_gives_the_overall_rate(monkeypatch):
    """The clock reads 1 (start), 2, 2 (round 1), 2, 2 (round 2), 5, 5 (the final report), 5 (end): no engine time
    between the rounds, so
    the projection falls back to work / elapsed = 2e9 per s: 300 more excursions x 2e7 / 2e9 = 3 s (mutant:
    ``sim >= first``, a ZeroDivisionError)."""
    seen = []
    _fake(monkeypatch, _rounds(1e9, 2e9), "n_excursions", clock=[1.0, 2.0, 2.0, 2.0, 2.0, 5.0, 5.0, 5.0])
    _recorded(lambda: dj.estimate_diffusivity(P, 7, h=H, n_excursions=400, progress=seen.append))
    assert [(d["left_s"], d["left_to"]) for d in seen] == [(None, None), (3.0, "n_excursions"), (None, None)]


def test_the_projection_leaves_out_the_compiling_round_and_the_reports(monkeypatch):
    """The engine's rate is that of the rounds after the first (README: "at the engine's rate after that round,
    which compiled it"), less the time spent in the reports.  Clock: start 0; round 1 ends at 10 (compiling), its
    report takes 1 s; round 2 ends at 12, its callback 100 s; round 3 ends at 113.  Engine time after round 1:
    1 s, then 2 s, for 1e9 and 2e9 more lane-steps: 1e9 per s.  Round 2: 300 more x 2e7 / 1e9 = 6 s; round 3
    (200 closed, 1.5e7 each): 200 x 1.5e7 / 1e9 = 3 s; the final report at 114 (mutants: the first round's time
    and work kept in the rate, 33 s; only the last report's time taken out, 4.5 s)."""
    rounds = [_stats(U40, T40, slot=s, truncated=c - 40) for s, c in ((1e9, 50), (2e9, 100), (3e9, 200))]
    seen = []
    _fake(monkeypatch, rounds, "n_excursions", clock=[0.0, 10.0, 11.0, 12.0, 112.0, 113.0, 113.0, 114.0, 114.0,
                                                                     115.0])
    _recorded(lambda: dj.estimate_diffusivity(P, 7, h=H, n_excursions=400, progress=seen.append))
    assert [(d["elapsed_s"], d["left_s"], d["left_to"]) for d in seen] == [
        (10.0, None, None), (12.0, 6.0, "n_excursions"), (113.0, 3.0, "n_excursions"), (114.0, None, None)]


def test_the_result_records_the_plan_and_the_version(monkeypatch):
    """The plan's predicted work, lanes, max_work and reason, the rtol and the package version (mutants: each
    replaced by a constant or the argument as given)."""
    _fake(monkeypatch, _rounds(1e9, 2e9), "target")
    r, _ = _recorded(lambda: dj.estimate_diffusivity(P, 7, method="auto", n_excursions=40, rtol=0.5, max_work=3e9))
    plan = dj.plan_estimate(P, method="auto", n_excursions=40, max_work=3e9)
    assert plan.reason and plan.predicted_work > 0
    assert (r.predicted_work, r.lanes, r.max_work, r.method_reason) == (plan.predicted_work, plan.lanes, 3e9,
                                                                        plan.reason)
    assert (r.rtol, r.version, r.stopped_by) == (0.5, dj.__version__, "target")


# ---- plan.check_h and plan.dtype_name ------------------------------------------------------------------------------

Q = dj.Params(Gamma=1.0, Delta=1.0, tau=0.5, tau_L=0.0123456)  # tau0 = 1 s > tau_L


def test_h_range_ends_are_fractions_of_the_fastest_time_scale():
    """[1e-12, 0.1] x min(tau0, tau_L), both ends included, the smallest from tau_L here (mutants: the upper end
    excluded, the lower end from tau0 alone, the value not returned as a float)."""
    fastest = 0.0123456
    assert check_h(Q, 0.1 * fastest) == 0.1 * fastest and check_h(Q, 1e-12 * fastest) == 1e-12 * fastest
    assert check_h(Q, 5e-13) == 5e-13  # below 1e-12 tau0, above 1e-12 tau_L
    got = check_h(Q, np.float32(0.001))
    assert type(got) is float and got == float(np.float32(0.001))
    assert check_h(Q, None) == 0.01 * fastest


def test_h_refusal_says_the_range_in_seconds_and_in_time_scales():
    """4 significant digits of each end (1.23456e-14 s and 0.00123456 s), rounded into the range (up at the
    bottom, down at the top: 0.001235, the nearest, was refused), then the fractions in order (mutants: 3
    digits, the fractions swapped)."""
    with pytest.raises(ValueError) as e:
        check_h(Q, 1.0)
    assert str(e.value) == ("h must be in [1.235e-14, 0.001234] s, i.e. between 1e-12 and 0.1 times "
                            "min(tau0, tau_L) (got 1.0)")


@pytest.mark.parametrize("dtype", [np.float32(1.0), np.zeros(2, np.float32), jnp.zeros(2, jnp.float32), object(), 5,
                                   "FLOAT32", "float16"])
def test_only_a_dtype_is_a_dtype(dtype):
    """A value (numpy scalar, numpy or JAX array) is not its dtype; what jnp.dtype cannot read is refused by
    name, as is another spelling (mutants: each of the three value types not excluded, ``except ValueError``,
    a case-blind name, the value shown without repr)."""
    with pytest.raises(ValueError) as e:
        dtype_name(dtype)
    assert str(e.value) == f"dtype must be one of ['float32', 'float64'] (got {dtype!r})"


def test_dtype_names_and_types_are_taken():
    assert [dtype_name(d) for d in ("float32", jnp.float64, np.dtype("float32"))] == ["float32", "float64", "float32"]


def test_a_run_that_reaches_n_as_it_passes_max_work_is_not_warned_short_of_n(monkeypatch):
    """The engine checks N before max_work and max_time (excursions.py: the round loop breaks on N first), and a
    round may pass max_work by up to a block per lane: a round that reaches N = 400 at 2.6e9 lane-steps with
    max_work = 2.5e9 ends the run by N.  Nothing is left to project (0 s to N), so no limit ends it first: no
    ProjectionWarning "short of 400 excursions" (it was said), and the report names N, not --max-work."""
    assert time_left(10.0, 3e9, 400, 0, 400, max_work=2.5e9) == (0.0, "n_excursions")
    assert time_left(10.0, 1e6, 120, 0, 100, max_time=5.0) == (0.0, "n_excursions")
    seen = []
    _fake(monkeypatch, [_stats(U40, T40, slot=1e9, truncated=10), _stats(U40, T40, slot=2.6e9, truncated=360)],
          "n_excursions")
    r, ws = _recorded(lambda: dj.estimate_diffusivity(P, 7, h=H, n_excursions=400, max_work=2.5e9,
                                                      progress=seen.append))
    assert r.stopped_by == "n_excursions" and (seen[1]["left_s"], seen[1]["left_to"]) == (0.0, "n_excursions")
    assert not [str(w.message) for w in ws if w.category is dj.ProjectionWarning]
