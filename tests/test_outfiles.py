"""Output files (dryfric_jax.outfiles): strict JSON that reads back, and the line a refusal names."""
import json
import math
import os
import re
import time

import numpy as np
import pytest

from dryfric_jax import outfiles
from dryfric_jax.outfiles import dumps, loads, read_records, write_atomic


def test_non_finite_floats_are_strict_json_and_read_back_with_their_sign():
    """inf, -inf and nan, as Python or numpy values, in dicts, lists and arrays, are written as
    strings a strict reader accepts and read back as the same floats (a sign or a list level lost
    would turn -inf into inf, or leave "inf" a string where a float was written)."""
    obj = {"a": [math.inf, -math.inf, math.nan], "b": np.float32(-np.inf), "c": np.array([1.0, -np.inf]),
           "d": {"e": [[-math.inf]]}}
    text = dumps(obj)
    json.loads(text, parse_constant=lambda c: pytest.fail(f"non-standard JSON constant {c}"))
    back = loads(text)
    assert back["a"][:2] == [math.inf, -math.inf] and math.isnan(back["a"][2])
    assert back["b"] == -math.inf and back["c"] == [1.0, -math.inf] and back["d"] == {"e": [[-math.inf]]}


def test_a_refused_line_is_named_by_its_number_in_the_file(tmp_path):
    """Blank lines are skipped but counted, so the number is the line an editor shows; a file that
    is not UTF-8 from its first byte is refused at line 1 (not 'line 0')."""
    refusal = "not a results file: {path} line {line}"
    path = tmp_path / "r.jsonl"
    path.write_text('{"k": 1}\n\n{"k": 2}\n   \n{"j": 3}\n')
    with pytest.raises(ValueError, match=r" line 5$"):
        read_records(str(path), ("k",), refusal)
    path.write_text('\n{"k": 1}\n\n{"k": 2}\n')
    assert read_records(str(path), ("k",), refusal) == [{"k": 1}, {"k": 2}]
    path.write_bytes(b"\xff\xfe\x00")
    with pytest.raises(ValueError, match=r" line 1$"):
        read_records(str(path), ("k",), refusal)


def test_a_reader_of_the_old_file_never_sees_a_part_of_the_new_one(tmp_path):
    """The new text goes to a new file renamed over the path: a reader that opened the old file
    reads it whole after the write (written in place, it read '' or a mix)."""
    path = tmp_path / "r.jsonl"
    path.write_text("old line\n" * 100)
    with open(path) as reader:
        write_atomic(str(path), "new\n")
        assert reader.read() == "old line\n" * 100
    assert path.read_text() == "new\n"


def test_a_failed_write_keeps_the_old_file_and_leaves_no_temporary_file(tmp_path, monkeypatch):
    """A rename that fails (a full disk, a file system gone read-only) raises, leaves the old file as it
    was, and removes the temporary file (it stayed as .dryfric-*.tmp beside the results)."""
    path = tmp_path / "r.jsonl"
    path.write_text("old\n")

    def failed(src, dst):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(outfiles.os, "replace", failed)
    with pytest.raises(OSError, match="No space left"):
        write_atomic(str(path), "new\n")
    assert path.read_text() == "old\n" and os.listdir(tmp_path) == ["r.jsonl"]


@pytest.mark.parametrize("name", ["r" * 250 + ".json", "é" * 125 + ".json"])  # 255 and 255 bytes
def test_a_name_at_the_file_systems_limit_is_written_atomically(tmp_path, name):
    """A name of 234-255 bytes passed check_writable and failed at write_atomic, whose temporary name adds 22 bytes
    (ENAMETOOLONG: after an estimate's run, and at every start of a sweep on such a file: an audit)."""
    path = tmp_path / name
    outfiles.check_writable(str(path))
    write_atomic(str(path), "one\n")
    write_atomic(str(path), "two\n")
    assert path.read_text() == "two\n" and os.listdir(tmp_path) == [name]
    with outfiles.claim(str(path), "point") as c:  # its claims too (none could be made: every point computed twice)
        assert c.held and len(os.listdir(outfiles.claims_dir(str(path)))) == 1
        with outfiles.claim(str(path), "point") as other:
            assert not other.held


