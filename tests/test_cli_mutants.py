"""CLI wiring, from a mutation audit of dryfric_jax/cli.py: does each option reach the API with the value given?

The API functions the CLI calls (estimate_diffusivity, bruteforce_diffusivity, run_sweep, combine_estimates,
run_figures, tune_layout, run_bench) are replaced by stand-ins that record their arguments and return a small
fake result: nothing is simulated, and every expected value is the one on the command line (or the API's own
default where the option is left out).  The mutants named in each docstring are single edits of cli.py that the
test fails on; some of them the slower CLI tests also catch (through a refusal or a real run), others only these."""
import inspect
import json
import math
import sys
import types

import pytest

from dryfric_jax import api, bench, combine, figures, sweep
from dryfric_jax import cli
from dryfric_jax.api import estimate_diffusivity as _api_estimate  # the real one, for its defaults
from dryfric_jax.cli import main
from dryfric_jax.params import FIG3, Params
from dryfric_jax.plan import plan_estimate


def _result(**extra):
    """A stand-in estimate / brute-force result: what the CLI reads of one."""
    d = dict(D=1.5, D_ci=0.1, M0=0.25, M0_ci=0.01, n_truncated=0, stopped_by="n_excursions",
             warnings=["stand-in warning"], method_reason="stand-in reason: chose di")
    d.update(extra)
    return types.SimpleNamespace(**d, to_dict=lambda: {k: v for k, v in d.items() if k != "method_reason"},
                                 summary=lambda: f"D = {d['D']} (stand-in summary)")


@pytest.fixture
def calls(monkeypatch):
    """Stand-ins for the API functions the CLI calls; each call's arguments are appended as
    (name, args, kwargs).  ``calls.result`` (a dict) sets the fake result's fields."""
    got = []
    got_result = {}

    def rec(name, value):
        def f(*a, **kw):
            got.append((name, a, kw))
            if isinstance(value, BaseException):
                raise value
            return value() if callable(value) else value
        return f

    def result():
        return _result(**got_result)

    monkeypatch.setattr(api, "estimate_diffusivity", rec("estimate", result))
    monkeypatch.setattr(api, "bruteforce_diffusivity", rec("bruteforce", result))
    monkeypatch.setattr(combine, "combine_estimates", rec("combine", result))
    monkeypatch.setattr(figures, "run_figures", rec("figures", {}))
    monkeypatch.setattr(bench, "tune_layout", rec("tune_layout", {"stand-in": "layouts"}))
    monkeypatch.setattr(bench, "run_bench", rec("run_bench", {"stand-in": "bench"}))
    monkeypatch.setattr(bench, "format_layouts", lambda b: "layouts table")
    monkeypatch.setattr(bench, "format_table", lambda b: "bench table")
    summary = dict(computed=0, skipped=0, total=0, duplicates=0, interrupted=False, refused=0, failed=0,
                   truncated=0, time_limited=0, no_count=0, kept_d=0)
    monkeypatch.setattr(sweep, "run_sweep", lambda pts, out, **kw: (got.append(("sweep", (pts, out), kw)),
                                                                     dict(summary))[1])
    ns = types.SimpleNamespace(list=got, result=got_result, summary=summary, rec=rec)
    return ns


def _only(calls, name):
    (call,) = [c for c in calls.list if c[0] == name]
    return call[1], call[2]


def test_every_estimate_option_reaches_the_estimator(calls, capsys):
    """Mutants: estimate_diffusivity given seed 0 instead of --seed, method 'di' instead of --method, h=None,
    delta=None, --n-excursions raised, max_steps=None, dtype 'float64' instead of --dtype, rtol=None,
    max_time=None, lanes=None, --max-work not passed (**_work_options dropped), --block not passed."""
    assert main(["estimate", "--seed", "7", "--method", "pdmp", "--delta", "0.2", "--n-excursions", "300",
                 "--max-steps", "5000", "--dtype", "float32", "--rtol", "0.05", "--max-time", "12", "--lanes", "48",
                 "--block", "32", "--max-work", "3e9", "--json"]) == 0
    (p, seed), kw = _only(calls, "estimate")
    assert seed == 7 and isinstance(p, Params)
    assert {k: kw[k] for k in ("method", "delta", "n_excursions", "max_steps", "dtype", "rtol", "max_time", "lanes",
                               "block", "max_work")} == dict(method="pdmp", delta=0.2, n_excursions=300, max_steps=5000,
                                                             dtype="float32", rtol=0.05, max_time=12.0, lanes=48,
                                                             block=32, max_work=3e9)
    calls.list.clear()
    assert main(["estimate", "--h", "0.0005", "--json"]) == 0
    assert _only(calls, "estimate")[1]["h"] == 0.0005
    capsys.readouterr()


