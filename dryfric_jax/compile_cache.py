r"""Compiled code kept on disk between ``dryfric`` commands (JAX's persistent compilation cache).

Every ``dryfric`` process compiles the lane engine anew.  JAX can keep the executables XLA compiled
on disk and load them in the next process instead of compiling again.  An executable is looked up
by a hash of its program, the jaxlib version, the backend, the XLA flags and the compile options,
so a process loads only code compiled from exactly the same program, and loaded code is the code
a fresh compilation gives: the numbers are the same to the last bit (tested).  A default
``dryfric estimate`` (2 CPU cores, 2026-12-03, 4 interleaved runs each) took 9.6-10.2 s without
the cache (~2.3 s of it importing JAX and the package, its run 6.3-6.5 s) and 6.5-7.6 s with it
warm (its run 3.2-3.8 s); an hour later, the machine slower, 11.1-12.7 s and 7.3-9.7 s.  The first
run, which writes the cache, took 0.4-1.3 s more.  It writes 3-5 entries, ~350 kB.

The ``dryfric`` command turns the cache on (:func:`enable`) in

    ``$DRYFRIC_CACHE_DIR``, or ``$XDG_CACHE_HOME/dryfric_jax/xla`` (``~/.cache/dryfric_jax/xla``),

in a subdirectory per jaxlib version and host CPU (:func:`host_tag`), whatever JAX's key holds:
code compiled for one CPU (with AVX-512, say) must never reach another (without it), as it could
on a cluster whose nodes share a home directory.  ``DRYFRIC_CACHE_DIR=off`` (or ``0``, ``no``,
``false``, ``none``, empty) turns it off; a cache directory the user gave JAX
(``JAX_COMPILATION_CACHE_DIR``) is used as it is.  If the directory cannot be made or takes no
file, or no home directory can be found, the command runs without a cache; entries a full disk left
empty are removed when it is turned on (JAX never rewrites an entry).  Python code (a notebook) keeps its
compiled code for the life of the
process anyway; :func:`enable` (``dryfric_jax.enable_compilation_cache()``), called before the
first computation, gives it the disk cache too.
"""
from __future__ import annotations

import contextlib
import hashlib
import os
import platform

#: compilations shorter than this are not written (JAX's default is 1 s): at 0.1 s the default
#: ``dryfric estimate`` writes 3-5 entries (its rounds, key splits and whatever else took longer than
#: 0.1 s to compile that time), at 0 s 43 entries (0.5 MB), with no difference in its time beyond the
#: run-to-run spread
MIN_COMPILE_TIME_S = 0.1

_OFF = {"", "0", "off", "no", "false", "none"}


def _cpu_features() -> str:
    """The host CPU's model and instruction-set flags (Linux's /proc/cpuinfo; elsewhere what
    :mod:`platform` knows)."""
    keep = ("model name", "flags", "features", "cpu implementer", "cpu part", "isa")
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as f:
            lines = []
            for ln in f:  # the first processor's block (a many-core machine lists hundreds)
                if not ln.strip():
                    break
                lines.append(ln.rstrip("\n"))
    except OSError:
        return platform.processor()
    return "\n".join(sorted(ln for ln in lines if ln.split(":")[0].strip().lower() in keep))


def host_tag() -> str:
    """``jaxlib-<version>-<machine>-<hash of the CPU's model and flags>``: one cache per jaxlib
    and host CPU type (module docstring)."""
    import jaxlib

    digest = hashlib.sha256(_cpu_features().encode()).hexdigest()[:12]
    return f"jaxlib-{jaxlib.__version__}-{platform.machine() or 'unknown'}-{digest}"


def cache_root(environ=None) -> str | None:
    """Where the cache lives (without :func:`host_tag`), or None where ``DRYFRIC_CACHE_DIR`` turns
    it off or there is no home directory (module docstring)."""
    env = os.environ if environ is None else environ
    given = env.get("DRYFRIC_CACHE_DIR")
    if given is not None:
        return None if given.strip().lower() in _OFF else os.path.expanduser(given)
    base = env.get("XDG_CACHE_HOME", "")
    if not os.path.isabs(base):  # unset, empty or relative: the XDG spec says to ignore it
        base = os.path.join(os.path.expanduser("~"), ".cache")
    # no home directory to be found (expanduser leaves "~"): no cache rather than one in the working directory
    return os.path.join(base, "dryfric_jax", "xla") if os.path.isabs(base) else None


def _drop_empty_entries(path: str) -> None:
    """Remove the empty entries of the cache in ``path``: JAX writes an entry in place and never rewrites one that
    exists, so a write a full disk (or a kill) left empty made every later run compile anew, without a word (an
    audit: 6.1-6.6 s a run against 1.8-2.1 s).  An entry being written by another process at this moment costs it
    one compilation at most."""
    with contextlib.suppress(OSError):
        for e in os.scandir(path):
            with contextlib.suppress(OSError):
                if e.name.endswith("-cache") and e.is_file(follow_symlinks=False) and e.stat().st_size == 0:
                    os.unlink(e.path)


def enable(root: str | None = None) -> str | None:
    """Turn on JAX's persistent compilation cache in ``root`` (default :func:`cache_root`) /
    :func:`host_tag`, before this process compiles anything.  Returns the directory JAX's cache
    uses: this one, or one set before (the user's own ``JAX_COMPILATION_CACHE_DIR``, or an earlier
    call's), which is left as it is; None where there is none (turned off, no home directory, or a
    directory that cannot be made or takes no file).  Never raises for the directory: a run without a cache is still a run."""
    import jax

    if jax.config.jax_compilation_cache_dir:  # the user's own (JAX_COMPILATION_CACHE_DIR), or ours
        return jax.config.jax_compilation_cache_dir
    root = cache_root() if root is None else root
    if root is None:
        return None
    from .outfiles import _can_create_in  # a real file made and removed: os.access is wrong on a read-only mount

    path = os.path.join(root, host_tag())
    try:
        os.makedirs(path, exist_ok=True)
    except OSError:  # a file in the way, a read-only home, no permission
        return None
    if not _can_create_in(path):
        return None
    _drop_empty_entries(path)
    jax.config.update("jax_compilation_cache_dir", path)
    jax.config.update("jax_persistent_cache_min_compile_time_secs", MIN_COMPILE_TIME_S)
    return path