def test_the_probe_is_closed_before_it_is_removed(tmp_path, monkeypatch):
    """Windows refuses to remove a file that is open: the writability probe, removed while its descriptor was open,
    was left behind as an empty private file (an audit).  Here unlink refuses, as there, a file still open."""
    opened, real_open, real_close, real_unlink = {}, os.open, os.close, os.unlink

    def open_(path, *a, **kw):
        fd = real_open(path, *a, **kw)
        opened[fd] = os.path.abspath(path)
        return fd

    def close(fd):
        opened.pop(fd, None)
        real_close(fd)

    def unlink(path, *a, **kw):
        if os.path.abspath(path) in opened.values():
            raise PermissionError(13, "The process cannot access the file because it is being used")
        real_unlink(path, *a, **kw)

    monkeypatch.setattr(outfiles.os, "open", open_)
    monkeypatch.setattr(outfiles.os, "close", close)
    monkeypatch.setattr(outfiles.os, "unlink", unlink)
    outfiles.check_writable(str(tmp_path / "new.json"))
    assert not (tmp_path / "new.json").exists()


def test_a_file_that_cannot_be_renamed_over_is_overwritten_in_place(tmp_path, monkeypatch):
    """A file that is a mount point (Docker's -v file:file) cannot be renamed over (EBUSY): a sweep on one failed
    at every start, an estimate after its run (an audit).  It is overwritten in place, keeping its inode, and no
    temporary file is left; any other rename failure is raised as before."""
    import errno

    path = tmp_path / "r.jsonl"
    path.write_text("a much longer old text\n")
    inode = path.stat().st_ino

    real_replace = os.replace

    def busy(src, dst):  # nothing can be renamed over the mount point
        if str(dst) == str(path):
            raise OSError(errno.EBUSY, os.strerror(errno.EBUSY))
        real_replace(src, dst)

    monkeypatch.setattr(outfiles.os, "replace", busy)
    write_atomic(str(path), "new é\n")
    assert path.read_text(encoding="utf-8") == "new é\n" and path.stat().st_ino == inode
    assert os.listdir(tmp_path) == ["r.jsonl"]
    # a write that fails part way (a full disk) keeps the whole new text, named so that no cleanup of stale
    # temporary files removes it, and says where (it was removed, and a buffered close hid the message: a review)
    real_open = open

    class Full:  # the file as a full disk takes a write: 4 bytes, then ENOSPC
        def __init__(self, f):
            self.f, self.n = f, 0

        def write(self, b):
            if self.n:
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
            self.n = self.f.write(bytes(b[:4]))
            return self.n

        def __getattr__(self, k):
            return getattr(self.f, k)

        def __enter__(self):
            return self

        def __exit__(self, *a):
            self.f.close()

    def full_open(name, mode="r", *a, **kw):
        f = real_open(name, mode, *a, **kw)
        return Full(f) if str(name) == str(path) and mode == "r+b" else f

    monkeypatch.setattr(outfiles, "open", full_open, raising=False)
    with pytest.raises(OSError, match=r"could not be overwritten in place, and may be torn; its whole new text is in "
                                      r"'.*\.new'\)?$"):
        write_atomic(str(path), "newer\n")
    (kept,) = [n for n in os.listdir(tmp_path) if n != "r.jsonl"]
    assert kept.endswith(".new") and (tmp_path / kept).read_text() == "newer\n"
    monkeypatch.setattr(outfiles, "STALE_TMP_S", -1.0)
    with outfiles.locked(str(path)):  # the cleanup of killed writes' temporary files leaves it
        pass
    assert (tmp_path / kept).exists()
    (tmp_path / kept).unlink()
    monkeypatch.undo()
    monkeypatch.setattr(outfiles.os, "replace", busy)
    write_atomic(str(path), "new é\n")
    assert path.read_text(encoding="utf-8") == "new é\n" and os.listdir(tmp_path) == ["r.jsonl"]
    monkeypatch.setattr(outfiles.os, "replace", lambda s, d: (_ for _ in ()).throw(OSError(errno.EXDEV, "x")))
    with pytest.raises(OSError):
        write_atomic(str(path), "other\n")
    assert os.listdir(tmp_path) == ["r.jsonl"]