def test_estimate_without_options_runs_the_apis_defaults(calls, capsys):
    """Left out, each option is the API's default (seed 0, the DI in float64 at N = 20 000, no rtol, no time
    limit, the API's max_work and block).  Mutants: --seed's default 1; --dtype's default float32."""
    assert main(["estimate", "--json"]) == 0
    (p, seed), kw = _only(calls, "estimate")
    sig = inspect.signature(_api_estimate)
    assert seed == sig.parameters["key"].default == 0
    for k in ("method", "h", "delta", "n_excursions", "dtype", "lanes", "max_steps", "rtol", "max_time"):
        assert kw[k] == sig.parameters[k].default, k
    assert "max_work" not in kw and "block" not in kw
    assert p == Params(**FIG3)
    capsys.readouterr()


@pytest.mark.parametrize("argv,want", [
    # SI: each option is its parameter, 0 included (a given 0 is not "left out")
    (["--Gamma", "2", "--Delta", "1.5", "--tau", "0.3", "--tau-L", "inf", "--gamma-bar", "0"],
     dict(Gamma=2.0, Delta=1.5, tau=0.3, tau_L=math.inf, gamma_bar=0.0)),
    (["--Delta", "2"], {**FIG3, "Delta": 2.0}),
    (["--gamma-bar", "0.1"], {**FIG3, "gamma_bar": 0.1}),
    (["--tau-L", "Infinity"], {**FIG3, "tau_L": math.inf}),
])
def test_model_options_are_the_params_si(calls, capsys, argv, want):
    """Mutants: pick() taking a given 0 for "not given" (--gamma-bar 0 ran at the Fig. 3 bias); --Delta read
    only when --Gamma is given; --gamma-bar ignored."""
    assert main(["estimate", "--json", *argv]) == 0
    (p, _), _ = _only(calls, "estimate")
    assert p.as_dict() == want
    capsys.readouterr()


def test_nondim_options_are_in_tau0_u0_units_with_the_fig3_point_as_default(calls, capsys):
    """--nondim: Gamma and Delta default to 1, tau, tau_L, gamma_bar to the Fig. 3 point's nondimensional
    values; given ones are read in tau0, u0 units.  Mutants: the nondim tau_L default inf; the nondim
    gamma_bar default 0; Gamma's or Delta's nondim default the SI Fig. 3 value."""
    fig = Params(**FIG3).nondim()
    assert main(["estimate", "--nondim", "--tau", "0.5", "--json"]) == 0
    (p, _), _ = _only(calls, "estimate")
    assert (p.Gamma, p.Delta) == (1.0, 1.0)
    n = p.nondim()
    assert n.tau == pytest.approx(0.5, rel=1e-14)
    assert n.tau_L == pytest.approx(fig.tau_L, rel=1e-14) and n.gamma_bar == pytest.approx(fig.gamma_bar, rel=1e-14)
    capsys.readouterr()
    assert main(["theory", "--nondim", "--Gamma", "4", "--Delta", "2", "--tau-L", "2", "--gamma-bar", "0.1",
                 "--json"]) == 0
    out = json.loads(capsys.readouterr().out)["params"]
    n = Params(**{k: float(v) for k, v in out.items()}).nondim()
    assert (out["Gamma"], out["Delta"]) == (4.0, 2.0)
    assert (n.tau, n.tau_L, n.gamma_bar) == pytest.approx((fig.tau, 2.0, 0.1), rel=1e-14)


@pytest.mark.parametrize("tty", [True, False])
def test_the_progress_line_is_shown_on_a_terminal_only_and_never_under_json(calls, capsys, monkeypatch, tty):
    """Mutant: show = sys.stderr.isatty() (--json no longer turning the progress line off)."""
    monkeypatch.setattr(sys.stderr, "isatty", lambda: tty)
    for argv, want in ((["estimate", "--json"], None), (["estimate"], cli._progress_line if tty else None)):
        calls.list.clear()
        assert main(argv) == 0
        assert _only(calls, "estimate")[1]["progress"] is want
    capsys.readouterr()


