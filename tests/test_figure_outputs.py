"""What ``dryfric figures`` leaves in ``--out`` and how a rerun treats it (an audit, 2026-12-05): each
scene's JSON records what made it, a finished scene is not made again, its files are never torn, and
truncated excursions behind a figure exit 3; what it says while it runs.  Fake scenes and runs, but for small real
ones where the progress reports must leave a run's bits alone."""
import dataclasses
import json

import matplotlib.pyplot as plt
import pytest

import dryfric_jax
from dryfric_jax import figures
from dryfric_jax.api import EstimateResult
from dryfric_jax.cli import main
from dryfric_jax.figures import common, points
from dryfric_jax.params import FIG3, Params


def _scene(calls):
    """A stand-in for Fig. 1-2's scene (same name, so the same files) that records its calls."""
    def fig1_2(out_dir, quick, seed):
        calls.append((quick, seed))
        fig, ax = plt.subplots()
        ax.plot([0, 1], [0, 1])
        return common.save(fig, out_dir, "fig1_2", dict(x=1.0), 0.0, quick=quick, seed=seed)
    return fig1_2


def test_scene_json_records_seed_quick_and_versions(tmp_path):
    fig, _ = plt.subplots()
    common.save(fig, str(tmp_path), "s", dict(a=1), 0.0, quick=True, seed=7)
    got = json.loads((tmp_path / "s.json").read_text())
    import jax
    assert {k: got[k] for k in ("a", "seed", "quick", "version", "jax_version")} == dict(
        a=1, seed=7, quick=True, version=dryfric_jax.__version__, jax_version=jax.__version__)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.json", "s.pdf", "s.png"]


def test_a_finished_scene_is_not_made_again_unless_its_seed_quick_or_version_differ(tmp_path, monkeypatch):
    """A rerun of ``--fig all`` after an interruption made every finished scene again (~900 s at full
    settings); now only a scene whose files are missing, or were made by another version, seed or quick
    setting, is made (``redo=True`` makes it anyway)."""
    calls = []
    monkeypatch.setitem(figures.SCENES, "1", _scene(calls))
    out = str(tmp_path)
    first = figures.run_figures("1", out, quick=True, seed=3)
    assert calls == [(True, 3)]
    assert figures.run_figures("1", out, quick=True, seed=3) == first and calls == [(True, 3)]  # read back
    figures.run_figures("1", out, quick=True, seed=4)
    figures.run_figures("1", out, quick=False, seed=4)
    figures.run_figures("1", out, quick=False, seed=4, redo=True)
    assert calls == [(True, 3), (True, 4), (False, 4), (False, 4)]
    path = tmp_path / "fig1_2.json"
    path.write_text(json.dumps(dict(json.loads(path.read_text()), version="0.0.1")))  # another version's
    figures.run_figures("1", out, quick=False, seed=4)
    (tmp_path / "fig1_2.pdf").unlink()  # a file missing
    figures.run_figures("1", out, quick=False, seed=4)
    path.write_text("{torn")  # not JSON
    figures.run_figures("1", out, quick=False, seed=4)
    assert calls[4:] == [(False, 4)] * 3


def test_an_interrupted_savefig_leaves_the_old_file_whole(tmp_path, monkeypatch):
    """A Ctrl-C inside ``savefig`` of the PDF left it cut at 848 bytes beside a new PNG; now each file is
    drawn in memory and written atomically: the old PDF and JSON stay as they were, nothing else is left."""
    fig, _ = plt.subplots()
    common.save(fig, str(tmp_path), "s", dict(a=1), 0.0, quick=True, seed=0)
    old = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    real = plt.Figure.savefig

    def savefig(self, fname, *a, **kw):
        if kw.get("format") == "pdf" or str(fname).endswith(".pdf"):  # part of the PDF, then the Ctrl-C
            if hasattr(fname, "write"):
                fname.write(b"%PDF-1.4 cut")
            else:
                with open(fname, "wb") as f:
                    f.write(b"%PDF-1.4 cut")
            raise KeyboardInterrupt
        return real(self, fname, *a, **kw)

    monkeypatch.setattr(plt.Figure, "savefig", savefig)
    fig, _ = plt.subplots()
    with pytest.raises(KeyboardInterrupt):
        common.save(fig, str(tmp_path), "s", dict(a=2), 0.0, quick=True, seed=1)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.json", "s.pdf", "s.png"]
    assert (tmp_path / "s.pdf").read_bytes() == old["s.pdf"] and (tmp_path / "s.json").read_bytes() == old["s.json"]


