"""Mutation audit of the Ctrl-C handling: :mod:`dryfric_jax.interrupts` (the unraisable hook, the quiet
exit 130 while the command starts, ``launched_as_cli``, ``cancel_timers``), ``cli.main``'s KeyboardInterrupt
path, the API's "interrupted" result, a sweep's Ctrl-C and the engine's rounds loop
(``simulate_long_excursions``), which must never lose what completed rounds reached.

Expected values come from the documented behaviour only: the module docstrings of ``interrupts`` (who is the
command, "after DELAY_S", "cancel every Timer still waiting to fire; returns how many"), ``cli.main``'s comment
("from here a Ctrl-C is the KeyboardInterrupt below"; the one line "dryfric: interrupted" with the reason when
there is one) and the docstring of ``simulate_long_excursions`` (a first Ctrl-C finishes the in-flight
excursions, also when it comes during the final round, which then runs again; a second one drops them; the
stop reason is "interrupted"; completed rounds are never lost), with the API's "before 2 excursions have
closed ... the KeyboardInterrupt goes on up".  The engine tests use stand-in lanes whose rounds return
hand-made counts, so what the loop returns can be named without running a chain.  In-process with stand-ins,
except one process that imports the package (~3 s): < 5 s in all.

73 mutants were tried (I: the unraisable hook, L: launched_as_cli, S/T/Q: the handler while starting and
started(), C: cancel_timers, N: the calls in __init__, M: cli.main / _run, E: the rounds loop, A: the API, W: the
sweep).  The Ctrl-C tests of test_plumbing_mutants, test_reproducibility, test_cli, test_cli_mutants,
test_engine(_audit), test_api_audit, test_sweep, test_plumbing_audit and test_figures killed 53; two are
equivalent (I01: the hook's ``exc_type is not None`` guard, CPython never calls the hook without an exception
type; W02: ``raise`` for ``return None`` in sweep._compute, the sweep's own ``except KeyboardInterrupt`` then does
the same and the claim is left the same way); these tests kill 17 more (L02, L05, L09, S04, C03, C04, C06, N02,
M02, M05, E01, E03, E04, E05, E06, E08, W05).  One was no mistake but a fix: C02 (``t.is_alive()`` dropped from
cancel_timers) also cancels a Timer whose thread was created but has not yet run (``threading.enumerate()`` lists
it, ``is_alive()`` is False until it runs), the state a Ctrl-C landing in ``Timer.start()`` can leave it in.  It
is the module's code now, and test_a_timer_listed_before_its_thread_runs_is_cancelled_too pins it.
"""
import sys
import threading
import types

import pytest

from dryfric_jax import cli, interrupts, rounds


@pytest.mark.parametrize("at", [1, 3])
def test_a_signal_while_the_handlers_are_swapped_never_leaves_one_held(monkeypatch, at):
    """held_interrupts swaps SIGINT's and SIGTERM's handlers one after the other, and back.  A SIGTERM between the
    two swaps (taken as a Ctrl-C, as under sigterm_as_ctrl_c) left the context before its ``try``, with SIGINT's
    handler the hold for good, so that every later Ctrl-C was swallowed (a review).  Now the swaps are inside the
    ``try``: the SIGTERM acts at once and both handlers are restored (``at`` 1).  A restore cut short by a signal
    (a Ctrl-C raised after SIGINT's is restored, ``at`` 3) leaves SIGTERM's hold in place, which then acts as the
    handler it replaced.  The signals are raised in this thread (``signal.raise_signal``), so they are taken at
    once."""
    import signal

    def on_term(signum, frame):
        raise KeyboardInterrupt("term")

    def on_int(signum, frame):
        raise KeyboardInterrupt("int")

    before = signal.signal(signal.SIGINT, on_int), signal.signal(signal.SIGTERM, on_term)
    real, swaps = signal.signal, []

    def swap(s, h):
        out = real(s, h)
        swaps.append(s)
        if len(swaps) == at:
            signal.raise_signal(signal.SIGTERM if at == 1 else signal.SIGINT)
        return out
    try:
        monkeypatch.setattr(signal, "signal", swap)
        with pytest.raises(KeyboardInterrupt) as e:
            with interrupts.held_interrupts():
                pass
        monkeypatch.setattr(signal, "signal", real)
        assert str(e.value) == ("term" if at == 1 else "int")
        assert signal.getsignal(signal.SIGINT) is on_int
        if at == 1:
            assert signal.getsignal(signal.SIGTERM) is on_term
        for s, name in ((signal.SIGINT, "int"), (signal.SIGTERM, "term")):  # neither is held
            with pytest.raises(KeyboardInterrupt, match=f"^{name}$"):
                signal.raise_signal(s)
    finally:
        signal.signal(signal.SIGINT, before[0])
        signal.signal(signal.SIGTERM, before[1])