@pytest.mark.parametrize("ends", ["result", "error", "interrupt"])
def test_the_progress_line_is_cleared_when_the_estimate_ends_however_it_ends(calls, capsys, monkeypatch, ends):
    """On a terminal the status line is cleared before the result (its last redraw showed an earlier round's N and
    D), an error's or an interrupt's message: each starts on a clean line.  The message of a run that ended with
    fewer than 2 excursions was glued onto the status line (an audit).  Mutant: no clearing on an exception."""
    from dryfric_jax.api import NoEstimateError

    monkeypatch.setattr(sys.stderr, "isatty", lambda: True)
    end = {"error": NoEstimateError("fewer than 2 complete excursions within the work bounds"),
           "interrupt": KeyboardInterrupt("fewer than 2 complete excursions before the interrupt")}.get(ends)

    def estimate(*a, progress=None, **kw):
        progress(dict(n_excursions=1, D=math.nan, D_ci=math.nan, rtol=None, target=2000, elapsed_s=3.0,
                      left_s=None, left_to=None))
        if end is not None:
            raise end
        return _result()

    monkeypatch.setattr(api, "estimate_diffusivity", estimate)
    assert main(["estimate"]) == {"result": 0, "error": 1, "interrupt": 130}[ends]
    cap = capsys.readouterr()
    line = "\r  N =         1   D = \u2013   (target N = 2000)   3 s\x1b[K"
    said = {"result": "dryfric: warning: stand-in warning\n", "error": "dryfric: error: fewer than 2 complete excursions within the work bounds\n",
            "interrupt": "dryfric: interrupted: fewer than 2 complete excursions before the interrupt\n"}[ends]
    assert cap.err == line + "\r\x1b[K" + said
    assert cap.out == ("D = 1.5 (stand-in summary)\n" if ends == "result" else "")


def test_text_and_json_output_and_the_warnings_on_stderr(calls, capsys):
    """The result's warnings go to stderr, one line each; --json prints the result's to_dict() (its
    warnings included), the text the summary and, for --method auto only, the method's reason.
    Mutants: warnings printed to stdout; the JSON without 'warnings'; the reason printed for pdmp, not auto."""
    assert main(["estimate", "--json"]) == 0
    cap = capsys.readouterr()
    assert json.loads(cap.out) == _result().to_dict() and cap.err == "dryfric: warning: stand-in warning\n"
    assert main(["estimate", "--method", "auto"]) == 0
    cap = capsys.readouterr()
    assert cap.out == "D = 1.5 (stand-in summary)\nstand-in reason: chose di\n"
    assert main(["estimate", "--method", "pdmp"]) == 0
    assert capsys.readouterr().out == "D = 1.5 (stand-in summary)\n"


def test_estimate_exit_codes(calls, capsys):
    """A result stopped by Ctrl-C: exit 130 (its numbers printed); truncated excursions: exit 3 with the
    remedy (--allow-truncated, or --max-steps), 0 with --allow-truncated.  Mutants: the interrupted result
    exiting 1; the --max-steps remedy dropped; --allow-truncated ignored."""
    calls.result.update(stopped_by="interrupted")
    assert main(["estimate"]) == 130
    capsys.readouterr()
    from dryfric_jax.api import BOUND_NOTE, CUT_NOTE

    bound, cut = f"4 of 9 excursions {BOUND_NOTE} (max_steps = 64 steps per excursion)", f"{CUT_NOTE} 2 x max_time"
    calls.result.update(stopped_by="n_excursions", n_truncated=4, warnings=[bound])
    assert main(["estimate"]) == 3
    err = capsys.readouterr().err
    assert "4 truncated excursions" in err and "(--allow-truncated accepts it, --max-steps raises the bound)" in err
    # the remedy follows the cause: the final round's deadline names --max-time, not --max-steps
    calls.result.update(warnings=[cut])
    assert main(["estimate"]) == 3
    assert "(--allow-truncated accepts it, a larger --max-time lets the final round finish)" in capsys.readouterr().err
    calls.result.update(warnings=[cut, bound])
    assert main(["estimate"]) == 3
    assert ("(--allow-truncated accepts it, --max-steps raises the bound, a larger --max-time lets the final round "
            "finish)") in capsys.readouterr().err
    assert main(["estimate", "--allow-truncated"]) == 0
    assert "truncated" not in capsys.readouterr().err


def test_a_run_failure_is_exit_1(calls, capsys, monkeypatch):
    """Mutant: RuntimeError (no result possible) exiting 2, the user-error code."""
    monkeypatch.setattr(api, "estimate_diffusivity", calls.rec("estimate", RuntimeError("stand-in failure")))
    assert main(["estimate"]) == 1
    assert capsys.readouterr().err == "dryfric: error: stand-in failure\n"


