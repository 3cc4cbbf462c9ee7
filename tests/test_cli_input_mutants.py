"""CLI parsing and user-error paths, from a second mutation audit of dryfric_jax/cli.py (the first,
test_cli_mutants.py, checked that each option reaches the API; its stand-ins are reused here).

Audited: _in_float64, _number, _tau_L, _list_of, _join_negative_values, _int_at_least, _count_option, _check_out,
_write_out, _read_results, _progress_line, _truncation_exit, _theory, _points, _warnings_kept_in_result, _report
and the exit codes and error paths of _run, _sweep and main.  62 one-line mutants: 31 failed the existing tests
(28 the fast CLI tests, 3 only test_combine's CLI tests), 4 are equivalent (a .strip() that float() and the
substring checks do not need; "+inf" listed though float() reads it; a "^" in a pattern used with re.match; a
one-line file's error said with "line 1"), 27 passed them and fail here; none is left alive.
Each test names the mutants (single edits of cli.py) it fails on and that the other CLI tests let pass.  Expected
values are the documented behaviour (the module docstring's exit codes, the options' help, README), worked out
by hand: nothing is simulated."""
import math
import sys
import warnings

import pytest

from test_cli_mutants import _only, calls  # noqa: F401, F811  (calls: the stand-ins fixture)

from dryfric_jax import cli, figures, sweep
from dryfric_jax.api import DryfricWarning, ProjectionWarning
from dryfric_jax.cli import main


def _err_line(capsys):
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith("dryfric: error: "), err
    return err[0]


def test_zeros_and_infinities_written_any_way_are_read_as_such(calls, capsys):
    """Only a number float64 cannot hold is refused as out of its range: a zero with an exponent ("0e5") is
    0, and "Inf" in capitals is inf (--max-time inf: no limit; --gamma-bar 0: no bias).  Mutants: the
    mantissa taken after the 'e' ("0e5" refused as 1e-400 would be); the text not lower-cased ("Inf" refused
    as beyond float64)."""
    assert main(["estimate", "--gamma-bar", "0e5", "--max-time", "Inf", "--json"]) == 0
    (p, _), kw = _only(calls, "estimate")
    assert p.gamma_bar == 0.0 and kw["max_time"] == math.inf
    calls.list.clear()
    assert main(["estimate", "--gamma-bar", "-0E-5", "--max-time", "INFINITY", "--json"]) == 0
    (p, _), kw = _only(calls, "estimate")
    assert p.gamma_bar == 0.0 and kw["max_time"] == math.inf
    capsys.readouterr()
    assert main(["estimate", "--max-time", "1E400"]) == 2  # and a real overflow, in capitals, still refused
    assert "--max-time must be a number within float64's range" in _err_line(capsys)


def test_an_option_left_without_its_value_is_one_line_exit_2(calls, capsys):
    """``dryfric estimate --tau`` (the value forgotten at the end of the line): argparse's "expected one
    argument", naming the option, exit 2.  Mutants: the negative-value join looking past the end of argv
    (an IndexError traceback); every "argument ...: " prefix cut (the option's name lost)."""
    for argv in (["estimate", "--tau"], ["sweep", "--out", "s.jsonl", "--gamma-bar"], ["theory", "--h"]):
        assert main(argv) == 2
        line = _err_line(capsys)
        assert argv[-1] in line and "expected one argument" in line, line
    assert calls.list == []


def test_a_list_with_a_blank_item_is_refused_as_a_list(calls, capsys):
    """A blank item in a sweep axis ("1, ,2") is a value left out, refused as for "1,,2" (not as the number
    ' ').  Mutant: the items not stripped before the emptiness check."""
    assert main(["sweep", "--Gamma", "1, ,2", "--out", "s.jsonl"]) == 2
    assert "--Gamma must be a comma-separated list of values, none empty (got '1, ,2')" in _err_line(capsys)
    assert main(["sweep", "--Gamma", " 1 , 2 ", "--out", "s.jsonl"]) == 0  # spaces around the values: read
    (pts, _), _ = _only(calls, "sweep")
    assert pts == sweep.grid(Gamma=[1.0, 2.0])
    capsys.readouterr()