# --------------------------------------------------------------------------------------------- launched_as_cli
@pytest.mark.parametrize("argv,orig,is_cli", [
    (["/venv/Scripts/dryfric-script.py", "theory"], ["python", "/venv/Scripts/dryfric-script.py", "theory"], True),
    (["-c", "-m", "dryfric_jax.cli"], ["python", "-c", "import dryfric_jax", "-m", "dryfric_jax.cli"], False),
    (["app.py", "-m", "dryfric_jax.cli"], ["python", "app.py", "-m", "dryfric_jax.cli"], False),
    (["app.py", "-mdryfric_jax.cli"], ["python", "app.py", "-mdryfric_jax.cli"], False),
    ([], ["embedding-app"], False),
])
def test_who_is_the_command(monkeypatch, argv, orig, is_cli):
    """The command is its console script (also setuptools' ``dryfric-script.py`` on Windows) or ``python -m
    dryfric_jax.cli`` while ``sys.argv[0]`` is "-m"; a program (``-c``, a script) that merely has "-m
    dryfric_jax.cli" among its own arguments is not, and neither is an embedding application with an empty
    ``sys.argv``.  Mutants: L02 (the ``-script.py`` name dropped), L05 (the ``argv0 == "-m"`` test dropped),
    L09 (``sys.argv[0]`` read unguarded: IndexError)."""
    monkeypatch.setattr(sys, "argv", argv)
    monkeypatch.setattr(sys, "orig_argv", orig)
    assert interrupts.launched_as_cli() is is_cli


# ------------------------------------------------------------------------------------------ the unraisable hook
class _Timer:
    def __init__(self, delay, fn):
        self.delay, self.fn, self.daemon, self.started = delay, fn, None, False
        made.append(self)

    def start(self):
        self.started = True


made = []


def test_the_swallowed_ctrl_c_is_delivered_after_a_positive_delay(monkeypatch):
    """The hook runs in the main thread, inside the callback that swallowed the Ctrl-C: an interrupt sent at
    once "is raised in the hook and ignored again" (module docstring), so the timer that sends it waits a
    positive delay, and a short one (a Ctrl-C acts within a second).  Mutants: I06 (``DELAY_S = 0``: the
    existing unit test compares the timer's delay with DELAY_S itself, and test_reproducibility's real delivery
    catches it only through a race), I14 (``DELAY_S = 60``)."""
    monkeypatch.setattr(sys, "unraisablehook", lambda u: None)
    monkeypatch.setattr(interrupts.threading, "Timer", _Timer)
    made.clear()
    interrupts.keep_ctrl_c()
    sys.unraisablehook(types.SimpleNamespace(exc_type=KeyboardInterrupt, exc_value=KeyboardInterrupt()))
    assert len(made) == 1 and made[0].started and made[0].fn is interrupts._thread.interrupt_main
    assert 0 < made[0].delay <= 1.0


