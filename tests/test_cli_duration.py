"""``dryfric duration``: the DI's mean long-excursion duration (dryfric_jax.durations) from the command line."""
import json
import math

import pytest

from dryfric_jax.cli import main
from dryfric_jax.durations import di_long_excursion_duration
from dryfric_jax.params import FIG3, Params

SMALL = ["--n-lanes", "32", "--n-excursions", "32"]


def test_prints_the_mean_with_its_ci_and_is_the_python_result(capsys):
    """The text and the JSON are the library's result for the same seed and settings, to the last bit."""
    assert main(["duration", *SMALL, "--seed", "4"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("mean long-excursion duration = ") and "(releases counted; 32 asked) in 32 lanes" in out
    assert main(["duration", *SMALL, "--seed", "4", "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    want = json.loads(di_long_excursion_duration(Params(**FIG3), 4, n_lanes=32, n_excursions=32).to_json())
    assert {k: v for k, v in got.items() if k != "wall_s"} == {k: v for k, v in want.items() if k != "wall_s"}
    assert got["params"] == FIG3 and got["seed"] == 4 and got["bridge"]
    assert len(got["warnings"]) == 1 and got["warnings"][0].startswith(f"n_excursions = {got['n_excursions']} < 100")


def test_no_bridge_is_the_raw_count(capsys):
    """--no-bridge: the library's bridge=False, to the last bit, and said in the text."""
    assert main(["duration", *SMALL, "--seed", "4", "--no-bridge", "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    want = json.loads(di_long_excursion_duration(Params(**FIG3), 4, n_lanes=32, n_excursions=32,
                                                 bridge=False).to_json())
    assert {k: v for k, v in got.items() if k != "wall_s"} == {k: v for k, v in want.items() if k != "wall_s"}
    assert not got["bridge"]
    assert main(["duration", *SMALL, "--seed", "4", "--no-bridge"]) == 0
    assert "raw count (no bridge correction)" in capsys.readouterr().out


def test_out_file_and_strict_json_for_tau_L_inf(tmp_path, capsys):
    out = tmp_path / "d.json"
    assert main(["duration", *SMALL, "--tau-L", "inf", "--gamma-bar", "0", "--out", str(out), "--json"]) == 0
    printed = capsys.readouterr().out
    assert json.loads(out.read_text()) == json.loads(printed) and '"tau_L": "inf"' in printed


def test_truncated_excursions_exit_3_unless_allowed(capsys):
    """Excursions in flight at --max-steps are counted, said and exit 3 (the mean is biased low), as 'estimate' does
    with truncated excursions; --allow-truncated accepts them."""
    argv = ["duration", *SMALL, "--max-steps", "15000", "--h", "6.7e-4"]  # the D estimator's h: shorter runs
    assert main(argv) == 3
    err = capsys.readouterr().err
    assert "bound max_steps = 15104 stopped" in err and "long excursions truncated: the mean above is biased low" in err
    assert main([*argv, "--allow-truncated"]) == 0


@pytest.mark.parametrize("argv,said", [
    (["--n-excursions", "1"], "--n-excursions"), (["--n-lanes", "0"], "--n-lanes"),
    (["--max-steps", "1e20"], "--max-steps must be an integer in [1, (2^31 - 2) x 128]"),
    (["--h", "1e-10"], "max_work must be >= "), (["--max-work", "1"], "max_work must be"),
    (["--max-steps", "0"], "--max-steps"),
    (["--max-steps", "100"], "max_steps = 128 is too small"), (["--dtype", "float16"], "dtype must be one of"),
    (["--tau-L", "inf", "--gamma-bar", "4"], "gamma_bar must satisfy |gamma_bar| < Delta"), (["--h", "-1"], "h must"),
    (["--seed", "-1"], "--seed")])
def test_bad_input_exits_2_with_one_line(capsys, argv, said):
    # a --max-steps that ran and counted fewer than 2: exit 1, no result possible (as estimate's), not 2
    assert main(["duration", *SMALL[:2], *argv]) == (1 if said.startswith("max_steps = ") else 2)
    err = capsys.readouterr().err
    assert said in err and "Traceback" not in err and err.startswith("dryfric: error: ")


def test_a_run_that_fails_still_says_its_warnings_first(capsys):
    """The warning that explains a failure (tau/h < 10 here: the count is not the paper's excursion) was kept for the
    result, which never came: only the error was printed (an audit).  Warnings are now said as they come.  (h is
    asked for: the default keeps tau/h >= 700.)"""
    assert main(["duration", "--nondim", "--tau", "1e-3", "--h", "0.01", "--n-lanes", "4", "--n-excursions", "2",
                 "--max-steps", "128"]) == 1  # it ran: no result possible, as for estimate (it was 2)
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 2 and err[0].startswith("dryfric: warning: tau/h = ") and "too small" in err[1]


def test_warnings_are_said_once_and_kept_in_the_json(capsys):
    assert main(["duration", *SMALL, "--max-steps", "15000", "--h", "6.7e-4", "--json", "--allow-truncated"]) == 0
    cap = capsys.readouterr()
    said = [line for line in cap.err.splitlines() if line.startswith("dryfric: warning: ")]
    assert len(said) == 2 and "bound max_steps = 15104 stopped" in said[0] and "< 100: the t CI under-covers" in said[1]
    assert json.loads(cap.out)["warnings"] == [x.removeprefix("dryfric: warning: ") for x in said]


def test_max_time_reaches_the_count_and_a_bad_one_exits_2(capsys):
    """--max-time is the library's max_time: a limit not reached gives the bits of a run without it, with the
    limit recorded; 0 or a word is refused in one line naming it."""
    assert main(["duration", *SMALL, "--seed", "4", "--max-time", "1e6", "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    want = json.loads(di_long_excursion_duration(Params(**FIG3), 4, n_lanes=32, n_excursions=32).to_json())
    assert got["max_time"] == 1e6 and got["stopped_by"] == want["stopped_by"] == "n_excursions"
    assert {k: v for k, v in got.items() if k not in ("wall_s", "max_time")} == {
        k: v for k, v in want.items() if k not in ("wall_s", "max_time")}
    for bad in ("0", "x"):
        assert main(["duration", *SMALL, "--max-time", bad]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and ("max-time" in err[0] or "max_time" in err[0]) and "Traceback" not in err[0], err


def test_a_ctrl_c_prints_what_was_counted_and_exits_130(monkeypatch, tmp_path, capsys):
    """The first Ctrl-C finishes the excursions in flight, and the command prints and writes what it counted (a
    result, not a traceback) and exits 130, as 'estimate' does."""
    from test_durations import _ctrl_c_at

    _ctrl_c_at(monkeypatch, {30})
    out = tmp_path / "d.json"
    assert main(["duration", "--Gamma", "10", "--tau", "0.125", "--n-excursions", "10000", "--n-lanes", "64",
                 "--seed", "5", "--out", str(out)]) == 130
    cap = capsys.readouterr()
    assert cap.out.startswith("mean long-excursion duration = ") and "Traceback" not in cap.err
    assert "dryfric: interrupted: finishing the long excursions in flight" in cap.err
    got = json.loads(out.read_text())
    assert got["stopped_by"] == "interrupted" and got["n_truncated"] == 0 and 2 <= got["n_excursions"] < 10_000


@pytest.mark.parametrize("tty", [True, False])
def test_a_terminal_shows_the_counts_progress_and_json_never_does(capsys, monkeypatch, tty):
    """On a terminal the count's status line is redrawn after every piece and cleared before the summary, a
    warning or an error (each on a clean line); under --json, or off a terminal, stderr has none of it, and the
    result is the same.  Mutants: the line shown under --json; not cleared after a failed run."""
    import sys

    monkeypatch.setattr(sys.stderr, "isatty", lambda: tty)
    assert main(["duration", *SMALL, "--seed", "4", "--json"]) == 0
    cap = capsys.readouterr()
    got = json.loads(cap.out)
    assert "long excursions =" not in cap.err and "\r" not in cap.err
    assert main(["duration", *SMALL, "--seed", "4"]) == 0
    cap = capsys.readouterr()
    assert f"mean long-excursion duration = {got['mean']:g}"[:36] in cap.out
    assert ("\r  long excursions = " in cap.err) is tty and ("\x1b[K" in cap.err) is tty
    if tty:  # the small-sample warning said after the count, on a cleared line; the line cleared at the end
        assert "\r\x1b[Kdryfric: warning: n_excursions = " in cap.err and cap.err.endswith("\r\x1b[K")
    assert main(["duration", *SMALL[:2], "--max-steps", "100"]) == 1
    err = capsys.readouterr().err
    assert err.endswith("\r\x1b[Kdryfric: error: " + err.split("dryfric: error: ")[-1]) is tty


def test_the_counts_status_line(capsys):
    """Counted so far of those asked, the mean so far (a dash before the first), the time so far and left, naming
    --max-time when it will end the count; once no excursion starts, those still in flight.  Mutants: the time
    left shown while stopping; --max-time not named; nan shown."""
    from dryfric_jax.cli import _duration_line

    def line(**d):
        _duration_line(dict(n_excursions=40, target=2048, in_flight=12, mean_s=4.25, stopping=False, elapsed_s=12.0,
                            left_s=None, left_to=None) | d)
        cap = capsys.readouterr()
        assert cap.out == "" and cap.err.startswith("\r") and cap.err.endswith("\x1b[K")
        return cap.err

    assert "long excursions =      40 of 2048   mean so far = 4.25 s   12 s\x1b[K" in line()
    assert "12 s, ~30 s left\x1b[K" in line(left_s=30.0, left_to="n_excursions")
    assert "12 s, ~30 s left (stops at --max-time)" in line(left_s=30.0, left_to="max_time")
    assert "12 s, finishing the 3 in flight\x1b[K" in line(stopping=True, in_flight=3, left_s=30.0)
    assert "12 s, done\x1b[K" in line(stopping=True, in_flight=0)
    nan = line(n_excursions=0, mean_s=math.nan)
    assert "mean so far = –   12 s" in nan and "nan" not in nan
