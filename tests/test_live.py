"""``progress=True``: a live status line (``dryfric_jax.live``): one display updated in place in a Jupyter kernel, a
self-overwriting line on a terminal's stderr, nothing elsewhere; it never changes the numbers.  The notebook is a
stand-in ``IPython`` module whose shell has a kernel (the package does not depend on IPython)."""
import sys
import types
import warnings

import pytest

import dryfric_jax as dj
from dryfric_jax import durations, live, sweep
from dryfric_jax.params import FIG3

FAST = dj.Params(10.0, 3.84, 0.125, 0.067, 0.342)  # Fig. 3's fastest point


class _Handle:
    def __init__(self, log):
        self.log = log

    def update(self, obj, **kw):
        self.log.append(("update", obj, kw))


def _ipython(monkeypatch, kernel):
    """A stand-in IPython whose shell has ``kernel``; returns the log of its displays and updates."""
    log = []
    ipython, display = types.ModuleType("IPython"), types.ModuleType("IPython.display")
    shell = types.SimpleNamespace(kernel=kernel)
    ipython.get_ipython = lambda: shell

    def show(obj, **kw):
        log.append(("display", obj, kw))
        return _Handle(log)

    display.display, ipython.display = show, display
    monkeypatch.setitem(sys.modules, "IPython", ipython)
    monkeypatch.setitem(sys.modules, "IPython.display", display)
    return log


@pytest.fixture
def notebook(monkeypatch):
    return _ipython(monkeypatch, kernel=object())


def _texts(log):
    """The texts shown, checking that the first is a new display with an id, every later one updates it, and the
    last clears it (the run's end)."""
    assert log and log[0][0] == "display" and log[0][2] == dict(raw=True, display_id=True)
    assert all(kind == "update" and kw == dict(raw=True) for kind, _, kw in log[1:])
    assert all(set(obj) == {"text/plain"} for _, obj, _ in log)
    texts = [obj["text/plain"] for _, obj, _ in log]
    assert texts[-1] == "" and "" not in texts[:-1]
    return texts[:-1]


def test_where_the_line_goes(monkeypatch):
    """A kernel: the notebook, even where its stderr says it is a terminal; an IPython without a kernel (the
    terminal IPython) or none: the terminal where stderr is one, else nowhere (also for a closed stderr)."""
    monkeypatch.delitem(sys.modules, "IPython", raising=False)
    monkeypatch.setattr(sys, "stderr", types.SimpleNamespace(isatty=lambda: False))
    assert live.where() is None
    monkeypatch.setattr(sys, "stderr", types.SimpleNamespace(isatty=lambda: True))
    assert live.where() == "terminal"
    _ipython(monkeypatch, kernel=object())
    assert live.where() == "notebook"
    _ipython(monkeypatch, kernel=None)
    assert live.where() == "terminal"

    def closed():
        raise ValueError("I/O operation on closed file")

    monkeypatch.setattr(sys, "stderr", types.SimpleNamespace(isatty=closed))
    assert live.where() is None


def test_an_estimate_in_a_notebook_updates_one_display(notebook, capsys):
    """A display per round, the first new and the others updating it, each the round's D so far and N of the
    target with its time; the last the result's N, then cleared; the numbers those of a run with a callback (and of
    none), and nothing on stderr."""
    kw = dict(n_excursions=300, lanes=16)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", dj.SmallSampleWarning)
        seen = []
        quiet = dj.estimate_diffusivity(dj.Params(**FIG3), 3, progress=seen.append, **kw)
        r = dj.estimate_diffusivity(dj.Params(**FIG3), 3, progress=True, **kw)
    assert (r.D, r.D_ci, r.M0, r.n_excursions) == (quiet.D, quiet.D_ci, quiet.M0, quiet.n_excursions)
    texts = _texts(notebook)
    assert len(texts) == len(seen) >= 2
    assert all(t.startswith("D=") and (" of 300" in t or " (300 asked)" in t) and t.endswith("]") for t in texts)
    assert [t.split(" N=")[1].split(" ")[0] for t in texts] == [str(d["n_excursions"]) for d in seen]
    assert r.n_excursions > 300 and f"N={r.n_excursions} (300 asked)" in texts[-1]  # not "302 of 300"
    assert capsys.readouterr().err == ""