# ---------------------------------------------------------------------------------- the handler while starting
def test_a_program_importing_the_package_keeps_python_s_ctrl_c(monkeypatch):
    """Where a program or a notebook imports the package (not the command), Python's own handler stays: a
    Ctrl-C there is a KeyboardInterrupt, not an exit 130.  Mutants: Q01 (the ``launched_as_cli()`` test
    dropped: the existing tests die with the process, exit 130, at the first re-delivered Ctrl-C), Q05 (the
    test negated)."""
    monkeypatch.setattr(interrupts, "launched_as_cli", lambda: False)
    monkeypatch.setattr(interrupts.signal, "getsignal", lambda signum: interrupts.signal.default_int_handler)
    monkeypatch.setattr(interrupts.signal, "signal", lambda *a: pytest.fail(f"signal.signal{a} called"))
    interrupts.quiet_ctrl_c_while_starting()


class _Exited(BaseException):
    pass


def test_a_ctrl_c_while_starting_ends_the_process_even_where_exceptions_are_caught(monkeypatch):
    """The starting handler may run in the middle of any import, where an exception would be caught or turned
    into an ImportError (a compiled module's initialisation): it writes its one line to stderr (fd 2) and ends
    the process at once with ``os._exit(130)``, which no ``except`` stops (stand-ins for ``os.write`` and
    ``os._exit``, run inside an ``except BaseException``).  Mutant: S04 (``raise SystemExit(130)``: caught
    there, the command went on); S01-S03 (code, fd, line) too, without a process."""
    wrote, exited = [], []

    def exit_(code):
        exited.append(code)
        raise _Exited

    monkeypatch.setattr(interrupts.os, "write", lambda fd, b: wrote.append((fd, b)) or len(b))
    monkeypatch.setattr(interrupts.os, "_exit", exit_)
    with pytest.raises(_Exited):
        try:
            interrupts._stop_while_starting(2, None)
        except _Exited:
            raise
        except BaseException:  # what an import in progress may do with an exception
            pass
    assert exited == [130] and wrote == [(2, b"dryfric: interrupted while starting (nothing was run)\n")]


def test_importing_the_package_keeps_a_ctrl_c_swallowed_in_a_callback():
    """Importing the package is what installs the hook (the package docstring): in a fresh process that only
    imports it, a KeyboardInterrupt raised in a ``__del__`` (unraisable) reaches the main thread.  The other
    tests install the hook themselves (pytest swaps it per test).  Mutant: N02 (``keep_ctrl_c()`` not called
    on import: "lost" after 10 s).  One process, ~3 s."""
    import os
    import pathlib
    import subprocess

    code = ("import time\nimport dryfric_jax\nclass C:\n    def __del__(self):\n        raise KeyboardInterrupt\n"
            "try:\n    C()\n    for _ in range(200):\n        time.sleep(0.05)\n    print('lost')\n"
            "except KeyboardInterrupt:\n    print('delivered')\n")
    root = pathlib.Path(__file__).parent.parent
    p = subprocess.run([sys.executable, "-c", code], cwd=root, env={**os.environ, "PYTHONPATH": str(root)},
                       capture_output=True, text=True, timeout=120)
    assert (p.returncode, p.stdout) == (0, "delivered\n"), p.stderr[-800:]


# --------------------------------------------------------------------------------------------- cancel_timers
class _Lingering(threading.Timer):
    """A timer whose thread stays alive after it was cancelled (until ``release`` is set)."""
    release = threading.Event()

    def run(self):
        super().run()
        self.release.wait(30)


def test_cancel_timers_cancels_and_counts_only_the_timers_still_waiting(monkeypatch):
    """Two 60-s timers waiting to fire are cancelled (their threads end at once) and counted; a timer already
    cancelled (its thread still alive) and a plain thread are not counted, and the plain thread is left alone.
    Mutants: C03 (a cancelled timer counted again), C04 / C06 (the count not kept: 0 returned), C05 (nothing
    cancelled: the timers still run)."""
    fired, stop = [], threading.Event()
    waiting = [threading.Timer(60.0, fired.append, args=(i,)) for i in range(2)]
    done = _Lingering(60.0, fired.append, args=("cancelled",))
    plain = threading.Thread(target=stop.wait, args=(30,), daemon=True)
    for t in (*waiting, done, plain):
        t.daemon = True
        t.start()
    try:
        done.cancel()  # its thread is alive, held in run() after the wait
        assert interrupts.cancel_timers() == 2
        for t in waiting:
            t.join(10)
            assert not t.is_alive() and t.finished.is_set()
        assert plain.is_alive() and fired == []
    finally:
        for t in waiting:
            t.cancel()
        _Lingering.release.set()
        stop.set()


