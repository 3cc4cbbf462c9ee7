"""Sweep checks, from a second mutation audit of dryfric_jax/sweep.py (the parts the first, test_sweep_mutants.py,
did not target): the validation of hand-edited records (_is_real, _check_record, read_results), of the points
(_check_points, _no_negative_zero) and of the axes (grid), the refusal message (_refusal_text, _first_clause),
max_time and stopped_by (stopped_by, _time_limited, _more_time, _compute, _record), the branches of run_sweep and
_finished_elsewhere, _outdated, the counts, the warnings (_at_point), failures, rows and progress_bar.

77 one-line mutants were tried (against test_sweep_mutants, test_sweep, and the sweep tests of test_plumbing_audit,
test_cli_mutants, test_bad_input, test_combine, test_interrupts_mutants and test_plumbing_mutants): 44 were killed by
those tests, 6 are equivalent (a non-dict params or result, or a missing sweep_seed, is refused anyway through the
AttributeError or KeyError that read_records turns into the refusal; _no_negative_zero sees numbers only as floats;
_outdated is never asked about a refused record; _finished_elsewhere's read needs no lock, every write being an atomic
rename), 27 are killed only by this file, none is left.  One defect was found (the last test; fixed in sweep._check_record).

The estimator is the stand-in of test_sweep_mutants.py (``calls``); records are made with ``sweep._record`` and
hand-edited.  Expected values come from the docstrings and the README, worked out by hand."""
import json
import math
import sys
import warnings

import numpy as np
import pytest

from dryfric_jax import outfiles, sweep
from dryfric_jax.api import DryfricWarning, ProjectionWarning
from dryfric_jax.params import FIG3
from dryfric_jax.plan import check_settings
from test_sweep_mutants import KW, _lines, stand_in_result
from test_sweep_mutants import calls  # noqa: F401, F811  (the stand-in estimator, a fixture)

SETTINGS = check_settings(**KW)
RESULT = stand_in_result()  # Fig. 3's point, as _rec's records of Gamma = 5


def _rec(state="ok", gamma=5.0, max_time=None, **what):
    """A record of the point Gamma = ``gamma`` (Fig. 3 otherwise) at the settings KW, sweep seed 0."""
    if state == "ok":
        what.setdefault("result", dict(RESULT))
    else:
        what.setdefault("reason", "fewer than 2 complete excursions within the work bounds: stand-in")
    return sweep._record(0, {**FIG3, "Gamma": gamma}, SETTINGS, state, max_time, **what)


def _file(tmp_path, *recs):
    out = str(tmp_path / "s.jsonl")
    outfiles.write_records(out, list(recs))
    return out


@pytest.mark.parametrize("edit", [
    dict(params={**FIG3, "Gamma": True}),  # a JSON true is not a number (it was the point Gamma = 1.0)
    dict(params={**FIG3, "Delta": None}),  # every parameter is checked, not only Gamma
    dict(params={**FIG3, "tau_L": "0.067"}),
    dict(sweep_seed=True),  # not the sweep seed 1
    dict(result={**RESULT, "M0": "x"}),  # every number a table reads, M0 too
    dict(result={**RESULT, "M0_ci": None}),
    dict(result={**RESULT, "D": float("nan")}),  # kept as a finished point, never rerun (an audit)
    dict(result={**RESULT, "D_ci": float("inf")}),
    dict(status="refused", reason=5),  # a reason is text (the progress line and the refusal cut it at ':')
    dict(status="failed", reason="fewer than 2 complete excursions", sweep_seed="0"),  # a reason does not excuse it
])
def test_a_hand_edited_record_is_refused_by_line(tmp_path, edit):
    """read_results refuses a file with a line that is not a sweep record, naming the line (the second here:
    the first is well formed).  Mutants: _is_real taking a bool; only Gamma of the parameters checked; a bool
    sweep_seed taken; M0 and M0_ci of a result not checked; a refused record's reason checked for presence
    only; the reason check made for every record that failed the other checks (``else`` for ``elif ok``)."""
    good = _rec("ok")
    out = _file(tmp_path, good, {k: v for k, v in {**good, **edit}.items() if k != "result" or "status" not in edit})
    with pytest.raises(ValueError, match=r"^out must be a dryfric sweep file \(JSON Lines\); .* line 2 is not a sweep"):
        sweep.read_results(out)


