"""Mutation audit of dryfric_jax/outfiles.py: strict JSON, atomic writes, JSON Lines records, the
directory lock, the per-point claims and the writability checks.  Each test fails on the mutants its
docstring names (single edits of outfiles.py that the other tests let through); all are in-process
and fast (< 1 s each): system calls are observed or made to fail through monkeypatch."""
import json
import math
import os
import stat
import subprocess
import sys

import pytest

fcntl = pytest.importorskip("fcntl")  # POSIX: a Windows checkout skips these (it failed to collect the suite)

from dryfric_jax import outfiles
from dryfric_jax.outfiles import (check_writable, check_writable_dir, claim, claims_dir, dumps, loads, locked,
                                  put_record, read_records, write_atomic)

_REFUSAL = "not a results file: {path} line {line}"


def _locked_now(path):
    """Whether the directory of ``path`` is under an exclusive ``flock`` now (a shared one is refused
    without waiting), tried through a descriptor of its own."""
    fd = os.open(os.path.dirname(os.path.realpath(path)), os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
    except BlockingIOError:
        return True
    finally:
        os.close(fd)
    return False


def test_non_finite_floats_inside_a_tuple_are_strict_json():
    """A tuple (a grid's values, a pair of bounds) is a JSON list whose non-finite floats are written as
    strings too, and reads back as a list of floats.  Mutant: only lists walked (a tuple holding inf
    reached ``json.dumps`` with ``allow_nan=False`` and the write failed)."""
    text = dumps({"bounds": (-math.inf, 1.0, math.inf)})
    assert json.loads(text) == {"bounds": ["-inf", 1.0, "inf"]}
    assert loads(text) == {"bounds": [-math.inf, 1.0, math.inf]}


def test_a_write_is_flushed_and_fsynced_into_a_file_beside_the_target_before_the_rename(tmp_path, monkeypatch):
    """The new text is on the temporary file (flushed: the descriptor's size is the whole text) when it
    is fsynced, and the fsync comes before the rename; the temporary file is in the target's own
    directory (a rename from /tmp is not atomic across file systems, or fails with EXDEV).  Mutants:
    no fsync; no flush before the fsync (the text still in Python's buffer); ``mkstemp`` without
    ``dir`` (the default temporary directory)."""
    path = tmp_path / "r.jsonl"
    text = "é\n" * 1000  # 3000 bytes in UTF-8
    calls, real_fsync, real_replace = [], os.fsync, os.replace

    def fsync(fd):
        calls.append(("fsync", os.fstat(fd).st_size))
        real_fsync(fd)

    def replace(src, dst):
        calls.append(("replace", os.path.dirname(os.path.abspath(src)), os.fspath(dst)))
        real_replace(src, dst)

    monkeypatch.setattr(outfiles.os, "fsync", fsync)
    monkeypatch.setattr(outfiles.os, "replace", replace)
    write_atomic(str(path), text)
    assert calls == [("fsync", 3000), ("replace", str(tmp_path), str(path))]
    assert path.read_text() == text


def test_a_new_file_gets_the_umask_mode(tmp_path):
    """A new results file has the mode any new file gets, 0666 less the umask (mkstemp's 0600 would make
    it private; 0666 ignoring the umask would make it writable by all).  Mutants: the umask ignored;
    no chmod of the temporary file (0600)."""
    old = os.umask(0o027)
    try:
        write_atomic(str(tmp_path / "new.jsonl"), "x\n")
    finally:
        os.umask(old)
    assert stat.S_IMODE(os.stat(tmp_path / "new.jsonl").st_mode) == 0o640


def test_ctrl_c_during_a_write_keeps_the_old_file_and_removes_the_temporary_one(tmp_path, monkeypatch):
    """A KeyboardInterrupt (not an Exception) at the rename propagates, and the temporary file is
    removed all the same.  Mutant: the cleanup under ``except Exception`` (a .dryfric-*.tmp left
    beside the results on every Ctrl-C)."""
    path = tmp_path / "r.jsonl"
    path.write_text("old\n")

    def interrupted(src, dst):
        raise KeyboardInterrupt

    monkeypatch.setattr(outfiles.os, "replace", interrupted)
    with pytest.raises(KeyboardInterrupt):
        write_atomic(str(path), "new\n")
    assert path.read_text() == "old\n" and os.listdir(tmp_path) == ["r.jsonl"]


def test_a_dangling_link_or_a_directory_is_refused_by_path(tmp_path):
    """A results path that exists but is not a file (a symlink to nothing, a directory) is refused,
    naming the path, not read as an empty file (the next write would create the link's target
    somewhere unexpected).  Mutants: ``exists`` for ``lexists`` (a dangling link read as no file);
    the path left out of the refusal."""
    link = tmp_path / "r.jsonl"
    link.symlink_to(tmp_path / "gone" / "r.jsonl")
    for path in (link, tmp_path):
        with pytest.raises(ValueError) as e:
            read_records(str(path), ("k",), _REFUSAL)
        assert str(e.value) == f"not a results file: {path} line 0 (got {str(path)!r}, not a file)"


def test_a_refusal_names_the_file_and_a_record_of_the_wrong_shape_is_refused(tmp_path):
    """The refusal names the file's path and the line (1-based, as an editor shows); a line that is
    JSON but not an object (a list, a number: TypeError on indexing), a record that ``check``
    refuses (whatever it raises of ValueError, KeyError, TypeError, AttributeError) is refused the
    same way, not raised as is.  A file saved with a byte-order mark is read.  Mutants: the path left
    out; ``check`` not called; TypeError or AttributeError not turned into the refusal; the BOM not
    accepted (``utf-8``)."""
    path = tmp_path / "r.jsonl"
    for line2 in ('[1, 2]', '5'):
        path.write_text('{"k": 1}\n' + line2 + '\n')
        with pytest.raises(ValueError) as e:
            read_records(str(path), ("k",), _REFUSAL)
        assert str(e.value) == f"not a results file: {path} line 2"

    def check(rec):
        if rec["k"] == 2:
            rec["k"].upper()  # AttributeError: an int has no upper

    path.write_text('{"k": 1}\n{"k": 2}\n')
    with pytest.raises(ValueError) as e:
        read_records(str(path), ("k",), _REFUSAL, check=check)
    assert str(e.value) == f"not a results file: {path} line 2"

    def strict(rec):
        if rec["k"] != 1:
            raise ValueError("k must be 1")

    with pytest.raises(ValueError, match=" line 2$"):
        read_records(str(path), ("k",), _REFUSAL, check=strict)
    path.write_bytes(b'\xef\xbb\xbf{"k": 1}\n{"k": -1}\n')
    assert read_records(str(path), ("k",), _REFUSAL) == [{"k": 1}, {"k": -1}]


def test_the_directory_lock_is_exclusive_and_held_for_the_whole_block(tmp_path, monkeypatch):
    """While ``locked(path)`` is held, another descriptor of the directory cannot take even a shared
    lock; after it, it can.  A relative path (no directory part) locks the current directory.
    Mutants: a shared lock; the lock released right after it is taken; the lock never taken; the
    directory of the path as given (``dirname('r.jsonl')`` is '', which cannot be opened: no lock)."""
    monkeypatch.chdir(tmp_path)
    for path in (str(tmp_path / "r.jsonl"), "r.jsonl"):
        with locked(path):
            assert _locked_now(path)
        assert not _locked_now(path)


def test_put_record_reads_and_rewrites_under_the_lock_and_replaces_in_place(tmp_path):
    """``put_record`` reads the file under the directory lock, and a record that ``same`` matches is
    replaced where it stands (no second copy, the order kept); another one is appended.  Mutants: no
    lock around the read-and-rewrite; the matching record appended instead of replaced."""
    path = str(tmp_path / "r.jsonl")
    seen = []

    def read(p):
        seen.append(_locked_now(p))
        return read_records(p, ("k",), _REFUSAL)

    put_record(path, {"k": 1, "v": "a"}, lambda old: old["k"] == 1, read)
    put_record(path, {"k": 2, "v": "b"}, lambda old: old["k"] == 2, read)
    put_record(path, {"k": 1, "v": "c"}, lambda old: old["k"] == 1, read)
    assert seen == [True, True, True]
    with open(path) as f:
        assert f.read() == '{"k": 1, "v": "c"}\n{"k": 2, "v": "b"}\n'


def test_a_finished_claim_removes_its_file_and_the_empty_directory_only_when_held(tmp_path):
    """A held claim's ``finish()`` removes its file and then the claims directory, now empty.  A claim
    that is not held (another process's point) leaves the holder's file in place even if ``finish()``
    is called on it, so a third claimant is still excluded.  Mutants: the directory not removed after
    a finished point; the file removed by a claimant that did not hold it."""
    p = str(tmp_path / "r.jsonl")
    with claim(p, "k") as c:
        assert c.held
        c.finish()
    assert not os.path.exists(claims_dir(p))
    with claim(p, "k") as holder:
        assert holder.held
        with claim(p, "k") as other:
            assert not other.held
            other.finish()
        assert len(os.listdir(claims_dir(p))) == 1
        with claim(p, "k") as third:
            assert not third.held


def test_check_writable_refuses_blank_long_and_unwritable_names_by_their_name(tmp_path):
    """A blank path, a name the file system refuses (over 255 bytes: said why) and a directory are
    refused, by the option's name.  Mutants: a whitespace-only path accepted; the new name itself not
    tried (the long name passed, and the write failed after the run); the reason or the option's
    name left out of the message."""
    for bad in ("   ", str(tmp_path)):
        with pytest.raises(ValueError, match="^table must be a writable file path"):
            check_writable(bad, "table")
    with pytest.raises(ValueError, match=r"^table must be .*: File name too long\)$"):
        check_writable(str(tmp_path / ("x" * 300)), "table")
    assert os.listdir(tmp_path) == []


def test_check_writable_tries_the_directory_a_link_points_into(tmp_path, monkeypatch):
    """Through a symlink the file is replaced where it lies (``write_atomic`` resolves it), so the
    directory tried is the target's, not the link's.  Mutant: the link's own directory tried."""
    (tmp_path / "data").mkdir()
    target, link = tmp_path / "data" / "r.jsonl", tmp_path / "r.jsonl"
    target.write_text("x\n")
    link.symlink_to(target)
    tried, real = [], outfiles._can_create_in
    monkeypatch.setattr(outfiles, "_can_create_in", lambda d: tried.append(d) or real(d))
    check_writable(str(link))
    assert tried == [str(tmp_path / "data")]


def test_the_probe_of_a_new_name_never_removes_another_process_s_file(tmp_path, monkeypatch):
    """``check_writable`` of a new name creates it and removes it.  Another process (a sweep writing its
    first record to the same new file) may rename its file over the name in between: that file stayed
    deleted (an audit's two-process harness saw it 3 times in 1688 writes).  The probe is removed only
    while the name is still the probe; a file seen and gone before its mode is read is no traceback.
    Mutant: the old unconditional unlink."""
    p = tmp_path / "r.jsonl"
    real_fstat = os.fstat

    def fstat_then_the_other_writes(fd):  # the moment between the probe's creation and its removal
        st = real_fstat(fd)
        write_atomic(str(p), "theirs\n")
        return st

    monkeypatch.setattr(outfiles.os, "fstat", fstat_then_the_other_writes)
    check_writable(str(p))
    monkeypatch.undo()
    assert p.read_text() == "theirs\n"
    check_writable(str(tmp_path / "new.json"))  # with nobody else there, the probe is gone
    assert sorted(os.listdir(tmp_path)) == ["r.jsonl"]
    seen = iter([True, False])  # isfile says yes, then the file is gone: treated as a new name
    monkeypatch.setattr(outfiles.os.path, "isfile", lambda q: next(seen, False))
    q = tmp_path / "gone.json"
    check_writable(str(q))
    assert not q.exists()


def test_check_writable_dir_refuses_a_file_and_a_directory_where_nothing_can_be_made(tmp_path):
    """An existing file is not a directory to write into; /proc accepts no new file (``os.access``
    says it does).  Mutants: an existing file accepted as a new directory; a failed trial file taken
    as success."""
    (tmp_path / "f").write_text("x\n")
    for bad in (str(tmp_path / "f"), "/proc"):
        with pytest.raises(ValueError, match="^figs must be a writable directory"):
            check_writable_dir(bad, "figs")


def test_a_claim_through_a_link_excludes_one_through_the_file_it_names(tmp_path):
    """A results file named through a symlink and by its real path is one file, so its points have one
    claims directory (beside the real file): a claim through either excludes one through the other.
    Mutant: ``abspath`` for ``realpath`` in ``claims_dir`` (two directories; both claims held)."""
    (tmp_path / "data").mkdir()
    target, link = tmp_path / "data" / "r.jsonl", tmp_path / "r.jsonl"
    link.symlink_to(target)
    with claim(str(link), "k") as c:
        assert c.held and os.path.isdir(tmp_path / "data" / ".r.jsonl.claims")
        with claim(str(target), "k") as other:
            assert not other.held


_NAMES = """
import importlib.util, os, sys, tempfile, types
pkg = types.ModuleType("dryfric_jax"); pkg.__path__ = []
params = types.ModuleType("dryfric_jax.params"); params.shown = repr
sys.modules.update({"dryfric_jax": pkg, "dryfric_jax.params": params})
spec = importlib.util.spec_from_file_location("dryfric_jax.outfiles", sys.argv[1])
mod = importlib.util.module_from_spec(spec); spec.loader.exec_module(mod)
p = os.path.join(tempfile.mkdtemp(dir=sys.argv[2]), "r.jsonl")
with mod.claim(p, "point-7") as c:
    print(os.listdir(mod.claims_dir(p))[0])
"""


def test_a_points_claim_file_has_the_same_name_in_every_process(tmp_path):
    """Two processes claiming one point must open the same file, so its name cannot depend on the
    process: two interpreters with different string-hash seeds (outfiles.py loaded alone, without
    JAX, to stay fast) name it alike.  Mutant: the name from Python's ``hash()`` (salted per process:
    two sweeps then computed every point twice)."""
    names = set()
    for seed in ("1", "2"):
        out = subprocess.run([sys.executable, "-c", _NAMES, outfiles.__file__, str(tmp_path)], capture_output=True,
                             text=True, timeout=30, env=dict(os.environ, PYTHONHASHSEED=seed), check=True)
        names.add(out.stdout.strip())
    assert len(names) == 1 and names != {""}
