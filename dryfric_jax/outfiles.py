"""Output files: checked writable before any work, written atomically (never a torn file), in strict
JSON (:func:`dumps`, :func:`loads`)."""
from __future__ import annotations

import contextlib
import hashlib
import json
import math
import os
import stat
import tempfile
import time

try:
    import fcntl
except ImportError:  # not POSIX (Windows): no lock
    fcntl = None

import numpy as np

from .interrupts import held_interrupts

from .params import shown


_NONFINITE = {"inf": math.inf, "-inf": -math.inf, "nan": math.nan}


def _to_strict(x):
    """Plain JSON values: numpy arrays and scalars as Python ones, non-finite floats as strings."""
    if isinstance(x, np.ndarray):
        return _to_strict(x.tolist())
    if isinstance(x, (np.floating, np.integer, np.bool_)):
        x = x.item()
    if isinstance(x, float) and not math.isfinite(x):
        return "nan" if math.isnan(x) else ("inf" if x > 0 else "-inf")
    if isinstance(x, dict):
        return {k: _to_strict(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_to_strict(v) for v in x]
    return x


def from_strict(x):
    """What :func:`dumps` wrote, already parsed (``json.load``): the strings ``"inf"``, ``"-inf"``,
    ``"nan"`` as floats again, in nested dicts and lists."""
    if isinstance(x, str):
        return _NONFINITE.get(x, x)
    if isinstance(x, dict):
        return {k: from_strict(v) for k, v in x.items()}
    if isinstance(x, list):
        return [from_strict(v) for v in x]
    return x


def dumps(obj, **kw) -> str:
    """``json.dumps`` as strict JSON (numpy values included): a non-finite float (tau_L = inf, a D
    with no CI) is written as
    the string ``"inf"``, ``"-inf"`` or ``"nan"``; Python's ``Infinity`` / ``NaN`` are refused by
    jq, JavaScript and other strict readers.  :func:`loads` reads them back as floats."""
    return json.dumps(_to_strict(obj), allow_nan=False, **kw)


def loads(text: str):
    """``json.loads`` of :func:`dumps` output (and of older files with ``Infinity``): the strings
    ``"inf"``, ``"-inf"``, ``"nan"`` become floats again."""
    return from_strict(json.loads(text))


def _can_create_in(d: str) -> bool:
    """Whether a file can really be created in the directory ``d`` (a temporary one is made and
    removed): ``os.access`` says yes for /proc, a read-only mount or a full quota."""
    try:
        fd, tmp = tempfile.mkstemp(dir=d, prefix=".dryfric-", suffix=".tmp")
    except OSError:
        return False
    os.close(fd)
    os.unlink(tmp)
    return True


def _path_text(path) -> str | None:
    """``path`` as text, or None for anything that is not a non-empty path."""
    if not isinstance(path, (str, os.PathLike)):
        return None
    path = os.fspath(path)
    return path if isinstance(path, str) and path.strip() else None


def _can_create(p: str) -> str | None:
    """Why a new file ``p`` cannot be created under its own name (None if it can: it is made and
    removed).  The name's length and characters are the file system's to judge (a name over 255
    bytes, a trailing '/', passed the check of the directory and failed after the run)."""
    try:
        fd = os.open(p, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    except OSError as e:
        return e.strerror
    try:  # removed only while it is still the probe: another process (a sweep on the same new file) may have
        mine = os.fstat(fd).st_ino  # renamed its first record over it since (an audit's harness saw it deleted)
        if os.stat(p).st_ino == mine:
            os.unlink(p)
    except OSError:
        pass
    finally:
        os.close(fd)
    return None


def _mode(p: str) -> int:
    """``p``'s mode bits, or all write bits if it went away since it was seen (another process's)."""
    try:
        return os.stat(p).st_mode
    except FileNotFoundError:
        return 0o222


def check_writable(path: str, name: str = "out") -> None:
    """Raise ``ValueError`` naming ``name`` unless ``path`` can be created or replaced as a regular
    file (a file is created and removed in its directory, and a new ``path`` itself, to be sure).
    An existing path that is not a regular file (a directory, a device such as /dev/null, a pipe) is
    refused: :func:`write_atomic` renames a new file over ``path``, which would replace it."""
    p = _path_text(path)
    ok, why = p is not None and "\0" not in p and not p.endswith(("/", os.sep)), None
    if ok:
        d = os.path.dirname(os.path.realpath(p))
        ok = (not os.path.lexists(p) or os.path.isfile(p)) and os.path.isdir(d) and _can_create_in(d)
        if ok and os.path.isfile(p) and not _mode(p) & 0o222:
            ok, why = False, "the file is read-only"
        if ok and not os.path.lexists(p):
            why = _can_create(p)
            ok = why is None
    if not ok:
        raise ValueError(f"{name} must be a writable file path in an existing directory, not a directory or a "
                         f"device (got {shown(path, 80, 40)}" + (f": {why})" if why else ")"))


def check_writable_dir(path: str, name: str = "out") -> None:
    """Raise ``ValueError`` naming ``name`` unless ``path`` is a writable directory or can be
    created as one (its parent exists and is writable)."""
    p = _path_text(path)
    ok = p is not None
    if ok and os.path.isdir(p):
        ok = _can_create_in(p)
    elif ok:
        parent = os.path.dirname(os.path.abspath(p))
        ok = not os.path.lexists(p) and os.path.isdir(parent) and _can_create_in(parent)
    if not ok:
        raise ValueError(f"{name} must be a writable directory, or a new one in an existing directory (got {path!r})")


def _tmp_prefix(path: str) -> str:
    """The name :func:`write_atomic`'s temporary files for ``path`` begin with: ``.<name>.dryfric-``, so that those
    a kill left behind can be told apart by the file they were for (:func:`_drop_stale_tmp`)."""
    return f".{os.path.basename(path)}.dryfric-"


#: a temporary file of :func:`write_atomic` this old (s) is a killed write's: a live write takes seconds
STALE_TMP_S = 600.0


def _drop_stale_tmp(path: str) -> None:
    """Remove the temporary files of ``path`` that a killed write left (a SIGKILL between :func:`write_atomic`'s
    creating and renaming one; each a whole copy of the results, 10 MB in an audit, one more per kill), and those
    of the older unnamed kind (``.dryfric-*.tmp``, before 2026-12-07), older than :data:`STALE_TMP_S`.  Called only
    under a held :func:`locked` of ``path``: every writer of a results file holds that lock; the age also spares a
    writer on another host where the lock is per host (NFS with ``local_lock``: a review)."""
    real = os.path.realpath(path)
    d, prefix = os.path.dirname(real), _tmp_prefix(real)
    try:
        names = os.listdir(d)
    except OSError:
        return
    now = time.time()
    for name in names:
        if (name.startswith(prefix) or name.startswith(".dryfric-")) and name.endswith(".tmp"):
            f = os.path.join(d, name)
            with contextlib.suppress(OSError):
                if now - os.stat(f).st_mtime > STALE_TMP_S:
                    os.unlink(f)


def write_atomic(path: str, text: str | bytes) -> None:
    """Write ``text`` (or bytes: a figure's PNG or PDF) to a temporary file in the same directory, fsync,
    then rename over ``path``: a reader (or a kill at any moment) sees the old file or the new one, never a part."""
    path = os.path.realpath(path)  # a symlinked file is replaced where it lies; the link stays
    d = os.path.dirname(path)
    fd, tmp = tempfile.mkstemp(dir=d, prefix=_tmp_prefix(path), suffix=".tmp")
    try:
        with os.fdopen(fd, "wb" if isinstance(text, bytes) else "w") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        try:  # a replaced file keeps its mode
            mode = stat.S_IMODE(os.stat(path).st_mode)
        except FileNotFoundError:
            umask = os.umask(0)
            os.umask(umask)
            mode = 0o666 & ~umask  # mkstemp makes it private; a new output file is not
        os.chmod(tmp, mode)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def read_records(path: str, keys: tuple, refusal: str, check=None) -> list[dict]:
    """The records of a JSON Lines results file (empty if it does not exist), each a JSON object
    with ``keys`` (and passing ``check(record)``, which raises on a malformed one); any other
    line, or a file that is not UTF-8 text, raises ``ValueError(refusal.format(path=path,
    line=i))``, so a foreign file is refused rather than overwritten or half-read."""
    if not os.path.lexists(path):
        return []
    if not os.path.isfile(path):
        raise ValueError(refusal.format(path=path, line=0).split(";")[0] + f" (got {path!r}, not a file)")
    out, i = [], 0
    try:
        with open(path, encoding="utf-8-sig") as f:  # -sig: a file saved with a byte-order mark
            for i, line in enumerate(f, 1):
                if not line.strip():
                    continue
                rec = loads(line)
                for k in keys:
                    rec[k]
                if check is not None:
                    check(rec)
                out.append(rec)
    except (ValueError, KeyError, TypeError, AttributeError):  # UnicodeDecodeError is a ValueError
        raise ValueError(refusal.format(path=path, line=i + (i == 0))) from None
    return out


@contextlib.contextmanager
def locked(path: str):
    """Hold an exclusive lock on ``path``'s directory (``flock``) while a results file is read and
    rewritten, so two processes updating one file take turns instead of writing over each
    other's records.  No lock where ``fcntl`` is missing (Windows) or the directory cannot be
    opened or locked (some network file systems)."""
    fd = None
    if fcntl is not None:
        try:
            fd = os.open(os.path.dirname(os.path.realpath(path)), os.O_RDONLY)
            fcntl.flock(fd, fcntl.LOCK_EX)
        except OSError:
            if fd is not None:
                os.close(fd)
            fd = None
    if fd is not None:  # held: no other writer of this file is at work
        _drop_stale_tmp(path)
    try:
        yield
    finally:
        if fd is not None:
            os.close(fd)  # releases the lock


def claims_dir(path: str) -> str:
    """The hidden directory of :func:`claim`'s files beside the results file ``path``."""
    d, base = os.path.split(os.path.realpath(path))
    return os.path.join(d, f".{base}.claims")


class Claim:
    """What :func:`claim` yields: ``held`` (this process may compute the point) and :meth:`finish`."""

    def __init__(self, held: bool):
        self.held, self.finished = held, False

    def finish(self) -> None:
        """The point's record is written: its claim file is removed when the claim is released."""
        self.finished = True


def _claim_fd(name: str):
    """An open descriptor of the claim file ``name`` (its directory made), or None if it cannot be
    made (read-only or foreign directory: the point is then computed unclaimed)."""
    for _ in range(3):  # another process may remove the empty directory between the two calls
        try:
            os.makedirs(os.path.dirname(name), exist_ok=True)
            return os.open(name, os.O_RDWR | os.O_CREAT, 0o600)
        except FileNotFoundError:
            continue
        except OSError:
            return None
    return None


@contextlib.contextmanager
def claim(path: str, key: str, wait: bool = False):
    """Claim the point ``key`` of the results file ``path`` against other processes while it is
    computed, so that two sweeps sharing a file share the work of the points in both grids.

    The claim is an exclusive ``flock`` on a small file in :func:`claims_dir` (named by a hash of
    ``key``); the kernel releases it when the process ends, also when it is killed.  Yields a
    :class:`Claim`: ``held`` is False when another process holds the point and ``wait`` is False
    (with ``wait`` it blocks until the other releases it).  The holder must read the results file
    again before computing (the other may have finished the point meanwhile), and call
    ``finish()`` once the record is written: the claim file is then removed (and the directory,
    if empty).  An interrupted
    holder leaves the (empty) file, which the next claimant reuses.  Without ``fcntl`` (Windows)
    or a directory where the file can be made, every claim is held (no exclusion, as before)."""
    name = os.path.join(claims_dir(path), hashlib.sha256(key.encode()).hexdigest()[:32])
    fd = None if fcntl is None else _claim_fd(name)
    if fd is None:
        yield Claim(True)
        return
    try:
        c = Claim(True)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | (0 if wait else fcntl.LOCK_NB))
        except BlockingIOError:  # another process holds it
            c.held = False
        except OSError:  # no flock on this file system: unclaimed
            pass
        yield c
        if c.held and c.finished:  # removed while held: a process that opened it meanwhile re-reads the results
            with contextlib.suppress(OSError):
                os.unlink(name)
            drop_claims_dir(path)  # when no other point is claimed (_claim_fd makes it again if needed)
    finally:
        os.close(fd)


def drop_claims_dir(path: str) -> None:
    """Remove :func:`claims_dir` if it is empty (no point is being computed)."""
    with contextlib.suppress(OSError):
        os.rmdir(claims_dir(path))


def put_record(path: str, rec: dict, same, read, done=None) -> None:
    """Write one finished record to a JSON Lines results file that other processes may update too:
    under :func:`locked`, the file is read again (``read(path)``), so the records they wrote
    meanwhile are kept; ``rec`` replaces the first record ``same(old)`` holds for, or is appended;
    the file is rewritten atomically (:func:`write_records`).  A Ctrl-C or SIGTERM breaks the wait for the lock
    as usual, but once the lock is held it acts only after the write and ``done()`` (the caller's bookkeeping
    of it, if given; :func:`~dryfric_jax.interrupts.held_interrupts`): a sweep's finished point caught by one
    during its write was lost (an audit), and a hold over the wait made a process waiting on a stuck lock
    deaf to Ctrl-C (the review after it)."""
    with locked(path), held_interrupts():
        records = read(path)
        at = next((k for k, old in enumerate(records) if same(old)), None)
        if at is None:
            records.append(rec)
        else:
            records[at] = rec
        write_records(path, records)
        if done is not None:
            done()


def write_records(path: str, records: list[dict]) -> None:
    """Rewrite a JSON Lines results file with ``records``, atomically (:func:`write_atomic`)."""
    write_atomic(path, "".join(dumps(rec) + "\n" for rec in records))
