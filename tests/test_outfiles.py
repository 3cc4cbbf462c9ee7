"""Output files (dryfric_jax.outfiles): strict JSON that reads back, and the line a refusal names."""
import json
import math
import os
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


def test_a_killed_writes_temporary_file_is_removed_by_the_next_locked_write(tmp_path, monkeypatch):
    """A SIGKILL between write_atomic's creating and renaming its temporary file left it beside the results, a
    whole copy of them, one more per kill (an audit: 10 MB each).  The next write under the file's lock removes
    those of that file, and those of the older unnamed kind, older than STALE_TMP_S (a live write takes seconds;
    the age spares another host's writer where the lock is per host: a review); another file's are left alone."""
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


def test_a_ctrl_c_breaks_the_wait_for_the_lock(tmp_path):
    """put_record holds a Ctrl-C during its write, but not while it waits for the lock: held over the wait, a
    process waiting on a stuck lock (another sweep stopped with Ctrl-Z) could not be interrupted (a review)."""
    import signal
    import subprocess
    import sys
    import threading
    import time

    if outfiles.fcntl is None:
        pytest.skip("no flock here")
    holder = subprocess.Popen([sys.executable, "-c", "import fcntl, os, sys, time; fd = os.open(sys.argv[1], "
                               "os.O_RDONLY); fcntl.flock(fd, fcntl.LOCK_EX); print('held', flush=True); "
                               "time.sleep(20)", str(tmp_path)], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        main = threading.main_thread().ident  # to the thread waiting in flock, as a terminal's Ctrl-C reaches it
        timer = threading.Timer(0.3, lambda: signal.pthread_kill(main, signal.SIGINT))
        t0 = time.monotonic()
        timer.start()
        with pytest.raises(KeyboardInterrupt):
            outfiles.put_record(str(tmp_path / "r.jsonl"), {"a": 1}, lambda old: False, lambda p: [])
        assert time.monotonic() - t0 < 10 and not (tmp_path / "r.jsonl").exists()
    finally:
        holder.kill()
        holder.wait()
