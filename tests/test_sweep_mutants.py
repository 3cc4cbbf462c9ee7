"""Sweep bookkeeping, from a mutation audit of dryfric_jax/sweep.py and the parts of outfiles.py it uses.

The estimator is replaced by a cheap deterministic stand-in that records each call (the point's
parameters and the seed it was given): the tests check which points a sweep runs, with which seed,
and what its file and tables then hold, not the numbers.  The mutants named in each docstring are
single edits of the package that the test fails on (and that the other sweep tests let through)."""
import dataclasses
import json
import math
import os
import types

import numpy as np
import pytest

import dryfric_jax as dj
from dryfric_jax import outfiles, sweep
from dryfric_jax.api import NoEstimateError
from dryfric_jax.estimators import psi_D, psi_M
from dryfric_jax.excursions import STAT_NAMES
from dryfric_jax.cli import main
from dryfric_jax.params import FIG3, Params

KW = dict(n_excursions=50)


def stand_in_result(point=None, seed=0, n=10, **extra):
    """A stand-in result at the parameters ``point`` (Fig. 3's by default) whose D, M0 and n_excursions are those
    of its sums, as a record of this version must have (sweep._agrees_with_sums); the sums' U^2 moves with
    ``seed``, and D with it."""
    sums = {**{k: 1.0 for k in STAT_NAMES}, "n": n, "t": 5.0, "U2": 1.0 + seed / 2**31}
    p = Params(**{**FIG3, **(point or {})})
    x = np.array([sums[k] for k in ("U", "U2", "t", "Ut", "t2")]) / sums["n"]
    return {**dict(D=float(psi_D(x)) * p.D0, D_ci=0.1, M0=float(psi_M(x)) * p.v0, M0_ci=0.05, n_truncated=0,
                   n_excursions=n, sums=sums), **extra}


def _lines(path):
    with open(path) as f:
        return [json.loads(x) for x in f if x.strip()]


@pytest.fixture
def calls(monkeypatch):
    """The stand-in estimator: each call's (parameters, seed) is appended; a point with Gamma = 3 ends
    without an estimate (NoEstimateError), as a point past its work bounds does."""
    got = []

    def estimate(p, seed, **kw):
        got.append((p.as_dict(), seed))
        if p.Gamma == 3.0:
            raise NoEstimateError("fewer than 2 complete excursions within the work bounds (stand-in)")
        res = {**stand_in_result(p.as_dict(), seed, kw["n_excursions"]),
               **dict(mean_duration=1.0, method=kw["method"], params={}, stopped_by="n_excursions", seed=seed)}
        return types.SimpleNamespace(stopped_by="n_excursions", to_dict=lambda: dict(res))

    monkeypatch.setattr(sweep, "estimate_diffusivity", estimate)
    return got


def test_every_parameter_to_full_precision_is_part_of_a_points_identity_and_seed(tmp_path, calls):
    """Six points, the Fig. 3 one and five that each differ from it in one parameter, in the 10th
    significant digit: six points run, each with its own seed (the one its record names), and a
    resumed sweep runs none.  Another sweep seed gives six other seeds.
    Mutants: gamma_bar left out of a point's identity (the gamma_bar point was taken for the Fig. 3
    one, its record reused); parameters compared to 6 significant digits (all six one point);
    the estimator given the sweep seed instead of the point's (every point the same random stream,
    the records naming seeds that were not used); point_seed not depending on the point."""
    out = str(tmp_path / "s.jsonl")
    pts = [dict(FIG3)] + [{**FIG3, k: FIG3[k] * (1 + 1e-9)} for k in sweep.PARAM_KEYS]
    r = sweep.run_sweep(pts, out, seed=0, **KW)
    assert (r["computed"], r["skipped"], r["total"]) == (6, 0, 6)
    assert [p for p, _ in calls] == pts
    seeds = [s for _, s in calls]
    assert len(set(seeds)) == 6
    recs = _lines(out)
    assert [(x["params"], x["seed"]) for x in recs] == list(zip(pts, seeds))
    calls.clear()
    r = sweep.run_sweep(pts, out, seed=0, **KW)
    assert (r["computed"], r["skipped"], calls) == (0, 6, [])
    r = sweep.run_sweep(pts, out, seed=1, **KW)
    assert r["computed"] == 6 and len({s for _, s in calls}) == 6 and not {s for _, s in calls} & set(seeds)