def test_negative_values_written_from_the_point_need_no_equals_sign(calls, tmp_path, capsys):
    """"-.5,.25" (a sweep list) and "-.5e-1" are values, as "-0.5" is (argparse alone takes only "-.25"-like
    plain decimals).  Mutant: the join's pattern without "-." (these read as unknown options)."""
    out = str(tmp_path / "s.jsonl")
    assert main(["sweep", "--gamma-bar", "-.5,.25", "--out", out]) == 0
    (pts, _), _ = _only(calls, "sweep")
    assert pts == sweep.grid(gamma_bar=[-0.5, 0.25])
    assert main(["estimate", "--gamma-bar", "-.5e-1", "--json"]) == 0
    (p, _), _ = _only(calls, "estimate")
    assert p.gamma_bar == -0.05
    capsys.readouterr()


def test_integer_options_take_both_ends_of_their_range(calls, capsys):
    """--n-excursions in [2, 2^62], --seed in [0, 2^62 - 2^20] (the help's and the messages' ranges), both
    ends included, one past them refused with the range.  2^62 = 4611686018427387904 and
    2^62 - 2^20 = 4611686018427387904 - 1048576 = 4611686018426339328.  Mutants: the lower end refused
    (v <= lo); the upper end refused (v >= hi); the seed's bound 2^62 (2^62 - 2^20 + 1 taken); the counts'
    bound 2^63 (2^62 + 1 taken)."""
    top_seed = 4611686018426339328
    assert main(["estimate", "--n-excursions", "2", "--seed", "0", "--json"]) == 0
    (_, seed), kw = _only(calls, "estimate")
    assert (seed, kw["n_excursions"]) == (0, 2)
    calls.list.clear()
    assert main(["estimate", "--n-excursions", "4611686018427387904", "--seed", str(top_seed), "--json"]) == 0
    (_, seed), kw = _only(calls, "estimate")
    assert (seed, kw["n_excursions"]) == (top_seed, 2**62)
    capsys.readouterr()
    assert main(["estimate", "--seed", str(top_seed + 1)]) == 2
    assert f"--seed must be an integer in [0, 2^62 - 2^20] (got '{top_seed + 1}')" in _err_line(capsys)
    assert main(["estimate", "--n-excursions", "4611686018427387905"]) == 2
    assert "--n-excursions must be an integer in [2, 2^62] (got '4611686018427387905')" in _err_line(capsys)
    assert main(["bench", "--repeat", "1", "--lanes", "1", "--block", "1", "--json"]) == 0  # ">= 1": 1 taken
    capsys.readouterr()


def test_combine_refuses_a_file_that_holds_no_object_and_reads_records_by_line(calls, tmp_path, capsys):
    """A JSON file that is not an object (a list) holds no estimate result: exit 2, naming it.  A results file of
    records (JSON Lines) is read one record a line, blank lines skipped, each labelled path:line (its line
    number in the file, from 1).  A file that is not JSON or not UTF-8 is refused naming it.  Mutants: only a
    string refused (a list passed on); blank lines not skipped; the labels without the line, or counted from 0;
    only OSError turned into the refusal (the JSON or UTF-8 error said without the file's name)."""
    bad = tmp_path / "list.json"
    bad.write_text("[1, 2]\n")
    assert main(["combine", str(bad)]) == 2
    assert f"files: {str(bad)!r} holds no estimate result (a JSON object)" in _err_line(capsys)
    for text in (b"not json\n", b"\xff\xfe{}"):  # one line, not JSON; not UTF-8
        bad.write_bytes(text)
        assert main(["combine", str(bad)]) == 2
        assert f"files: cannot read an estimate result from {str(bad)!r} (" in _err_line(capsys)
    recs = tmp_path / "s.jsonl"
    recs.write_text('{"seed": 1}\n\n{"seed": 2}\n')
    assert main(["combine", str(recs), "--json"]) == 0
    (results,), kw = _only(calls, "combine")
    assert results == [{"seed": 1}, {"seed": 2}] and kw == dict(labels=[f"{recs}:1", f"{recs}:3"], allow_mixed_versions=False)
    capsys.readouterr()