def test_a_file_mounted_read_only_is_refused_before_the_run(tmp_path, monkeypatch):
    """A file mounted read-only (Docker's -v out.json:/work/out.json:ro) has write bits in its mode: it passed the
    check and failed after the run (a review).  statvfs says the mount is read-only (simulated); a file the user
    cannot write but may replace (another's, mode 0644, in a writable directory) is still taken."""
    path = tmp_path / "out.json"
    path.write_text("{}")
    real = os.statvfs

    class ReadOnly:
        f_flag = os.ST_RDONLY

    monkeypatch.setattr(outfiles.os, "statvfs", lambda q: ReadOnly() if str(q) == str(path) else real(q))
    with pytest.raises(ValueError, match=r"\(got '.*: the file is read-only\)$"):  # a long path is shortened
        outfiles.check_writable(str(path))
    monkeypatch.undo()
    monkeypatch.setattr(outfiles.os, "access", lambda *a, **kw: False)  # not this user's to write: renamed over
    outfiles.check_writable(str(path))


def test_a_killed_writes_temporary_file_is_removed_by_the_next_locked_write(tmp_path, monkeypatch):
    """A SIGKILL between write_atomic's creating and renaming its temporary file left it beside the results, a
    whole copy of them, one more per kill (an audit: 10 MB each).  The next write under the file's lock removes
    those of that file, and those of the older unnamed kind, older than STALE_TMP_S (a live write takes seconds;
    the age spares another host's writer where the lock is per host: a review); another file's are left alone."""
    if outfiles.fcntl is None:
        pytest.skip("no lock without fcntl (Windows): nothing is removed")
    path = tmp_path / "r.jsonl"
    names = {"stale": ".r.jsonl.dryfric-abc123.tmp", "unnamed": ".dryfric-old456.tmp",
             "fresh": ".r.jsonl.dryfric-new000.tmp", "other": ".fig3.json.dryfric-xyz789.tmp"}
    old = time.time() - outfiles.STALE_TMP_S - 60
    for what, name in names.items():
        (tmp_path / name).write_text(what + "\n")
        if what != "fresh":
            os.utime(tmp_path / name, (old, old))
    outfiles.put_record(str(path), {"a": 1}, lambda old: False, lambda p: [])
    assert sorted(os.listdir(tmp_path)) == sorted([names["fresh"], names["other"], "r.jsonl"])
    seen, real = [], os.replace
    monkeypatch.setattr(os, "replace", lambda a, b: (seen.append(os.path.basename(a)), real(a, b))[1])
    write_atomic(str(path), "x\n")  # its own temporary file is named for its target
    assert seen[0].startswith(".r.jsonl.dryfric-") and seen[0].endswith(".tmp")


def _lock_holder(tmp_path):
    """Another process holding the directory's lock (another sweep writing, or one stopped with Ctrl-Z)."""
    import subprocess
    import sys

    if outfiles.fcntl is None:
        pytest.skip("no flock here")
    holder = subprocess.Popen([sys.executable, "-c", "import fcntl, os, sys, time; fd = os.open(sys.argv[1], "
                               "os.O_RDONLY); fcntl.flock(fd, fcntl.LOCK_EX); print('held', flush=True); "
                               "time.sleep(20)", str(tmp_path)], stdout=subprocess.PIPE, text=True)
    assert holder.stdout.readline().strip() == "held"
    return holder


def _ctrl_c_at(*times):
    """SIGINT to the main thread (waiting in flock, as a terminal's Ctrl-C reaches it) at each of ``times`` s."""
    import signal
    import threading

    main = threading.main_thread().ident
    timers = [threading.Timer(t, lambda: signal.pthread_kill(main, signal.SIGINT)) for t in times]
    for t in timers:
        t.start()
    return timers