def test_every_bruteforce_option_reaches_the_estimator(calls, capsys):
    """Mutants: bruteforce_diffusivity given seed 0, method 'di', h=None, delta=None, burn_in=0, dtype
    'float64', no max_work, more paths than --n-paths, or no max_events (--max-events: the PDMP's
    event bound, which its refusal says to raise)."""
    assert main(["bruteforce", "--t", "2.5", "--n-paths", "40", "--seed", "9", "--method", "pdmp", "--delta", "0.2",
                 "--burn-in", "0.5", "--dtype", "float32", "--max-work", "4e9", "--max-events", "12345", "--json"]) == 0
    (p, seed), kw = _only(calls, "bruteforce")
    assert seed == 9 and p == Params(**FIG3)
    assert kw == dict(t=2.5, n_paths=40, method="pdmp", h=None, delta=0.2, burn_in=0.5, dtype="float32",
                      max_events=12345, max_work=4e9)
    calls.list.clear()
    assert main(["bruteforce", "--t", "1", "--n-paths", "40", "--h", "0.0005", "--json"]) == 0
    assert _only(calls, "bruteforce")[1]["h"] == 0.0005
    assert _only(calls, "bruteforce")[1]["max_events"] is None  # the API's default bound
    capsys.readouterr()


def test_every_sweep_option_reaches_run_sweep(calls, tmp_path, capsys):
    """Mutants: run_sweep given seed 0, method 'di', h=None, delta=None, dtype 'float64', more excursions than
    --n-excursions, rtol=None, max_time=None, skip_refused=False, no max_work, no durations; the gamma_bar axis
    dropped from the grid; no progress bar; no line within a point."""
    out = str(tmp_path / "s.jsonl")
    assert main(["sweep", "--Gamma", "1,2", "--gamma-bar", "-0.5,0.25", "--out", out, "--seed", "5", "--method",
                 "pdmp", "--delta", "0.2", "--dtype", "float32", "--n-excursions", "40", "--rtol", "0.05",
                 "--max-time", "9", "--skip-refused", "--max-work", "3e9", "--durations", "64"]) == 0
    (pts, path), kw = _only(calls, "sweep")
    assert path == out and pts == sweep.grid(Gamma=[1.0, 2.0], gamma_bar=[-0.5, 0.25])
    assert {p["gamma_bar"] for p in pts} == {-0.5, 0.25}
    bar, within = kw.pop("progress"), kw.pop("point_progress")  # the bar shows the axes that vary: gamma_bar too
    assert (bar.func, bar.keywords) == (sweep.progress_bar, dict(axes=("Gamma", "tau", "gamma_bar")))
    assert (within.func, within.keywords) == (sweep.point_line, bar.keywords)  # and so does the line within a point
    assert kw == dict(seed=5, method="pdmp", h=None, delta=0.2, dtype="float32", n_excursions=40, rtol=0.05,
                      max_time=9.0, skip_refused=True, max_work=3e9, durations=64)
    calls.list.clear()
    assert main(["sweep", "--tau", "0.25", "--h", "0.0005", "--out", out]) == 0
    (pts, _), kw = _only(calls, "sweep")
    assert kw["h"] == 0.0005 and pts == sweep.grid(tau=[0.25]) and kw["durations"] is None
    capsys.readouterr()


def test_sweep_defaults_are_the_estimates(calls, tmp_path, capsys):
    """Mutants: the sweep's --seed default 1; its --n-excursions default 2000 (estimate's is 20 000)."""
    assert main(["sweep", "--out", str(tmp_path / "s.jsonl")]) == 0
    _, kw = _only(calls, "sweep")
    assert (kw["seed"], kw["n_excursions"]) == (0, 20_000)
    capsys.readouterr()


