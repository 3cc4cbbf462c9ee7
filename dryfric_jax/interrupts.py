"""A Ctrl-C is never swallowed.

Python raises ``KeyboardInterrupt`` wherever the main thread is when SIGINT arrives.  Inside a
garbage-collection callback (JAX registers one) it cannot propagate: Python prints "Exception
ignored in: <function _xla_gc_callback ...>" and goes on, so the Ctrl-C was lost and the run
finished as if nothing had happened (measured: ``dryfric estimate`` interrupted ~1 s after its
start exited 0 after the whole run).  :func:`keep_ctrl_c`, called when the package is imported,
installs a ``sys.unraisablehook`` that delivers such a ``KeyboardInterrupt`` to the main thread
again (``_thread.interrupt_main`` from a helper thread after :data:`DELAY_S`: called in the hook
itself, or from a thread at once, it is raised in the hook and ignored again; should it land in a
callback once more, the hook delivers it again)
and passes every other unraisable exception to the hook it replaced.

A Ctrl-C while the ``dryfric`` command imports the package (``import jax``: the first 1-2 s)
printed Python's KeyboardInterrupt traceback (or an ImportError, when it landed in a compiled
module's initialisation) and exited -SIGINT or 1.  :func:`quiet_ctrl_c_while_starting`, called
first thing on import, makes such a Ctrl-C end the command at once with exit code 130 and one line
on stderr, as later ones do, until ``cli.main`` takes over (:func:`started`: the window between the
end of the package's import and main's ``try`` gave a traceback too); it acts only in the command
(:func:`launched_as_cli`), never where a program or a notebook imports the package.

SIGTERM (``kill``, a batch scheduler's time limit, ``timeout``) ended the command at once with
exit 143 and threw away every round already run, printing nothing.  :func:`sigterm_as_ctrl_c`,
entered by ``cli.main``, makes it a Ctrl-C: what was reached is printed and written, and the exit
status is still the signal's, 128 + 15 (:func:`exit_status`).
"""
from __future__ import annotations

import _thread
import contextlib
import os
import signal
import sys
import threading
from collections.abc import Callable

#: the delay after which a swallowed Ctrl-C is delivered again (the callback has returned by then)
DELAY_S = 0.05


def _is_ctrl_c(unraisable) -> bool:
    return unraisable.exc_type is not None and issubclass(unraisable.exc_type, KeyboardInterrupt)


def keep_ctrl_c() -> None:
    """Install the hook (once; a second call does nothing)."""
    previous = sys.unraisablehook
    if getattr(previous, "_dryfric_keeps_ctrl_c", False):
        return

    def hook(unraisable):
        if _is_ctrl_c(unraisable):
            t = threading.Timer(DELAY_S, _thread.interrupt_main)  # once the callback has returned
            t.daemon = True
            t.start()
        else:
            previous(unraisable)

    hook._dryfric_keeps_ctrl_c = True
    sys.unraisablehook = hook


#: the line a Ctrl-C during the command's import prints (nothing was computed yet)
STARTING_LINE = b"dryfric: interrupted while starting (nothing was run)\n"


#: the modules ``python -m`` runs as the ``dryfric`` command
CLI_MODULES = ("dryfric_jax.cli", "dryfric_jax")


def launched_as_cli() -> bool:
    """Whether this process is the ``dryfric`` command: its console script (``sys.argv[0]`` is
    .../dryfric), ``python -m dryfric_jax.cli`` or ``python -m dryfric_jax`` (its ``__main__``; it had Python's
    traceback for a Ctrl-C while starting and for a too-old JAX, exit 1 not 2: a README audit), whose
    ``sys.argv[0]`` is "-m" while the module is located (which imports the package)."""
    argv0 = sys.argv[0] if sys.argv else ""
    if os.path.basename(argv0).removesuffix(".exe") in ("dryfric", "dryfric-script.py"):
        return True
    orig = list(getattr(sys, "orig_argv", ()))
    joined = [f"-m{m}" for m in CLI_MODULES]  # "-mdryfric_jax.cli", one argument
    return argv0 == "-m" and any(a in joined or (a == "-m" and b in CLI_MODULES) for a, b in zip(orig, orig[1:] + [""]))