def test_a_record_of_another_patch_version_or_of_no_version_is_rerun_in_place(tmp_path, calls):
    """The version is raised with every change to the numbers a seed gives (dryfric_jax._version),
    the patch number too; a record without a version predates versions.  Both are rerun and replaced
    in place (not reused, not doubled).  Mutants: _outdated comparing major.minor only; a record
    without a version taken as this version's; _outdated ignoring the version."""
    out = str(tmp_path / "s.jsonl")
    pts = sweep.grid(Gamma=[2.0, 4.0])
    sweep.run_sweep(pts, out, **KW)
    first = _lines(out)
    major, minor, patch = dj.__version__.split(".")[:3]
    old = [dict(first[0], version=f"{major}.{minor}.{int(patch) + 1}"), {k: v for k, v in first[1].items()
                                                                          if k != "version"}]
    outfiles.write_records(out, old)
    calls.clear()
    r = sweep.run_sweep(pts, out, **KW)
    assert (r["computed"], r["skipped"]) == (2, 0) and len(calls) == 2
    again = _lines(out)
    assert [x["params"]["Gamma"] for x in again] == [2.0, 4.0]
    assert [x["version"] for x in again] == [dj.__version__] * 2
    assert [x["seed"] for x in again] == [x["seed"] for x in first]  # the same points, the same seeds


def test_a_sweep_checks_each_record_of_its_file_once_and_appends_new_points(tmp_path, calls, monkeypatch):
    """A sweep reads its file before and after each point (another sweep may share it); it used to parse, check and
    rewrite every record each time, ~1 s a point at 10^4 records.  Now each record is checked once per sweep, a new
    point is appended (the file is not replaced), and a rerun point's record is still replaced in place.  Records of
    the same parameters with other settings, or of another sweep seed, are not taken for the point (sweep._of_point
    compares the parameters before the identity)."""
    out = tmp_path / "s.jsonl"
    sweep.run_sweep(sweep.grid(Gamma=[2.0, 4.0, 5.0, 6.0]), str(out), **KW)
    sweep.run_sweep(sweep.grid(Gamma=[4.0]), str(out), **{**KW, "n_excursions": KW["n_excursions"] + 1})
    sweep.run_sweep(sweep.grid(Gamma=[4.0]), str(out), seed=1, **KW)
    old = _lines(out)
    major, minor, patch = dj.__version__.split(".")[:3]
    old[0]["version"] = f"{major}.{minor}.{int(patch) + 1}"  # Gamma = 2: rerun and replaced
    outfiles.write_records(str(out), old)
    checked, real = [], sweep._check_record
    monkeypatch.setattr(sweep, "_check_record", lambda rec: (checked.append(rec["params"]["Gamma"]), real(rec)))
    inos = []  # the file's, after the sweep's first rewrite (before any point) and after each point
    calls.clear()
    new = sweep.grid(Gamma=[7.0, 8.0, 9.0])
    r = sweep.run_sweep(sweep.grid(Gamma=[4.0]) + new, str(out), progress=lambda *a: inos.append(os.stat(out).st_ino),
                        **KW)
    assert (r["computed"], r["skipped"], len(calls)) == (3, 1, 3)
    assert len(inos) == 4 and len(set(inos)) == 1
    assert sorted(checked) == sorted([x["params"]["Gamma"] for x in old] + [7.0, 8.0])  # 9.0 written last, not read
    assert _lines(out) == old + _lines(out)[len(old):] and [x["params"]["Gamma"] for x in _lines(out)[len(old):]] == \
        [7.0, 8.0, 9.0]
    checked.clear()
    inos.clear()  # the rerun point's record replaces its old one: the file is rewritten (a new file renamed over it,
    # made while the old one exists, so a new inode; one freed earlier may be reused: compared within the sweep)
    r = sweep.run_sweep(sweep.grid(Gamma=[2.0]) + new, str(out), progress=lambda *a: inos.append(os.stat(out).st_ino),
                        **KW)
    assert (r["computed"], r["skipped"]) == (1, 3) and len(inos) == 2 and inos[0] != inos[1]
    got = _lines(out)
    assert len(got) == len(old) + 3 and (got[0]["params"]["Gamma"], got[0]["version"]) == (2.0, dj.__version__)
    assert [(x["params"]["Gamma"], x["sweep_seed"], x["settings"]["n_excursions"]) for x in got[1:len(old)]] == \
        [(x["params"]["Gamma"], x["sweep_seed"], x["settings"]["n_excursions"]) for x in old[1:]]