def test_a_timer_listed_before_its_thread_runs_is_cancelled_too(monkeypatch):
    """A Ctrl-C inside ``Timer.start()`` can leave the timer listed by ``threading.enumerate()`` (Python puts a
    thread there before its thread runs) with ``is_alive()`` still False.  Such a timer is waiting to fire, so
    cancel_timers cancels and counts it; started later, it never fires.  Before, it was skipped (0 returned), and
    the exit waited the timer's 60 s again.  Kills ``t.is_alive()`` back in the test."""
    fired = []
    t = threading.Timer(0.01, fired.append, args=("fired",))
    t.daemon = True
    monkeypatch.setattr(threading, "enumerate", lambda: [t])
    assert not t.is_alive()
    assert interrupts.cancel_timers() == 1 and t.finished.is_set()
    monkeypatch.undo()
    t.start()
    t.join(10)
    assert not t.is_alive() and fired == []


def _no_ctrl_c_escapes(fn, *args, **kw):
    """``fn(...)``; a KeyboardInterrupt leaving it fails the test (pytest would stop the whole session)."""
    try:
        return fn(*args, **kw)
    except KeyboardInterrupt:
        pytest.fail("the KeyboardInterrupt went on up")


# ------------------------------------------------------------------------------------------------- cli.main
def _main_with(monkeypatch, started=None, run=None):
    cancelled = []
    monkeypatch.setattr(cli.interrupts, "cancel_timers", lambda: cancelled.append(1) or 0)
    if started is not None:
        monkeypatch.setattr(cli.interrupts, "started", started)
    if run is not None:
        monkeypatch.setattr(cli, "_run", run)
    return _no_ctrl_c_escapes(cli.main, ["theory"]), cancelled


def test_a_ctrl_c_as_main_hands_ctrl_c_back_is_main_s_exit_130(monkeypatch, capsys):
    """A SIGINT that arrives just as ``started()`` puts Python's handler back (stand-in: ``started`` raises
    KeyboardInterrupt) is main's KeyboardInterrupt: exit 130, one line, the timers cancelled.  Mutant: M02
    (``started()`` called before the ``try``: the KeyboardInterrupt leaves main, a traceback)."""
    def started():
        raise KeyboardInterrupt

    rc, cancelled = _main_with(monkeypatch, started=started)
    assert (rc, capsys.readouterr().err, cancelled) == (130, "dryfric: interrupted\n", [1])


def test_a_bare_ctrl_c_is_one_line_without_a_reason(monkeypatch, capsys):
    """A KeyboardInterrupt without a reason prints exactly "dryfric: interrupted" (no ": " after it); one with
    a reason prints it after ": ".  Mutants: M05 (": " always appended), M06 (the reason dropped)."""
    def run(a, reason):
        raise KeyboardInterrupt(*reason)

    for reason, said in (((), "dryfric: interrupted\n"), (("2 points kept",), "dryfric: interrupted: 2 points kept\n")):
        rc, cancelled = _main_with(monkeypatch, run=lambda a: run(a, reason))
        assert (rc, capsys.readouterr().err, cancelled) == (130, said, [1])


# -------------------------------------------------------------------------------------------- the rounds loop
def _stats(n, in_flight):
    return types.SimpleNamespace(n_excursions=n, n_truncated=0, n_in_flight=in_flight, useful_steps=100 * (n + 1),
                                 n_unfinished=0)