@pytest.mark.parametrize("points,match", [
    ({"Gamma": 5.0}, r"^points must be a list of parameter dicts, e\.g\. .* \(got dict\)"),
    (5.0, r"^points must be a list of parameter dicts, e\.g\. .* \(got float\)"),
    ([{"Gamma": 2.0}, 5.0], r"^points\[1\] must be a dict of parameters \(got float\)"),
    ([{"Gamma": 2.0}, {"Gama": 1.0}], r"^points\[1\] has unknown parameters \['Gama'\]"),
])
def test_points_that_are_not_a_list_of_parameter_dicts_are_refused_by_name(tmp_path, calls, points, match):
    """Mutants: a dict of points taken as its keys (refused as 'points[0] must be a dict', a misleading
    index); a number of points a TypeError; only the first point checked (a TypeError from a later one)."""
    out = tmp_path / "s.jsonl"
    with pytest.raises(ValueError, match=match):
        sweep.run_sweep(points, str(out), **KW)
    assert not out.exists() and calls == []


def test_grid_is_in_the_parameters_order_and_checks_its_axes():
    """The product is taken in the order Gamma, Delta, tau, tau_L, gamma_bar whatever the keywords' order
    ("in a stable order"); a 2-d array axis is its values; an unknown axis or a dict axis is refused.
    Mutants: the keywords' order; a 2-d array taken row by row; the unknown axis dropped silently; a dict
    taken as its keys."""
    assert sweep.grid(tau=[0.5, 1.0], Gamma=[2.0, 3.0]) == [dict(Gamma=2.0, tau=0.5), dict(Gamma=2.0, tau=1.0),
                                                           dict(Gamma=3.0, tau=0.5), dict(Gamma=3.0, tau=1.0)]
    assert sweep.grid(Gamma=np.array([[1.0, 2.0], [3.0, 4.0]])) == [dict(Gamma=g) for g in (1.0, 2.0, 3.0, 4.0)]
    with pytest.raises(ValueError, match=r"^sweep axes must be among \['Gamma', .*\] \(got \['Gama'\]\)"):
        sweep.grid(Gamma=[1.0], Gama=[2.0])
    with pytest.raises(ValueError, match=r"^sweep axis Gamma must be a list of numbers \(got \{'a': 1\}\)"):
        sweep.grid(Gamma={"a": 1})


def test_a_refusal_of_six_points_names_them_all_with_their_first_clauses(tmp_path, calls):
    """6 of 7 points refused (max_work, as in test_sweep.py): the first with its whole reason and its point,
    the other 5 (MAX_NAMED) each with its point and its reason up to the first colon, and no 'and 0 more'.
    Mutants: 'and N more' from N >= MAX_NAMED; the others' reasons left out; the others' reasons in full;
    the first point not named."""
    pts = [dict(Gamma=g, tau=2.0) for g in (0.5, 0.51, 0.52, 0.53, 0.54, 0.55)] + [dict(Gamma=5.0)]
    with pytest.raises(ValueError, match=r"^6 of 7 sweep points are refused\. max_work must be >= ") as e:
        sweep.run_sweep(pts, str(tmp_path / "s.jsonl"), n_excursions=100)
    msg = str(e.value)
    assert "more" not in msg and msg.count("excursions of predicted mean duration") == 1 and calls == []
    head, also = msg.split(". Also refused: ")
    assert '[at sweep point {"Gamma": 0.5, ' in head
    also, tail = also.split(".  Nothing was run; ")
    named = also.split("; ")
    assert len(named) == 5 and tail.startswith("--skip-refused records the refused points")
    for g, part in zip((0.51, 0.52, 0.53, 0.54, 0.55), named):
        assert part.startswith('{"Gamma": %s, ' % g) and "} (max_work must be >= " in part
        assert part.endswith(" for these parameters (got 1e+11))")


def test_max_time_inf_is_no_limit_and_is_not_recorded(tmp_path, calls):
    """max_time = inf is no limit, "as recorded": the record has no max_time, like one made without it, and
    a resume without a limit finds the point done.  Mutant: inf kept (each record carried max_time = inf)."""
    out = str(tmp_path / "s.jsonl")
    assert sweep.run_sweep(sweep.grid(Gamma=[2.0]), out, max_time=math.inf, **KW)["computed"] == 1
    (rec,) = _lines(out)
    assert "max_time" not in rec and rec["status"] == "ok"
    assert sweep.run_sweep(sweep.grid(Gamma=[2.0]), out, **KW)["skipped"] == 1 and len(calls) == 1