def _progress(capsys, **d):
    cli._progress_line(dict(dict(n_excursions=1234, D=2.0, D_ci=0.1, rtol=0.05, target=5000, elapsed_s=12.0,
                                 left_s=None, left_to=None), **d))
    cap = capsys.readouterr()
    assert cap.out == "" and cap.err.startswith("\r") and cap.err.endswith("\x1b[K")
    return cap.err


def test_the_progress_line(capsys):
    """The status line: N, D with its CI half-width in percent of |D| (0.1 / 2 = 5.00%), the goal (rtol 0.05 as
    5%, or N), the time so far and left, naming --max-work or --max-time when that limit will end the run.
    Mutants: the percent of D, not |D| (negative); the rtol not in percent; --max-time not named;
    the limit named with its API name (max_work) instead of the option's."""
    line = _progress(capsys)
    assert "N =      1234   D = 2 ± 5.00%   (target 5%)   12 s" in line and "left" not in line
    assert "D = -2 ± 5.00%" in _progress(capsys, D=-2.0)
    line = _progress(capsys, rtol=None, left_s=30.0, left_to="max_time")
    assert "(target N = 5000)" in line and "12 s, ~30 s left (stops at --max-time)" in line
    assert "~30 s left (stops at --max-work)" in _progress(capsys, left_s=30.0, left_to="max_work")
    line = _progress(capsys, left_s=30.0, left_to="rtol")
    assert "~30 s left" in line and "stops at" not in line
    # no D before 2 excursions have closed (the API gives nan): a dash, not "nan ± nan%"
    for d, ci in ((math.nan, math.nan), (2.0, math.nan), (0.0, 0.0)):
        line = _progress(capsys, n_excursions=0, D=d, D_ci=ci)
        assert "N =         0   D = –   (target 5%)" in line and "nan" not in line, line


def test_theory_prints_the_chains_step_bias_in_percent(capsys):
    """``theory --h``: the chain's D, M0 and E[V^2] with their relative differences from white noise's,
    100 (chain / exact - 1) percent, signed ("white noise: 0" where white noise's is 0: M0 without bias).  The
    point and step of test_cli's JSON check (fast).  Mutant: the ratio inverted (exact / chain)."""
    from dryfric_jax import theory
    from dryfric_jax.chain_law import white_chain_law
    from dryfric_jax.params import Params

    assert main(["theory", "--nondim", "--tau", "1e-5", "--tau-L", "inf", "--gamma-bar", "0", "--h", "0.05"]) == 0
    out = capsys.readouterr().out.splitlines()
    p = Params.from_nondim(1e-5, math.inf, 0.0)
    law, D, v2 = white_chain_law(p, 0.05), theory.exact_D(p), theory.exact_mean_square_velocity(p)
    want = [f"D = {law.D:.6g} ({100 * (law.D / D - 1):+.2f}%)", f"M0 = {law.M0:.6g} (white noise: 0)",
            f"E[V^2] = {law.mean_v2:.6g} ({100 * (law.mean_v2 / v2 - 1):+.2f}%)"]
    assert len(out) == 3 and all(w in out[2] for w in want), (out, want)
    assert law.D < D and "D = " in out[2] and "(-" in out[2]  # the chain's D is below white noise's