class _Lanes:
    """Stand-in lanes: each ``advance`` / ``finish`` call takes the next item of its script, a round's counts
    or ``KeyboardInterrupt`` (the Ctrl-C that arrives during that round, before it is kept); a call past the script
    fails.  A round is kept as ``Lanes._round`` keeps one: counted in ``rounds``, its counts in ``last``."""
    script = dict(advance=[], finish=[])
    calls = []
    deadlines = []

    def __init__(self, chain, lanes, block, max_steps):
        self.n_real, self.paid, self.rounds, self.last = lanes, 0, 0, None

    def _next(self, what):
        _Lanes.calls.append(what)
        assert _Lanes.script[what], f"{what} called after the script's end"
        item = _Lanes.script[what].pop(0)
        if item is KeyboardInterrupt:
            raise KeyboardInterrupt
        self.paid += 100
        self.rounds, self.last = self.rounds + 1, item
        return item

    def advance(self, key, budget):
        return self._next("advance")

    def finish(self, key, budget=0, deadline=None):
        _Lanes.deadlines.append(deadline)
        return self._next("finish")


def _loop(monkeypatch, advance, finish, more=None, ctrl_c_escapes=False, max_time=None):
    import jax

    monkeypatch.setattr(rounds, "Lanes", _Lanes)
    _Lanes.script, _Lanes.calls, _Lanes.deadlines = dict(advance=list(advance), finish=list(finish)), [], []
    run = rounds.simulate_long_excursions
    args = (None, jax.random.key(0), 4)
    kw = dict(lanes=8, block=8, more=more, max_time=max_time)
    return run(*args, **kw) if ctrl_c_escapes else _no_ctrl_c_escapes(run, *args, **kw)


def test_a_ctrl_c_before_any_round_completed_goes_on_up_at_once(monkeypatch):
    """A Ctrl-C in the first round: no completed round, nothing in flight to finish; the KeyboardInterrupt
    goes on up without a final round (which would simulate a whole round after the Ctrl-C).  Mutant: E01
    (the ``raise`` dropped: a final round run from the lanes' start)."""
    with pytest.raises(KeyboardInterrupt):
        _loop(monkeypatch, [KeyboardInterrupt], [_stats(5, 0)], ctrl_c_escapes=True)
    assert _Lanes.calls == ["advance"]


def test_a_ctrl_c_in_the_rounds_ends_the_run_even_when_the_target_wants_more(monkeypatch):
    """A Ctrl-C in the paused rounds: the final round finishes the in-flight excursions and the run ends,
    "interrupted", with that final round's counts, even though the precision target (``more``) still wants
    excursions.  Mutant: E06 (an interrupted run went on with more rounds)."""
    final = _stats(6, 0)
    st, stopped = _loop(monkeypatch, [_stats(1, 8), KeyboardInterrupt], [final], more=lambda s: 1000)
    assert (st, stopped, _Lanes.calls) == (final, "interrupted", ["advance", "advance", "finish"])


def test_a_first_ctrl_c_in_the_final_round_runs_it_again_and_says_interrupted(monkeypatch):
    """The rounds reach the target; a Ctrl-C during the final round is the run's first: that round runs again
    and its counts are returned, "interrupted" (not "target", though ``more`` wants nothing more).  Mutants:
    E03 / E08 (the first Ctrl-C in the final round taken for the second: the in-flight excursions dropped),
    E05 (the stop reason not set there: "target")."""
    final = _stats(6, 0)
    st, stopped = _loop(monkeypatch, [_stats(4, 2)], [KeyboardInterrupt, final], more=lambda s: 0)
    assert (st, stopped, _Lanes.calls) == (final, "interrupted", ["advance", "finish", "finish"])


def test_a_second_ctrl_c_in_the_final_round_keeps_the_completed_rounds(monkeypatch):
    """Two Ctrl-Cs during the final round: the second ends it at once; what the completed (paused) round
    reached is returned, its in-flight excursions dropped (still counted in ``n_in_flight``), not lost.
    Mutant: E04 (the first Ctrl-C not remembered: every Ctrl-C ran the final round again)."""
    paused = _stats(4, 2)
    st, stopped = _loop(monkeypatch, [paused], [KeyboardInterrupt, KeyboardInterrupt, _stats(6, 0)])
    assert (st, stopped, _Lanes.calls) == (paused, "interrupted", ["advance", "finish", "finish"])