def test_points_summary_counts_the_truncated_excursions_of_the_runs_used(tmp_path, monkeypatch):
    """Computed and reused runs alike: a figure whose runs lost excursions says so in its JSON."""
    base = EstimateResult(D=1.0, D_ci=0.1, M0=0.0, M0_ci=0.1, mean_duration=1.0, n_excursions=10, n_truncated=0,
                          method="di", h=1e-3, dtype="float64", seed=0, wall_s=1.0, lane_steps_per_s=1.0, params={})
    monkeypatch.setitem(points._KINDS, "estimate",
                        (lambda params, seed, **kw: dataclasses.replace(base, seed=seed, n_truncated=seed),
                         EstimateResult))
    p = Params(**FIG3)
    pts = points.Points(str(tmp_path), "s")
    pts.estimate(p, 2, n_excursions=10)
    pts.estimate(p, 3, n_excursions=10)
    assert pts.summary()["n_truncated"] == 5
    again = points.Points(str(tmp_path), "s")
    again.estimate(p, 3, n_excursions=10)
    assert again.summary()["n_truncated"] == 3 and again.summary()["reused"] == 1


def test_a_duration_count_is_kept_and_reused_to_the_bit(tmp_path, monkeypatch):
    """Fig. 3's long-excursion counts go through the points file: a second figure run (or a resumed one) reuses
    the kept count instead of running it again, and gets the same LEDuration, warnings and all.  Its truncated
    excursions stay out of the summary's n_truncated (Fig. 3 counts them as le_dur_truncated: counted in both,
    the exit message would give them twice)."""
    from dryfric_jax.durations import LEDuration

    p = Params(Gamma=10.0, Delta=3.84, tau=0.125, tau_L=0.067, gamma_bar=0.342)
    kw = dict(n_excursions=64, n_lanes=64, max_steps=5000)  # a bound that cuts some: truncated, and a warning
    pts = points.Points(str(tmp_path), "s")
    a = pts.duration(p, 3, **kw)
    assert isinstance(a, LEDuration) and a.n_truncated > 0 and a.warnings
    assert (pts.computed, pts.summary()["n_truncated"]) == (1, 0)
    monkeypatch.setitem(points._KINDS, "duration", (lambda *a, **k: pytest.fail("ran again"), LEDuration))
    again = points.Points(str(tmp_path), "s")
    b = again.duration(p, 3, **kw)
    assert b == a and b.warnings == a.warnings and b.wall_s == a.wall_s
    assert (again.reused, again.computed, again.summary()["n_truncated"]) == (1, 0, 0)
    assert not again.kept(p, 3, kind="duration", **dict(kw, n_excursions=65))


@pytest.mark.parametrize("extra,code", [([], 3), (["--allow-truncated"], 0)])
def test_figures_with_truncated_runs_exit_3(tmp_path, monkeypatch, capsys, extra, code):
    monkeypatch.setattr(figures, "run_figures", lambda *a, **k: {"3": dict(runs=dict(n_truncated=2)),
                                                                  "4": dict(x=1), "8": dict(runs=dict(n_truncated=0))})
    assert main(["figures", "--out", str(tmp_path), *extra]) == code
    err = capsys.readouterr().err
    assert ("3: 2 truncated excursions: " in err) == (code == 3) and "Traceback" not in err and "8:" not in err