def test_a_count_in_a_notebook_updates_one_display(notebook, capsys):
    """The long-excursion count's line: counted so far of those asked, then those in flight, and done."""
    kw = dict(n_excursions=100, n_lanes=16)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", dj.SmallSampleWarning)
        quiet = dj.di_long_excursion_duration(FAST, 5, **kw)
        r = dj.di_long_excursion_duration(FAST, 5, progress=True, **kw)
    assert (r.mean, r.ci, r.n_excursions) == (quiet.mean, quiet.ci, quiet.n_excursions)
    texts = _texts(notebook)
    assert all(t.startswith("LE=") and (" of 100" in t or " (100 asked)" in t) for t in texts)
    assert r.n_excursions > 100 and texts[-1].startswith(f"LE={r.mean:.4g}s so far, {r.n_excursions} (100 asked), "
                                                         "done [")
    assert capsys.readouterr().err == ""


def test_on_a_terminal_the_line_is_redrawn_then_cleared(monkeypatch, capsys):
    """On a terminal: a carriage return, the line and a clear-to-end per report, and the line cleared at the end so
    that the result prints on a clean row; the same where the run ends in an error."""
    monkeypatch.delitem(sys.modules, "IPython", raising=False)
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True)
    monkeypatch.setattr(durations, "PIECE_S", 1e-9)  # one block per piece: the same pieces in both runs
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", dj.SmallSampleWarning)
        seen = []
        dj.di_long_excursion_duration(FAST, 5, n_excursions=100, n_lanes=16, progress=seen.append)
        dj.di_long_excursion_duration(FAST, 5, n_excursions=100, n_lanes=16, progress=True)
    err = capsys.readouterr().err
    draws = err.split("\r")[1:]
    assert len(draws) == len(seen) + 1 and draws[-1] == "\x1b[K"
    assert all(d.startswith("LE=") and d.endswith("]\x1b[K") for d in draws[:-1])
    with pytest.raises(RuntimeError, match="boom"):
        with live.live_progress(True, lambda d: (d, "")) as show:
            show("half")
            raise RuntimeError("boom")
    assert capsys.readouterr().err == "\rhalf\x1b[K\r\x1b[K"
    with live.live_progress(True, lambda d: (d, "")):  # nothing drawn: nothing cleared
        pass
    assert capsys.readouterr().err == ""


def test_on_a_terminal_a_warning_starts_on_a_clean_row(monkeypatch, capsys):
    """A warning said while the line is drawn (a ProjectionWarning) clears the line first, and the next report
    draws the line after it; it was written onto the line's row.  Where no line is drawn nothing is cleared, and
    the warnings' own showwarning is back after the block."""
    monkeypatch.delitem(sys.modules, "IPython", raising=False)
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True)
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        own = warnings.showwarning = lambda m, c, *a, **k: print(f"{c.__name__}: {m}", file=sys.stderr)
        with live.live_progress(True, lambda d: (d, "")) as show:
            warnings.warn("early", dj.ProjectionWarning)
            show("half")
            warnings.warn("careful", dj.ProjectionWarning)
            show("again")
        assert warnings.showwarning is own
    assert capsys.readouterr().err == ("ProjectionWarning: early\n\rhalf\x1b[K\r\x1b[KProjectionWarning: careful\n"
                                       "\ragain\x1b[K\r\x1b[K")
    with warnings.catch_warnings():  # blocks that end out of order (threads) leave showwarning as found (an audit)
        own = warnings.showwarning = lambda *a, **k: None
        one, two = live.live_progress(True, lambda d: (d, "")), live.live_progress(True, lambda d: (d, ""))
        one.__enter__()
        two.__enter__()
        one.__exit__(None, None, None)
        assert warnings.showwarning is not own  # a line is still drawn
        two.__exit__(None, None, None)
        assert warnings.showwarning is own
        with live.live_progress(True, lambda d: (d, "")) as show:  # a catch_warnings that outlives the line puts
            inner = warnings.catch_warnings()  # the line's showwarning back: a later line must not recurse
            inner.__enter__()
        inner.__exit__(None, None, None)
        with live.live_progress(True, lambda d: (d, "")) as show:
            show("x")
            warnings.warn("after", dj.ProjectionWarning)  # was a RecursionError (an audit)
        assert warnings.showwarning is own