@pytest.mark.parametrize("where", ["rounds", "final round"])
def test_a_first_ctrl_c_gives_the_final_round_a_grace_deadline_and_says_so(monkeypatch, capsys, where):
    """DEFECT (a hard-cases audit): after a first Ctrl-C (SIGTERM in the CLI) the final round finishing the
    excursions in flight had no deadline without ``max_time``: at Gamma = 1e8 (Fig. 3's point) 'timeout 75
    dryfric estimate' was still running, silent, 10 minutes later.  Now the final round is cut
    INTERRUPT_GRACE_S after the Ctrl-C (the clock here: 100 s), or at the max_time deadline if earlier, and
    one line on stderr says so, naming the excursions in flight."""
    monkeypatch.setattr(rounds, "_now", lambda: 100.0)
    grace = 100.0 + rounds.INTERRUPT_GRACE_S
    if where == "rounds":  # the target wants more, so a second paused round runs, and is interrupted
        advance, finish, more = [_stats(1, 8), KeyboardInterrupt], [_stats(6, 0)], lambda s: 1000
    else:
        advance, finish, more = [_stats(4, 2)], [KeyboardInterrupt, _stats(6, 0)], lambda s: 0
    _loop(monkeypatch, advance, finish, more=more)
    assert _Lanes.deadlines[-1] == grace and (where == "rounds" or _Lanes.deadlines[0] is None)
    in_flight = 8 if where == "rounds" else 2
    assert capsys.readouterr().err == (f"dryfric: interrupted: finishing the {in_flight} excursions in flight for at "
                                       "most 20 s (any still running then are reported as truncated); interrupt "
                                       "again to drop them\n")
    _loop(monkeypatch, [_stats(1, 8), KeyboardInterrupt], [_stats(6, 0)], more=lambda s: 1000,
          max_time=1.0)  # max_time's deadline is the earlier, and the line says how long is left
    assert _Lanes.deadlines == [100.0 + rounds.FINAL_DEADLINE * 1.0]
    assert "for at most 2 s (any" in capsys.readouterr().err


# ------------------------------------------------------------------------------------------------------ sweeps
def test_a_ctrl_c_in_a_sweep_does_not_then_wait_for_another_sweeps_point(tmp_path, monkeypatch):
    """A point of the grid is claimed by another sweep (here: this test), so it is left for later; a Ctrl-C in
    the next point ends the sweep at once: "interrupted", nothing computed, and no wait for the claimed point
    (which could last the other sweep's whole point).  Mutant: W05 (the outer loop not left after the Ctrl-C:
    the sweep went on to wait for the later points)."""
    import contextlib

    from dryfric_jax import sweep
    from dryfric_jax.outfiles import claim
    from dryfric_jax.params import FIG3
    from dryfric_jax.plan import check_settings

    waits, real = [], sweep.claim

    @contextlib.contextmanager
    def no_wait(path, key, wait=False):
        if wait:
            waits.append(key)
            raise KeyboardInterrupt  # stands for the wait, which would block while this test holds the claim
        with real(path, key) as c:
            yield c

    def ctrl_c(*a, **kw):
        raise KeyboardInterrupt

    monkeypatch.setattr(sweep, "claim", no_wait)
    monkeypatch.setattr(sweep, "estimate_diffusivity", ctrl_c)
    out = str(tmp_path / "s.jsonl")
    held = sweep._ident(0, {**FIG3, "Gamma": 2.0}, check_settings(n_excursions=50))
    with claim(out, held) as c:
        assert c.held
        r = _no_ctrl_c_escapes(sweep.run_sweep, sweep.grid(Gamma=[2.0, 3.0]), out, n_excursions=50)
    assert (r["interrupted"], r["computed"], r["skipped"], waits) == (True, 0, 0, [])
