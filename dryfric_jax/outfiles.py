"""Output files: checked writable before any work, written atomically (never a torn file)."""
from __future__ import annotations

import json
import os
import tempfile


def check_writable(path: str, name: str = "out") -> None:
    """Raise ``ValueError`` naming ``name`` unless ``path`` can be created or replaced as a file."""
    d = os.path.dirname(os.path.abspath(path))
    if os.path.isdir(path) or not os.path.isdir(d) or not os.access(d, os.W_OK):
        raise ValueError(f"{name} must be a writable file path in an existing directory (got {path!r})")


def check_writable_dir(path: str, name: str = "out") -> None:
    """Raise ``ValueError`` naming ``name`` unless ``path`` is a writable directory or can be
    created as one (its parent exists and is writable)."""
    if os.path.isdir(path):
        ok = os.access(path, os.W_OK)
    else:
        parent = os.path.dirname(os.path.abspath(path))
        ok = not os.path.exists(path) and os.path.isdir(parent) and os.access(parent, os.W_OK)
    if not ok:
        raise ValueError(f"{name} must be a writable directory, or a new one in an existing directory (got {path!r})")


def write_atomic(path: str, text: str) -> None:
    """Write ``text`` to a temporary file in the same directory, fsync, then rename over ``path``:
    a reader (or a kill at any moment) sees the old file or the new one, never a part."""
    d = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(dir=d, prefix=".dryfric-", suffix=".tmp")
    try:
        with os.fdopen(fd, "w") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes it private; an output file is not
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def read_records(path: str, keys: tuple, refusal: str) -> list[dict]:
    """The records of a JSON Lines results file (empty if it does not exist), each a JSON object
    with ``keys``; any other line raises ``ValueError(refusal.format(path=path, line=i))``, so a
    foreign file is refused rather than overwritten."""
    if not os.path.exists(path):
        return []
    out = []
    with open(path) as f:
        for i, line in enumerate(f, 1):
            if not line.strip():
                continue
            try:
                rec = json.loads(line)
                for k in keys:
                    rec[k]
            except (ValueError, KeyError, TypeError):
                raise ValueError(refusal.format(path=path, line=i)) from None
            out.append(rec)
    return out


def write_records(path: str, records: list[dict]) -> None:
    """Rewrite a JSON Lines results file with ``records``, atomically (:func:`write_atomic`)."""
    write_atomic(path, "".join(json.dumps(rec) + "\n" for rec in records))
