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
"""
from __future__ import annotations

import _thread
import sys
import threading

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