def test_a_record_without_a_status_is_a_finished_point(tmp_path, calls):
    """Records written before statuses existed are "ok" (module docstring): read, tabled as "ok", not
    listed by failures() and not rerun.  Mutant: status() defaulting to "failed" (the file was then
    refused as not a sweep file: a "failed" record needs a reason)."""
    out = str(tmp_path / "s.jsonl")
    sweep.run_sweep(sweep.grid(Gamma=[2.0]), out, **KW)
    (rec,) = _lines(out)
    rec.pop("status")
    outfiles.write_records(out, [rec])
    assert [x["status"] for x in sweep.rows(out)] == ["ok"] and sweep.failures(out) == []
    calls.clear()
    r = sweep.run_sweep(sweep.grid(Gamma=[2.0]), out, **KW)
    assert (r["computed"], r["skipped"], calls) == (0, 1, [])


def test_rows_keep_the_asked_seed_and_every_asked_setting_sorted_by_all_parameters(tmp_path, calls):
    """One file, three sweeps of the same 2 x 2 grid: seed 0 and seed 1 at n_excursions = 50 (float64),
    and seed 0 at n_excursions = 60 in float32.  rows(seed=0) is the 8 records of seed 0 (seed 0 is a
    seed, not "any"); two settings keep the records matching both; the rows are sorted by Gamma, then
    tau.  Mutants: ``seed and ...`` for ``seed is not None and ...`` (rows(seed=0) returned every seed);
    ``all`` for ``any`` in the settings filter (a record matching one asked setting of two was kept);
    rows sorted by Gamma alone (tau in file order)."""
    out = str(tmp_path / "s.jsonl")
    pts = sweep.grid(Gamma=[2.0, 1.0], tau=[0.5, 0.25])
    for seed, kw in ((0, KW), (1, KW), (0, dict(n_excursions=60, dtype="float32"))):
        sweep.run_sweep(pts, out, seed=seed, **kw)
    assert len(_lines(out)) == 12
    assert len(sweep.rows(out, seed=0)) == 8 and len(sweep.rows(out, seed=1)) == 4
    assert sweep.rows(out, n_excursions=50, dtype="float32") == []
    both = sweep.rows(out, n_excursions=60, dtype="float32")
    assert len(both) == 4 and {x["n_excursions"] for x in both} == {60}
    assert [(x["Gamma"], x["tau"]) for x in sweep.rows(out, seed=1)] == [(1.0, 0.25), (1.0, 0.5), (2.0, 0.25),
                                                                         (2.0, 0.5)]


def test_progress_counts_the_points_already_in_the_file(tmp_path, calls):
    """A resumed sweep of 3 points, 2 of them in the file: progress says 2 of 3 at the start and 3 of 3
    after the new point (the bar ends full).  Mutants: the points computed now passed as done (1 of 3 at
    the end); done counted from 0 (also caught by test_sweep.py, through the skipped count)."""
    out = str(tmp_path / "s.jsonl")
    sweep.run_sweep(sweep.grid(Gamma=[2.0, 4.0]), out, **KW)
    seen = []
    sweep.run_sweep(sweep.grid(Gamma=[2.0, 4.0, 5.0]), out, progress=lambda d, t, rec: seen.append((d, t)), **KW)
    assert seen == [(2, 3), (3, 3)]


def test_a_point_listed_twice_is_one_point_in_the_counts(tmp_path, calls):
    """A failed point listed twice in the grid runs once and is one failed point (the CLI says
    "1 point failed"), on the first run and on a resume.  Mutant: the counts over the grid's
    entries instead of its distinct points (2 failed)."""
    out = str(tmp_path / "s.jsonl")
    pts = sweep.grid(Gamma=[3.0, 3.0, 2.0])
    r = sweep.run_sweep(pts, out, **KW)
    assert (r["computed"], r["failed"], len(calls)) == (2, 1, 2)
    assert [x["status"] for x in _lines(out)] == ["failed", "ok"]
    assert sweep.run_sweep(pts, out, **KW)["failed"] == 1