def test_a_second_ctrl_c_breaks_the_wait_for_the_lock(tmp_path, capsys):
    """put_record holds a first Ctrl-C, saying so, but a second one acts while it waits for the lock: held over the
    wait, a process waiting on a stuck lock (another sweep stopped with Ctrl-Z) could not be interrupted (a
    review)."""
    import time

    holder = _lock_holder(tmp_path)
    try:
        t0 = time.monotonic()
        _ctrl_c_at(0.3, 0.6)
        with pytest.raises(KeyboardInterrupt):
            outfiles.put_record(str(tmp_path / "r.jsonl"), {"a": 1}, lambda old: False, lambda p: [])
        assert time.monotonic() - t0 < 10 and not (tmp_path / "r.jsonl").exists()
        assert holder.poll() is None  # the lock was still held: the second Ctrl-C broke the wait
        assert capsys.readouterr().err == outfiles.WRITING_FIRST + "\n"
    finally:
        holder.kill()
        holder.wait()


def test_a_first_ctrl_c_while_waiting_for_the_lock_writes_the_record_first(tmp_path, capsys):
    """A first Ctrl-C while another process holds the lock waits for it, writes the finished record, then acts (a
    KeyboardInterrupt after the write): a sweep's finished point caught so was lost, the lock's wait broken by
    the first signal (an interrupt audit; mutant: the first Ctrl-C breaks the wait)."""
    import threading
    import time

    holder = _lock_holder(tmp_path)
    try:
        t0 = time.monotonic()
        _ctrl_c_at(0.3)
        threading.Timer(1.0, holder.kill).start()  # the other process lets go of the lock
        with pytest.raises(KeyboardInterrupt):
            outfiles.put_record(str(tmp_path / "r.jsonl"), {"a": 1}, lambda old: False, lambda p: [])
        assert time.monotonic() - t0 >= 1.0
        assert (tmp_path / "r.jsonl").read_text() == '{"a": 1}\n'
        assert capsys.readouterr().err == outfiles.WRITING_FIRST + "\n"
    finally:
        holder.kill()
        holder.wait()


_KEYS, _REFUSAL = ("k",), "not a results file: {path} line {line}"


def _rec(i, pad="x" * 60):
    return {"k": i, "pad": pad}


def _read(path, **kw):
    return read_records(str(path), _KEYS, _REFUSAL, **kw)


def _put(path, rec):
    outfiles.put_record(str(path), rec, lambda old: old["k"] == rec["k"], _read)


def test_a_new_record_is_appended_and_one_that_replaces_another_rewrites_the_file(tmp_path):
    """A new record is one line appended to the file (rewriting the whole file after each point cost ~1 s a
    point at 10^4 records); one that replaces a record rewrites the file atomically (a new file renamed over it).
    A file the first append makes gets the mode a new file gets (as write_atomic gives it)."""
    path = tmp_path / "r.jsonl"
    umask = os.umask(0o022)
    try:
        _put(path, _rec(1))
    finally:
        os.umask(umask)
    assert os.stat(path).st_mode & 0o777 == 0o644
    _put(path, _rec(2))
    ino = os.stat(path).st_ino
    _put(path, _rec(3))
    assert os.stat(path).st_ino == ino and path.read_text() == "".join(dumps(_rec(i)) + "\n" for i in (1, 2, 3))
    _put(path, _rec(2, pad="new"))
    assert os.stat(path).st_ino != ino and _read(path) == [_rec(1), _rec(2, pad="new"), _rec(3)]


@pytest.mark.parametrize("cut", [1, 4, 7, 30, -2])
def test_a_record_whose_write_was_cut_short_is_skipped_and_removed_by_the_next_write(tmp_path, cut):
    """A SIGKILL between two pages of an append, or a power cut, can leave the last line a part of a record: it is
    skipped with a warning naming its line (its point was never written), and the next write removes it before its
    own line (appended after it, it would make the file unreadable)."""
    from dryfric_jax import DryfricWarning

    path = tmp_path / "r.jsonl"
    whole = dumps(_rec(1)) + "\n"
    path.write_text(whole + dumps(_rec(2))[:cut])
    with pytest.warns(DryfricWarning, match=r"r\.jsonl line 2 is a record whose write was cut short"):
        assert _read(path) == [_rec(1)]
    with pytest.warns(DryfricWarning):
        _put(path, _rec(3))
    assert path.read_text() == whole + dumps(_rec(3)) + "\n"