def test_a_stopped_record_without_its_max_time_is_kept_not_an_error(tmp_path, calls):
    """A hand-edited record stopped by max_time without the max_time it had: with a limit now, it is not known
    to get more time and is kept (not a TypeError comparing a number with None); without a limit it is rerun.
    Mutant: the old max_time compared without checking that it is a number."""
    rec = _rec("ok", 5.0, result=dict(RESULT, stopped_by="max_time"))
    assert "max_time" not in rec
    out = _file(tmp_path, rec)
    r = sweep.run_sweep(sweep.grid(Gamma=[5.0]), out, max_time=5.0, **KW)
    assert (r["computed"], r["skipped"], r["time_limited"]) == (0, 1, 1) and _lines(out) == [rec]
    assert sweep.run_sweep(sweep.grid(Gamma=[5.0]), out, **KW)["computed"] == 1



def test_only_a_projection_warning_is_shown_with_its_point(tmp_path, monkeypatch, calls):
    """A point's warnings are kept in its record, not shown; a ProjectionWarning is shown at once with the
    point appended.  Mutants: the points' own warnings shown; the point not appended."""
    stand_in = sweep.estimate_diffusivity

    def warns(p, seed, **kw):
        warnings.warn("a point's own warning", DryfricWarning)
        warnings.warn("max_work will end this point", ProjectionWarning)
        return stand_in(p, seed, **kw)

    monkeypatch.setattr(sweep, "estimate_diffusivity", warns)
    with warnings.catch_warnings(record=True) as got:
        warnings.simplefilter("always")
        sweep.run_sweep(sweep.grid(Gamma=[2.0]), str(tmp_path / "s.jsonl"), **KW)
    assert len(got) == 1 and got[0].category is ProjectionWarning
    assert str(got[0].message).startswith('max_work will end this point [at sweep point {"Gamma": 2.0, "Delta": ')


def test_a_record_holds_the_result_without_its_params_and_seed(tmp_path, calls):
    """The record's seed and params are the point's, at the top level; the result (what combine and rows read)
    does not repeat them.  Mutant: the result's seed kept."""
    out = str(tmp_path / "s.jsonl")
    sweep.run_sweep(sweep.grid(Gamma=[2.0]), out, **KW)
    (rec,) = _lines(out)
    assert rec["seed"] == calls[0][1] and "seed" not in rec["result"] and "params" not in rec["result"]


def test_rows_fill_reason_and_stopped_by_with_empty_text(tmp_path):
    """rows: ``reason`` and ``stopped_by`` are "" where the record has none (an "ok" point, an older record
    whose result does not say), and a record without an asked setting does not match it (a record of an
    older version, hand-written).  Mutants: None for a missing reason or stopped_by; a KeyError for a record
    without the asked setting."""
    ok = _rec("ok", 5.0)
    refused = _rec("refused", 6.0, reason="max_work must be >= 1e12: stand-in")
    bare = dict(_rec("ok", 7.0), settings={"method": "di"}, version="0.1.0")
    out = _file(tmp_path, ok, refused, bare)
    got = [(x["Gamma"], x["status"], x["reason"], x["stopped_by"]) for x in sweep.rows(out)]
    assert got == [(5.0, "ok", "", ""), (6.0, "refused", refused["reason"], ""), (7.0, "ok", "", "")]
    assert [x["Gamma"] for x in sweep.rows(out, n_excursions=50)] == [5.0, 6.0]
    assert [x["Gamma"] for x in sweep.rows(out, method="di")] == [5.0, 6.0, 7.0]


def test_rows_say_what_stopped_the_count(tmp_path):
    """``le_stopped_by``: the count's own (``max_time`` stopped it at 15 of 32 while the D ran to its N: the row
    said ``stopped_by`` "n_excursions" with a finite ``le_duration``, and nothing flagged it: a sweep audit); ""
    without a count (a refused point here)."""
    le = dict(mean=0.5, ci=0.1, n_excursions=15, n_truncated=0, h=1e-4, stopped_by="max_time")
    timed = sweep._record(0, {**FIG3, "Gamma": 5.0}, {**SETTINGS, "durations": 32}, "ok", None, result=dict(RESULT),
                          durations=le)
    out = _file(tmp_path, timed, _rec("refused", 6.0, reason="stand-in"))
    got = [(x["Gamma"], x["stopped_by"], x["le_stopped_by"], x["le_n_excursions"]) for x in sweep.rows(out)]
    assert got[0] == (5.0, "", "max_time", 15) and got[1][2] == ""


def _bar(n):
    return "[" + "#" * n + "." * (30 - n) + "]"