def test_sweep_summary_line_and_exit_codes(calls, tmp_path, capsys):
    """The summary line counts what run_sweep returned; exit 3 for truncated points unless
    --allow-truncated, 1 for failed ones.  Mutants: 'truncated' left out of the summary; the --max-time count
    left out; 'already in' not the skipped count; a failed point exiting 3; --allow-truncated ignored; --json
    printing the text line."""
    out = str(tmp_path / "s.jsonl")
    calls.summary.update(computed=2, skipped=1, total=4, refused=1, truncated=1, time_limited=1)
    assert main(["sweep", "--out", out]) == 3
    cap = capsys.readouterr()
    assert cap.out == (f"2 points computed, 1 already in {out}, 4 in the grid, 1 refused, 1 truncated, "
                       "1 stopped by --max-time\n")
    assert "exit 3 (--allow-truncated accepts them)" in cap.err
    assert main(["sweep", "--out", out, "--allow-truncated", "--json"]) == 0
    assert json.loads(capsys.readouterr().out) == calls.summary
    calls.summary.update(failed=1)
    assert main(["sweep", "--out", out, "--allow-truncated"]) == 1
    assert "1 point ended without an estimate" in capsys.readouterr().err
    # a point with D but without its count's mean (--durations): exit 1 too, said in the summary and on stderr
    calls.summary.update(failed=0, no_count=2)
    assert main(["sweep", "--out", out, "--allow-truncated"]) == 1
    cap = capsys.readouterr()
    assert cap.out.endswith(", 2 without a duration count\n") and "error: 2 points got D but no mean" in cap.err


def test_combine_passes_each_result_with_its_file_as_label(calls, tmp_path, capsys):
    """A pooled result with truncated excursions exits 3 unless --allow-truncated.  Mutants:
    combine_estimates given labels=None (a refusal then names no file); combine always exiting 0."""
    files = []
    for seed in (1, 2):
        files.append(str(tmp_path / f"r{seed}.json"))
        with open(files[-1], "w") as f:
            json.dump(dict(seed=seed), f)
    assert main(["combine", *files, "--json"]) == 0
    (results,), kw = _only(calls, "combine")
    assert results == [dict(seed=1), dict(seed=2)] and kw == dict(labels=files, allow_mixed_versions=False)
    calls.result.update(n_truncated=3)
    assert main(["combine", *files]) == 3
    err = capsys.readouterr().err
    assert "3 truncated excursions" in err and "they come from" not in err  # the inputs hold none here
    assert main(["combine", *files, "--allow-truncated"]) == 0
    capsys.readouterr()
    with open(files[1], "w") as f:  # the file that holds them is named (an audit)
        json.dump(dict(seed=2, n_truncated=3), f)
    assert main(["combine", *files]) == 3
    assert f"they come from {files[1]})" in capsys.readouterr().err


def test_figures_options_reach_run_figures(calls, tmp_path, capsys, monkeypatch):
    """Mutants: run_figures given seed 0 instead of --seed; quick=True without --quick; a Ctrl-C exiting 1; no
    progress lines."""
    from dryfric_jax.cli import _figures_line

    out = str(tmp_path / "figs")
    assert main(["figures", "--fig", "3", "--out", out, "--seed", "4"]) == 0
    assert calls.list == [("figures", ("3", out), dict(quick=False, seed=4, redo=False, progress=_figures_line))]
    calls.list.clear()
    assert main(["figures", "--fig", "table1", "--quick", "--out", out, "--redo"]) == 0
    assert calls.list == [("figures", ("table1", out), dict(quick=True, seed=0, redo=True, progress=_figures_line))]
    monkeypatch.setattr(figures, "run_figures", calls.rec("figures", KeyboardInterrupt()))
    assert main(["figures", "--fig", "3", "--out", out]) == 130
    assert "interrupted" in capsys.readouterr().err


def test_bench_options_reach_the_bench(calls, capsys):
    """--lanes or --block: the layout sweep at the given lists (the other the run's own), dtype, N and rounds;
    neither: the side-by-side bench.  Mutants: the layout sweep's dtype always float32; its repeat 1; --block
    alone running the side-by-side bench; run_bench's repeat 1."""
    assert main(["bench", "--block", "64", "--n-excursions", "500", "--repeat", "3", "--dtype", "float64"]) == 0
    plan = plan_estimate(Params(**FIG3), n_excursions=500)
    assert calls.list == [("tune_layout", ([plan.lanes], [64], "float64"), dict(n_excursions=500, repeat=3))]
    calls.list.clear()
    assert main(["bench", "--lanes", "64,128", "--n-excursions", "500"]) == 0
    assert calls.list == [("tune_layout", ([64, 128], [plan.block], "float32"), dict(n_excursions=500, repeat=1))]
    calls.list.clear()
    assert main(["bench", "--n-excursions", "300", "--repeat", "2", "--json"]) == 0
    assert calls.list == [("run_bench", (), dict(n_excursions=300, repeat=2))]
    assert json.loads(capsys.readouterr().out.splitlines()[-1]) == {"stand-in": "bench"}