def test_a_last_line_without_its_newline_is_kept_and_ended_before_the_next_record(tmp_path):
    """A file written by hand may end without a newline: its last record is read, and the next record goes on a line
    of its own (not removed as a write cut short, not run into it)."""
    path = tmp_path / "r.jsonl"
    path.write_text(dumps(_rec(1)) + "\n" + dumps(_rec(2)))
    assert _read(path) == [_rec(1), _rec(2)]
    _put(path, _rec(3))
    assert path.read_text() == "".join(dumps(_rec(i)) + "\n" for i in (1, 2, 3))


@pytest.mark.parametrize("text,line", [("hello", 1), ('{"j": 1}', 1), ('{"k": 1}\nnot json', 2), ('{"k": 1}\n{"k"', 0),
                                       ('{"k": 1}\n{"j": 2', 2), ("{", 1), ('{"k": 1, "x": 2,}', 1),
                                       ('{"k": {\'a\': 1}}', 1), ('{"k": 1}{"k": 2}', 1)])
def test_only_the_start_of_a_record_is_taken_for_a_write_cut_short(tmp_path, text, line):
    """An unterminated last line is skipped only where it follows a record and is a record's beginning that is not
    JSON; any other (a foreign file's text, a line without the keys, a lone line that is not JSON however it begins:
    a review) is refused as before, naming its line, and the file is left."""
    path = tmp_path / "r.jsonl"
    path.write_text(text)
    if line:
        # a lone line that begins as a record may be a first record cut short: the refusal says what to do
        hint = "; it begins as a record does: if a kill cut short the file's first record, the file holds nothing else"
        lone = text in ("{", '{"k": 1, "x": 2,}', '{"k": {\'a\': 1}}', '{"k": 1}{"k": 2}')
        with pytest.raises(ValueError, match=f" line {line}" + (re.escape(hint) + ", delete it$" if lone else "$")):
            _read(path)
    else:
        with pytest.warns(UserWarning, match="cut short"):
            assert _read(path) == [{"k": 1}]
    assert path.read_text() == text