def test_sweep_counts_notes_and_exit_codes(calls, tmp_path, capsys):
    """"1 point", "0 points"; a Ctrl-C (run_sweep says interrupted): exit 130 and the points written are said;
    a refused point without a failed one is noted with where its reason is (exit 0).  Mutants: "0 point";
    the interrupted sweep exiting 1; the note only when points were both refused and failed."""
    out = str(tmp_path / "s.jsonl")
    calls.summary.update(computed=1, total=1)
    assert main(["sweep", "--out", out]) == 0
    assert capsys.readouterr().out == f"1 point computed, 0 already in {out}, 1 in the grid\n"
    calls.summary.update(computed=0, skipped=2, total=3, refused=1)
    assert main(["sweep", "--out", out, "--skip-refused"]) == 0
    cap = capsys.readouterr()
    assert cap.out == f"0 points computed, 2 already in {out}, 3 in the grid, 1 refused\n"
    assert cap.err == (f"dryfric: note: 1 point refused and 0 points failed: no result; their reasons are in {out} "
                       "(status, reason)\n")
    calls.summary.update(computed=2, refused=0, interrupted=True)
    assert main(["sweep", "--out", out]) == 130
    assert (f"dryfric: interrupted: 2 points newly written to {out}; run the same command again to resume"
            in capsys.readouterr().err)
    # a Ctrl-C in a point's duration count keeps its D (run_sweep's kept_d): said, not "0 points" alone
    calls.summary.update(computed=0, kept_d=1)
    assert main(["sweep", "--out", out, "--durations", "100"]) == 130
    assert (f"dryfric: interrupted: 0 points and the finished D of the point in progress (not its duration count) "
            f"newly written to {out}; run the same command again" in capsys.readouterr().err)


@pytest.mark.parametrize("cmd", ["sweep", "figures"])
def test_write_failures_after_the_start_are_exit_1_and_say_what_is_kept(calls, tmp_path, capsys, monkeypatch, cmd):
    """A results file or figure that cannot be written once the run is going (a full disk) is exit 1 (no result
    possible), not 2 (a user mistake), and says the finished points are kept: the same command resumes.  A
    points file that is not one (ValueError "out must ...") is the user's --out: exit 2, named.  Mutants: the
    OSError turned into a ValueError (exit 2); the "out must" refusal not given the option's "--"."""
    out = str(tmp_path / "o")
    argv = ["sweep", "--out", out] if cmd == "sweep" else ["figures", "--fig", "3", "--out", out]
    where = (sweep, "run_sweep") if cmd == "sweep" else (figures, "run_figures")
    monkeypatch.setattr(*where, calls.rec(cmd, OSError(28, "No space left on device")))
    assert main(argv) == 1
    line = _err_line(capsys)
    assert "--out" in line and "No space left on device" in line and "the same command resumes" in line
    monkeypatch.setattr(*where, calls.rec(cmd, ValueError("out must be a points file of this command")))
    assert main(argv) == 2
    assert _err_line(capsys) == "dryfric: error: --out must be a points file of this command"


@pytest.mark.parametrize("tty", [False, True])
def test_only_the_projection_warning_is_said_at_once(capsys, monkeypatch, tty):
    """In a run, a ProjectionWarning goes to stderr at once ("dryfric: warning: ...", after clearing the
    progress line on a terminal only); the other DryfricWarnings are kept in the result (printed by _report)
    and not said twice.  Mutants: DryfricWarnings ignored (the projection too); every DryfricWarning said at
    once; the terminal's clearing code written into a file or pipe."""
    monkeypatch.setattr(sys.stderr, "isatty", lambda: tty)
    with cli._warnings_kept_in_result():
        warnings.warn("in the result", DryfricWarning)
        warnings.warn("max_work is projected to end the run", ProjectionWarning)
    cap = capsys.readouterr()
    assert cap.out == "" and cap.err == ("\r\x1b[K" if tty else "") + (
        "dryfric: warning: max_work is projected to end the run\n")


@pytest.mark.parametrize("cmd", [["estimate"], ["combine"]])
def test_one_truncated_excursion_is_exit_3(calls, tmp_path, capsys, cmd):
    """Exit 3 when excursions hit the work bound, even one (the result is biased).  Mutant: 'n_truncated > 1'."""
    calls.result.update(n_truncated=1)
    if cmd == ["combine"]:
        f = tmp_path / "r.json"
        f.write_text('{"seed": 1}')
        cmd = cmd + [str(f)]
    assert main(cmd) == 3
    assert "dryfric: warning: 1 truncated excursions: the result above is biased low; exit 3" in capsys.readouterr().err