@pytest.mark.parametrize("nums,said", [
    ({"3": dict(runs=dict(n_truncated=0), le_dur_truncated=0, le_dur_missing=1)}, "3: 1 DI duration points missing:"),
    ({"3": dict(runs=dict(n_truncated=4), le_dur_truncated=5, le_dur_missing=0)},
     "3: 4 truncated excursions, 5 DI duration lanes stopped by their bound:")])
def test_figures_name_what_was_cut_in_fig3s_durations(tmp_path, monkeypatch, capsys, nums, said):
    """A missing DI duration point (no lane reached its count) exited 3 with "truncated excursions in 3 (1)": the
    message now says which of the three it was."""
    monkeypatch.setattr(figures, "run_figures", lambda *a, **k: nums)
    assert main(["figures", "--out", str(tmp_path)]) == 3
    err = capsys.readouterr().err
    assert said in err and "biased low or missing" in err and "Traceback" not in err


def test_a_bad_points_file_is_refused_before_any_scene_runs(tmp_path, monkeypatch, capsys):
    """``garbage`` in fig9.points.jsonl was refused only after the eight other scenes had run (~2 h at full
    settings); now at once, exit 2, naming the file, with no scene run."""
    calls = []
    monkeypatch.setitem(figures.SCENES, "1", _scene(calls))
    (tmp_path / "fig9.points.jsonl").write_text("garbage\n")
    assert main(["figures", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "fig9.points.jsonl" in err and "Traceback" not in err and calls == []


def test_the_script_is_quiet_on_a_ctrl_c_while_starting():
    """``scripts/reproduce_figures.py`` interrupted while JAX loads printed a KeyboardInterrupt traceback
    where ``dryfric figures`` prints one line and exits 130.  ~2 s."""
    import os
    import pathlib
    import signal
    import subprocess
    import sys
    import time

    root = pathlib.Path(__file__).parent.parent
    p = subprocess.Popen([sys.executable, str(root / "scripts" / "reproduce_figures.py"), "--fig", "1", "--quick",
                          "--out", os.devnull + "/x"], env={**os.environ, "PYTHONPATH": str(root)},
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    time.sleep(0.3)
    p.send_signal(signal.SIGINT)
    out, err = p.communicate(timeout=300)
    assert "Traceback" not in err, err[-800:]
    assert p.returncode in (130, 2), (p.returncode, err)  # 2: JAX loaded before the signal, --out refused


def test_runs_of_another_version_are_said_before_the_scene_computes_them_again(tmp_path, monkeypatch, capsys):
    """After an upgrade a scene's kept runs were computed again without a word (Fig. 3: 87 min at full
    settings); now ``dryfric figures`` says, before the scene runs, how many runs of which version it
    will not reuse, and the scene's JSON records them.  A finished scene, not run again, says nothing."""
    base = EstimateResult(D=1.0, D_ci=0.1, M0=0.0, M0_ci=0.1, mean_duration=1.0, n_excursions=10, n_truncated=0,
                          method="di", h=1e-3, dtype="float64", seed=0, wall_s=1.0, lane_steps_per_s=1.0, params={})
    monkeypatch.setitem(points._KINDS, "estimate",
                        (lambda params, seed, **kw: dataclasses.replace(base, seed=seed), EstimateResult))
    p, out = Params(**FIG3), str(tmp_path)
    monkeypatch.setattr(points, "__version__", "0.0.1")
    old = points.Points(out, "fig1_2")
    old.estimate(p, 1, n_excursions=10)
    old.estimate(p, 2, n_excursions=10)
    monkeypatch.setattr(points, "__version__", dryfric_jax.__version__)
    assert points.other_versions(out, "fig1_2") == {"0.0.1": 2} and points.other_versions(out, "fig3") == {}

    def fig1_2(out_dir, quick, seed):  # a scene of kept runs under Fig. 1-2's name
        pts = points.Points(out_dir, "fig1_2")
        pts.estimate(p, 1, n_excursions=10)
        fig, _ = plt.subplots()
        return common.save(fig, out_dir, "fig1_2", dict(runs=pts.summary()), 0.0, quick=quick, seed=seed)

    monkeypatch.setitem(figures.SCENES, "1", fig1_2)
    assert main(["figures", "--fig", "1", "--out", out]) == 0
    err = capsys.readouterr().err
    assert (f"dryfric: warning: fig1_2.points.jsonl holds 2 runs made by other versions (0.0.1: 2), which version "
            f"{dryfric_jax.__version__} does not reuse") in err and "computes its runs again" in err, err
    runs = json.loads((tmp_path / "fig1_2.json").read_text())["runs"]
    assert (runs["other_versions"], runs["computed"], runs["reused"]) == ({"0.0.1": 2}, 1, 0)
    assert main(["figures", "--fig", "1", "--out", out]) == 0  # finished: read back, nothing to say
    assert "warning" not in capsys.readouterr().err
    assert main(["figures", "--fig", "1", "--out", out, "--redo"]) == 0  # made again: said again
    assert "holds 2 runs made by other versions (0.0.1: 2)" in capsys.readouterr().err


@pytest.mark.parametrize("name,layout,kept", [("fig3", None, False), ("fig3", 1, False), ("fig3", 2, True),
                                              ("fig6", None, False), ("fig4", None, True), ("fig4", 1, True),
                                              ("fig1_2", 1, False), ("fig5", 1, False), ("fig5", 2, True)])
def test_a_scene_json_of_an_older_layout_is_not_finished(tmp_path, name, layout, kept):
    """Fig. 3's JSON of 0.2.7 made before the DI durations by counting releases (no ``le_dur``) was taken
    as finished, so a rerun kept a figure without them: a scene's layout (common.SCENE_LAYOUT) is checked too;
    a JSON without one is of layout 1."""
    fig, _ = plt.subplots()
    nums = common.save(fig, str(tmp_path), name, dict(a=1), 0.0, quick=True, seed=3)
    assert nums["layout"] == common.SCENE_LAYOUT.get(name, 1)
    if layout is None:
        del nums["layout"]
    else:
        nums["layout"] = layout
    (tmp_path / f"{name}.json").write_text(json.dumps(nums))
    assert (common.finished(str(tmp_path), name, True, 3) is not None) == kept



@pytest.mark.parametrize("key,value", [("seed", True), ("layout", 2.0), ("layout", True), ("quick", 1), ("seed", 1.0)])
def test_a_scene_json_whose_meta_has_another_type_is_not_finished(tmp_path, key, value):
    """seed = true passed for seed 1, layout = 2.0 for 2 (Python's == across bool, int and float; an audit)."""
    fig, _ = plt.subplots()
    nums = common.save(fig, str(tmp_path), "fig3", dict(a=1), 0.0, quick=True, seed=1)
    assert common.finished(str(tmp_path), "fig3", True, 1) is not None
    (tmp_path / "fig3.json").write_text(json.dumps(dict(nums, **{key: value})))
    assert common.finished(str(tmp_path), "fig3", True, 1) is None


@pytest.mark.filterwarnings("ignore::dryfric_jax.DryfricWarning")
def test_a_scenes_runs_report_their_progress_and_give_the_same_bits(tmp_path):
    """Under ``points.reporting`` each computed run says what it is as it starts (``run`` None) and passes on its
    own progress; a kept run says nothing.  The callback is not part of a run's identity, and a run made with it
    is the run made without it, to the bit (a real estimate and a real count, small).  Mutants: progress in the
    identity (the run not reused); no report at the start; the run's progress not passed on."""
    import dryfric_jax as dj

    p = Params(Gamma=10.0, Delta=3.84, tau=0.125, tau_L=0.067, gamma_bar=0.342)
    seen = []
    pts = points.Points(str(tmp_path), "s")
    with points.reporting(seen.append):
        a = pts.estimate(p, 5, n_excursions=300, method="pdmp")
        d = pts.duration(p, 6, n_excursions=64)
        pts.estimate(p, 5, n_excursions=300, method="pdmp")  # kept: no report
    assert a.sums == dj.estimate_diffusivity(p, 5, n_excursions=300, method="pdmp").sums
    assert d.mean == dj.di_long_excursion_duration(p, 6, n_excursions=64).mean
    est, dur = [x for x in seen if x["kind"] == "estimate"], [x for x in seen if x["kind"] == "duration"]
    assert len(est) + len(dur) == len(seen) and len(est) >= 2 and len(dur) >= 2
    assert est[0]["run"] is None and est[0]["method"] == "pdmp" and est[0]["params"] == p.as_dict()
    assert dur[0]["run"] is None and dur[0]["method"] is None and {x["runs"] for x in dur} == {1}
    assert {x["runs"] for x in est} == {0} and all(x["run"] is not None for x in est[1:] + dur[1:])
    assert est[-1]["run"]["target"] == 300 and dur[-1]["run"]["n_excursions"] == d.n_excursions
    again = points.Points(str(tmp_path), "s")
    again.estimate(p, 5, n_excursions=300, method="pdmp")  # reused: progress is not in the identity
    assert (again.reused, again.computed) == (1, 0)


def test_a_scene_without_runs_reports_its_steps(tmp_path, monkeypatch):
    """``points.report_step`` reaches ``run_figures``' progress as stage "step" with its text and the scene's time
    so far, between start and done; outside ``reporting`` (and with no progress) it does nothing.  Mutants: the
    step sent as a run; the step's time missing."""
    points.report_step("nobody listens")  # no callback: nothing, no error

    def fig1_2(out_dir, quick, seed):
        points.report_step("stage one")
        points.report_step("stage two")
        fig, _ = plt.subplots()
        return common.save(fig, out_dir, "fig1_2", dict(x=1.0), 0.0, quick=quick, seed=seed)

    monkeypatch.setitem(figures.SCENES, "1", fig1_2)
    seen = []
    figures.run_figures("1", str(tmp_path / "a"), quick=True, progress=seen.append)
    where = dict(scene="fig1_2", index=1, total=1)
    assert [x["stage"] for x in seen] == ["start", "step", "step", "done"]
    assert [{k: v for k, v in x.items() if k != "elapsed_s"} for x in seen[1:3]] == [
        dict(where, stage="step", step="stage one"), dict(where, stage="step", step="stage two")]
    assert 0 <= seen[1]["elapsed_s"] <= seen[2]["elapsed_s"] <= seen[3]["wall_s"]
    figures.run_figures("1", str(tmp_path / "b"), quick=True)  # no progress: the steps go nowhere


def test_run_figures_reports_each_scene(tmp_path, monkeypatch):
    """``run_figures(progress=)``: a scene that runs says start, its runs (none here) and done with its wall time;
    one found finished says done, kept.  Its numbers are those without progress.  Mutant: done before start."""
    calls, seen = [], []
    monkeypatch.setitem(figures.SCENES, "1", _scene(calls))
    out = str(tmp_path)
    first = figures.run_figures("1", out, quick=True, seed=3, progress=seen.append)
    where = dict(scene="fig1_2", index=1, total=1)
    assert [{k: v for k, v in x.items() if k != "wall_s"} for x in seen] == [
        dict(where, stage="start"), dict(where, stage="done", kept=False)]
    assert seen[-1]["wall_s"] >= 0 and calls == [(True, 3)]
    seen.clear()
    assert figures.run_figures("1", out, quick=True, seed=3, progress=seen.append) == first
    assert seen == [dict(where, stage="done", kept=True)] and calls == [(True, 3)]
    with pytest.raises(ValueError, match=r"^progress must be a callable or None \(got 3\)$"):
        figures.run_figures("1", out, progress=3)


@pytest.mark.parametrize("tty", [True, False])
def test_dryfric_figures_says_each_scene_and_on_a_terminal_each_run(tmp_path, monkeypatch, capsys, tty):
    """A line per scene on stderr (written, with its time; or found made), also off a terminal; on a terminal a
    status line while a scene computes, naming its run and the run's progress, cleared before the next line and
    before an interrupt's message.  Mutants: the status line off a terminal; not cleared before the interrupt."""
    import sys

    def fig1_2(out_dir, quick, seed):
        pts = points.Points(out_dir, "fig1_2")
        pts.duration(Params(Gamma=10.0, Delta=3.84, tau=0.125, tau_L=0.067, gamma_bar=0.342), 1, n_excursions=16)
        if seed == 9:
            raise KeyboardInterrupt
        fig, _ = plt.subplots()
        return common.save(fig, out_dir, "fig1_2", dict(runs=pts.summary()), 0.0, quick=quick, seed=seed)

    monkeypatch.setitem(figures.SCENES, "1", fig1_2)
    monkeypatch.setattr(sys.stderr, "isatty", lambda: tty)
    out = str(tmp_path)
    assert main(["figures", "--fig", "1", "--out", out]) == 0
    err = capsys.readouterr().err
    assert ("\r  fig1_2 (1 of 1): run 1, duration at Gamma=10 tau=0.125: LE=" in err) is tty
    assert ("\r\x1b[K  fig1_2 (1 of 1): written in " if tty else "  fig1_2 (1 of 1): written in ") in err
    assert ("\r" in err) is tty and err.count("written in") == 1
    assert main(["figures", "--fig", "1", "--out", out]) == 0
    assert "  fig1_2 (1 of 1): already made by this version with this --seed and --quick" in capsys.readouterr().err
    assert main(["figures", "--fig", "1", "--out", out, "--seed", "9"]) == 130
    err = capsys.readouterr().err
    assert ("\r\x1b[Kdryfric: interrupted; " in err) is tty and "written in" not in err


def test_the_figures_status_line(capsys, monkeypatch):
    """Worked by hand: a PDMP estimate at 17% and a count finishing; a brute-force run shows no progress of its
    own.  Mutants: the method not named; the scene's time not shown."""
    import sys

    from dryfric_jax.cli import _figures_line

    monkeypatch.setattr(sys.stderr, "isatty", lambda: True)
    base = dict(scene="fig8", index=8, total=9, stage="run", kind="estimate", method="pdmp", runs=11,
                params=dict(FIG3, Gamma=2.15, tau=1e-3), elapsed_s=150.0)
    est = dict(n_excursions=1200, D=2.0, D_ci=0.34, target=100000, rtol=None, elapsed_s=3.0, left_s=40.0,
               left_to="n_excursions")
    _figures_line(dict(base, run=est))
    assert capsys.readouterr().err == ("\r  fig8 (8 of 9): run 12, estimate (pdmp) at Gamma=2.15 tau=0.001: "
                                       "D=2\u00b117% N=1200 of 100000, ~40 s left [2.5 min]\x1b[K")
    _figures_line(dict(base, kind="bruteforce", method=None, run=None))
    assert capsys.readouterr().err == "\r  fig8 (8 of 9): run 12, bruteforce at Gamma=2.15 tau=0.001 [2.5 min]\x1b[K"
    _figures_line(dict(scene="fig8", index=8, total=9, stage="start"))  # as run_figures says it: no time yet
    assert capsys.readouterr().err == "\r  fig8 (8 of 9): computing\x1b[K"
    _figures_line(dict(scene="fig4", index=4, total=9, stage="step", step="DI stationary paths, tau=0.5 s (4 of 6)",
                       elapsed_s=3000.0))
    assert capsys.readouterr().err == "\r  fig4 (4 of 9): DI stationary paths, tau=0.5 s (4 of 6) [50.0 min]\x1b[K"
    monkeypatch.setattr(sys.stderr, "isatty", lambda: False)
    _figures_line(dict(scene="fig4", index=4, total=9, stage="step", step="x", elapsed_s=1.0))
    assert capsys.readouterr().err == ""


def test_the_figures_status_line_ticks():
    """``cli._Ticking``, with a clock set by hand: a tick redraws the last line with the scene's time advanced by the
    clock's, also a "start" line (which has no time of its own), and redraws nothing after a scene's "done" line.
    Mutants: the time not advanced; the "done" scene's line redrawn."""
    from dryfric_jax.cli import _Ticking

    now, drawn = [100.0], []
    t = _Ticking(drawn.append, clock=lambda: now[0])
    where = dict(scene="fig4", index=4, total=9)
    t.tick()  # nothing said yet
    assert drawn == []
    t(dict(where, stage="start"))
    now[0] = 102.5
    t.tick()
    assert drawn == [dict(where, stage="start"), dict(where, stage="start", elapsed_s=2.5)]
    step = dict(where, stage="step", step="DI stationary paths", elapsed_s=10.0)
    t(step)
    now[0] = 163.0
    t.tick()
    assert drawn[-2:] == [step, dict(step, elapsed_s=70.5)]
    t(dict(where, stage="done", kept=False, wall_s=75.0))
    now[0] = 200.0
    t.tick()
    assert drawn[-1]["stage"] == "done" and len(drawn) == 5


def test_the_ticking_thread_runs_while_the_block_does_and_not_after():
    """``cli._ticking``: on a terminal a thread redraws the line (every 10 ms here) until the block ends, however
    it ends, and then no more; off a terminal the callback is ``draw`` itself and no thread starts.  No redraw
    while a warning's line is written (``_LINE_LOCK`` held).  Mutants: the thread not stopped; started off a
    terminal."""
    import threading
    import time
    import warnings

    from dryfric_jax.api import DryfricWarning
    from dryfric_jax.cli import _LINE_LOCK, _Ticking, _ticking, _warnings_as_lines

    drawn = []
    before = threading.active_count()
    with _ticking(drawn.append, False) as said:
        assert said == drawn.append and threading.active_count() == before
    with pytest.raises(KeyboardInterrupt):
        with _ticking(drawn.append, True, period=0.01) as said:
            said(dict(scene="fig4", index=4, total=9, stage="step", step="x", elapsed_s=1.0))
            for _ in range(500):
                if len(drawn) >= 3:
                    break
                time.sleep(0.01)
            raise KeyboardInterrupt
    assert len(drawn) >= 3 and drawn[-1]["elapsed_s"] > 1.0  # redrawn with a later time
    n = len(drawn)
    time.sleep(0.1)
    assert len(drawn) == n and threading.active_count() == before
    with _ticking(drawn.append, True, period=0.01) as said:
        said(dict(scene="fig4", index=4, total=9, stage="step", step="x", elapsed_s=1.0))
        with _LINE_LOCK:  # as while a warning's line is written: the ticking thread's redraws wait
            n = len(drawn)
            time.sleep(0.1)
            assert len(drawn) == n
    # a line drawn (the callback) and a warning's line take the lock too: from another thread they wait for it
    said_lines = []
    t = _Ticking(said_lines.append)
    with _warnings_as_lines():
        shown = warnings.showwarning
        with _LINE_LOCK:
            others = [threading.Thread(target=t, args=(dict(stage="step"),)),
                      threading.Thread(target=shown, args=("w", DryfricWarning, "f", 1))]
            for th in others:
                th.start()
            time.sleep(0.1)
            assert said_lines == [] and all(th.is_alive() for th in others)
        for th in others:
            th.join(5)
    assert said_lines == [dict(stage="step")]
