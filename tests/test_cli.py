"""CLI: JSON keys, bad input gives exit code 2 and one line naming the parameter."""
import json
import math
import subprocess
import sys

import pytest

from dryfric_jax.chain_law import white_chain_law
from dryfric_jax.cli import main
from dryfric_jax.params import FIG3, Params
from dryfric_jax.plan import plan_estimate

FIG3_TAU = FIG3["tau"]
# admissible PDMP grid step at the Fig. 3 point, from the documented condition
# tau delta (L_req + 2 delta) < 2, L_req = 8/sqrt(tau) (nondimensional; README "The PDMP")
_t = FIG3_TAU * FIG3["Delta"] ** 2 / FIG3["Gamma"]
_L = 8 / _t**0.5
_dm = (-_t * _L + (_t * _t * _L * _L + 16 * _t) ** 0.5) / (4 * _t) * FIG3['Delta'] / FIG3['Gamma'] ** 0.5
_digit = 10.0 ** (math.floor(math.log10(_dm)) - 3)
DELTA_MAX = f"{math.floor(_dm / _digit) * _digit:.4g}"  # 4 digits, rounded down (into the range)

ESTIMATE_KEYS = {"D", "D_ci", "M0", "M0_ci", "mean_duration", "n_excursions", "n_truncated", "method", "h", "dtype",
                 "seed", "wall_s", "lane_steps_per_s", "params"}

BAD = [  # (argv, word the one-line message must contain)
    (["estimate", "--Gamma", "0"], "Gamma"),
    (["estimate", "--Gamma", "-1"], "Gamma"),
    (["estimate", "--Gamma", "nan"], "Gamma"),
    (["estimate", "--Delta", "inf"], "Delta"),
    (["estimate", "--tau", "0"], "tau"),
    (["estimate", "--tau", "-2"], "tau"),
    (["estimate", "--tau-L", "0"], "tau_L"),
    (["estimate", "--tau-L", "abc"], "--tau-L"),
    (["estimate", "--gamma-bar", "nan"], "gamma_bar"),
    (["estimate", "--h", "0"], "h must"),
    (["estimate", "--h=-1e-4"], "h must"),
    (["estimate", "--h", "-1e-4"], "h must be in"),  # argparse took -1e-4 for an option ("expected one argument")
    (["estimate", "--h", "1.0"], "h must"),  # not small against tau0
    (["estimate", "--n-excursions", "1"], "--n-excursions"),
    (["estimate", "--n-excursions", "2.5"], "--n-excursions"),
    (["estimate", "--seed", "-3"], "--seed"),
    (["estimate", "--seed", "x"], "--seed"),
    (["estimate", "--method", "magic"], "method"),
    (["estimate", "--dtype", "float16"], "dtype"),
    (["bruteforce", "--t", "-1", "--n-paths", "10"], "t must"),
    (["bruteforce", "--t", "1", "--n-paths", "1"], "--n-paths"),
    # numbers beyond float64 were read as inf or 0: "(got 0.0)" for 1e-400, and tau_L = 1e999 ran as inf
    (["estimate", "--Gamma", "1e-400"], "--Gamma must be a number within float64's range, 1e-308 to 1e308 in "
                                        "magnitude (got '1e-400')"),
    (["estimate", "--tau-L", "1e999"], "--tau-L must be a number within float64's range"),
    (["estimate", "--gamma-bar", "-1e400"], "--gamma-bar must be a number within float64's range"),
    (["sweep", "--out", "/nonexistent-dir/x.jsonl", "--tau", "0.1,1e400"], "--tau must be a number within"),
    (["bruteforce", "--t", "1", "--n-paths", "10", "--h", "0.00e-999"], "h must be in ["),  # a zero: its range
    # an option given twice ran silently at the last value
    (["estimate", "--tau", "1", "--Gamma", "2", "--tau", "2"], "--tau must be given once (it was given again: 2.0)"),
    (["bruteforce", "--t", "1", "--n-paths", "10", "--t=2"], "--t must be given once"),
    (["sweep", "--out", "/nonexistent-dir/x.jsonl", "--seed", "1", "--seed", "1"], "--seed must be given once"),
    (["combine", "a.json", "--out", "x.json", "--out", "y.json"], "--out must be given once"),
    (["theory", "--tau-L", "inf", "--gamma-bar", "4"], "gamma_bar"),  # |gamma_bar| >= Delta: no stationary state
    (["estimate", "--Gamma", "abc"], "--Gamma"),
    (["estimate", "--method", "pdmp", "--delta", "0"], f"delta must be in (0, {DELTA_MAX})"),
    (["estimate", "--method", "pdmp", "--delta", "-0.1"], f"delta must be in (0, {DELTA_MAX})"),
    (["estimate", "--method", "pdmp", "--delta", "0.5"], f"delta must be in (0, {DELTA_MAX})"),  # tau delta L_X >= 2
    (["estimate", "--method", "pdmp", "--delta", "nan"], "delta must be in"),
    (["estimate", "--method", "auto", "--delta", "1"], "delta must be in"),
    (["estimate", "--method", "di", "--delta", "0.1"], "delta"),
    (["estimate", "--method", "pdmp", "--h", "0.001"], "h must not be given"),
    (["bruteforce", "--method", "pdmp", "--delta", "0.4", "--t", "1", "--n-paths", "10"], "delta must be in"),
    (["bruteforce", "--method", "auto", "--t", "1", "--n-paths", "10"], "method"),
]


# every numeric option: negative, zero, NaN and inf where they are out of range (valid: tau-L inf,
# gamma-bar negative or zero, max-time inf)
_BF = ["bruteforce", "--t", "1", "--n-paths", "10"]
_NUMERIC = [  # (command prefix, option, API name in the message, out-of-range values)
    (["estimate"], "--Gamma", "Gamma", ["-1", "0", "nan", "inf"]),
    (["estimate"], "--Delta", "Delta", ["-1", "0", "nan", "inf"]),
    (["estimate"], "--tau", "tau", ["-1", "0", "nan", "inf"]),
    (["estimate"], "--tau-L", "tau_L", ["-1", "0", "nan"]),
    (["estimate"], "--gamma-bar", "gamma_bar", ["nan", "inf", "-inf"]),
    (["estimate"], "--h", "h", ["-1", "0", "nan", "inf", "1.0"]),  # 1.0 s >= tau0: larger than an excursion
    (["estimate", "--method", "pdmp"], "--delta", "delta", ["-1", "0", "nan", "inf"]),
    (["estimate"], "--n-excursions", "n-excursions", ["-1", "0", "1", "nan", "inf", "2.5"]),
    (["estimate"], "--rtol", "rtol", ["-1", "0", "nan", "inf", "1.5"]),
    (["estimate"], "--max-time", "max_time", ["-1", "0", "nan"]),
    (["estimate"], "--max-work", "max_work", ["-1", "0", "nan", "inf"]),
    (["estimate"], "--max-steps", "max-steps", ["-1", "0", "nan", "1.5"]),
    (["estimate"], "--seed", "seed", ["-1", "1.5", "nan"]),
    (_BF[:1] + _BF[3:], "--t", "t", ["-1", "0", "nan", "inf"]),
    (_BF[:3], "--n-paths", "n-paths", ["-1", "0", "1", "2", "nan"]),
    (_BF, "--burn-in", "burn_in", ["-1", "nan", "inf"]),
    (_BF, "--max-work", "max_work", ["0", "nan"]),
]
BAD += [(pre + [f"{opt}={v}"], word) for pre, opt, word, vals in _NUMERIC for v in vals]
BAD += [
    (["estimate", "--tau-L", "1e"], "--tau-L"),
    (["estimate", "--tau-L", "infinite"], "--tau-L"),
    (["estimate", "--method", "DI"], "method"),
    (["bruteforce", "--t", "1", "--n-paths", "10", "--dtype", "double"], "dtype"),
    (["estimate", "--out", "/nonexistent-dir/result.json"], "--out"),
    (["estimate", "--out", "."], "--out"),  # a directory
    (["estimate", "--out", "/etc/passwd/result.json"], "--out"),  # parent is a file
    (["bruteforce", "--t", "1", "--n-paths", "10", "--out", "/nonexistent-dir/bf.json"], "--out"),
    (["figures", "--fig", "3", "--out", "/etc/passwd/figs"], "--out"),  # parent is a file
    (["figures", "--fig", "3", "--out", "/nonexistent-dir/deeper/figs"], "--out"),
    (["figures", "--fig", "99", "--out", "figs"], "--fig"),
    (["sweep", "--Gamma", "1,2", "--out", "/nonexistent-dir/s.jsonl"], "--out"),
    (["estimate", "--out", ""], "--out"),  # an empty path (it used to fail after the run, losing the result)
    (["bruteforce", "--t", "1", "--n-paths", "10", "--out", " "], "--out"),
    (["figures", "--fig", "3", "--out", ""], "--out"),
    (["sweep", "--Gamma", "1,2", "--out", ""], "--out"),
    (["estimate", "--out", "/proc/dryfric-result.json"], "--out"),  # os.access says yes; no file can be made
    (["estimate", "--out", "/dev/null"], "--out"),  # a device: the atomic rename would replace it
    (["sweep", "--Gamma", "1,,2", "--out", "s.jsonl"], "--Gamma"),  # was read as [1, 2]
    (["sweep", "--Gamma", "1,", "--out", "s.jsonl"], "--Gamma"),
    (["sweep", "--Gamma", "1", "--Gamma", "2", "--out", "s.jsonl"], "--Gamma must be given once"),  # kept only 2
    (["estimate", "--Gamma", "-1e3"], "Gamma must be"),  # was "expected one argument"
    # Python's float and int read "5_0" as 50: a typo for 5.0 ran silently at Gamma = 50
    (["theory", "--Gamma", "5_0"], "--Gamma must be a number (got '5_0'"),
    (["sweep", "--tau-L", "1,0_5", "--out", "s.jsonl"], "--tau-L must be a number (got '0_5'"),
    (["estimate", "--n-excursions", "1_000"], "--n-excursions must be an integer"),
    (["theory", "--gamma-bar", "-inf"], "gamma_bar must be"),
    (["theory", "--gamma-bar", "-nan"], "gamma_bar must be"),  # was "--gamma-bar: expected one argument"
    (["estimate", "--tau-L", "-NaN"], "tau_L must be"),
    # was an OverflowError traceback
    (["estimate", "--max-steps", str(2**63)], "--max-steps must be an integer in [1, 2^62]"),
    (["bruteforce", "--t", "1e300", "--n-paths", "10", "--max-work", "1e308"], "t must keep"),  # the same
    (["bruteforce", "--method", "pdmp", "--t", "1e300", "--n-paths", "10", "--max-work", "1e308"], "t must keep"),
    (["theory", "--h", "5e-324"], "h must be in ["),  # was an OverflowError; 1e-300 named a 150-digit count
    (["estimate", "--tau", "30"], "max_work must"),  # slow weak noise: predicted work refused up front
    (["estimate", "--tau-L", "inf", "--gamma-bar", "3.84"], "gamma_bar"),  # runaway
    (["bruteforce", "--t", "1e6", "--n-paths", "1000"], "max_work must"),
    (["combine", "/nonexistent-dir/r.json"], "files"),
    (["theory", "--h", "1"], "h must be in"),
    # h so small that the steps per tau0 were inf: refused as if max_work or t were wrong (audit)
    (["estimate", "--h", "5e-324"], "h must be in ["), (["bruteforce", "--t", "1", "--n-paths", "10", "--h", "1e-300"],
                                                        "h must be in ["),
    (["combine", "/etc/passwd"], "files"),  # not JSON
    # the range in full for a value below it too: ">= 1" was said, and 4194305 then refused (a hard-cases audit)
    (["bench", "--lanes", "0"], "--lanes must be an integer in [1, 2^22] (got '0')"),
    (["bench", "--lanes", "64,x"], "--lanes"),
    (["bench", "--block", "2048"], "block must be an integer in [1, 1024]"),
    (["bench", "--lanes", "4194304", "--block", "1024"], "lanes * block"),  # 2^32 normals per block
    (["estimate", "--lanes", "0"], "--lanes must be an integer in [1, 2^22] (got '0')"),
    (["estimate", "--lanes", "8388608"], "--lanes must be an integer in [1, 2^22] (got '8388608')"),
    (["estimate", "--block", "0"], "--block must be an integer in [1, 1024] (got '0')"),
    (["estimate", "--max-steps", "0"], "--max-steps must be an integer in [1, 2^62] (got '0')"),
    (["estimate", "--max-steps", "99999999999999999999"], "--max-steps must be an integer in [1, 2^62]"),
    (["estimate", "--block", "4096"], "block must be an integer in [1, 1024]"),
    (["bench", "--lanes", "64", "--dtype", "half"], "dtype"),
    (["bench", "--repeat", "0"], "--repeat"),
    # 10^23 rounds were taken and ran until killed, nothing printed (an audit)
    (["bench", "--repeat", "1001"], "--repeat must be an integer in [1, 1000] (got '1001')"),
    (["estimate", "--seed", str(2**70)], "--seed"),  # was an OverflowError traceback
    (["figures", "--seed", "-1", "--out", "figs"], "--seed"),
    (["estimate", "--Gamma", "1e-300"], "Gamma and Delta"),  # tau0 underflows
    (["estimate", "--tau", "1e300"], "tau must keep"),
    # a 1e30-digit work bound, in brief, and no advice to raise max_work (no float is large enough)
    (["estimate", "--Gamma", "1e-30"], "predicted mean duration < 1.8e308 tau0 (float range; got >= 10^(1.9e+30)"),
    (["estimate", "--gamma-bar", "1e300"],  # its log overflows: the bound as 10^(float max), it said "inf"
     "predicted mean duration < 1.8e308 tau0 (float range; got >= 10^(1.79e+308) tau0"),
    # beyond int64: a TypeError traceback from lanes_for (np.log2 of a Python int)
    (["estimate", "--n-excursions", str(2**70), "--max-work", "1e308", "--max-time", "5"],
     "--n-excursions must be an integer in [2, 2^62]"),
    (["sweep", "--n-excursions", str(10**31), "--max-work", "1e308", "--out", "s.jsonl"], "--n-excursions must be"),
    (["bruteforce", "--t", "1", "--n-paths", str(2**70), "--max-work", "1e308"], "--n-paths must be"),
]