def test_a_failed_append_leaves_the_file_as_it_was(tmp_path, monkeypatch):
    """An append that fails part way (a full disk) is taken back: the file keeps its records and no part line."""
    path = tmp_path / "r.jsonl"
    for i in (1, 2):
        _put(path, _rec(i))
    before, real = path.read_bytes(), os.write

    def half(fd, data):
        real(fd, data[:len(data) // 2])
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(outfiles.os, "write", half)
    with pytest.raises(OSError, match="No space left"):
        _put(path, _rec(3))
    monkeypatch.undo()
    assert path.read_bytes() == before


def test_a_cached_read_is_the_plain_one_whatever_became_of_the_file(tmp_path):
    """read_records with a ReadCache parses only what was appended since its last read, and gives what a plain read
    gives after any change: appends, an earlier line changed in place (a hand edit: kept, or made bad and refused),
    a file cut shorter, a byte-order mark, a last line without its newline or cut short."""
    path, cache, checked = tmp_path / "r.jsonl", outfiles.ReadCache(), []
    lines = [dumps(_rec(i)) + "\n" for i in range(5)]

    def both(n_parsed=None):
        checked.clear()
        got = _read(path, cache=cache, check=checked.append)
        assert got == _read(path)
        if n_parsed is not None:
            assert len(checked) == n_parsed
        return got

    path.write_text("".join(lines[:3]))
    assert both(3) == [_rec(0), _rec(1), _rec(2)]
    with open(path, "a") as f:
        f.write(lines[3])
    assert both(1)[-1] == _rec(3)
    assert both(0) == [_rec(i) for i in range(4)]
    path.write_text("".join(lines[:4]).replace('"k": 1', '"k": 7'))  # same length, same inode
    assert both(4)[1] == _rec(7)
    path.write_text("".join(lines[:4]).replace('"k": 1', '"j": 1'))
    with pytest.raises(ValueError, match=" line 2$"):
        _read(path, cache=cache)
    path.write_text("".join(lines[:2]))
    assert both(2) == [_rec(0), _rec(1)]
    path.write_bytes(b"\xef\xbb\xbf" + "".join(lines[:3]).encode())  # the mark is not a line, nor the bytes read
    assert both(1) == [_rec(0), _rec(1), _rec(2)]
    with open(path, "a") as f:
        f.write(lines[3].strip())
    assert both(1)[-1] == _rec(3)
    with open(path, "a") as f:
        f.write("\n" + lines[4][:10])
    with pytest.warns(UserWarning, match="line 5 is a record whose write was cut short"):
        assert both(1) == [_rec(i) for i in range(4)]


def test_lines_ended_by_a_carriage_return_alone_are_lines(tmp_path):
    """A file whose lines end in a bare CR (or mixes them) is read line by line, as text mode reads it, and the next
    record is appended after its last line: its records were taken for one record cut short, skipped and then
    removed by the next write (a review)."""
    path = tmp_path / "r.jsonl"
    path.write_bytes("".join(dumps(_rec(i)) + "\r" for i in range(3)).encode())
    assert _read(path) == [_rec(0), _rec(1), _rec(2)]
    _put(path, _rec(3))
    assert _read(path) == [_rec(i) for i in range(4)]
    path.write_bytes((dumps(_rec(0)) + "\n" + dumps(_rec(1)) + "\r" + dumps(_rec(2))).encode())
    assert _read(path) == [_rec(0), _rec(1), _rec(2)]
    _put(path, _rec(3))
    assert _read(path) == [_rec(i) for i in range(4)]


def test_the_writability_probe_never_removes_a_record_written_meanwhile(tmp_path, monkeypatch):
    """check_writable makes and removes a probe file under a new results file's own name.  A sweep that appended its
    first record to it meanwhile lost that record when the probe was removed (a review: the probe's inode was
    checked, but an append keeps it).  The probe is made under the file's lock, and removed only while empty."""
    path = str(tmp_path / "r.jsonl")
    real = os.fstat

    def fstat_with_a_write(fd):  # another writer's first record, as between the probe's making and removal
        with open(path, "ab") as f:
            f.write((dumps(_rec(1)) + "\n").encode())
        return real(fd)

    monkeypatch.setattr(outfiles.os, "fstat", fstat_with_a_write)
    outfiles.check_writable(path)
    monkeypatch.undo()
    assert _read(path) == [_rec(1)]


def test_a_ctrl_c_inside_the_lock_releases_it(tmp_path, monkeypatch):
    """A Ctrl-C that came after the flock but before the locked block began (in the stale-file sweep) left the lock
    held by a leaked descriptor: every reader and writer of the directory, this process's next one too, then waited
    for ever (a review).  The lock is released however the block is left, and the thread's count is reset."""
    import subprocess
    import sys

    if outfiles.fcntl is None:
        pytest.skip("no flock here")
    path = str(tmp_path / "r.jsonl")

    def interrupted(p):
        raise KeyboardInterrupt

    monkeypatch.setattr(outfiles, "_drop_stale_tmp", interrupted)
    with pytest.raises(KeyboardInterrupt):
        with outfiles.locked(path):
            pytest.fail("the block ran")
    monkeypatch.undo()
    code = ("import fcntl, os, sys; fd = os.open(sys.argv[1], os.O_RDONLY); "
            "fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB); print('free')")
    got = subprocess.run([sys.executable, "-c", code, str(tmp_path)], capture_output=True, text=True, timeout=60)
    assert got.stdout.strip() == "free", got.stderr
    _put(path, _rec(1))  # and this thread locks it again
    assert _read(path) == [_rec(1)]


def test_a_ctrl_c_during_the_write_acts_after_it_without_a_word(tmp_path, capsys):
    """A Ctrl-C once the lock is held (here in ``done()``, the caller's bookkeeping of the write): the record is
    written and counted, the KeyboardInterrupt comes after, and nothing is said (it said "writing ... first;
    interrupt again to drop it" with nothing left to drop: a review)."""
    import signal

    done = []

    def count():
        signal.raise_signal(signal.SIGINT)
        done.append(1)

    with pytest.raises(KeyboardInterrupt):
        outfiles.put_record(str(tmp_path / "r.jsonl"), {"a": 1}, lambda old: False, lambda p: [], done=count)
    assert done == [1] and (tmp_path / "r.jsonl").read_text() == '{"a": 1}\n' and capsys.readouterr().err == ""