def test_the_progress_bar_lines(capsys, monkeypatch):
    """Not a terminal: one line per point, none at the start.  A terminal: one line rewritten in place (each
    "\\r", the rest of the row cleared), ended by a newline once done = total, an empty grid (0 of 0) included.
    Worked by hand: 1 of 2 fills 15 of 30; D = 1.23456 +- 0.0123 is shown as 1.235+-0.012.  Mutants: a line
    at the start off a terminal; no newline at the end on a terminal; a ZeroDivisionError at 0 of 0; tau
    not shown."""
    ok = _rec("ok", 5.0, result=dict(RESULT, D=1.23456, D_ci=0.0123))
    failed = _rec("failed", 5.0, 2.0, reason="fewer than 2 complete excursions within max_time (raise it): 1 of 50",
                  stopped_by="max_time")
    ok_line = _bar(15) + " 1/2 points  Gamma=5 tau=0.5: D=1.235\u00b10.012"
    failed_line = (_bar(30) + " 2/2 points  Gamma=5 tau=0.5: failed (fewer than 2 complete excursions within "
                   "max_time (raise it)) [stopped by max_time]")
    monkeypatch.setattr(sys.stderr, "isatty", lambda: False)
    sweep.progress_bar(0, 2, None)
    sweep.progress_bar(1, 2, ok)
    sweep.progress_bar(2, 2, failed)
    assert capsys.readouterr().err == ok_line + "\n" + failed_line + "\n"
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True)
    sweep.progress_bar(0, 0, None)
    sweep.progress_bar(1, 2, ok)
    sweep.progress_bar(2, 2, ok)
    done = _bar(30) + " 2/2 points  Gamma=5 tau=0.5: D=1.235\u00b10.012"
    assert capsys.readouterr().err == ("\r" + _bar(0) + " 0/0 points\x1b[K\n" + "\r" + ok_line + "\x1b[K"
                                       + "\r" + done + "\x1b[K\n")


def test_the_line_within_a_point(capsys, monkeypatch):
    """While a point runs (``run_sweep``'s ``point_progress``), the bar's line says where its D estimate or its
    count is: on a terminal only, rewritten in place and never ended (the point's own line follows).  Worked by
    hand: D = 1.23456e-5 +- 3.4567e-7 is 2.8%; 1 of 4 fills 7 of 30.  Mutants: a line off a terminal; the time left
    shown while the count finishes; max_time not named; nan shown before a D; the rtol target not shown."""
    d = dict(stage="D", n_excursions=1200, D=1.23456e-5, D_ci=3.4567e-7, target=20000, rtol=None, elapsed_s=12.0,
             left_s=30.0, left_to="n_excursions", params=dict(FIG3, Gamma=5.0, tau_L=0.067), done=1, total=4)
    le = dict(stage="durations", n_excursions=40, target=2048, in_flight=12, mean_s=4.25, stopping=False,
              elapsed_s=3.0, left_s=None, left_to=None, params=d["params"], done=1, total=4)
    monkeypatch.setattr(sys.stderr, "isatty", lambda: False)
    sweep.point_line(d)
    assert capsys.readouterr().err == ""
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True)

    def line(base, axes=("Gamma", "tau"), **kw):
        sweep.point_line({**base, **kw}, axes=axes)
        err = capsys.readouterr().err
        assert err.startswith("\r" + _bar(7) + " 1/4 points  Gamma=5 tau=0.5") and err.endswith("\x1b[K")
        return err[:-3]

    assert line(d).endswith(": D=1.235e-05\u00b12.8% N=1200 of 20000, ~30 s left [12 s]")
    assert line(d, left_s=None).endswith(": D=1.235e-05\u00b12.8% N=1200 of 20000 [12 s]")
    assert line(d, rtol=0.01, left_to="max_time").endswith(" N=1200 (target 1%), ~30 s left (stops at max_time) [12 s]")
    assert line(d, D=math.nan, D_ci=math.nan).endswith(": D=\u2013 N=1200 of 20000, ~30 s left [12 s]")
    assert " tau_L=0.067: D=" in line(d, axes=("Gamma", "tau", "tau_L"))
    assert line(le).endswith(": LE=4.25s so far, 40 of 2048, 12 in flight [3 s]")  # no projection: those in flight
    assert line(le, in_flight=0).endswith(": LE=4.25s so far, 40 of 2048 [3 s]")
    assert line(le, left_s=95.0, left_to="max_work").endswith(" 40 of 2048, ~1.6 min left (stops at max_work) [3 s]")
    assert line(le, stopping=True, left_s=9.0).endswith(" 40 of 2048, finishing the 12 in flight [3 s]")
    assert line(le, stopping=True, in_flight=0).endswith(" 40 of 2048, done [3 s]")
    assert line(le, n_excursions=0, mean_s=math.nan).endswith(": LE=\u2013 so far, 0 of 2048, 12 in flight [3 s]")