@pytest.mark.parametrize("argv,word", BAD)
def test_bad_input_exit_2_one_line(argv, word, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("dryfric: error:"), err
    assert word in err[0] or word.replace("-", "_") in err[0], err


@pytest.mark.parametrize("value", ["-1e-3", "-0.5", "-.25"])
def test_negative_values_need_no_equals_sign(value, capsys):
    """argparse took "-1e-3" for an option, so only --gamma-bar=-1e-3 worked (and a sweep list
    "-0.5,0.5" never did)."""
    assert main(["theory", "--gamma-bar", value, "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["params"]["gamma_bar"] == float(value)
    from dryfric_jax import theory
    assert out["M0"] == theory.exact_M0(Params(**{**FIG3, "gamma_bar": float(value)})) < 0


def test_a_negative_sweep_list_is_read(tmp_path, capsys):
    """Read, planned and refused as a whole (a tiny max_work): the message names both points."""
    out = tmp_path / "s.jsonl"
    assert main(["sweep", "--gamma-bar", "-0.5,0.25", "--out", str(out), "--max-work", "1e3"]) == 2
    err = capsys.readouterr().err
    assert '"gamma_bar": -0.5' in err and '"gamma_bar": 0.25' in err and not out.exists()


def test_out_refuses_a_pipe_and_leaves_it(tmp_path, capsys):
    """An existing path that is not a regular file is refused before the run (write_atomic renames
    a new file over the path: it would have replaced a device or a pipe by a regular file)."""
    import os
    import stat

    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    for argv in (["estimate"], ["combine", "a.json"], ["sweep", "--Gamma", "1"]):
        assert main(argv + ["--out", str(fifo)]) == 2
        assert "--out must be a writable file path" in capsys.readouterr().err
    assert stat.S_ISFIFO(os.stat(fifo).st_mode)


@pytest.mark.parametrize("name", ["newdir/", "r" * 300 + ".json", "a\0b.json"])
@pytest.mark.parametrize("cmd", [["estimate", "--n-excursions", "50"],
                                 ["sweep", "--Gamma", "5", "--n-excursions", "50"]])
def test_out_that_cannot_be_created_is_refused_before_the_run(tmp_path, cmd, name, capsys):
    """A trailing '/', a name over 255 bytes or a NUL passed the directory's check: the run happened,
    then 'could not write' (exit 1; the sweep said its finished points were in the file)."""
    assert main(cmd + ["--out", f"{tmp_path}/{name}"]) == 2  # pathlib drops a trailing "/"
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("dryfric: error: --out must be a writable file path"), err
    assert len(err[0]) < 300 and list(tmp_path.iterdir()) == []


def test_a_failed_write_after_the_run_keeps_the_printed_result(tmp_path, capsys, monkeypatch):
    """The result is printed before --out is written; if the write fails (say the disk filled up
    during the run), the error says so and exits 1, and the result is on stdout."""
    import dryfric_jax.cli as cli

    def full_disk(path, text):
        raise OSError(28, "No space left on device")
    monkeypatch.setattr(cli, "write_atomic", full_disk)
    out = tmp_path / "r.json"
    assert main(["theory", "--json"]) == 0  # no --out: untouched
    capsys.readouterr()
    assert main(["bruteforce", "--t", "0.5", "--n-paths", "16", "--json", "--out", str(out)]) == 1
    cap = capsys.readouterr()
    assert json.loads(cap.out)["D_t"] > 0
    assert "could not write --out" in cap.err and "No space left" in cap.err and not out.exists()


def test_truncation_exits_3_unless_allowed_and_the_result_is_kept(tmp_path, capsys):
    """Excursions cut by --max-steps: warning on stderr, exit 3, result still printed and written;
    --allow-truncated accepts it (exit 0)."""
    argv = ["estimate", "--nondim", "--tau", "1e-3", "--tau-L", "inf", "--gamma-bar", "0", "--n-excursions", "300",
            "--max-steps", "3000", "--json"]
    out = tmp_path / "r.json"
    assert main(argv + ["--out", str(out)]) == 3
    cap = capsys.readouterr()
    res = json.loads(cap.out)
    assert res["n_truncated"] > 0 and "truncated excursions" in cap.err and "exit 3" in cap.err
    assert json.loads(out.read_text()) == res  # nothing computed is lost
    assert main(argv + ["--allow-truncated"]) == 0
    assert json.loads(capsys.readouterr().out)["n_truncated"] == res["n_truncated"]


def test_combine_of_truncated_runs_exits_3_unless_allowed(tmp_path, capsys):
    """The pooled result of runs with truncated excursions is biased as theirs are: 'combine' exited
    0 (a script checking the exit code took it), now 3 as 'estimate' and 'sweep' do, the result
    still printed and written; --allow-truncated accepts it.  The layout of the test above (its
    compilation): 0.5 s after it, ~20 s alone on 2 loaded cores."""
    argv = ["estimate", "--nondim", "--tau", "1e-3", "--tau-L", "inf", "--gamma-bar", "0", "--n-excursions", "300",
            "--allow-truncated"]
    files = [str(tmp_path / f"r{seed}.json") for seed in (1, 2)]
    assert main(argv + ["--seed", "1", "--out", files[0]]) == 0
    assert main(argv + ["--seed", "2", "--max-steps", "3000", "--out", files[1]]) == 0
    capsys.readouterr()
    out = tmp_path / "pooled.json"
    assert main(["combine", *files, "--json", "--out", str(out)]) == 3
    cap = capsys.readouterr()
    res = json.loads(cap.out)
    assert res["n_truncated"] > 0 and "truncated excursions" in cap.err and "exit 3" in cap.err
    assert json.loads(out.read_text()) == res  # printed and written
    assert main(["combine", *files, "--allow-truncated"]) == 0
    assert json.loads(open(files[0]).read())["n_truncated"] == 0
    assert main(["combine", files[0]]) == 0  # none truncated: 0


def test_max_work_projection_is_said_at_once_on_stderr(capsys):
    """A run that max_work will end early says so on stderr while it runs (the library's
    ProjectionWarning, not kept in the result), before the result's own warnings; the JSON on
    stdout is untouched."""
    assert main(["estimate", "--n-excursions", "3000", "--max-work", "2e7", "--lanes", "256", "--seed", "2",
                 "--json"]) == 0
    cap = capsys.readouterr()
    res = json.loads(cap.out)
    lines = cap.err.splitlines()
    early = [i for i, ln in enumerate(lines) if ln.startswith("dryfric: warning: max_work = 2e+07 steps is projected")]
    late = [i for i, ln in enumerate(lines) if "work bound reached" in ln]
    assert len(early) == 1 and late and early[0] < late[0], lines
    assert res["stopped_by"] == "work_bound" and not any("projected" in w for w in res["warnings"])


def test_bad_input_in_a_real_process_has_no_traceback():
    p = subprocess.run([sys.executable, "-m", "dryfric_jax.cli", "estimate", "--tau", "nan"], capture_output=True,
                       text=True)
    assert p.returncode == 2 and "Traceback" not in p.stderr and p.stderr.count("\n") == 1


@pytest.mark.parametrize("launcher", ["console script", "python -m"])
def test_ctrl_c_while_the_command_imports_jax_exits_130_without_a_traceback(tmp_path, launcher):
    """A Ctrl-C in the first 1-2 s of ``dryfric ...`` (``import jax``) printed Python's
    KeyboardInterrupt traceback and exited -SIGINT, or an ImportError (exit 1) when it landed in
    numpy's or jaxlib's initialisation (measured at 0.1-1.5 s after the start, 2 CPU cores).  A
    SIGINT at 0.25 s lands in the import on any machine (jax takes longer to import; the
    interpreter starts in ~0.05 s); one at 1.0 s in the import or in the run: exit 130 either way.
    ~2-6 s."""
    import os
    import pathlib
    import signal
    import time

    root = pathlib.Path(__file__).parent.parent
    script = tmp_path / "dryfric"  # what pip writes for the [project.scripts] entry
    script.write_text("import sys\nfrom dryfric_jax.cli import main\nif __name__ == '__main__':\n"
                      "    sys.exit(main())\n")
    cmd = [str(script)] if launcher == "console script" else ["-m", "dryfric_jax.cli"]
    env = {**os.environ, "PYTHONPATH": str(root)}
    said = []
    for delay in (0.25, 1.0):
        p = subprocess.Popen([sys.executable, *cmd, "estimate", "--n-excursions", "200"], cwd=root, env=env,
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        time.sleep(delay)
        p.send_signal(signal.SIGINT)
        out, err = p.communicate(timeout=300)
        assert p.returncode == 130 and "Traceback" not in err and "Error" not in err, (delay, err[-800:])
        assert err.startswith("dryfric: interrupted") and err.count("\n") == 1, (delay, err)
        said.append(err)
    assert "while starting" in said[0]  # the 0.25 s one reached the import


@pytest.mark.parametrize("how", ["raised", "returned"])
def test_a_timer_left_running_does_not_hold_the_exit_after_ctrl_c(tmp_path, how):
    """JAX's TPU probe starts a 60 s non-daemon timer and cancels it in a ``finally`` that a Ctrl-C
    landing in ``Timer.start()`` skips; CI saw ``dryfric estimate`` interrupted at 1.0 s take 61 s to
    exit, with JAX's warning on stderr (interrupts.cancel_timers).  Here the command's run starts
    such a timer and is interrupted (a KeyboardInterrupt, or a sweep's own exit 130): it exits 130
    at once, with its one line.  Without the cancel: 60 s, then the timer's line."""
    import os
    import pathlib
    import time

    root = pathlib.Path(__file__).parent.parent
    script = tmp_path / "run.py"
    script.write_text(
        "import sys, threading\nimport dryfric_jax.cli as cli\n"
        "def run(a):\n"
        "    threading.Timer(60.0, lambda: print('the timer fired', file=sys.stderr)).start()\n"
        + ("    raise KeyboardInterrupt\n" if how == "raised" else
           "    print('dryfric: interrupted: 1 point kept', file=sys.stderr)\n    return 130\n")
        + "cli._run = run\nsys.exit(cli.main(['theory']))\n")
    t0 = time.perf_counter()
    p = subprocess.run([sys.executable, str(script)], cwd=root, env={**os.environ, "PYTHONPATH": str(root)},
                       capture_output=True, text=True, timeout=50)
    assert p.returncode == 130 and time.perf_counter() - t0 < 30, (p.returncode, p.stderr)
    assert p.stderr.startswith("dryfric: interrupted") and p.stderr.count("\n") == 1, p.stderr
    assert "timer" not in p.stderr


def test_ctrl_c_between_the_import_and_main_exits_130_quietly(tmp_path):
    """The window after the package's import (where its quiet handler was removed) and before
    ``main``'s try (importing ``cli.py``): a SIGINT there printed a KeyboardInterrupt traceback.  The
    console script's process signals itself right there; then ``main`` hands Ctrl-C back to Python's
    handler (its KeyboardInterrupt is main's exit 130).  ~3 s."""
    import os
    import pathlib

    root = pathlib.Path(__file__).parent.parent
    script = tmp_path / "dryfric"  # the console script's name: launched_as_cli()
    script.write_text("import os, signal, sys, time\nimport dryfric_jax.cli as cli\n"
                      "if sys.argv[1:] == ['window']:\n    os.kill(os.getpid(), signal.SIGINT)\n    time.sleep(5)\n"
                      "    print('not stopped')\n"
                      "else:\n    assert cli.main(['theory', '--json']) == 0\n"
                      "    print(signal.getsignal(signal.SIGINT) is signal.default_int_handler)\n")
    env = {**os.environ, "PYTHONPATH": str(root)}
    p = subprocess.run([sys.executable, str(script), "window"], env=env, capture_output=True, text=True, timeout=300)
    assert (p.returncode, p.stdout, p.stderr) == (130, "", "dryfric: interrupted while starting (nothing was run)\n")
    p = subprocess.run([sys.executable, str(script)], env=env, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0 and p.stdout.splitlines()[-1] == "True", p.stderr[-800:]


def test_a_command_started_with_ctrl_c_ignored_still_ignores_it_while_starting():
    """A background job (``dryfric ... &`` in a script) starts with SIGINT ignored: a Ctrl-C at the
    terminal must not end it, during the import either.  ~3 s."""
    import pathlib
    import signal
    import time

    # the shell's trap ignores SIGINT and exec keeps it ignored (a preexec_fn would run Python in a
    # child forked from this multithreaded process: a deadlock risk, and a RuntimeWarning)
    p = subprocess.Popen(["sh", "-c", 'trap "" INT; exec "$0" -m dryfric_jax.cli theory --json', sys.executable],
                         cwd=pathlib.Path(__file__).parent.parent, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                         text=True)
    time.sleep(0.4)
    p.send_signal(signal.SIGINT)
    out, err = p.communicate(timeout=300)
    assert p.returncode == 0 and json.loads(out)["D"] > 0, err[-800:]


def test_only_the_command_exits_quietly_on_ctrl_c_while_importing(monkeypatch):
    """A program or notebook importing the package keeps Python's KeyboardInterrupt."""
    from dryfric_jax.interrupts import launched_as_cli

    assert not launched_as_cli()  # pytest
    for argv0, orig in (("/venv/bin/dryfric", ["/venv/bin/python", "/venv/bin/dryfric"]),
                        ("-m", ["python", "-m", "dryfric_jax.cli", "theory"]),
                        ("-m", ["python", "-X", "dev", "-mdryfric_jax.cli"]),
                        ("-m", ["python", "-m", "dryfric_jax", "theory"]), ("-m", ["python", "-mdryfric_jax"])):
        monkeypatch.setattr(sys, "argv", [argv0, "theory"])
        monkeypatch.setattr(sys, "orig_argv", orig)
        assert launched_as_cli(), orig
    for argv0, orig in (("app.py", ["python", "app.py"]), ("-m", ["python", "-m", "mypkg", "dryfric_jax.cli"]),
                        ("-m", ["python", "-m", "dryfric_jax_extra"]), ("-m", ["python", "-mdryfric_jax.paths"]),
                        ("-c", ["python", "-c", "import dryfric_jax"]), ("/x/dryfric.py", ["python", "dryfric.py"])):
        monkeypatch.setattr(sys, "argv", [argv0])
        monkeypatch.setattr(sys, "orig_argv", orig)
        assert not launched_as_cli(), orig


def test_estimate_json(capsys):
    assert main(["estimate", "--nondim", "--tau", "1e-3", "--tau-L", "inf", "--gamma-bar", "0",
                 "--n-excursions", "200", "--json"]) == 0
    cap = capsys.readouterr()
    out = json.loads(cap.out)
    assert ESTIMATE_KEYS <= set(out)
    # every lane finishes its in-flight excursion: at least N come back, all reported
    assert out["n_excursions"] >= 200 and out["method"] == "di" and out["params"]["Gamma"] == 1.0
    assert "under-covers" in cap.err  # N below the CI threshold is flagged
    assert (out["lanes"], out["block"]) == (plan_estimate(Params.from_nondim(1e-3, math.inf, 0.0),
                                                          n_excursions=200).lanes, 128)
    # the layout is the user's to choose, and the JSON records it (with the seed it fixes the streams)
    assert main(["estimate", "--nondim", "--tau", "1e-3", "--tau-L", "inf", "--gamma-bar", "0",
                 "--n-excursions", "200", "--lanes", "48", "--block", "32", "--json"]) == 0
    lay = json.loads(capsys.readouterr().out)
    assert (lay["lanes"], lay["block"]) == (48, 32) and lay["D"] != out["D"]
    assert abs(lay["D"] - out["D"]) < 3 * math.hypot(lay["D_ci"], out["D_ci"]) / 1.96


def test_bruteforce_max_events(capsys):
    """--max-events bounds the PDMP's events per path: at 3 (far below the expected count for t = 0.5 s) every
    path reaches it and the run fails (exit 1) saying how many did and what to raise; with the DI, which
    has no events, it is refused by name (exit 2).  The refusal told a CLI user to raise max_events,
    which the CLI did not offer."""
    assert main(["bruteforce", "--method", "pdmp", "--t", "0.5", "--n-paths", "8", "--max-events", "3"]) == 1
    err = capsys.readouterr().err.splitlines()
    assert err == ["dryfric: error: 8 of 8 PDMP paths hit max_events = 3 before t; raise max_events"], err
    assert main(["bruteforce", "--t", "0.5", "--n-paths", "8", "--max-events", "3"]) == 2
    assert capsys.readouterr().err.startswith("dryfric: error: max_events must not be given with method 'di'")


def test_bruteforce_and_theory_json(capsys, solve_rounding):
    assert main(["bruteforce", "--t", "1", "--n-paths", "50", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert {"D_t", "D_t_ci", "M0_t", "M0_t_ci"} <= set(out)
    assert main(["theory", "--nondim", "--tau", "1e-5", "--tau-L", "inf", "--gamma-bar", "0", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["D"] == pytest.approx(10.0, rel=1e-8) and abs(out["M0"]) < 1e-12
    # the chain at a step: what white_chain_law gives (its values are tested in test_chain_law),
    # D below the continuum's, M0 zero by symmetry
    assert main(["theory", "--nondim", "--tau", "1e-5", "--tau-L", "inf", "--gamma-bar", "0", "--h", "0.05",
                 "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    law = white_chain_law(Params.from_nondim(1e-5, math.inf, 0.0), 0.05)
    assert (out["chain_D"], out["chain_M0"], out["chain_mean_v2"]) == (law.D, law.M0, law.mean_v2)
    assert out["chain_D"] < out["D"] and abs(out["chain_M0"]) < solve_rounding(law)
    assert out["chain_warnings"] == [] and capsys.readouterr().err == ""


def test_theory_says_the_chain_laws_warning(capsys):
    """The chain law warns where its M0 is round-off (E[V] far below the solve's resolution against V's spread);
    `dryfric theory --h` silenced it with theory's "tau is not used" note and printed an M0 off by 1e14 % with exit
    0 (an audit).  Now it is said on stderr and kept in the JSON's chain_warnings."""
    argv = ["theory", "--nondim", "--tau", "1e-6", "--tau-L", "1e-50", "--gamma-bar", "0.5", "--h", "5e-52"]
    from dryfric_jax import DryfricWarning

    with pytest.warns(DryfricWarning, match="the chain law's M0 is unreliable here"):
        white_chain_law(Params.from_nondim(1e-6, 1e-50, 0.5), 5e-52)  # what the command must pass on
    assert main(argv) == 0
    cap = capsys.readouterr()
    assert cap.err.startswith("dryfric: warning: the chain law's M0 is unreliable here") and "DI chain at h" in cap.out
    assert main(argv + ["--json"]) == 0
    (note,) = json.loads(capsys.readouterr().out)["chain_warnings"]
    assert note.startswith("the chain law's M0 is unreliable here")


def test_theory_prints_the_continuum_when_the_chain_law_at_h_is_refused(capsys):
    """The chain law at --h may be refused (its grid too wide near the runaway bias); the white-noise D and M0 are
    still printed, and the error says so (it exited 2 with nothing printed: a hard-cases audit)."""
    from dryfric_jax import theory

    argv = ["theory", "--nondim", "--tau", "1e-5", "--tau-L", "inf", "--gamma-bar", "0.9", "--h", "0.01"]
    p = Params.from_nondim(1e-5, math.inf, 0.9)
    assert main(argv) == 2
    cap = capsys.readouterr()
    assert cap.out == f"white-noise D  = {theory.exact_D(p):.6g} m^2/s\nwhite-noise M0 = {theory.exact_M0(p):.6g} m/s\n"
    assert "grid nodes" in cap.err and "(the white-noise D and M0 are printed above" in cap.err
    assert main(argv + ["--json"]) == 2
    out = json.loads(capsys.readouterr().out)
    assert (out["D"], out["M0"]) == (theory.exact_D(p), theory.exact_M0(p)) and "grid nodes" in out["refused"]["h"]


def test_theory_prints_m0_when_only_d_leaves_float64(capsys):
    """At tau_L = 1e-300 s, D ~ 2 tau_L^2 Gamma underflows float64 but M0 ~ 3e-301 m/s does not: D is
    refused by name (exit 2) and M0 still printed, in text and in JSON (the whole output was refused)."""
    from dryfric_jax import theory

    m0 = theory.exact_M0(Params(**{**FIG3, "tau_L": 1e-300}))
    # independently: as tau_L -> 0 the stationary law exp(-v^2/(2 Gamma tau_L) - Delta|v|/Gamma + gamma_bar v/Gamma)
    # (MODEL_NOTES section 2) is the Gaussian of mean gamma_bar tau_L, up to O(Delta sqrt(tau_L/Gamma)) ~ 1e-150
    assert m0 == pytest.approx(FIG3["gamma_bar"] * 1e-300, rel=1e-12)
    assert main(["theory", "--tau-L", "1e-300", "--json"]) == 2
    cap = capsys.readouterr()
    out = json.loads(cap.out)
    assert out["D"] is None and out["M0"] == m0 and out["refused"]["D"].startswith("D underflows float64 for")
    assert cap.err.startswith("dryfric: error: D underflows float64") and cap.err.endswith("(M0 printed above)\n")
    assert main(["theory", "--tau-L", "1e-300", "--h", "1e-303"]) == 2
    cap = capsys.readouterr()
    assert cap.out == f"white-noise M0 = {m0:.6g} m/s\n" and "the DI chain at --h is not computed" in cap.err
    assert "Traceback" not in cap.err
    # both refused (a runaway bias, a user's mistake): nothing printed, the reason said once
    assert main(["theory", "--tau-L", "inf", "--gamma-bar", "4", "--json"]) == 2
    cap = capsys.readouterr()
    assert cap.out == "" and cap.err.count("gamma_bar must") == 1 and cap.err.count("\n") == 1


@pytest.mark.parametrize("stopped,code,said", [
    ("interrupted", 130, "dryfric: interrupted: fewer than 2 complete excursions before the interrupt"),
    ("max_time", 1, "dryfric: error: fewer than 2 complete excursions within max_time (raise it): max_time reached"),
    ("work_bound", 1, "dryfric: error: fewer than 2 complete excursions within the work bounds (raise max_work / "
                      "max_steps): work bound reached")])
def test_no_estimate_says_what_ended_the_run(monkeypatch, capsys, stopped, code, said):
    """Fewer than 2 excursions closed: the message names what ended the run, and a Ctrl-C exits 130
    (it exited 1 and said to raise max_work, also after Ctrl-C or max_time): the API lets that
    Ctrl-C go on up, having nothing to return."""
    import numpy as np

    from dryfric_jax import api
    from dryfric_jax.excursions import STAT_NAMES
    from dryfric_jax.rounds import ExcursionStats

    empty = ExcursionStats(np.zeros((4, len(STAT_NAMES))), 0, 0, 0)
    monkeypatch.setattr(api, "simulate_long_excursions", lambda *a, **k: (empty, stopped))
    assert main(["estimate", "--n-excursions", "50", "--max-time", "60"]) == code
    err = capsys.readouterr().err
    assert err.startswith(said) and err.count("\n") == 1, err


def test_bench_json_has_the_side_by_side_numbers(capsys):
    assert main(["bench", "--n-excursions", "50", "--repeat", "2", "--json"]) == 0
    b = json.loads(capsys.readouterr().out)
    # two rounds: every number is the median of the rounds' values, every ratio taken within a round
    rounds = b["rounds"]
    assert b["repeat"] == 2 and len(rounds) == 2 and set(b["ranges"]) == set(rounds[0])
    for k, (lo, hi) in b["ranges"].items():
        assert lo <= b[k] <= hi and b[k] == pytest.approx((rounds[0][k] + rounds[1][k]) / 2, rel=1e-12), k
    for r in rounds:
        ratio = r["di_float64_lane_steps_per_s"] / r["rng_bound_float64_lane_steps_per_s"]
        assert r["ratio_di_float64_to_rng_bound"] == ratio
    # the same seeds in every round: the same estimate
    assert rounds[0]["D"] == rounds[1]["D"] and rounds[0]["D_ci"] == rounds[1]["D_ci"]
    for dt in ("float32", "float64"):
        assert b[f"di_{dt}_lane_steps_per_s"] > 0 and b[f"rng_bound_{dt}_lane_steps_per_s"] > 0
        assert b[f"ratio_di_{dt}_to_rng_bound"] > 0
        # the chain floor splits the gap into engine / floor and floor / bound
        for k in (f"di_chain_floor_{dt}_lane_steps_per_s", f"pdmp_event_floor_{dt}_events_per_s",
                  f"ratio_di_{dt}_to_chain_floor", f"ratio_di_chain_floor_{dt}_to_rng_bound"):
            assert b[k] > 0, k
    assert b["time_to_1pct_ci_s"] > 0
    # the versions the numbers depend on (numba 0.61 -> 0.62 slowed its legacy np.random 1.8x: bench_numba)
    import jax

    assert b["jax_version"] == jax.__version__
    try:
        import numba
    except ImportError:
        assert "numba_version" not in b and "numba_rng" not in b and b["numba"].startswith("unavailable")
    else:
        assert b["numba_version"] == numba.__version__
        assert b["numba_rng"].startswith("numpy.random.Generator(PCG64)")


def test_bench_layout_sweep(capsys):
    """``bench --lanes --block``: one row per layout, the best is the fastest, and the layouts'
    estimates agree (each (lanes, K) its own seed: other random streams, same law)."""
    assert main(["bench", "--lanes", "32,64", "--block", "64", "--n-excursions", "200", "--dtype", "float64",
                 "--repeat", "2", "--json"]) == 0
    b = json.loads(capsys.readouterr().out)
    rows = b["layouts"]
    assert b["repeat"] == 2
    for r in rows:  # two interleaved rounds: the median of two lies between them
        lo, hi = r["lane_steps_per_s_range"]
        assert lo <= r["lane_steps_per_s"] <= hi and r["lane_steps_per_s"] == pytest.approx((lo + hi) / 2, rel=1e-12)
    assert [(r["lanes"], r["block"]) for r in rows] == [(32, 64), (64, 64)]
    assert all(r["n_excursions"] >= max(200, 8 * r["lanes"]) and r["D_ci"] > 0 for r in rows)
    assert b["best_lane_steps_per_s"] == max(r["lane_steps_per_s"] for r in rows)
    assert b["ratio_best_to_rng_bound"] > 0 and b["max_z"] < 3


def test_layout_disagreement_counts_the_twins_of_a_layout_once():
    """``max_z`` compares each layout's D with the pool of the others: the wait and fused layouts
    (and the unrolls) of one (lanes, K) run the same excursions, so a row's twin must not sit in its
    pool (it pulled the pool towards the row: the z of two layouts shrank by sqrt(2/3) with
    ``events=wait,fused``)."""
    from dryfric_jax.bench import _summarise_layouts

    def row(lanes, events, D, unroll=1):
        return dict(lanes=lanes, block=64, unroll=unroll, events=events, D=D, D_ci=1.96, lane_steps_per_s=lanes)

    two = dict(layouts=[row(32, "wait", 0.0), row(64, "wait", 5.0)])
    _summarise_layouts(two)
    assert two["max_z"] == pytest.approx(5 / math.sqrt(2), rel=1e-12) and two["D_pooled"] == 2.5
    twins = dict(layouts=[row(32, "wait", 0.0), row(32, "fused", 0.0), row(32, "wait", 0.0, unroll=2),
                          row(64, "wait", 5.0), row(64, "fused", 5.0)])
    assert _summarise_layouts(twins)["lanes"] == 64
    assert (twins["max_z"], twins["D_pooled"]) == (two["max_z"], two["D_pooled"])
    branch = dict(layouts=two["layouts"] + [row(64, "branch", 5.0)])  # other excursions: a layout of its own
    _summarise_layouts(branch)
    assert branch["max_z"] > two["max_z"]
    # unequal CIs: weights (1.96 / D_ci)^2 = 1 and 4, pooled D = 12 / 5, z = 3 / sqrt(1 + 1/4) (weights
    # 1.96 / D_ci, not squared, passed with equal CIs)
    unequal = dict(layouts=[row(32, "wait", 0.0), dict(row(64, "wait", 3.0), D_ci=0.98)])
    _summarise_layouts(unequal)
    assert unequal["max_z"] == pytest.approx(3 / math.sqrt(1.25), rel=1e-12)
    assert unequal["D_pooled"] == pytest.approx(2.4, rel=1e-12)


def test_bench_ratios_of_a_round_divide_the_right_numbers():
    """Every ratio of :func:`run_bench`'s round on numbers chosen so that an inverted ratio, a wrong
    denominator or the other dtype's number gives another value (only one of the ten ratios per dtype
    was checked, in a slow test); without numba, no numba ratio.  The duration count's against the
    float64 floor: 48 / 96 (float32's would give 1.2)."""
    from dryfric_jax.bench import _ratios

    m = dict(numba_2t_steps_per_s=8.0, numba_pdmp_2t_events_per_s=2.0, di_duration_lane_steps_per_s=48.0)
    for dt, (di, floor, bound, jr, pdmp, ev_floor) in (("float64", (64, 96, 256, 32, 6, 24)),
                                                       ("float32", (30, 40, 160, 32, 10, 50))):
        m.update({f"di_{dt}_lane_steps_per_s": di, f"di_chain_floor_{dt}_lane_steps_per_s": floor,
                  f"rng_bound_{dt}_lane_steps_per_s": bound, f"jax_random_normal_{dt}_lane_steps_per_s": jr,
                  f"pdmp_{dt}_events_per_s": pdmp, f"pdmp_event_floor_{dt}_events_per_s": ev_floor})
    want = dict(ratio_pdmp_float64_to_numba_2t=3.0, ratio_di_float64_to_numba_2t=8.0,
                ratio_pdmp_float32_to_numba_2t=5.0, ratio_di_float32_to_numba_2t=3.75,
                ratio_di_float64_to_rng_bound=0.25, ratio_rng_bound_float64_to_jax_random_normal=8.0,
                ratio_di_float64_to_chain_floor=2 / 3, ratio_di_chain_floor_float64_to_rng_bound=0.375,
                ratio_pdmp_float64_to_event_floor=0.25,
                ratio_di_float32_to_rng_bound=0.1875, ratio_rng_bound_float32_to_jax_random_normal=5.0,
                ratio_di_float32_to_chain_floor=0.75, ratio_di_chain_floor_float32_to_rng_bound=0.25,
                ratio_pdmp_float32_to_event_floor=0.2, ratio_di_duration_to_chain_floor=0.5)
    assert _ratios(m) == pytest.approx(want, rel=1e-15)
    del m["numba_2t_steps_per_s"], m["numba_pdmp_2t_events_per_s"]
    assert _ratios(m) == pytest.approx({k: v for k, v in want.items() if "numba" not in k}, rel=1e-15)


def test_numba_rates_are_the_steps_of_a_timed_run_per_second(monkeypatch):
    """The numba baseline's rate: the steps the timed run reports over its own wall time (compile run
    first, not timed), for each thread count, with the seed passed on."""
    from dryfric_jax import bench

    calls, clock = [], iter([10.0, 12.0, 20.0, 23.0])
    monkeypatch.setattr(bench.time, "perf_counter", lambda: next(clock))

    def run(model, n, threads, seed=None):
        calls.append((model, n, threads, seed))
        return None, 600 * threads

    assert bench._numba_rates(run, "m", 40, 7) == {1: 300.0, 2: 400.0}
    assert calls == [("m", 20, 1, None), ("m", 40, 1, 7), ("m", 40, 2, 7)]


def test_a_numba_baseline_that_stops_is_said_and_the_other_rounds_numbers_kept():
    """A baseline that reaches its work bound (``BaselineIncomplete``: broken) in the second round: that
    round and the later ones have no numba rates, ``out["numba"]`` says why, and the medians are over the
    numbers every round has (the first round's numba rates are not reported as if measured throughout)."""
    from dryfric_jax import bench

    class Stop(RuntimeError):
        pass

    def ok(model, n, threads, seed=None):
        return None, 100

    def broken(model, n, threads, seed=None):
        if n != 20:  # the compile run passes
            raise Stop("worker 0 reached its work bound")
        return None, 1

    out = {}
    first = bench._numba_round(out, (ok, "p"), (ok, "d"), 40, 0, Stop)
    assert set(first) == {f"numba_{w}{k}t_{u}_per_s" for k in (1, 2) for w, u in (("pdmp_", "events"), ("", "steps"))}
    assert bench._numba_round(out, (ok, "p"), (broken, "d"), 40, 0, Stop) == {}
    assert out == {"numba": "stopped (worker 0 reached its work bound)"}
    assert bench._numba_round(out, (ok, "p"), (ok, "d"), 40, 0, Stop) == {}  # not measured again
    got = bench._medians({"numba": out["numba"]}, [dict(first, x=1.0), dict(x=3.0), dict(x=8.0)])
    assert got["x"] == 3.0 and not any(k.startswith("numba_") for k in got) and got["ranges"] == {"x": [1.0, 8.0]}
    assert got["numba"].startswith("stopped") and len(got["rounds"]) == 3
    assert "ranges" not in bench._medians({}, [dict(x=2.0)])


def test_bench_tables_show_the_numbers_they_are_given():
    """format_table: one number a line (4 significant digits), with the rounds' [min-max] where they
    differ; format_layouts: the best layout and its ratios, and the layouts' agreement."""
    from dryfric_jax.bench import format_layouts, format_table

    b = dict(device="cpu:0", n_devices=2, cpu_count=4, params=dict(tau=1.0), n_excursions=50, repeat=2,
             D=0.1234567, ratio_x=2.5, ranges=dict(D=[0.1, 0.2], ratio_x=[2.5, 2.5]), rounds=[{}, {}])
    assert format_table(b).splitlines() == [
        "device        cpu:0 (x2, 4 CPU cores)",
        "              medians of 2 rounds [min-max]; each ratio is taken within its round",
        "n_excursions  50", "repeat        2", "D             0.1235  [0.1-0.2]", "ratio_x       2.5"]
    row = dict(lanes=64, block=32, unroll=1, events=None, n_excursions=512, lane_steps_per_s=1.5e8,
               lane_steps_per_s_range=[1.4e8, 1.6e8], utilization=0.9, wall_s=1.25, D=0.2, D_ci=0.01)
    lay = dict(device="cpu:0", n_devices=1, cpu_count=2, dtype="float32", repeat=1, layouts=[row], best_lanes=64,
               best_block=32, best_lane_steps_per_s=1.5e8, rng_bound_lane_steps_per_s=3e8, ratio_best_to_rng_bound=0.5,
               chain_floor_lane_steps_per_s=2e8, ratio_best_to_chain_floor=0.75, ratio_chain_floor_to_rng_bound=2 / 3,
               numba_2t_steps_per_s=1e7, ratio_best_to_numba_2t=15.0, max_z=1.234, D_pooled=0.2)
    lines = format_layouts(lay).splitlines()
    assert lines[2].split() == ["64", "32", "1", "default", "512", "1.5e+08", "0.900", "1.25", "0.2", "±", "0.01"]
    assert lines[3:] == [
        "best: lanes = 64, K = 32, 1.5e+08 lane-steps/s = 0.5 x the RNG bound (3e+08)",
        "       0.75 x the chain floor (2e+08; floor / bound = 0.667)",
        "       15 x the numba 2-thread CPU loop (1e+07 steps/s)",
        "layouts agree: largest |D - pooled others| = 1.23 SE (pooled D = 0.2)"]


def test_layout_sweep_over_unrolls_streams_rows_and_keeps_to_its_budget():
    """What ``scripts/device_check.py`` asks of :func:`tune_layout`: the wait loop's unroll and the
    event layouts swept (each unroll compiled afresh, the engine's settings restored after),
    each row handed over as it is measured, the D of every layout within the CIs (rounding, not
    the law, changes), and a budget that starts no new layout once spent."""
    from dryfric_jax import excursions
    from dryfric_jax.bench import tune_layout

    unroll0, seen = excursions.QUIET_UNROLL, []
    b = tune_layout([32], [64], "float64", n_excursions=200, numba_excursions=0, unrolls=[1, 2],
                    events=["wait", "fused", "branch"], on_layout=seen.append, bound_n=1 << 16)
    assert excursions.QUIET_UNROLL == unroll0 and excursions.DEFAULT_EVENTS is None
    assert seen == b["layouts"] and b["skipped"] == [] and b["failed"] == []
    assert [(r["unroll"], r["events"]) for r in seen] == [(u, e) for u in (1, 2) for e in ("wait", "fused", "branch")]
    # "fused" is the "wait" loop with no unroll, bit for bit on a CPU, whatever QUIET_UNROLL says
    # (unrolling changes the loop's rounding); "branch" uses the numbers otherwise
    assert seen[0]["D"] == seen[1]["D"] == seen[4]["D"]
    assert b["best_unroll"] in (1, 2) and b["max_z"] < 3
    assert b["chain_floor_lane_steps_per_s"] > 0 and b["ratio_best_to_chain_floor"] > 0
    b = tune_layout([32, 64], [64], "float64", n_excursions=200, numba_excursions=0, budget_s=1e-9,
                    bound_n=1 << 16)  # the first layout starts at once; none after it
    assert [r["lanes"] for r in b["layouts"]] == [32]
    assert b["skipped"] == [dict(lanes=64, block=64, unroll=unroll0, events=None)]


def test_device_check_runs_its_new_stages_end_to_end():
    """``scripts/device_check.py`` is run only on a lent GPU, minutes a session: a crash there loses the
    lease.  Its kernel sweep, block breakdown and tile rerun on a CPU, tiny (16 lanes, K = 8, the fused
    layout in Pallas's interpreter): every JSON line parses; the kernel is timed at both tiles; the
    breakdown's parts are positive and its rounds of 1, 4 and 16 blocks were timed and fitted; the layouts ran at
    the default tile and again at the fastest (tiles 4 and 8 are not the default 256), with D equal to
    rounding (a tile splits lanes between programs, not their numbers); the round and final-call caps
    each ran, and only the round's changed D."""
    import os
    import pathlib

    root = pathlib.Path(__file__).parent.parent
    env = {**os.environ, "PYTHONPATH": str(root)}
    argv = ["scripts/device_check.py", "--dtypes", "float64", "--lanes", "16", "--block", "8", "--events", "fused",
            "--n", "64", "--bound-n", "4096", "--numba-n", "0", "--budget-s", "120", "--kernel-tiles", "4,8",
            "--kernel-warps", "1", "--breakdown", "--round-steps", "1024,1048576", "--final-call-steps", "1,134217728"]
    p = subprocess.run([sys.executable, *argv], cwd=root, env=env, capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stderr[-2000:]
    rows = [json.loads(line) for line in p.stdout.splitlines()]
    kinds = [r["kind"] for r in rows]
    assert kinds[0] == "device" and kinds[-1] == "done" and "failed" not in kinds and "skipped" not in kinds
    kernel = [r for r in rows if r["kind"] == "kernel"]
    assert [(r["tile"], r["warps"]) for r in kernel] == [(4, 1), (8, 1)]
    assert all(r["slot_steps_per_s"] > 0 and r["draw_slot_steps_per_s"] > 0 for r in kernel)
    (bd,) = [r for r in rows if r["kind"] == "breakdown"]
    assert bd["events"] == "fused" and min(bd["draw_s"], bd["quiet_s"], bd["block_s"]) > 0
    # (a fit, not checked for sign: at 16 lanes a block is ~50 us, below the jitter of a round's call)
    assert bd["round_blocks"] == [1, 4, 16, 1, 4, 16] and min(bd["round_s"]) > 0 and math.isfinite(bd["round_block_s"])
    rounds = [r for r in rows if r["kind"] == "rounds"]
    assert [(r["round_lane_steps"], r["final_call_lane_steps"]) for r in rounds] == [
        (1024, 1), (1024, 134217728), (1048576, 1), (1048576, 134217728)]
    # a final call's size changes no number; a round's size changes the streams (the same law)
    assert rounds[0]["D"] == rounds[1]["D"] and rounds[2]["D"] == rounds[3]["D"] and rounds[0]["D"] != rounds[2]["D"]
    lay = [r for r in rows if r["kind"] == "layout"]
    best = max(kernel, key=lambda r: r["slot_steps_per_s"])
    assert [(r["tile"], r["warps"]) for r in lay] == [(256, 4), (best["tile"], 1)]
    (tc,) = [r for r in rows if r["kind"] == "tile_check"]
    assert math.isclose(tc["D"], tc["D_default_tile"], rel_tol=1e-12)
    assert tc["same_D"] == (tc["D"] == tc["D_default_tile"])
    assert [r["tile"] for r in rows if r["kind"] == "tune"] == [256, best["tile"]]


def test_layout_sweep_lists_a_layout_that_fails_and_goes_on(monkeypatch):
    """A layout whose compile run raises (a kernel a device cannot build) is listed under
    ``failed`` with its error, and the sweep measures the others."""
    from dryfric_jax import bench

    real = bench.estimate_diffusivity

    def flaky(p, seed, **kw):
        if kw["lanes"] == 64:
            raise RuntimeError("no kernel for 64 lanes")
        return real(p, seed, **kw)

    monkeypatch.setattr(bench, "estimate_diffusivity", flaky)
    b = bench.tune_layout([64, 32], [64], "float64", n_excursions=200, numba_excursions=0, repeat=2, bound_n=1 << 16)
    assert [r["lanes"] for r in b["layouts"]] == [32] and b["best_lanes"] == 32
    assert [(f["lanes"], f["error"]) for f in b["failed"]] == [(64, "RuntimeError: no kernel for 64 lanes")]
    monkeypatch.setattr(bench, "estimate_diffusivity", lambda p, seed, **kw: flaky(p, seed, lanes=64))
    with pytest.raises(ValueError, match="no layout ran"):
        bench.tune_layout([64], [64], "float64", n_excursions=200, numba_excursions=0, bound_n=1 << 16)


def test_layout_sweep_skips_the_layouts_past_the_bound(monkeypatch):
    """A grid whose lanes * K pass the layout bound (2^28; 2^10 here) in some cells lists those as
    skipped and measures the others (2^19 lanes at K = 1024 refused a whole device check); a grid
    with no cell within it is refused, naming the layout."""
    from dryfric_jax import bench

    monkeypatch.setattr(bench, "MAX_LAYOUT", 1 << 10)
    b = bench.tune_layout([16, 64], [8, 32], "float64", n_excursions=200, numba_excursions=0, bound_n=1 << 14)
    assert sorted((r["lanes"], r["block"]) for r in b["layouts"]) == [(16, 8), (16, 32), (64, 8)]
    assert [(r["lanes"], r["block"], r["reason"]) for r in b["skipped"]] == [(64, 32, "lanes * K > 2^28")]
    assert "skipped (lanes * K > 2^28)" in bench.format_layouts(b)
    with pytest.raises(ValueError, match=r"^lanes \* block must be <= 2\^28 for some layout .*\[64\], block \[32\]"):
        bench.tune_layout([64], [32], "float64", n_excursions=200, numba_excursions=0, bound_n=1 << 14)


def test_pdmp_and_auto_json(capsys):
    assert main(["estimate", "--method", "pdmp", "--delta", "0.2", "--n-excursions", "200", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert ESTIMATE_KEYS | {"delta", "L_X", "events_per_s"} <= set(out)
    assert out["method"] == "pdmp" and out["delta"] == 0.2 and out["h"] is None and out["events_per_s"] > 0
    assert out["L_X"] >= 8 / FIG3_TAU**0.5
    # slow noise (tau' = 2.9): auto picks the PDMP and says why; fast noise: the DI
    assert main(["estimate", "--method", "auto", "--tau", "1", "--n-excursions", "100", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["method"] == "pdmp" and "chose pdmp" in out["method_reason"]
    assert main(["estimate", "--method", "auto", "--tau", "0.05", "--n-excursions", "100", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["method"] == "di" and "chose di" in out["method_reason"] and out["delta"] is None
    assert main(["bruteforce", "--method", "pdmp", "--t", "2", "--n-paths", "50", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["method"] == "pdmp" and out["events_per_s"] > 0 and out["n_unfinished"] == 0


def test_combine_pools_estimate_files_and_refuses_a_seed_twice(tmp_path, capsys):
    base = ["estimate", "--nondim", "--tau", "1e-3", "--tau-L", "1", "--gamma-bar", "0.3", "--n-excursions", "300"]
    files = []
    for seed in (1, 2):
        files.append(str(tmp_path / f"r{seed}.json"))
        assert main(base + ["--seed", str(seed), "--out", files[-1]]) == 0
    capsys.readouterr()
    out = tmp_path / "pooled.json"
    assert main(["combine", *files, "--json", "--out", str(out)]) == 0
    res = json.loads(capsys.readouterr().out)
    parts = [json.loads(open(f).read()) for f in files]
    assert res["n_excursions"] == sum(r["n_excursions"] for r in parts) and res["combined_from"] == [1, 2]
    assert json.loads(out.read_text()) == res
    assert main(["combine", files[0], files[0]]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "seeds must differ" in err[0]


@pytest.mark.parametrize("edit,field", [
    (dict(h="0.00067"), "h"),  # "Unknown format code 'g' for object of type 'str'", no field named
    (dict(sums={"n": 1e20}), "finite excursion sums, n a whole number"),  # TypeError: no callable sqrt method
])
def test_combine_names_the_file_and_the_field_of_a_malformed_result(tmp_path, edit, field, capsys):
    from dryfric_jax.excursions import STAT_NAMES

    files = []
    for seed in (1, 2):
        d = dict(D=1.0, D_ci=0.1, M0=0.0, M0_ci=0.1, mean_duration=1.0, n_excursions=200, n_truncated=0,
                 method="di", h=6.7e-4, dtype="float64", seed=seed, wall_s=1.0, lane_steps_per_s=1e6,
                 params=Params(**FIG3).as_dict(), sums=dict.fromkeys(STAT_NAMES, 1.0))
        if seed == 2:
            d.update({k: {**d["sums"], **v} if k == "sums" else v for k, v in edit.items()})
        files.append(tmp_path / f"r{seed}.json")
        files[-1].write_text(json.dumps(d))
    assert main(["combine", *map(str, files)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"dryfric: error: {files[1]} must have {field}"), err


@pytest.mark.parametrize("rtol", ["1e-160", "5e-324"])
def test_a_tiny_rtol_runs_until_the_work_bound_and_says_so(rtol, capsys):
    """int(ceil(N (rel/rtol)^2)) overflowed ("cannot convert float infinity to integer") after the
    first round: the excursions asked for are capped, and max_work ends the run."""
    assert main(["estimate", "--nondim", "--tau", "1e-3", "--tau-L", "inf", "--gamma-bar", "0", "--n-excursions", "200",
                 "--rtol", rtol, "--max-work", "2e6", "--allow-truncated", "--json"]) == 0
    cap = capsys.readouterr()
    res = json.loads(cap.out)
    assert res["stopped_by"] == "work_bound" and res["n_excursions"] >= 200 and math.isfinite(res["D_ci"])
    # predicted: N x the DI's fast-noise cycle floor (limits.di_cycle_floor: 8 tau0 at h/tau = 10) x 1/h' steps
    assert f"work bound reached (max_work = 2e+06 steps, predicted >= {200 * 8 * 100:.3g}) before the target rtol = " \
        f"{float(rtol)}" in cap.err


def test_text_output_is_the_results_summary(capsys):
    """``dryfric estimate`` / ``bruteforce`` print the result's ``summary()``; ``print(result)``
    in Python shows the same lines and the warnings (on stderr in the CLI), ``repr`` every field."""
    import warnings

    import dryfric_jax as dj

    assert main(["estimate", "--n-excursions", "200", "--seed", "4"]) == 0
    cli = capsys.readouterr()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", dj.DryfricWarning)
        r = dj.estimate_diffusivity(Params(**FIG3), 4, n_excursions=200)
    text = r.summary()
    assert text.startswith(f"D  = {r.D:.6g} ± {r.D_ci:.2g}") and "(95% CI)" in text and f"M0 = {r.M0:.6g}" in text
    # the same numbers as the CLI's (the wall time and the speed differ between runs)
    assert cli.out.splitlines()[:4] == text.splitlines()[:4]
    assert "n_excursions = " in cli.err and str(r) == text + "\nwarning: " + r.warnings[0] and len(r.warnings) == 1
    assert repr(r).startswith("EstimateResult(D=")
    bf = dj.bruteforce_diffusivity(Params(**FIG3), 5, t=0.5, n_paths=16)
    # 16 < 500 paths, t = 0.5 s < 100 tau_c = 50 s, and the start at the threshold with colored noise (tau' = 1.47),
    # of D_t and of M0_t
    assert bf.summary().startswith(f"D_t  = {bf.D_t:.6g}") and len(bf.warnings) == 4
    assert bf.warnings[0].startswith("n_paths = 16") and bf.warnings[1].startswith("t = 0.5 s is 1 < 100")
    assert bf.warnings[2].startswith("the paths start at rest with the noise at its threshold")
    assert bf.warnings[3].startswith("M0_t is biased by O(tau_c/t)")
    assert str(bf) == bf.summary() + "".join("\nwarning: " + w for w in bf.warnings)


def test_json_is_strict_with_tau_L_inf_and_reads_back(tmp_path, capsys):
    """tau_L = inf (pure dry friction) used to be written as Python's ``Infinity``, which jq,
    JavaScript and other strict JSON readers refuse: it is the string "inf" now, on stdout and
    in --out files, and combine reads it back as the float."""
    def strict(text):
        return json.loads(text, parse_constant=lambda c: pytest.fail(f"non-standard JSON constant {c}"))

    common = ["estimate", "--tau-L", "inf", "--Gamma", "10", "--tau", "0.125", "--n-excursions", "100", "--json"]
    n = 0
    for seed in (1, 2):
        assert main(common + ["--seed", str(seed), "--out", str(tmp_path / f"r{seed}.json")]) == 0
        out = strict(capsys.readouterr().out)
        assert out["params"]["tau_L"] == "inf" and math.isfinite(out["D"])
        assert strict((tmp_path / f"r{seed}.json").read_text()) == out
        n += out["n_excursions"]
    assert main(["combine", str(tmp_path / "r1.json"), str(tmp_path / "r2.json"), "--json"]) == 0
    pooled = strict(capsys.readouterr().out)
    assert pooled["params"]["tau_L"] == "inf" and pooled["n_excursions"] == n


@pytest.mark.parametrize("argv,match", [
    (["scripts/device_check.py", "--n", "nan"], "argument --n: must be a finite number >= 0"),  # were tracebacks
    (["scripts/device_check.py", "--budget-s", "inf"], "argument --budget-s: must be a finite number >= 0"),
    (["scripts/ci_calibration.py", "--seed", "-1", "--total", "100", "--sizes", "10"],
     r"seed must be an integer in \[0, 2\^62\] \(got -1\)"),
])
def test_scripts_refuse_bad_numbers_in_one_line(argv, match):
    import pathlib
    import re

    root = pathlib.Path(__file__).parent.parent
    p = subprocess.run([sys.executable, *argv], cwd=root, capture_output=True, text=True, timeout=300)
    assert p.returncode == 2 and "Traceback" not in p.stderr and re.search(match, p.stderr), p.stderr[-600:]


def test_a_closed_stdout_pipe_ends_quietly_with_141():
    """``dryfric ... | head -1``: the reader leaves and the next write to stdout fails (EPIPE).  That
    printed a BrokenPipeError traceback (exit 1), and Python's flush at exit another "Exception
    ignored" line.  Now: nothing on stderr, exit 141 (128 + SIGPIPE, what a shell shows for a program
    that SIGPIPE ended).  The pipe's read end is closed before the child has imported JAX.  ~3 s.
    (``--help`` was already quiet: argparse ignores the failed write.)"""
    import os
    import pathlib

    env = {**os.environ, "PYTHONPATH": str(pathlib.Path(__file__).parent.parent)}
    code = "import sys; from dryfric_jax.cli import main; sys.exit(main(['theory']))"
    p = subprocess.Popen([sys.executable, "-c", code], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    p.stdout.close()
    err = p.stderr.read().decode()
    assert (p.wait(timeout=300), err) == (141, "")


_CMDS_WITH_OUT = {
    "bruteforce": ["bruteforce", "--t", "0.5", "--n-paths", "16", "--json"],
    "estimate": ["estimate", "--n-excursions", "200", "--seed", "3"],
    "duration": ["duration", "--n-excursions", "20", "--seed", "3", "--json"],
    "figures": ["figures", "--fig", "table1", "--quick"],
}


@pytest.mark.parametrize("stdout", ["closed pipe", "/dev/full"])
@pytest.mark.parametrize("cmd", list(_CMDS_WITH_OUT))
def test_a_stdout_that_cannot_be_written_loses_no_result(tmp_path, cmd, stdout):
    """The result went to stdout first and to --out after, so a reader that left (``| true``: exit 141) or a
    full stdout (``> /dev/full``: a traceback) lost the finished run's file; Table 1 printed its rows before its
    files were written, so ``figures`` lost the scene (and with ``--fig all`` the scenes after it) and blamed the
    write (an audit).  Now the file is written, and the exit is 141 quietly, or 1 with one line naming the output."""
    import os
    import pathlib

    if stdout == "/dev/full" and not os.path.exists("/dev/full"):
        pytest.skip("no /dev/full here")
    out = tmp_path / ("figs" if cmd == "figures" else "r.json")
    env = {**os.environ, "PYTHONPATH": str(pathlib.Path(__file__).parent.parent)}
    code = f"import sys; from dryfric_jax.cli import main; sys.exit(main({_CMDS_WITH_OUT[cmd] + ['--out', str(out)]!r}))"
    if stdout == "closed pipe":
        p = subprocess.Popen([sys.executable, "-c", code], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        p.stdout.close()
        err = p.stderr.read().decode()
        rc = p.wait(timeout=600)
        assert rc == 141 and "Traceback" not in err and "error" not in err, err[-800:]
    else:
        with open("/dev/full", "w") as full:
            p = subprocess.run([sys.executable, "-c", code], env=env, stdout=full, stderr=subprocess.PIPE, text=True,
                               timeout=600)
        rc, err = p.returncode, p.stderr
        assert rc == 1 and "Traceback" not in err, err[-800:]
        assert err.strip().splitlines()[-1].startswith("dryfric: error: could not write the output ("), err[-800:]
    if cmd == "figures":
        assert (out / "table1.json").exists() and (out / "table1.png").exists()
    else:
        assert json.loads(out.read_text())["n_paths" if cmd == "bruteforce" else "n_excursions"] > 0


def test_figures_prints_table_1_once_its_files_are_written_also_when_kept(tmp_path, capsys):
    """Table 1's rows are printed by the command after the scenes are written (from the scene's JSON), also by a
    rerun that finds the scene written and does not compute it again."""
    for _ in range(2):
        assert main(["figures", "--fig", "table1", "--quick", "--out", str(tmp_path)]) == 0
        out = capsys.readouterr().out.splitlines()
        nums = json.loads((tmp_path / "table1.json").read_text())
        row = next(x for x in out if x.strip().startswith("MC (this model)"))
        assert [float(v) for v in row.split(")")[1].split()] == [round(v, 3) for v in nums["mc"]]
        assert out[0] == f"figures written to {tmp_path}" and len(out) == 7


def test_work_refusal_suggests_raising_max_work_only_when_a_float_could_allow_it(capsys):
    """Past float range (log work > log(1.8e308)) no ``--max-work`` allows the run: the message said
    "max_work must be >= 10^(1.9e+30) steps ... Raise --max-work".  Within it, it still says so."""
    assert main(["estimate", "--Gamma", "6.3e-3"]) == 2  # predicted mean duration 2.1e303 tau0, x 20000 x 100 steps
    err = capsys.readouterr().err
    assert "Raise max_work" not in err and "beyond float range (no max_work allows them)" in err
    assert "Coarsen h or delta, lower N" in err
    # the duration alone is out of reach (tau' = 7e30): no h, delta or N helps, so none is suggested (a
    # hard-cases audit: "Coarsen h or delta, lower N" at Delta = 1e8, where nothing could help)
    assert main(["estimate", "--Gamma", "1e-30"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("dryfric: error: the parameters must give excursions of predicted mean duration < "
                          "1.8e308 tau0 (float range; got >= 10^(1.9e+30) tau0 at tau' = 7.37e+30, ")
    assert err.rstrip().endswith(".  No h, delta or N makes this run feasible") and "Coarsen" not in err


@pytest.mark.parametrize("cmd", [["estimate", "--method", "pdmp"], ["estimate", "--method", "di"],
                                 ["estimate", "--method", "auto"], ["duration"]])
def test_a_run_whose_excursions_cannot_end_is_refused_for_that_whatever_the_method(capsys, cmd):
    """At gamma_bar' = 1e20 one excursion lasts past float range: the PDMP said "no delta is admissible for these
    parameters: use method 'di'", which then refused the run too (a hard-cases audit).  Every excursion method now
    says the duration is out of reach, before any h or delta; brute force, whose horizon is fixed, can use the DI."""
    assert main([*cmd, "--nondim", "--gamma-bar", "1e20"]) == 2
    err = capsys.readouterr().err
    # the damped runaway's Arrhenius term (README "Validity ranges"): z^2/2 / ln 10 decades, z = 1e20 sqrt(tau' +
    # tau_L') = 1e20 sqrt(1.4746 + 0.1977), so 3.631e39, rounded up to 3 digits
    assert err.startswith("dryfric: error: the parameters must give excursions of predicted mean duration < "
                          "1.8e308 tau0 (float range; got >= 10^(3.64e+39) tau0 at ")
    assert err.rstrip().endswith(".  No h, delta or N makes this run feasible") and "method 'di'" not in err
    assert main(["bruteforce", "--nondim", "--gamma-bar", "1e20", "--method", "pdmp", "--t", "1",
                 "--n-paths", "10"]) == 2
    assert capsys.readouterr().err.rstrip().endswith("no delta is admissible for these parameters: use method 'di'")
    assert main(["estimate", "--max-work", "1e3"]) == 2
    err = capsys.readouterr().err
    assert "max_work must be >= " in err and "(got 1e+03)" in err and "Raise max_work (--max-work), coarsen h" in err


_SIGTERM_ITSELF = """\
import os, signal, sys
from dryfric_jax import cli, rounds
real, calls = rounds.Lanes.advance, [0]
def advance(self, *a):
    calls[0] += 1
    if calls[0] == {at}:  # kill(1)'s SIGTERM, in the middle of a paused round
        os.kill(os.getpid(), signal.SIGTERM)
    return real(self, *a)
rounds.Lanes.advance = advance
sys.exit(cli.main(sys.argv[1:]))
"""


@pytest.mark.parametrize("at", [1, 4])
def test_sigterm_keeps_what_was_reached_as_ctrl_c_does(tmp_path, at):
    """SIGTERM (kill, a batch scheduler's time limit) ended ``dryfric estimate`` at once, exit 143, printing
    and writing nothing: every round run was lost (found by an audit).  It is now a Ctrl-C with the signal's
    exit status: in the 4th paused round, the result of the rounds reached is printed and written (stopped_by
    "interrupted"); in the first (the pilot, before any round ended), one line says so.  The process
    signals itself from inside the engine, so the moment is the same on any machine.  ~10 s each."""
    import pathlib

    script = tmp_path / "term.py"
    script.write_text(_SIGTERM_ITSELF.format(at=at))
    out = tmp_path / "r.json"
    p = subprocess.run([sys.executable, str(script), "estimate", "--n-excursions", "100000", "--json", "--out",
                        str(out)], cwd=pathlib.Path(__file__).parent.parent, capture_output=True, text=True,
                       timeout=600)
    assert p.returncode == 143 and "Traceback" not in p.stderr, p.stderr[-800:]
    if at == 1:
        assert (p.stdout, p.stderr) == ("", "dryfric: terminated (SIGTERM)\n")
        assert not out.exists()
        return
    r = json.loads(p.stdout)
    assert r == json.loads(out.read_text()) and r["stopped_by"] == "interrupted"
    assert 2 <= r["n_excursions"] < 100_000 and r["n_truncated"] == 0 and math.isfinite(r["D"])


def test_sigterm_is_ctrl_c_only_inside_main_and_only_where_it_has_its_default_action():
    """``main`` restores SIGTERM's handler when it returns; a SIGTERM handler someone else installed, or an
    ignored SIGTERM, is left as it was (cli.main is called from programs and tests, not only as the command)."""
    import signal

    from dryfric_jax import interrupts

    before = signal.getsignal(signal.SIGTERM)
    try:
        for h in (signal.SIG_DFL, signal.SIG_IGN, lambda s, f: None):
            signal.signal(signal.SIGTERM, h)
            seen = []
            with interrupts.sigterm_as_ctrl_c():
                seen.append(signal.getsignal(signal.SIGTERM))
            assert signal.getsignal(signal.SIGTERM) is h
            assert (seen[0] is interrupts._terminate) == (h is signal.SIG_DFL)
            assert not interrupts.terminated() and interrupts.exit_status(130) == 130
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
        assert main(["theory", "--json"]) == 0 and signal.getsignal(signal.SIGTERM) is signal.SIG_DFL
    finally:
        signal.signal(signal.SIGTERM, before)


def test_sigterm_keeps_its_default_action_in_commands_with_nothing_to_keep(monkeypatch):
    """'timeout 60 dryfric bench' at 2^22 lanes ran on for 10 minutes: SIGTERM, taken as a Ctrl-C, waited for a long
    compiled call to return, in a command with no partial result to keep (an audit).  Only estimate, sweep,
    figures and duration (since its loop runs in pieces of ~0.25 s and a Ctrl-C keeps what it counted) take it as
    a Ctrl-C; in the others (bench, bruteforce, theory, combine) it kills at once."""
    import signal

    from dryfric_jax import cli, interrupts

    seen = {}
    monkeypatch.setattr(cli, "_run", lambda a: seen.setdefault(a.cmd, signal.getsignal(signal.SIGTERM)) and 0)
    before = signal.getsignal(signal.SIGTERM)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    try:
        for argv in (["estimate"], ["sweep", "--out", "s.jsonl"], ["figures", "--out", "d"], ["bench"],
                     ["bruteforce", "--t", "1", "--n-paths", "10"], ["theory"], ["combine", "a.json"], ["duration"]):
            main(argv)
    finally:
        signal.signal(signal.SIGTERM, before)
    assert {c for c, h in seen.items() if h is interrupts._terminate} == {"estimate", "sweep", "figures", "duration"}
    assert {c for c, h in seen.items() if h is signal.SIG_DFL} == {"bench", "bruteforce", "theory", "combine"}


@pytest.mark.parametrize("argv, hint", [
    (["estimate", "--gamma", "5"], "--gamma: did you mean --Gamma or --gamma-bar?"),
    (["sweep", "--gamma", "1,2", "--out", "x.jsonl"], "--gamma: did you mean --Gamma or --gamma-bar?"),
    (["estimate", "--n-exc", "100"], "--n-exc: did you mean --n-excursions?"),
    (["estimate", "--tau-l=1"], "--tau-l: did you mean --tau-L?"),
    (["theory", "--delt", "1"], "--delt: did you mean --Delta or --delta?"),
])
def test_options_are_not_abbreviated(capsys, argv, hint):
    """argparse's abbreviations ran ``dryfric estimate --gamma 5`` as ``--gamma-bar 5``: the bias set to 5 where
    Gamma was meant, exit 0 and a wrong answer without a word (found by an audit).  Every option is now spelled
    out in full; an unknown one is refused (exit 2, nothing run) with the options it may have meant."""
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("dryfric: error: unrecognized arguments: ") and err.count("\n") == 1
    assert hint in err and "case-sensitive and spelled out in full" in err
    assert main(["estimate", "--foo", "1"]) == 2
    assert capsys.readouterr().err == "dryfric: error: unrecognized arguments: --foo 1\n"


def test_every_option_of_every_command_says_what_it_is():
    """'dryfric sweep --help' listed --h, --delta, --dtype, --seed, --n-excursions, --rtol, --max-work and the five
    axes with no text, and --seed nowhere said its range (a packaging audit)."""
    from dryfric_jax.cli import _all_actions, build_parser
    bare = sorted({s for a in _all_actions(build_parser()) if a.option_strings and not a.help
                   for s in a.option_strings})
    assert bare == [], bare
    seeds = [a.help for a in _all_actions(build_parser()) if "--seed" in a.option_strings]
    assert len(seeds) == 5 and "[0, 2^62 - 2^20]" in seeds[0]  # estimate, bruteforce, duration, figures, sweep
    assert all("[0, 2^62 - 2^20]" in s for s in seeds[:3])


def test_version_option_prints_the_package_version(capsys):
    from dryfric_jax import __version__
    from dryfric_jax.cli import main
    with pytest.raises(SystemExit) as e:
        main(["--version"])
    assert e.value.code == 0 and capsys.readouterr().out == f"dryfric_jax {__version__}\n"
