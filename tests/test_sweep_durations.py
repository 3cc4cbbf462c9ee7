"""A sweep's long-excursion durations: ``run_sweep(durations=N)``, ``dryfric sweep --durations N``.

The count itself is tested against the PDMP and for coverage in ``test_durations.py``; here: that a sweep's
numbers are the direct count's to the bit, that they leave the D (and the identities and seeds of sweeps without
them) as they were, and how a point without a count is refused, recorded and shown."""
import json
import math
import os
import re

import pytest

import dryfric_jax as dj
from dryfric_jax import sweep
from dryfric_jax.cli import main


def _lines(path):
    with open(path) as f:
        return [json.loads(x) for x in f if x.strip()]


def test_durations_are_the_direct_count_and_leave_the_d_as_it_was(tmp_path, monkeypatch, capsys):
    pts = sweep.grid(Gamma=[5.0, 10.0], tau=[0.125])
    kw = dict(n_excursions=200, seed=3)
    plain_out, out = str(tmp_path / "plain.jsonl"), str(tmp_path / "s.jsonl")
    sweep.run_sweep(pts, plain_out, **kw)
    plain = _lines(plain_out)
    # from scratch: the D is the sweep's without durations (its seed does not depend on them)
    seen = []  # within each point: its D estimate's rounds, then its count's pieces (and the same bits)
    r = sweep.run_sweep(pts, out, durations=64, progress=sweep.progress_bar, point_progress=seen.append, **kw)
    assert (r["computed"], r["total"], r["truncated"]) == (2, 2, 0)
    assert "LE=" in capsys.readouterr().err  # the progress line shows the count
    recs = _lines(out)
    for i, rec in enumerate(recs):
        mine = [d for d in seen if d["params"] == rec["params"]]
        stages = [d["stage"] for d in mine]
        assert stages == sorted(stages) and stages[0] == "D" and stages[-1] == "durations", stages
        assert {(d["done"], d["total"]) for d in mine} == {(i, 2)}
        ns = [d["n_excursions"] for d in mine if d["stage"] == "D"]  # after each round (not the last, that
        assert ns == sorted(ns) and ns[-1] <= rec["result"]["n_excursions"]  # finishes those in flight)
        assert {d["target"] for d in mine if d["stage"] == "D"} == {200}
        assert (mine[-1]["n_excursions"], mine[-1]["target"]) == (rec["durations"]["n_excursions"], 64)
    assert seen == sorted(seen, key=lambda d: d["done"])  # the first point's, then the second's
    for rec, old in zip(recs, plain):
        assert rec["result"]["sums"] == old["result"]["sums"] and rec["seed"] == old["seed"]
        assert rec["settings"] == {**old["settings"], "durations": 64}
        le, p = rec["durations"], dj.Params(**rec["params"])
        assert le["seed"] == sweep.duration_seed(3, rec["params"], rec["settings"]) != rec["seed"]
        assert le["h"] == dj.default_duration_h(p) and le["bridge"] and le["n_requested"] == 64
        # the loop's bound planned from the D estimate's mean cycle, as Fig. 3's (in whole blocks of 128 steps)
        assert le["max_steps"] == -(-dj.durations.max_steps_for(64, rec["result"]["mean_duration"] / le["h"])
                                    // 128) * 128
        direct = dj.di_long_excursion_duration(p, le["seed"], h=le["h"], n_excursions=64, max_steps=le["max_steps"])
        assert (le["mean"], le["ci"], le["n_excursions"], le["n_truncated"]) == (
            direct.mean, direct.ci, direct.n_excursions, 0)
        # the paper's excursion, not the D estimator's cycle (which spans one or more of them)
        assert le["mean"] < rec["result"]["mean_duration"]
    table = sweep.rows(out, durations=64)
    assert [t["le_duration"] for t in table] == [x["durations"]["mean"] for x in recs]
    assert [t["le_n_excursions"] for t in table] == [x["durations"]["n_excursions"] for x in recs]
    assert all(math.isnan(t["le_duration"]) for t in sweep.rows(plain_out))
    assert sweep.rows(out, durations=None) == []

    # added to a finished sweep of this version: only the counts run, the D is the record's
    def not_again(*a, **k):
        raise AssertionError("the D was estimated again")

    monkeypatch.setattr(sweep, "estimate_diffusivity", not_again)
    assert sweep.run_sweep(pts, plain_out, durations=64, **kw)["computed"] == 2
    added = _lines(plain_out)[2:]
    assert [x["result"] for x in added] == [x["result"] for x in plain]
    assert [x["durations"]["mean"] for x in added] == [x["durations"]["mean"] for x in recs]
    # resumed: nothing runs; another N is another point
    assert sweep.run_sweep(pts, out, durations=64, **kw)["computed"] == 0
    assert _lines(out) == recs
    monkeypatch.undo()
    assert sweep.run_sweep(pts[:1], out, durations=96, **kw)["computed"] == 1
    assert _lines(out)[2]["durations"]["seed"] != recs[0]["durations"]["seed"]


def test_a_sweep_run_again_without_durations_takes_the_d_of_a_record_with_them(tmp_path, monkeypatch):
    """The reverse of adding durations to a finished sweep: run again without them, a sweep takes each point's D from
    a record with them (this version's; any N), the bits a fresh sweep without them gives; it estimated every D again
    (stop 94's note).  Not from a record of another version, nor for other settings."""
    pts = sweep.grid(Gamma=[10.0], tau=[0.125])
    kw = dict(n_excursions=200, seed=3)
    out, fresh = str(tmp_path / "s.jsonl"), str(tmp_path / "fresh.jsonl")
    sweep.run_sweep(pts, out, durations=32, **kw)
    (counted,) = _lines(out)
    calls = []
    real = sweep.estimate_diffusivity
    monkeypatch.setattr(sweep, "estimate_diffusivity", lambda *a, **k: calls.append(k) or real(*a, **k))
    assert sweep.run_sweep(pts, out, **kw)["computed"] == 1 and calls == []
    plain = _lines(out)[1]
    assert plain["result"] == counted["result"] and "durations" not in plain
    assert plain["settings"] == {k: v for k, v in counted["settings"].items() if k != "durations"}
    sweep.run_sweep(pts, fresh, **kw)
    assert len(calls) == 1 and _lines(fresh)[0]["result"]["sums"] == plain["result"]["sums"]
    assert plain["seed"] == _lines(fresh)[0]["seed"]
    sweep.run_sweep(pts, out, **{**kw, "n_excursions": 150})  # other settings: estimated
    assert len(calls) == 2
    other = str(tmp_path / "old.jsonl")
    with open(other, "w") as f:
        f.write(json.dumps({**counted, "version": "0.0.1"}) + "\n")
    sweep.run_sweep(pts, other, **kw)  # another version's record: estimated
    assert len(calls) == 3


def test_durations_enter_a_points_identity_but_not_its_d_seed():
    """Without durations a point's identity (and so its seed) is the one sweeps had before the setting existed:
    their files resume as they were."""
    p = dict(Gamma=2.0, Delta=3.84, tau=0.5, tau_L=0.067, gamma_bar=0.342)
    base = dict(method="di", h=None, delta=None, dtype="float64", n_excursions=200, rtol=None, max_work=1e11)
    assert sweep._ident(3, p, base) == json.dumps(
        [3, {k: repr(float(v)) for k, v in p.items()}, {k: sweep._canon(v) for k, v in base.items()}], sort_keys=True)
    with64, with128 = {**base, "durations": 64}, {**base, "durations": 128}
    assert len({sweep._ident(3, p, s) for s in (base, with64, with128)}) == 3
    assert sweep.point_seed(3, p, base) == sweep.point_seed(3, p, with64) == sweep.point_seed(3, p, with128)
    seeds = {sweep.duration_seed(3, p, with64), sweep.duration_seed(3, p, with128), sweep.point_seed(3, p, base)}
    assert len(seeds) == 3


def test_a_point_whose_count_is_over_max_work_is_refused_with_the_grid(tmp_path):
    """Gamma = 1, tau = 1 s: its D (50 excursions) fits max_work = 1e9, 2048 long excursions do not (the count's
    own planner, durations.check_duration_run, asks for more).  Refused before anything runs, with that planner's
    reason; under skip_refused the point still gets its D, and its count that reason (the point was refused whole,
    its D lost: an audit), counted as a point without a count."""
    out = str(tmp_path / "s.jsonl")
    pts = [dict(Gamma=1.0, tau=1.0), dict(Gamma=10.0, tau=0.125)]
    kw = dict(n_excursions=50, max_work=1e9, durations=2048)
    p = dj.Params(**{**dj.FIG3, **pts[0]})
    with pytest.raises(ValueError) as direct:
        dj.durations.check_duration_run(p, sweep.duration_h(p, None), 2048, "float64", 1e9, name="durations")
    why = str(direct.value)
    assert why.endswith("(here for the 2048 long excursions (durations) counted in 256 lanes, each of which also "
                        "seeks its first one and finishes the one in flight at the end: lower them)")
    assert float(re.match(r"^max_work must be >= ([0-9.e+]+) steps ", why).group(1)) > 1e9
    with pytest.raises(ValueError, match=r"^durations: " + re.escape(why) + r" \[at sweep point .*Nothing was run"):
        sweep.run_sweep(pts, out, **kw)
    assert not os.path.exists(out)
    r = sweep.run_sweep(pts, out, skip_refused=True, **kw)
    assert (r["computed"], r["refused"], r["no_count"]) == (2, 0, 1)
    no_count, ok = _lines(out)
    assert no_count["status"] == "ok" and no_count["durations"] == {"reason": "durations: " + why}
    # its D is the sweep's without durations, bit for bit
    alone = sweep.run_sweep(pts[:1], str(tmp_path / "d.jsonl"), n_excursions=50, max_work=1e9)
    timing = ("wall_s", "lane_steps_per_s")
    same = [{k: v for k, v in rec["result"].items() if k not in timing} for rec in (_lines(str(tmp_path / "d.jsonl"))
                                                                                   + [no_count])]
    assert alone["computed"] == 1 and same[0] == same[1] and same[0]["D"] > 0
    assert ok["status"] == "ok" and ok["durations"]["n_excursions"] >= 2048
    row = sweep.rows(out)[0]
    assert row["status"] == "ok" and math.isnan(row["le_duration"]) and row["reason"] == "durations: " + why
    assert sweep.run_sweep(pts, out, skip_refused=True, **kw)["computed"] == 0  # a rerun skips it


def test_an_error_of_the_point_progress_callback_in_the_count_goes_up_and_records_nothing(tmp_path):
    """A ``ValueError`` raised by the caller's ``point_progress`` during a point's count was taken for the count's
    "fewer than 2 within the bound" and recorded as the point's durations (``{"reason": "bug in my callback"}``, kept
    on resume: an audit); it goes up now, and the point is not recorded, so a rerun computes it.  The count's own
    outcome (:class:`~dryfric_jax.NoCountError`) is still recorded (the test below)."""
    out = str(tmp_path / "s.jsonl")

    def callback(d):
        if d["stage"] == "durations":
            raise ValueError("bug in my callback")

    with pytest.raises(ValueError, match="^bug in my callback$"):
        sweep.run_sweep(sweep.grid(Gamma=[10.0], tau=[0.125]), out, n_excursions=100, durations=64,
                        point_progress=callback)
    assert not os.path.exists(out) or _lines(out) == []
    assert issubclass(dj.NoCountError, ValueError)


def test_a_count_cut_short_is_recorded_and_a_truncated_one_exits_3(tmp_path, monkeypatch, capsys):
    """A count with fewer than 2 long excursions within its bound keeps the point's D and says why, and the sweep
    exits 1 (a result asked for is missing; it exited 0 without a word in the summary); one that left excursions in
    flight at its bound (biased low) makes the point truncated: exit 3, as a truncated D does."""
    out = str(tmp_path / "s.jsonl")
    argv = ["sweep", "--Gamma", "10", "--tau", "0.125", "--n-excursions", "100", "--durations", "64", "--out", out]
    monkeypatch.setattr(sweep, "max_steps_for", lambda n, steps, lanes=None: 128)
    assert main(argv) == 1
    (rec,) = _lines(out)
    assert rec["status"] == "ok" and rec["result"]["D"] > 0 and rec["durations"]["max_steps"] == 128
    assert rec["durations"]["reason"].startswith("max_steps = 128 is too small here")
    cap = capsys.readouterr()
    assert "LE: none (max_steps = 128 is too small here" in cap.err
    assert "1 point computed, 0 already in" in cap.out and ", 1 without a duration count" in cap.out
    assert "error: 1 point got D but no mean long-excursion duration" in cap.err and "--max-steps" in cap.err
    (row,) = sweep.rows(out)
    assert math.isnan(row["le_duration"]) and row["reason"] == rec["durations"]["reason"]  # why it has no count
    assert row["warnings"] == rec["result"]["warnings"] and any("< 10000" in w for w in row["warnings"])  # N = 100
    assert main(argv + ["--json"]) == 1 and _lines(out) == [rec]  # resumed: not rerun (it would end the same way)
    assert json.loads(capsys.readouterr().out)["no_count"] == 1
    # 5 120 steps: ~2 mean excursions per lane, its seek included, so some are in flight at the bound
    monkeypatch.setattr(sweep, "max_steps_for", lambda n, steps, lanes=None: 5_000)
    out2 = str(tmp_path / "t.jsonl")
    assert main(argv[:-1] + [out2, "--json"]) == 3
    cap = capsys.readouterr()
    assert json.loads(cap.out)["truncated"] == 1 and "1 point with truncated excursions" in cap.err
    (rec2,) = _lines(out2)
    assert rec2["result"]["n_truncated"] == 0 and rec2["durations"]["n_truncated"] > 0
    assert sweep.rows(out2)[0]["le_n_truncated"] == rec2["durations"]["n_truncated"]


@pytest.mark.parametrize("bad", [1, 2**40 + 1, 2.5, True, "8", 3.0])
def test_bad_durations_are_refused_by_name(tmp_path, bad):
    with pytest.raises(ValueError, match=r"^durations must be an integer in \[2, 1099511627776\] \(long "):
        sweep.run_sweep(sweep.grid(Gamma=[5.0]), str(tmp_path / "s.jsonl"), n_excursions=50, durations=bad)


@pytest.mark.parametrize("bad", ["1", "2.5", "x", "1_000"])
def test_bad_durations_option_exit_2(tmp_path, bad, capsys):
    out = tmp_path / "s.jsonl"
    assert main(["sweep", "--Gamma", "5", "--durations", bad, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"--durations must be an integer in [2, 2^40] (got '{bad}')" in err[0], err
    assert not out.exists()


def test_a_record_of_a_durations_point_without_them_refuses_the_file(tmp_path, capsys):
    good = dict(params={"Gamma": 5.0, "Delta": 3.84, "tau": 0.5, "tau_L": 0.067, "gamma_bar": 0.342},
                settings={"method": "di", "n_excursions": 50, "durations": 64}, sweep_seed=0, status="ok",
                result={"D": 1.0, "D_ci": 0.1, "M0": 0.0, "M0_ci": 0.1, "n_truncated": 0},
                durations={"mean": 1.0, "ci": 0.1, "n_excursions": 64, "n_truncated": 0})
    out = tmp_path / "s.jsonl"
    for rec in (good, {**good, "durations": {"reason": "max_steps = 128 is too small here"}}):
        out.write_text(json.dumps(rec) + "\n")
        assert len(sweep.read_results(str(out))) == 1
    for edit in (dict(durations=None), dict(durations={"mean": 1.0}), dict(settings={**good["settings"],
                                                                                  "durations": 10**400})):
        out.write_text(json.dumps({**good, **edit}) + "\n")
        assert main(["sweep", "--Gamma", "6", "--n-excursions", "50", "--out", str(out)]) == 2
        assert "--out must be a dryfric sweep file (JSON Lines)" in capsys.readouterr().err


def test_max_time_bounds_the_count_and_a_count_it_stopped_is_rerun_with_more_time(tmp_path, monkeypatch):
    """The sweep's max_time reaches the count (di_long_excursion_duration's max_time).  A count it stopped
    (here marked so by a wrapper: the real stop is tested in test_durations.py) makes the point time-limited, like a
    D that max_time stopped: counted, kept, and rerun by a resumed sweep given more time, not by one given the
    same."""
    import dataclasses

    real, seen = sweep.di_long_excursion_duration, []

    def marked(*a, **kw):
        seen.append(kw["max_time"])
        return dataclasses.replace(real(*a, **kw), stopped_by="max_time")

    monkeypatch.setattr(sweep, "di_long_excursion_duration", marked)
    out = str(tmp_path / "s.jsonl")
    pts = sweep.grid(Gamma=[10.0], tau=[0.125])
    kw = dict(n_excursions=100, durations=64)
    r = sweep.run_sweep(pts, out, max_time=600, **kw)
    assert (r["computed"], r["time_limited"], r["no_count"]) == (1, 1, 0) and seen == [600.0]
    (rec,) = _lines(out)
    assert rec["durations"]["stopped_by"] == "max_time" and rec["max_time"] == 600
    assert sweep.run_sweep(pts, out, max_time=600, **kw)["computed"] == 0
    assert sweep.run_sweep(pts, out, max_time=1200, **kw)["computed"] == 1 and seen == [600.0, 1200.0]
    assert len(_lines(out)) == 1 and _lines(out)[0]["max_time"] == 1200


def test_a_point_interrupted_in_its_count_keeps_its_d_for_the_resumed_sweep(tmp_path, monkeypatch):
    """An audit (2026-12-07): a Ctrl-C during a point's count lost its finished D estimate (no record written), and
    the resumed sweep estimated it again.  Now the D is written as the point's record without durations (the one a
    sweep without them writes, to the bit), which the resumed sweep takes up: the estimator runs once."""
    pts = sweep.grid(Gamma=[5.0], tau=[0.125])
    out, plain = str(tmp_path / "s.jsonl"), str(tmp_path / "plain.jsonl")
    calls, estimate, count = [], sweep.estimate_diffusivity, sweep._durations
    monkeypatch.setattr(sweep, "estimate_diffusivity", lambda *a, **k: calls.append(a[1]) or estimate(*a, **k))

    def ctrl_c(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(sweep, "_durations", ctrl_c)
    r = sweep.run_sweep(pts, out, durations=64, n_excursions=200, seed=3)
    assert r["interrupted"] and (r["computed"], r["kept_d"]) == (0, 1) and len(calls) == 1
    (kept,) = _lines(out)
    sweep.run_sweep(pts, plain, n_excursions=200, seed=3)
    (ref,) = _lines(plain)
    assert "durations" not in kept["settings"] and kept["status"] == "ok" and kept["seed"] == ref["seed"]
    assert kept["result"]["sums"] == ref["result"]["sums"] and kept["settings"] == ref["settings"]
    monkeypatch.setattr(sweep, "_durations", count)
    r = sweep.run_sweep(pts, out, durations=64, n_excursions=200, seed=3)
    assert (r["computed"], r["kept_d"]) == (1, 0) and not r["interrupted"] and len(calls) == 2  # the plain sweep's
    d_only, full = _lines(out)
    assert d_only == kept and full["settings"]["durations"] == 64 and full["result"]["sums"] == kept["result"]["sums"]


def test_a_count_stopped_by_ctrl_c_neither_overwrites_a_kept_d_nor_fails_on_a_write(tmp_path, monkeypatch, capsys):
    """A review: the D kept at a Ctrl-C in the count replaced whatever record of the point's D the file held, also
    one another sweep had finished meanwhile (and the kept one could be cut short by max_time); and an error of that
    write, inside the Ctrl-C's handling, replaced the Ctrl-C (a traceback, not "interrupted").  Now another sweep's
    finished record stays, and a failed write is said and the sweep ends as interrupted."""
    pts = sweep.grid(Gamma=[5.0], tau=[0.125])
    out = str(tmp_path / "s.jsonl")
    kw = dict(n_excursions=200, seed=3)

    def other_sweep_then_ctrl_c(pt, seed, settings, *a, **k):
        d_only = {s: v for s, v in settings.items() if s != "durations"}
        rec = sweep._record(seed, pt, d_only, "ok", result={**_lines(plain)[0]["result"]}, marker="other sweep")
        dj.outfiles.put_record(out, rec, lambda old: False, sweep.read_results)
        raise KeyboardInterrupt

    plain = str(tmp_path / "plain.jsonl")
    sweep.run_sweep(pts, plain, **kw)
    monkeypatch.setattr(sweep, "_durations", other_sweep_then_ctrl_c)
    r = sweep.run_sweep(pts, out, durations=64, **kw)
    assert r["interrupted"] and r["kept_d"] == 0
    (rec,) = _lines(out)
    assert rec["marker"] == "other sweep"

    def ctrl_c(*a, **k):
        raise KeyboardInterrupt

    def full_disk(*a, **k):
        raise OSError(28, "No space left on device")

    out2 = str(tmp_path / "s2.jsonl")
    monkeypatch.setattr(sweep, "_durations", ctrl_c)
    monkeypatch.setattr(sweep, "put_record", full_disk)
    with pytest.warns(dj.DryfricWarning, match="finished D could not be kept .*No space left on device"):
        r = sweep.run_sweep(pts, out2, durations=64, **kw)
    assert r["interrupted"] and r["kept_d"] == 0 and (not os.path.exists(out2) or _lines(out2) == [])


def test_a_sweep_given_a_count_later_still_combines(tmp_path, capsys):
    """A README audit (stop 91): after a sweep was given --durations, each point's record is in its file twice, with
    and without the count, the same D (seed and sums); `dryfric combine` refused such a file, alone or with another
    seed's, as one seed used twice.  Now the twin is pooled once, and said; a file given twice is still refused."""
    pts = sweep.grid(Gamma=[5.0], tau=[0.125])
    files = [str(tmp_path / f"s{seed}.jsonl") for seed in (0, 1)]
    for seed, out in zip((0, 1), files):
        sweep.run_sweep(pts, out, n_excursions=200, seed=seed)
        sweep.run_sweep(pts, out, n_excursions=200, seed=seed, durations=64)
        assert len(_lines(out)) == 2 and _lines(out)[0]["result"]["sums"] == _lines(out)[1]["result"]["sums"]
    d_only = [_lines(out)[0] for out in files]
    with pytest.warns(dj.DryfricWarning, match="1 sweep record"):
        alone = dj.combine_estimates(_lines(files[0]))
    assert (alone.D, alone.n_excursions) == (d_only[0]["result"]["D"], d_only[0]["result"]["n_excursions"])
    want = dj.combine_estimates(d_only)
    assert main(["combine", *files, "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    assert (got["D"], got["D_ci"], got["n_excursions"]) == (want.D, want.D_ci, want.n_excursions)
    assert any("2 sweep record(s) repeating a point's D" in w for w in got["warnings"])
    assert main(["combine", files[0], files[0]]) == 2
    assert f"used twice by {files[0]}:1" in capsys.readouterr().err
    # records of other shapes are left to combine's own refusal (a review: params null was an AttributeError, a
    # count [64] a TypeError, from the twins' test)
    with pytest.raises(ValueError, match="^results must be estimate results|^results\\[0\\] must have"):
        dj.combine_estimates([{**_lines(files[0])[1], "params": None}])
    odd = {**_lines(files[0])[1], "settings": {**d_only[0]["settings"], "durations": [64]}}  # not a count: no twin
    assert dj.combine_estimates([odd]).D == alone.D
