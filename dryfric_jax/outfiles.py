"""Output files: checked writable before any work, written atomically (never a torn file), in strict
JSON (:func:`dumps`, :func:`loads`)."""
from __future__ import annotations

import json
import math
import os
import tempfile

import numpy as np


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


def _from_strict(x):
    if isinstance(x, str):
        return _NONFINITE.get(x, x)
    if isinstance(x, dict):
        return {k: _from_strict(v) for k, v in x.items()}
    if isinstance(x, list):
        return [_from_strict(v) for v in x]
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
    return _from_strict(json.loads(text))


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
                rec = loads(line)
                for k in keys:
                    rec[k]
            except (ValueError, KeyError, TypeError):
                raise ValueError(refusal.format(path=path, line=i)) from None
            out.append(rec)
    return out


def write_records(path: str, records: list[dict]) -> None:
    """Rewrite a JSON Lines results file with ``records``, atomically (:func:`write_atomic`)."""
    write_atomic(path, "".join(dumps(rec) + "\n" for rec in records))