def test_the_progress_bar_names_every_axis_that_varies(capsys, monkeypatch):
    """A grid over tau_L and gamma_bar: each line shows them beside Gamma and tau (every line read
    "Gamma=5 tau=0.001" before); an axis with one value, or none given, is not shown."""
    monkeypatch.setattr(sys.stderr, "isatty", lambda: False)
    points = sweep.grid(tau=[0.001], tau_L=[math.inf, 0.067], gamma_bar=[-0.342, 0.342], Delta=[3.84])
    bar = sweep.progress_bar_for(points)
    rec = _rec("ok", 5.0, result=dict(RESULT, D=1.23456, D_ci=0.0123))
    rec["params"] = dict(rec["params"], tau=0.001, tau_L=math.inf, gamma_bar=-0.342)
    bar(1, 4, rec)
    assert capsys.readouterr().err.endswith(" 1/4 points  Gamma=5 tau=0.001 tau_L=inf gamma_bar=-0.342: D=1.235\u00b10.012\n")
    sweep.progress_bar_for(sweep.grid(Gamma=[1, 2]))(1, 2, rec)
    assert capsys.readouterr().err.endswith(" 1/2 points  Gamma=5 tau=0.001: D=1.235\u00b10.012\n")


def test_a_setting_beyond_float_range_refuses_the_file_by_line(tmp_path, capsys):
    """DEFECT (fixed in sweep._check_record): a hand-edited setting that is an integer beyond float range (n_excursions = 10**400)
    was read as a sweep record, then made an OverflowError traceback where the point's identity is made (the
    case _is_real was written for, for the parameters only).  It is the file's refusal now, exit 2, the file
    left as it is, nothing run."""
    rec = _rec("ok", 5.0)
    rec["settings"]["n_excursions"] = 10**400
    out = tmp_path / "s.jsonl"
    text = json.dumps(rec) + "\n"
    out.write_text(text)
    with pytest.raises(ValueError, match=r"line 1 is not a sweep record"):
        sweep.read_results(str(out))
    from dryfric_jax.cli import main

    assert main(["sweep", "--Gamma", "6", "--n-excursions", "50", "--out", str(out)]) == 2
    assert "--out must be a dryfric sweep file (JSON Lines)" in capsys.readouterr().err and out.read_text() == text


def test_a_point_recorded_twice_keeps_one_record_on_resume(tmp_path, calls):
    """A hand-edited file holding one record twice was resumed with both kept, and rows() listed the point twice
    (an audit); the resume keeps one, the finished one where the other would be rerun (keeping the first whatever
    it was dropped a finished record for an old version's: a review), says so, and computes nothing."""
    out = str(tmp_path / "s.jsonl")
    assert sweep.run_sweep(sweep.grid(Gamma=[2.0, 3.0]), out, **KW)["computed"] == 2
    first, second = _lines(out)
    outfiles.write_records(out, [{**first, "version": "0.0.1"}, second, first, {**second, "note": "edited"}])
    with pytest.warns(DryfricWarning, match=r"held 2 records of points recorded already .* kept one record per point"):
        r = sweep.run_sweep(sweep.grid(Gamma=[2.0, 3.0]), out, **KW)
    assert (r["computed"], r["skipped"]) == (0, 2) and len(calls) == 2
    assert _lines(out) == [second, first] and len(sweep.rows(out)) == 2


def test_rows_of_a_file_holding_a_point_twice_list_it_once(tmp_path, calls):
    """rows() listed a point recorded twice twice until a resume rewrote the file (a review); it lists it once, the
    record a resume would keep, and says so."""
    out = str(tmp_path / "s.jsonl")
    sweep.run_sweep(sweep.grid(Gamma=[2.0]), out, **KW)
    (first,) = _lines(out)
    outfiles.write_records(out, [{**first, "version": "0.0.1"}, first])
    with pytest.warns(DryfricWarning, match="held 1 record of points recorded already"):
        (row,) = sweep.rows(out)
    assert row["D"] == first["result"]["D"] and len(_lines(out)) == 2  # read only