def test_elsewhere_nothing_is_shown_or_computed(monkeypatch, capsys):
    """stderr a file or a pipe and no kernel: no callback at all (the estimator then computes no snapshot for it),
    and False is None; a callable is passed as it is."""
    monkeypatch.delitem(sys.modules, "IPython", raising=False)
    monkeypatch.setattr(sys.stderr, "isatty", lambda: False)
    for off in (True, False, None):
        with live.live_progress(off, lambda d: (d, "")) as cb:
            assert cb is None
    with live.live_progress(print, lambda d: (d, "")) as cb:
        assert cb is print
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", dj.SmallSampleWarning)
        dj.di_long_excursion_duration(FAST, 5, n_excursions=50, n_lanes=16, progress=True)
    assert capsys.readouterr().err == ""


def test_a_sweep_in_a_notebook(notebook, tmp_path, capsys):
    """``progress=True``: a line per point on stderr (not a terminal); ``point_progress=True``: the point's line in one
    display, its D then its count, with the bar and the point's parameters."""
    out = str(tmp_path / "s.jsonl")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", dj.SmallSampleWarning)
        summary = sweep.run_sweep(sweep.grid(Gamma=[10.0], tau=[0.125, 0.25]), out, n_excursions=200, durations=20,
                                  progress=True, point_progress=True)
    assert summary["computed"] == 2
    texts = _texts(notebook)
    assert all(t.startswith("[") and "Gamma=10 tau=0." in t for t in texts)
    assert any("tau=0.125: D=" in t for t in texts) and any("tau=0.25: LE=" in t for t in texts)
    assert "1/2 points" in texts[-1]
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 2 and err[0].startswith("[" + "#" * 15 + "." * 15 + "] 1/2 points  Gamma=10 tau=0.125: D=")
    assert err[1].startswith("[" + "#" * 30 + "] 2/2 points  Gamma=10 tau=0.25: D=") and " LE=" in err[1]


def test_a_line_that_cannot_be_drawn_does_not_cost_the_run(monkeypatch):
    """A terminal that went away (stderr's writes fail) or a front end whose display fails: the line stops, the run
    goes on and returns its numbers (mutant: the error goes on up and the run is lost)."""
    monkeypatch.delitem(sys.modules, "IPython", raising=False)

    class Gone:
        def isatty(self):
            return True

        def write(self, text):
            raise OSError(5, "Input/output error")

        def flush(self):
            pass

    monkeypatch.setattr(sys, "stderr", Gone())
    kw = dict(n_excursions=100, n_lanes=16)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", dj.SmallSampleWarning)
        quiet = dj.di_long_excursion_duration(FAST, 5, **kw)
        assert dj.di_long_excursion_duration(FAST, 5, progress=True, **kw).mean == quiet.mean
        log = _ipython(monkeypatch, kernel=object())

        def broken(obj, **kw):
            log.append(obj)
            raise RuntimeError("no front end")

        monkeypatch.setattr(sys.modules["IPython.display"], "display", broken)
        assert dj.di_long_excursion_duration(FAST, 5, progress=True, **kw).mean == quiet.mean
    assert len(log) == 1  # tried once, then no more