def test_a_repeated_point_is_not_counted_as_already_in_the_file(tmp_path, calls, capsys):
    """A fresh file and the grid Gamma = 2, 4, 4, 4: two points run, none was in the file, two
    distinct points and two repeated entries; the CLI's summary line says so.  Before, the repeats
    were counted as points "already in" the file and in the grid's size (2 computed, 2 already in,
    4 in the grid, on a file that did not exist)."""
    out = str(tmp_path / "s.jsonl")
    seen = []
    r = sweep.run_sweep(sweep.grid(Gamma=[2.0, 4.0, 4.0, 4.0]), out, progress=lambda d, t, rec: seen.append((d, t)),
                        **KW)
    assert (r["computed"], r["skipped"], r["total"], r["duplicates"], len(calls)) == (2, 0, 2, 2, 2)
    assert seen == [(0, 2), (1, 2), (2, 2)]
    r = sweep.run_sweep(sweep.grid(Gamma=[4.0, 2.0, 2.0]), out, **KW)
    assert (r["computed"], r["skipped"], r["total"], r["duplicates"], len(calls)) == (0, 2, 2, 1, 2)
    assert main(["sweep", "--Gamma", "2,2,6", "--n-excursions", "50", "--out", out]) == 0
    said = capsys.readouterr().out
    assert f"1 point computed, 1 already in {out}, 2 in the grid (and 1 repeated, run once)" in said


def test_minus_zero_is_the_point_zero(tmp_path, calls):
    """gamma_bar = -0.0 is the point gamma_bar = 0: one run, one record (written as 0.0), one seed,
    and a resume with +0.0 finds it.  Before, -0.0 and 0.0 were two points of the same physics, each
    run with its own seed."""
    out = str(tmp_path / "s.jsonl")
    r = sweep.run_sweep(sweep.grid(gamma_bar=[-0.0, 0.0]), out, **KW)
    assert (r["computed"], r["total"], r["duplicates"], len(calls)) == (1, 1, 1, 1)
    (rec,) = _lines(out)
    assert math.copysign(1.0, rec["params"]["gamma_bar"]) == 1.0
    assert rec["seed"] == sweep.point_seed(0, {**FIG3, "gamma_bar": 0.0}, rec["settings"]) == calls[0][1]
    assert sweep.run_sweep(sweep.grid(gamma_bar=[0.0]), out, **KW)["skipped"] == 1 and len(calls) == 1


@pytest.mark.parametrize("fail", ["fsync", "replace"])
def test_a_write_that_fails_leaves_the_old_file_whole_and_no_temporary_file(tmp_path, monkeypatch, fail):
    """A results file rewritten when the disk is full (fsync fails) or the rename fails: the old file
    is left as it was, and the temporary file is removed.  Mutants: write_atomic writing into the
    file itself (a kill or a full disk left it truncated or torn); the temporary file not removed
    after a failure (a .dryfric-*.tmp left beside the results on every failed write)."""
    out = tmp_path / "s.jsonl"
    out.write_text("old\n")

    def boom(*a, **k):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(outfiles.os, fail, boom)
    with pytest.raises(OSError, match="No space left"):
        outfiles.write_atomic(str(out), "new\n")
    monkeypatch.undo()
    assert out.read_text() == "old\n" and os.listdir(tmp_path) == ["s.jsonl"]


def test_an_identity_tells_minus_inf_from_inf():
    """A point's identity writes a number as the repr of its float, so tau_L = -inf (refused by Params
    before any identity is made) can never share the identity, and so the seed and record, of tau_L =
    inf.  The old special case wrote both 'inf'."""
    ident = lambda tau_L: sweep._ident(0, {**FIG3, "tau_L": tau_L}, {})  # noqa: E731
    assert ident(-math.inf) != ident(math.inf)
    assert json.loads(ident(math.inf))[1]["tau_L"] == "inf"


