r"""Live status lines while a run goes on: ``progress=True`` of :func:`~dryfric_jax.estimate_diffusivity`,
:func:`~dryfric_jax.di_long_excursion_duration` and :func:`~dryfric_jax.sweep.run_sweep`.

Where the line goes (:func:`where`): in a Jupyter kernel one text display (with a display id) that each report
updates in place (``IPython.display``; a carriage return on the kernel's stderr would
be kept by some front ends and drawn as text by others, and the line would mix with the warnings there); on a
terminal, a self-overwriting line on stderr, fitted to its width (the ``dryfric`` commands' lines); elsewhere
(stderr to a file or a pipe, a test) nothing.
"""
from __future__ import annotations

import contextlib
import os
import sys
import threading
import warnings


def where() -> str | None:
    """``"notebook"`` inside a Jupyter kernel (IPython imported and running a kernel), ``"terminal"`` where stderr
    is a terminal, None elsewhere.  The kernel comes first: its stderr is a stream object that may say it is a
    terminal."""
    ipython = sys.modules.get("IPython")  # never imported here: a kernel has imported it
    shell = getattr(ipython, "get_ipython", lambda: None)()
    if shell is not None and getattr(shell, "kernel", None) is not None:
        return "notebook"
    try:
        return "terminal" if sys.stderr.isatty() else None
    except (AttributeError, ValueError, OSError):  # no stderr, or a closed one
        return None


def terminal_columns() -> int | None:
    """The width of the terminal stderr is on, read at each call (the window may be resized), or where stderr has
    no terminal size (a stand-in in a test), ``COLUMNS``; None where neither gives a number > 0."""
    try:
        n = os.get_terminal_size(sys.stderr.fileno()).columns
        if n > 0:  # a pty not yet sized says 0: then COLUMNS (a review)
            return n
    except (AttributeError, ValueError, OSError):  # no fileno (io.UnsupportedOperation is both), or not a terminal
        pass
    try:
        n = int(os.environ.get("COLUMNS", ""))
    except ValueError:
        return None
    return n if n > 0 else None


def fit_text(text: str, columns: int | None, tail: str = "") -> str:
    """``text + tail`` within ``columns - 1`` characters (None: as it is): a self-overwriting status line must stay
    on one row, since a carriage return goes back to the start of the last row only, and a line that wrapped left a
    stale row on the screen at each redraw (an audit: 15 rows by a sweep on 80 columns).  Where it is too long,
    ``text`` is cut at its end for "…" and ``tail`` (the times) kept whole, as long as that leaves ``text`` its first
    24 characters (half the room where that is less); otherwise the whole line is cut at its end."""
    room = None if columns is None else max(columns - 1, 0)
    if room is None or len(text) + len(tail) <= room:
        return text + tail
    if len(tail) > room - 1 - min(24, room // 2):
        text, tail = text + tail, ""
    return text[:max(room - len(tail) - 1, 0)] + "…"[:room] + tail


def status_line(text: str, tail: str = "") -> str:
    """A self-overwriting status line on stderr: a carriage return, ``text + tail`` fitted to the terminal's width
    (:func:`fit_text`, :func:`terminal_columns`) and the rest of the row cleared."""
    return "\r" + fit_text(text, terminal_columns(), tail) + "\x1b[K"


class StatusLine:
    """A live status line (:func:`where`): ``show(text, tail)`` draws it anew, ``close()`` clears it (a terminal's
    row, so that what is printed next starts on a clean one; a notebook's display, whose last text would be stale:
    a sweep's said "5/6 points" after the sixth).  ``tail`` (the times) is kept whole where a terminal's line is
    cut to its width.  Nothing is drawn where ``kind`` is None, nor after a drawing failed (a terminal closed, a
    front end gone): the line is cosmetic, and the run it shows goes on, its results kept."""

    def __init__(self, kind: str | None):
        self.kind, self.handle, self.drawn = kind, None, False

    def show(self, text: str, tail: str = "") -> None:
        try:
            if self.kind == "terminal":
                print(status_line(text, tail), end="", file=sys.stderr, flush=True)
            elif self.kind == "notebook":
                from IPython.display import display

                bundle = {"text/plain": text + tail}
                if self.handle is None:
                    self.handle = display(bundle, raw=True, display_id=True)
                else:
                    self.handle.update(bundle, raw=True)
        except Exception:  # noqa: BLE001  (whatever the stream or the front end raised: the run goes on)
            self.kind, self.handle = None, None
        self.drawn = self.kind is not None

    def close(self) -> None:
        try:
            if self.kind == "terminal" and self.drawn:
                print("\r\x1b[K", end="", file=sys.stderr, flush=True)
            elif self.handle is not None:
                self.handle.update({"text/plain": ""}, raw=True)
        except Exception:  # noqa: BLE001  (as in show: the run's result is not lost for its status line)
            pass
        self.drawn = False


@contextlib.contextmanager
def live_progress(progress, draw):
    """The callback a ``progress`` argument asks for, while the block runs: ``True``, a :class:`StatusLine`
    showing ``draw(d) -> (text, tail)`` of each report ``d``, closed when the block ends however it ends (None
    where :func:`where` finds no terminal or notebook, so that nothing is computed for it); ``False`` or None,
    None; a callable, itself.  On a terminal a warning said meanwhile (a ProjectionWarning) clears the line
    first, so it starts on a clean row and the next report draws the line below it; it was written onto the
    line's row, after the line's text."""
    if progress is not True:
        yield progress or None
        return
    kind = where()
    line = StatusLine(kind)
    if kind == "terminal":
        _clearing_warnings(line, True)
    try:
        yield (lambda d: line.show(*draw(d))) if kind else None
    finally:
        if kind == "terminal":
            _clearing_warnings(line, False)
        line.close()


#: the terminal lines drawn now, the ``warnings.showwarning`` found when the first of them began, and a lock for both
_LINES: list = []
_SHOWN: list = [None]
_LOCK = threading.Lock()


def _show_warning(*args, **kw):
    """``warnings.showwarning`` while terminal lines are drawn: clear them, then show the warning as before."""
    for line in list(_LINES):
        line.close()
    _SHOWN[0](*args, **kw)


def _clearing_warnings(line: StatusLine, on: bool) -> None:
    """Register (``on``) or drop a terminal line that a warning clears first: the first sets
    ``warnings.showwarning`` (:func:`_show_warning`), the last puts back the one it found, unless another was set
    meanwhile (``logging.captureWarnings``).  Lines that nest or overlap in any order (threads) leave it as found; a
    patch per block left its own behind where blocks ended out of order (an audit).  It never saves itself as the
    one found (a ``catch_warnings`` that put it back after its lines ended: each warning then recursed)."""
    with _LOCK:
        if on:
            if not _LINES:
                if warnings.showwarning is not _show_warning:
                    _SHOWN[0] = warnings.showwarning
                warnings.showwarning = _show_warning
            _LINES.append(line)
            return
        if line in _LINES:
            _LINES.remove(line)
        if not _LINES and warnings.showwarning is _show_warning:
            warnings.showwarning = _SHOWN[0]