def _stop_while_starting(signum, frame):
    os.write(2, STARTING_LINE)  # not print: the handler may run inside a write to sys.stderr
    os._exit(130)


def started() -> None:
    """Python's own Ctrl-C handler again, if :func:`quiet_ctrl_c_while_starting` installed its own:
    called by ``cli.main`` inside the ``try`` that turns a KeyboardInterrupt into exit 130 (a no-op
    elsewhere, and the second time)."""
    if signal.getsignal(signal.SIGINT) is _stop_while_starting:
        signal.signal(signal.SIGINT, signal.default_int_handler)


def quiet_ctrl_c_while_starting() -> None:
    """In the ``dryfric`` command, with Python's own Ctrl-C handler in place (not where SIGINT is
    ignored, as in a background job), a Ctrl-C exits 130 at once with one line on stderr until
    :func:`started` is called (by ``cli.main``, which handles it from then on).  A handler, not an ``except
    KeyboardInterrupt``: a KeyboardInterrupt raised in a compiled module's initialisation (numpy's,
    jaxlib's) comes out as an ImportError.  ``os._exit``: nothing was computed or opened for
    writing yet, and the handler may run in the middle of any import."""
    if not (launched_as_cli() and threading.current_thread() is threading.main_thread()
            and signal.getsignal(signal.SIGINT) is signal.default_int_handler):
        return
    signal.signal(signal.SIGINT, _stop_while_starting)


def cancel_timers() -> int:
    """Cancel every ``threading.Timer`` still waiting to fire; returns how many.  Called by
    ``cli.main`` when a Ctrl-C ends the command (exit 130).

    JAX probes for a TPU when its backends first start (``jax.devices()``, the first computation):
    ``xla_bridge.tpu_client_timer_callback`` starts a 60 s, non-daemon ``threading.Timer`` that
    warns "TPU backend initialization is taking more than 60 seconds", and cancels it in a
    ``finally`` entered only after ``Timer.start()`` returns.  A Ctrl-C that lands inside that
    ``start()`` (it waits for the new thread) skips the ``finally``: the interpreter then waited
    60 s at exit for the timer, which printed its warning (seen once in CI, 2026-11-28, jax
    0.10.2: ``dryfric estimate`` interrupted at 1.0 s took 61 s to exit 130).

    Such a timer's thread may be created and not yet running (``threading.enumerate`` lists it,
    ``is_alive()`` is still False): it is cancelled too, and its ``run`` then returns at once."""
    n = 0
    for t in threading.enumerate():
        if isinstance(t, threading.Timer) and not t.finished.is_set():
            t.cancel()
            n += 1
    return n


#: the signal :func:`sigterm_as_ctrl_c` turned into a KeyboardInterrupt, else None
_terminated: int | None = None


def _terminate(signum, frame):
    global _terminated
    _terminated = signum
    raise KeyboardInterrupt


@contextlib.contextmanager
def sigterm_as_ctrl_c():
    """Within: SIGTERM raises ``KeyboardInterrupt`` (the command's Ctrl-C path: the completed rounds'
    result printed and written, a sweep's or figure's finished points kept), and :func:`terminated`
    says so.  Only in the main thread and where SIGTERM has its default action (a handler someone
    installed, or an ignored SIGTERM, is left alone); the previous handler is restored on exit."""
    global _terminated
    _terminated = None
    if threading.current_thread() is not threading.main_thread() or signal.getsignal(signal.SIGTERM) != signal.SIG_DFL:
        yield
        return
    signal.signal(signal.SIGTERM, _terminate)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, signal.SIG_DFL)


def terminated() -> bool:
    """Whether the last :func:`sigterm_as_ctrl_c` block was ended by SIGTERM."""
    return _terminated is not None


