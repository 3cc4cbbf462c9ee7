"""Output files: checked writable before any work, written atomically (never a torn file), in strict
JSON (:func:`dumps`, :func:`loads`).  A results file (JSON Lines) grows by one appended line a record
(:func:`put_record`); a line whose write a kill cut short is skipped by readers and removed by the next writer
(where a record precedes it)."""
from __future__ import annotations

import contextlib
import errno
import functools
import hashlib
import json
import math
import os
import stat
import tempfile
import threading
import time
import warnings

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
    with locked(p):  # every writer of a results file holds it: none appends to the probe before it is removed
        try:
            fd = os.open(p, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        except OSError as e:
            return e.strerror
        try:  # removed only while it is still the empty probe: another process (a sweep on the same new file) may
            # have renamed its first record over it since (an audit's harness saw it deleted), or appended it (a review:
            # where there is no lock); closed first (Windows refuses to remove an open file: the probe was left, an
            # empty private file that combine then refused)
            try:
                mine = os.fstat(fd).st_ino
            finally:
                os.close(fd)
            st = os.stat(p)
            if st.st_ino == mine and st.st_size == 0:
                os.unlink(p)
        except OSError:
            pass
    return None


def _mode(p: str) -> int:
    """``p``'s mode bits, or all write bits if it went away since it was seen (another process's)."""
    try:
        return os.stat(p).st_mode
    except FileNotFoundError:
        return 0o222


def _read_only_mount(p: str) -> bool:
    """Whether ``p`` lies on a read-only mount (Docker's ``-v out.json:/work/out.json:ro``: its mode has write bits,
    it passed the check and failed after the run: a review).  Not the file's own permission: a file is replaced by
    renaming a new one over it, which the directory's permits."""
    try:
        return bool(os.statvfs(p).f_flag & os.ST_RDONLY)
    except (OSError, AttributeError):  # gone since, or no statvfs (Windows)
        return False


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
        if ok and os.path.isfile(p) and (not _mode(p) & 0o222 or _read_only_mount(p)):
            ok, why = False, "the file is read-only"  # its mode, or a read-only mount of it (a review)
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


#: bytes of a file's name that its temporary files' names keep (:func:`_tmp_prefix`)
TMP_NAME_KEEP = 200


def _tmp_prefix(path: str) -> str:
    """The name :func:`write_atomic`'s temporary files for ``path`` begin with: ``.<name>.dryfric-``, so that those
    a kill left behind can be told apart by the file they were for (:func:`_drop_stale_tmp`).  The name is cut to
    :data:`TMP_NAME_KEEP` bytes, so that the 22 bytes the temporary name adds keep it under the file system's 255:
    a results file named with 234-255 bytes passed the check and failed at its first rewrite (after the run, or
    at every start of a sweep: an audit)."""
    return f".{_kept_name(path)}.dryfric-"


def _kept_name(path: str) -> str:
    """``path``'s file name cut to :data:`TMP_NAME_KEEP` bytes (the names made from it stay under 255)."""
    name = os.path.basename(path)
    while len(os.fsencode(name)) > TMP_NAME_KEEP:
        name = name[:-1]
    return name


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


def _write_in_place(path: str, tmp: str) -> None:
    """Overwrite the file ``path`` where it lies (fsync'd) with the bytes of the temporary file ``tmp``, then remove
    ``tmp``: for a file no other can be renamed over.  Nothing is written where they are the same (a sweep's start
    rewrites its file unchanged).  A write that fails part way (a full disk: the temporary copy holds space too)
    keeps the whole new text as ``tmp`` renamed to end in ``.new`` (which no stale-file cleanup removes) and says
    where it is (a review: it was removed, and the file left torn); unbuffered, so that no close flushes again."""
    try:
        with open(tmp, "rb") as f:
            data = f.read()
        f = open(path, "r+b", buffering=0)
        try:
            same = f.readall() == data
        except BaseException:
            f.close()
            raise
    except BaseException:  # nothing written
        os.unlink(tmp)
        raise
    with f:
        if not same:
            try:
                f.seek(0)
                left = memoryview(data)
                while left:
                    left = left[f.write(left):]
                f.truncate()
                os.fsync(f.fileno())
            except BaseException as e:
                kept = tmp[: -len(".tmp")] + ".new"
                with contextlib.suppress(OSError):
                    os.replace(tmp, kept)
                if isinstance(e, OSError):
                    raise OSError(e.errno, f"{e.strerror}: {path!r} could not be overwritten in place, and may be "
                                           f"torn; its whole new text is in {kept!r}") from None
                raise
    os.unlink(tmp)


def write_atomic(path: str, text: str | bytes) -> None:
    """Write ``text`` (or bytes: a figure's PNG or PDF) to a temporary file in the same directory, fsync,
    then rename over ``path``: a reader (or a kill at any moment) sees the old file or the new one, never a part.
    A file that is a mount point (Docker's ``-v results.jsonl:/work/results.jsonl``) cannot be renamed over
    (EBUSY; a sweep on one failed at every start, an estimate after its run: an audit): it is overwritten in
    place instead (:func:`_write_in_place`), which a kill during the write can leave torn."""
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
        try:
            os.replace(tmp, path)
        except OSError as e:
            if e.errno != errno.EBUSY or not os.path.isfile(path):
                raise
            tmp, whole = None, tmp  # from here the temporary file is kept unless written over the file
            _write_in_place(path, whole)
    except BaseException:
        if tmp is not None and os.path.exists(tmp):
            os.unlink(tmp)
        raise


class ReadCache:
    """What :func:`read_records` parsed of one file before: its bytes through the last complete line, their
    records and their line count.  A file that still begins with those bytes (it only grew: :func:`put_record`
    appends) is parsed from there on; any other is parsed whole.  A sweep reads its file twice a point, and
    parsing and checking 10^4 records took 0.9 s each time."""

    def __init__(self):
        self.raw, self.records, self.lines = b"", [], 0


def _opening(keys: tuple) -> bytes:
    """How every record of a results file begins (:func:`dumps` keeps the writer's order; the first of ``keys``
    comes first in each; without keys, any object's beginning)."""
    return b'{"' + (keys[0].encode() + b'": ' if keys else b"")


def _cut_short(frag: bytes, keys: tuple) -> bool:
    """Whether an unterminated last line ``frag`` after a file's records is a record whose write was cut short (a
    SIGKILL between two pages of the write, a power cut): it is not JSON, and it begins as a record does (or is the
    start of that).  (Without a record before it, a file is not taken for a results file on so little: a review.)"""
    head = _opening(keys)
    n = min(len(frag), len(head))
    if frag[:n] != head[:n]:
        return False
    try:
        json.loads(frag)
    except ValueError:
        return True
    return False


def _text_lines(body: bytes, first: int, refusal: str, path: str) -> list:
    """``(line number, text)`` of the complete lines ``body`` (universal newlines, as text mode reads them);
    a line that is not UTF-8 raises the refusal naming it."""
    out = []
    for k, raw in enumerate(body.replace(b"\r\n", b"\n").replace(b"\r", b"\n").split(b"\n")[:-1], first):
        try:
            out.append((k, raw.decode("utf-8")))
        except UnicodeDecodeError:
            raise ValueError(refusal.format(path=path, line=k)) from None
    return out


def read_records(path: str, keys: tuple, refusal: str, check=None, cache: ReadCache | None = None) -> list[dict]:
    """The records of a JSON Lines results file (empty if it does not exist), each a JSON object
    with ``keys`` (and passing ``check(record)``, which raises on a malformed one); any other
    line, or a file that is not UTF-8 text, raises ``ValueError(refusal.format(path=path,
    line=i))``, so a foreign file is refused rather than overwritten or half-read.

    An unterminated last line after a record that is not JSON but begins as a record does is a write cut short
    (:func:`_cut_short`): it is skipped, with a ``FileWarning`` (its record was never written; the next
    :func:`put_record` removes it). A file's first record cut short is refused with the rest (the refusal says so):
    delete the file.
    Appends are made under :func:`locked`: a reader that holds it never sees one half written. With ``cache``
    (:class:`ReadCache`, kept by the caller between reads of one file) only what was appended since the last read
    is parsed; the list is new, its records are the cache's (not to be changed)."""
    if not os.path.lexists(path):
        return []
    if not os.path.isfile(path):
        raise ValueError(refusal.format(path=path, line=0).split(";")[0] + f" (got {path!r}, not a file)")
    with open(path, "rb") as f:
        data = f.read()
    data = data[3:] if data.startswith(b"\xef\xbb\xbf") else data  # a file saved with a byte-order mark
    if cache is not None and cache.raw and data.startswith(cache.raw):
        start, out, lines = len(cache.raw), list(cache.records), cache.lines
    else:
        start, out, lines = 0, [], 0
    end = max(data.rfind(b"\n"), data.rfind(b"\r"), start - 1) + 1  # through the last line end (CR-only too)
    numbered = _text_lines(data[start:end], lines + 1, refusal, path)
    out += _records(numbered, keys, refusal, check, path)
    lines += len(numbered)
    if cache is not None:
        cache.raw, cache.records, cache.lines = data[:end], list(out), lines
    frag = data[end:]
    if frag.strip() and out and _cut_short(frag, keys):
        from .api import FileWarning  # (api imports this module)
        warnings.warn(f"{path} line {lines + 1} is a record whose write was cut short (a kill or a full disk): "
                      "skipped; its run or point is not recorded", FileWarning, stacklevel=2)
    elif frag.strip():  # a last line without its newline (written by hand)
        if not out and _cut_short(frag, keys):  # refused (it may be a file written by hand), but not left a riddle
            refusal += ("; it begins as a record does: if a kill cut short the file's first record, the file holds "
                        "nothing else, delete it")
        out += _records(_text_lines(frag + b"\n", lines + 1, refusal, path), keys, refusal, check, path)
    return out


def _records(numbered: list, keys: tuple, refusal: str, check, path: str) -> list[dict]:
    """The records of the ``(line number, text)`` lines ``numbered`` (:func:`read_records`; blank lines skipped)."""
    out = []
    for i, line in numbered:
        if not line.strip():
            continue
        try:
            rec = loads(line)
            for k in keys:
                rec[k]
            if check is not None:
                check(rec)
        except (ValueError, KeyError, TypeError, AttributeError):
            raise ValueError(refusal.format(path=path, line=i)) from None
        out.append(rec)
    return out


_HELD = threading.local()  # the directories this thread holds locked (a count each)


#: the lock file :func:`locked` makes in a results file's directory on a network file system
LOCK_NAME = ".dryfric.lock"
#: file systems (``/proc/self/mountinfo``'s types) shared between hosts: there ``flock`` on a directory holds on
#: one host only (Linux's NFS client has no directory ``flock``: the kernel takes a local lock), so a record lock
#: (``lockf``, which these pass to the server) on :data:`LOCK_NAME` is taken
NETWORK_FS = ("nfs", "nfs4", "cifs", "smb3", "smbfs", "ceph", "glusterfs", "lustre", "gpfs", "beegfs", "9p", "afs",
              "fuse.glusterfs", "fuse.ceph-fuse", "fuse.beegfs", "fuse.juicefs", "fuse.moosefs")
#: shared file systems whose locks hold on one host only: sshfs (FUSE grants locks locally), NFS mounted
#: ``nolock`` or ``local_lock=posix|all``, CIFS mounted ``nobrl``, Lustre ``localflock`` (a review): a FileWarning
#: says so
HOST_LOCK_FS = ("fuse.sshfs",)
_THREAD_LOCKS: dict = {}  # one threading.Lock per directory: POSIX record locks do not exclude a process's threads
_UNLOCKED_SAID: set = set()  # the directories whose missing lock was said (once a process)


def _unescape_mount(field: str) -> str:
    """A mount point as ``/proc/self/mountinfo`` writes it (space, tab, newline and backslash as octal escapes)."""
    for code, ch in (("\\040", " "), ("\\011", "\t"), ("\\012", "\n"), ("\\134", "\\")):
        field = field.replace(code, ch)
    return field


def mount_type(d: str, mountinfo: str | None = None) -> tuple[str, str]:
    """The type and options (the mount's and the super block's, comma-joined) of the file system the directory
    ``d`` (a real path) lies on, from ``mountinfo`` (default ``/proc/self/mountinfo``; ``("", "")`` where it cannot
    be read, as off Linux): the longest mount point above ``d``, the last mounted there."""
    if mountinfo is None:
        try:
            with open("/proc/self/mountinfo", encoding="utf-8", errors="replace") as f:
                mountinfo = f.read()
        except OSError:
            return "", ""
    best, kind = -1, ("", "")
    for line in mountinfo.splitlines():
        left, sep, right = line.partition(" - ")
        fields, tail = left.split(), right.split()
        if not sep or len(fields) < 6 or not tail:
            continue
        mp = _unescape_mount(fields[4])
        if (d == mp or d.startswith(mp.rstrip("/") + "/")) and len(mp) >= best:
            best, kind = len(mp), (tail[0], fields[5] + "," + (tail[2] if len(tail) > 2 else ""))
    return kind


def lock_kind(fs_type: str, options: str) -> str:
    """How a directory on a file system of ``fs_type`` mounted with ``options`` is locked: ``"shared"`` (a record
    lock the server holds for every host), ``"host"`` (shared, but its locks hold on this host only) or
    ``"local"``."""
    opts = set(options.split(","))
    if fs_type in HOST_LOCK_FS or (fs_type.startswith("nfs") and opts & {"nolock", "local_lock=posix",
                                                                       "local_lock=all"}) \
            or (fs_type in ("cifs", "smb3") and "nobrl" in opts) or (fs_type == "lustre" and "localflock" in opts):
        return "host"
    return "shared" if fs_type in NETWORK_FS else "local"


@functools.lru_cache(maxsize=None)
def _lock_kind(d: str) -> str:
    """:func:`lock_kind` of the directory ``d``, read once a process."""
    return lock_kind(*mount_type(d))


def _os_lock(d: str):
    """An open descriptor holding an exclusive lock on the directory ``d``, and why it does not hold for every
    writer (None if it does); ``(None, why)`` where there is none.  ``flock`` on the directory; on a network file
    system (:data:`NETWORK_FS`, :func:`lock_kind`) a POSIX record lock (``lockf``) on the file :data:`LOCK_NAME`
    in it, which the server holds for every host (an audit found two writers losing records there), or where it
    cannot be had, the directory's ``flock`` (this host's writers only).  A Ctrl-C in the wait leaves no
    descriptor."""
    if fcntl is None:
        return None, "no fcntl on this platform"
    kind = _lock_kind(d)
    ways = [(d, os.O_RDONLY, False)]
    if kind == "shared":
        ways.insert(0, (os.path.join(d, LOCK_NAME), os.O_RDWR | os.O_CREAT, True))
    why = "its file system's locks hold on this host only" if kind == "host" else None
    failed = None  # why the first way failed
    for name, flags, record in ways:
        try:
            fd = os.open(name, flags, 0o666)
        except OSError as e:
            failed = failed or e.strerror
            continue
        try:
            if record:  # every user's writers open it (a umask of 022 left the others this host's lock only)
                with contextlib.suppress(OSError):
                    os.fchmod(fd, 0o666)
                fcntl.lockf(fd, fcntl.LOCK_EX)
            else:
                fcntl.flock(fd, fcntl.LOCK_EX)
        except OSError as e:
            failed = failed or e.strerror
            os.close(fd)
            continue
        except BaseException:
            os.close(fd)
            raise
        if failed is not None:  # the record lock could not be had: the directory's flock
            why = failed + "; only this host's writers are excluded"
        return fd, why
    return None, failed


@contextlib.contextmanager
def locked(path: str):
    """Hold an exclusive lock on ``path``'s directory (``flock``) while a results file is read and
    rewritten, so two processes updating one file take turns instead of writing over each
    other's records, and a reader never sees a record half appended.  On a network file system a record lock on a
    lock file in the directory serves (:func:`_os_lock`); where no lock holds for every writer (Windows: no
    ``fcntl``; a network file system without record locks), a ``FileWarning`` says once that two processes
    writing one results file there may lose each other's records (not for a directory that does not exist or
    takes no file: no process writes there).  Re-entrant within a thread: a reader that locks
    (:func:`~dryfric_jax.sweep.read_results`) may be called under a held lock (a second ``flock`` of the
    directory in one process waits for the first for ever); other threads of the process wait."""
    d = os.path.dirname(os.path.realpath(path))
    held = _HELD.__dict__
    if held.get(d):
        held[d] += 1
        try:
            yield
        finally:
            held[d] -= 1
        return
    with _THREAD_LOCKS.setdefault(d, threading.Lock()):  # released however the block is left
        fd = None
        try:  # from the lock on, one try: a Ctrl-C after the flock left it held by a leaked descriptor, and every
            # reader and writer of the directory then waited for the process to end (a review)
            fd, why = _os_lock(d)
            if fd is not None:  # held: no other writer of this file is at work
                _drop_stale_tmp(path)
            if why is not None and d not in _UNLOCKED_SAID and os.access(d, os.W_OK):  # none writes elsewhere
                _UNLOCKED_SAID.add(d)
                from .api import FileWarning  # (api imports this module)
                warnings.warn(f"cannot lock the directory {d!r} for every writer ({why}): two processes writing one "
                              "results file there at once may lose each other's records; run them one at a time",
                              FileWarning, stacklevel=3)
            held[d] = 1
            yield
        finally:
            held[d] = 0
            if fd is not None:
                os.close(fd)  # releases the lock


def claims_dir(path: str) -> str:
    """The hidden directory of :func:`claim`'s files beside the results file ``path`` (its name cut as a temporary
    file's: with a name of 248-255 bytes no claim could be made, and two sweeps both computed a point: a review)."""
    real = os.path.realpath(path)
    return os.path.join(os.path.dirname(real), f".{_kept_name(real)}.claims")


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


#: what :func:`put_record` says where a first Ctrl-C or SIGTERM comes while it waits for the file's lock
WRITING_FIRST = ("dryfric: interrupted: writing the finished result to its results file first (waiting for the "
                 "file's lock where another process holds it); interrupt again to drop it")


def put_record(path: str, rec: dict, same, read, done=None) -> None:
    """Write one finished record to a JSON Lines results file that other processes may update too:
    under :func:`locked`, the file is read again (``read(path)``), so the records they wrote
    meanwhile are kept; ``rec`` replaces the first record ``same(old)`` holds for (the file rewritten
    atomically, :func:`write_records`), or is appended (:func:`append_line`: rewriting the whole file after each of
    10^4 points cost ~1 s a point).  A first Ctrl-C or SIGTERM acts only after the write and ``done()`` (the
    caller's bookkeeping of it, if given; :func:`~dryfric_jax.interrupts.held_interrupts`), saying so while the
    lock is awaited; a second one acts at once while the lock is still awaited (it is held by another process: a
    process waiting on a stuck lock is not deaf to Ctrl-C, a review), and after the write where it comes during
    it.  A sweep's finished point caught by one during its write was lost (an audit), and so was one caught while
    it waited for the lock that another sweep held (an interrupt audit: the lock's wait was broken by the first
    signal)."""
    locking = [True]  # said only while the lock is awaited (after the write it was said with nothing left to drop)
    with held_interrupts(second_acts=True, said=lambda: WRITING_FIRST if locking[0] else None), locked(path), \
            held_interrupts():
        locking[0] = False
        records = read(path)
        at = next((k for k, old in enumerate(records) if same(old)), None)
        if at is None:
            append_line(path, dumps(rec) + "\n")
        else:
            records[at] = rec
            write_records(path, records)
        if done is not None:
            done()


def _last_line_start(f, size: int) -> int:
    """Where the unterminated last line of the file ``f`` (``size`` bytes, unbuffered) begins: after the last line
    end (CR-only too, as :func:`read_records` reads them)."""
    pos = size
    while pos > 0:
        lo = max(0, pos - 65536)
        f.seek(lo)
        chunk = f.read(pos - lo)
        k = max(chunk.rfind(b"\n"), chunk.rfind(b"\r"))
        if k >= 0:
            return lo + k + 1
        pos = lo
    return 0


def append_line(path: str, line: str) -> None:
    """Append ``line`` (one JSON record and its newline) to the results file ``path`` (made if missing, with the
    mode a new file gets), and fsync it.  Called under :func:`locked`, after :func:`read_records` read the file: an
    unterminated last line is first ended with a newline (a record written by hand), or removed where it is not
    JSON (a write a kill cut short, which the reading skipped).  A failed write (a full disk) is taken back, so the
    file is as it was."""
    with open(os.path.realpath(path), "ab+", buffering=0) as f:  # every write goes to the end
        size = f.seek(0, os.SEEK_END)
        data = line.encode()
        f.seek(max(size - 1, 0))
        if size and f.read(1) not in (b"\n", b"\r"):
            start = _last_line_start(f, size)
            f.seek(start)
            try:
                json.loads(f.read())
                data = b"\n" + data
            except ValueError:
                f.truncate(start)
                size = start
        try:
            while data:
                data = data[os.write(f.fileno(), data):]
            os.fsync(f.fileno())
        except BaseException:
            with contextlib.suppress(OSError):
                f.truncate(size)
            raise


def write_records(path: str, records: list[dict]) -> None:
    """Rewrite a JSON Lines results file with ``records``, atomically (:func:`write_atomic`)."""
    write_atomic(path, "".join(dumps(rec) + "\n" for rec in records))