@pytest.fixture
def whole(calls, monkeypatch):
    """The stand-in estimator (``calls``) with the fields combine needs of a result too."""
    part = sweep.estimate_diffusivity

    def estimate(p, seed, **kw):
        r = part(p, seed, **kw)
        d = dict(r.to_dict(), h=0.00067, dtype="float64", wall_s=1.0, lane_steps_per_s=1e6)
        return types.SimpleNamespace(stopped_by=r.stopped_by, to_dict=lambda: dict(d))

    monkeypatch.setattr(sweep, "estimate_diffusivity", estimate)
    return calls


def test_combine_checks_sweep_records_as_the_sweep_reads_them(tmp_path, whole, capsys):
    """combine pooled a hand-edited sweep record as it stood (tau moved to another point's, D tripled), which the
    sweep's own reader refuses; and refused a whole file whose last line a kill had cut short, which the sweep
    reads without it (an audit).  Now a record is checked as the sweep checks it (exit 2 naming its line), and a
    line cut short is skipped with a warning."""
    out = tmp_path / "s.jsonl"
    sweep.run_sweep(sweep.grid(tau=[0.5, 0.4]), str(out), **KW)
    sweep.run_sweep(sweep.grid(tau=[0.5]), str(out), seed=1, **KW)
    recs = _lines(out)
    good = dj.combine_estimates([recs[0], recs[2]])
    for edit in (lambda r: r["params"].update(tau=0.5), lambda r: r["result"].update(D=3 * r["result"]["D"])):
        bad = json.loads(json.dumps(recs[1]))
        edit(bad)
        with pytest.raises(ValueError, match=r"results\[1\] is not a sweep record as a sweep writes it"):
            dj.combine_estimates([recs[0], bad])
        edited = tmp_path / "e.jsonl"
        edited.write_text(json.dumps(recs[2]) + "\n" + json.dumps(bad) + "\n")
        assert main(["combine", str(edited)]) == 2
        assert f"{edited}:2 is not a sweep record" in capsys.readouterr().err
    cut = tmp_path / "cut.jsonl"
    text = out.read_text().splitlines()
    cut.write_text(text[0] + "\n" + text[2] + "\n" + text[1][:300])
    assert main(["combine", str(cut), "--json"]) == 0
    said = capsys.readouterr()
    got = json.loads(said.out)
    assert (got["D"], got["n_excursions"]) == (good.D, good.n_excursions)
    assert f"dryfric: warning: {cut} line 3 is a record whose write was cut short" in said.err  # not kept silent


def test_combine_names_the_runs_that_share_a_seed_and_shortens_a_long_list_of_seeds(tmp_path, whole, capsys):
    """A seed used twice was refused without saying which runs, a derived sweep seed the user never typed (an
    audit); a pool of 3000 records printed all their seeds on one line.  Sweeps with the same seed on two hosts, one
    given a count (durations), are one D: the note names both records."""
    a, b = tmp_path / "a.jsonl", tmp_path / "b.jsonl"
    sweep.run_sweep(sweep.grid(Gamma=[2.0]), str(a), **KW)
    sweep.run_sweep(sweep.grid(Gamma=[2.0]), str(b), **KW)
    assert main(["combine", str(a), str(b)]) == 2
    err = capsys.readouterr().err
    assert f"used by {a} and by {b})" in err, err  # a one-line file is one result, named by the file
    rec = dict(_lines(a)[0], settings={**_lines(a)[0]["settings"], "durations": 64},
               durations=dict(reason="stand-in: no count"))
    rec["seed"] = sweep.point_seed(0, rec["params"], rec["settings"])
    b.write_text(json.dumps(rec) + "\n")
    with pytest.warns(dj.DryfricWarning, match=r"the first: results\[1\] repeats results\[0\].*another --seed"):
        dj.combine_estimates(_lines(a) + _lines(b))
    pool = dataclasses.replace(dj.combine_estimates(_lines(a)), combined_from=list(range(3000)))
    line = next(ln for ln in pool.summary().splitlines() if "seeds" in ln)
    assert line.endswith("seeds [0, 1, 2, 3, 4, 5, ...] (3000 runs)") and len(line) < 200