@contextlib.contextmanager
def held_interrupts(second_acts: bool = False, said: Callable[[], str | None] | None = None):
    """Within: SIGINT and SIGTERM are held, not acted on, so that a finished result's write completes; on exit the
    previous handlers are restored and a signal held is delivered to them (``signal.raise_signal``: a
    ``KeyboardInterrupt`` as the block ends, or the default action).  A sweep's point finished but caught by a
    signal while its record was written (then the file read, checked and rewritten under its lock, ~1 s with 6000
    records) was lost: the write's temporary file deleted, the point not counted (an audit).  Only in the main
    thread (elsewhere it holds nothing), and only signals whose handler Python can restore (not one installed
    outside Python, nor an ignored one).

    ``second_acts``: only the first signal is held (``said()``, if given and not None, is printed on stderr as it
    comes, on a line of its own where stderr is a terminal, and not at all where that print fails); a second
    one restores the handlers and acts at once, for both (SIGTERM's action where either was SIGTERM): for a wait
    that may not end (a results file's lock that another process holds), so that a process stuck there still
    stops on a second Ctrl-C, as a run's second Ctrl-C drops what the first would have finished."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    held, old, active = [], {}, [True]

    def restore():
        active[0] = False
        for s, h in old.items():
            signal.signal(s, h)

    def hold(signum, frame):
        if active[0] and not (second_acts and held):
            held.append(signum)
            text = said() if said is not None and len(held) == 1 else None
            if text is not None:
                with contextlib.suppress(Exception):  # (a print the signal cut into: "reentrant call")
                    print(("\r\x1b[K" if sys.stderr.isatty() else "") + text, file=sys.stderr, flush=True)
            return
        # a second signal (second_acts), or a hold left in place by a restore that a signal cut short: act as the
        # handler it replaced, at once
        first = signal.SIGTERM if signal.SIGTERM in (*held, signum) and signal.SIGTERM in old else signum
        held.clear()
        restore()
        signal.raise_signal(first)
    # The handlers are swapped one at a time inside the try, so that a signal between two swaps (taken by the
    # handler not yet swapped: SIGTERM as a KeyboardInterrupt) still restores those swapped; a hold left in place
    # by a restore cut short acts as the handler it replaced.  Swapped before the try, such a SIGTERM left Ctrl-C
    # held for good (a review).
    try:
        for s in (signal.SIGINT, signal.SIGTERM):
            h = signal.getsignal(s)
            if h is not None and h != signal.SIG_IGN:
                old[s] = h
                signal.signal(s, hold)
        yield
    finally:
        restore()
        if held:  # SIGTERM first where both came: the command's exit status is then 143, as a scheduler expects
            signal.raise_signal(signal.SIGTERM if signal.SIGTERM in held else held[0])


@contextlib.contextmanager
def interrupt_noted():
    """Within: SIGINT and SIGTERM held (:func:`held_interrupts`); where one came, it is delivered as the block ends
    and the ``KeyboardInterrupt`` its handler raises is caught and noted instead of going on up: the list this
    yields then holds True.  For the last steps of a run that has finished (its estimate formed from the sums):
    a Ctrl-C or SIGTERM there threw the whole run away (an interrupt audit: ~0.17 s after a 2-9 s estimate, exit 143,
    nothing printed or written); the caller returns the result marked as interrupted instead.  A
    ``KeyboardInterrupt`` the block raises itself goes on up."""
    noted, body_done = [], [False]
    try:
        with held_interrupts():
            yield noted
            body_done[0] = True
    except KeyboardInterrupt:
        if not body_done[0]:
            raise
        noted.append(True)


def exit_status(rc: int) -> int:
    """A command's exit status: 130 (stopped by a KeyboardInterrupt) becomes 128 + SIGTERM when SIGTERM
    raised it, so a scheduler or a shell still sees the signal that ended the command."""
    return 128 + _terminated if rc == 130 and _terminated is not None else rc
