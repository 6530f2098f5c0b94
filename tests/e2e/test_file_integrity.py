"""What a run or a study may write over, and what its readers find in a damaged file (issue 41,
items 5, 6, 8 and 9). Each test failed on the code before:

- an h5py file of another program at &output file was replaced without `overwrite` (exit 0); it
  is now kept, even with `overwrite`, and the run refused (exit 2);
- eme_run wrote into a running study's folder (its case file, its index.h5); a lock file removed
  during a run let a second writer in and both died, and a run that lost its lock unlinked the
  next writer's at its exit; now a study's folder is the study's, a lost lock is noticed by its
  holder before its next write, and no process removes a lock file it does not hold;
- a continuation killed at a file operation left FILE.part saying the status of the run it
  continued ('incomplete: the step budget is spent ...'); it now says 'incomplete: running';
- a 1-step run's per-step datasets (one value each) had no checksum, and no text had any: a
  flipped byte read as another number or text; -eme_continue from a damaged file blamed a write.
  Now every dataset that holds a value has its Fletcher-32 checksum, every variable-length text
  is under the root attribute text_checksum (CRC-32: docs/output.md, Checksums), and the readers
  (summarize_runs.py and the scripts, a study's restart, -eme_continue) refuse a damaged file,
  naming it.

No test depends on timing: the writers are stopped or killed at chosen file operations by the
LD_PRELOAD shim kill_at_write.c, and writes fall due by rows (EME_WRITE_EVERY_ROWS)."""
import fcntl
import io
import os
import re
import shutil
import signal
import subprocess
import sys

import h5py
import numpy as np
import pytest

from conftest import BIN, ROOT, namelist_text
from faults import check_run_file, shim_library

sys.path.insert(0, str(ROOT / "postprocess"))
from file_checksums import DamagedFileError, check_texts, text_checksum  # noqa: E402
from summarize_runs import OPTIONAL, POINT_DATASETS, STEP_DATASETS  # noqa: E402

SUMMARIZE = ROOT / "postprocess" / "summarize_runs.py"
SHORT = {"integrator": {"scheme": "eme", "dt": 0.15, "t_end": 0.3}}
LONG = "&integrator dt=0.001, t_end=60 /\n&output file='same.h5' /\n"            # 60,000 steps
LONG_OTHER = "&integrator dt=0.001, t_end=60, scheme='midpoint' /\n&output file='same.h5' /\n"


def eme_run(folder, *arguments, env=None):
    return subprocess.run([str(BIN / "eme_run"), *arguments], cwd=folder, capture_output=True, text=True,
                          timeout=600, env=env)


def ensemble(folder, study="study.nml"):
    return subprocess.run([str(BIN / "eme_ensemble"), study], cwd=folder, capture_output=True, text=True,
                          timeout=600)


def listing(folder):
    """Every file under `folder` with its bytes."""
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def summarize(path):
    return subprocess.run([sys.executable, str(SUMMARIZE), str(path)], capture_output=True, text=True, timeout=120)


def shim(folder, **settings):
    """The environment of a writer under the shim: its file operations in `folder` counted."""
    return dict(os.environ, LD_PRELOAD=str(shim_library("kill_at_write")), EME_KILL_DIR=str(folder),
                **{key: str(value) for key, value in settings.items()})


def stopped(command, folder, cwd, stop_at, **settings):
    """`command` started under the shim, stopped (SIGSTOP) before its `stop_at`-th file operation
    in `folder`; returned once it has stopped."""
    process = subprocess.Popen(command, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               env=shim(folder, EME_KILL_AT=stop_at, EME_KILL_SIGNAL=int(signal.SIGSTOP), **settings))
    _, status = os.waitpid(process.pid, os.WUNTRACED)
    assert os.WIFSTOPPED(status), f"{command} ended before its file operation {stop_at}"
    return process


def operations(command, folder, log, **settings):
    """The file operations in `folder` of `command`, run whole under the shim: {number: name} (the
    log's lines are "number name path [other path]")."""
    result = subprocess.run(command, cwd=folder, capture_output=True, text=True, timeout=600,
                            env=shim(folder, EME_KILL_LOG=log, **settings))
    assert result.returncode in (0, 3), result.stderr
    return {int(fields[0]): fields[1] for fields in (line.split() for line in log.read_text().splitlines())}


def lock_is_held(path):
    """Whether another process holds the flock of the file at `path`."""
    with open(path, "rb") as probe:
        try:
            fcntl.flock(probe, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            return True
        fcntl.flock(probe, fcntl.LOCK_UN)
    return False


# ------------------------------------------------------------------ item 5: a foreign HDF5 file

@pytest.mark.parametrize("overwrite", [[], ["-eme_overwrite"]])
@pytest.mark.parametrize("kind", ["h5py file", "study index"])
def test_an_hdf5_file_that_is_not_a_run_file_is_never_replaced(tmp_path, kind, overwrite):
    output = tmp_path / "o.h5"
    if kind == "h5py file":
        with h5py.File(output, "w") as f:
            f["measurements"] = np.arange(5.0)
    else:
        (tmp_path / "base.nml").write_text(namelist_text(SHORT))
        (tmp_path / "study.nml").write_text("&study base = 'base.nml', output_dir = 'out', index_only = .true. /\n"
                                            "&sweep field = 'dt', values = 0.15 /\n")
        assert ensemble(tmp_path).returncode == 0
        shutil.move(tmp_path / "out" / "index.h5", output)
    (tmp_path / "run.nml").write_text(namelist_text({**SHORT, "output": {"file": "o.h5"}}))
    before = listing(tmp_path)
    result = eme_run(tmp_path, "run.nml", *overwrite)
    assert result.returncode == 2, result.stderr
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and "'o.h5' is an HDF5 file that is not an eme run file" in lines[0], result.stderr
    assert listing(tmp_path) == before


def test_a_run_file_is_still_replaced_as_before(tmp_path):
    """An incomplete run file is replaced; a complete one only with overwrite."""
    (tmp_path / "run.nml").write_text(namelist_text({**SHORT, "output": {"file": "o.h5"}}))
    assert eme_run(tmp_path, "run.nml").returncode == 0
    with h5py.File(tmp_path / "o.h5", "r+") as f:
        f.attrs["status"] = "incomplete: running"
    assert eme_run(tmp_path, "run.nml").returncode == 0
    assert eme_run(tmp_path, "run.nml").returncode == 2
    assert eme_run(tmp_path, "run.nml", "-eme_overwrite").returncode == 0


# ------------------------------------------------------------------ item 6: a study's folder and the locks

STUDY = """&study base = 'base.nml', output_dir = 'out' /
&sweep field = 'dt', values = 0.15, 0.1 /
"""


def make_study(folder):
    (folder / "base.nml").write_text(namelist_text(SHORT))
    (folder / "study.nml").write_text(STUDY)


def test_eme_run_into_a_running_studys_case_file_is_refused(tmp_path):
    """The study is stopped once it holds out/study.lock; eme_run onto its case_00001.h5 (with
    overwrite) is refused and writes nothing; the study then finishes every case."""
    make_study(tmp_path)
    (tmp_path / "out").mkdir()
    study = stopped([str(BIN / "eme_ensemble"), "study.nml"], tmp_path / "out", tmp_path, stop_at=3)
    try:
        (tmp_path / "case.nml").write_text(namelist_text({**SHORT, "output": {"file": "out/case_00001.h5"}}))
        before = listing(tmp_path)
        result = eme_run(tmp_path, "case.nml", "-eme_overwrite")
        after = listing(tmp_path)
    finally:
        study.send_signal(signal.SIGCONT)
    out, err = study.communicate(timeout=600)
    assert result.returncode == 2 and "output folder of a study" in result.stderr, result.stderr
    assert after == before
    assert study.returncode == 0, err
    with h5py.File(tmp_path / "out" / "index.h5", "r") as f:
        assert [status.decode() for status in f["cases"]["status"]] == ["complete", "complete"]


def test_eme_run_onto_a_studys_index_is_refused(tmp_path):
    make_study(tmp_path)
    assert ensemble(tmp_path).returncode == 0
    (tmp_path / "index.nml").write_text(namelist_text({**SHORT, "output": {"file": "out/index.h5"}}))
    before = listing(tmp_path)
    for overwrite in ([], ["-eme_overwrite"]):
        result = eme_run(tmp_path, "index.nml", *overwrite)
        assert result.returncode == 2, result.stderr
        assert "out/index.h5" in result.stderr
    assert listing(tmp_path) == before


@pytest.fixture(scope="module")
def first_exchange(tmp_path_factory):
    """The number of the first name exchange (renameat2) among the file operations of the long
    run, its writes due every 15,000 rows: a writer stopped there is between two writes' checks."""
    folder = tmp_path_factory.mktemp("sequence")
    (folder / "a.nml").write_text(LONG)
    sequence = operations([str(BIN / "eme_run"), "a.nml"], folder, folder.parent / "sequence.log",
                          EME_WRITE_EVERY_ROWS=15000)
    return min(number for number, name in sequence.items() if name == "renameat2")


def test_a_lock_removed_during_a_run_is_noticed_and_the_file_marked(tmp_path, first_exchange):
    (tmp_path / "a.nml").write_text(LONG)
    first = stopped([str(BIN / "eme_run"), "a.nml"], tmp_path, tmp_path, first_exchange, EME_WRITE_EVERY_ROWS=15000)
    (tmp_path / "same.h5.lock").unlink()
    first.send_signal(signal.SIGCONT)
    out, err = first.communicate(timeout=600)
    assert first.returncode == 1, err
    assert "same.h5.lock was removed" in err and "took the lock again" in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.nml", "same.h5"]
    status, steps = check_run_file(tmp_path / "same.h5")
    assert status == "incomplete: the lock same.h5.lock was removed while the run wrote"
    assert 15000 <= steps < 60000


def test_a_lock_taken_by_a_second_writer_stops_the_first_which_leaves_it_alone(tmp_path, first_exchange):
    """The lock file is removed while the first run is between two writes, and a second run of the
    same file takes a new one: the first stops at its next write, writing nothing more, and does
    not remove the second's lock as it exits; the second finishes its run alone."""
    (tmp_path / "a.nml").write_text(LONG)
    (tmp_path / "b.nml").write_text(LONG_OTHER)
    first = stopped([str(BIN / "eme_run"), "a.nml"], tmp_path, tmp_path, first_exchange, EME_WRITE_EVERY_ROWS=15000)
    (tmp_path / "same.h5.lock").unlink()
    second = stopped([str(BIN / "eme_run"), "b.nml"], tmp_path, tmp_path, 3, EME_WRITE_EVERY_ROWS=15000)
    try:
        first.send_signal(signal.SIGCONT)
        out, err = first.communicate(timeout=600)
        lock = tmp_path / "same.h5.lock"
        assert lock.exists() and lock_is_held(lock), "the first run removed the second's lock"
        assert f"process {second.pid} " in lock.read_text()
    finally:
        second.send_signal(signal.SIGCONT)
    second_out, second_err = second.communicate(timeout=600)
    assert first.returncode == 1, err
    assert "was replaced" in err and f"process {second.pid}" in err and "writes nothing more" in err, err
    assert second.returncode == 0, second_err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.nml", "b.nml", "same.h5"]
    assert check_run_file(tmp_path / "same.h5") == ("complete", 60000)
    with h5py.File(tmp_path / "same.h5", "r") as f:
        assert f.attrs["scheme"] == "midpoint" and f.attrs["input_file"] == "b.nml"


def test_a_study_whose_lock_is_taken_stops_and_leaves_it_alone(tmp_path):
    """A study stopped once it holds out/study.lock; the file is removed and another process takes
    a new one: the study notices as it records its first case, starts no other, exits 1 and
    leaves the other's lock as it is."""
    make_study(tmp_path)
    (tmp_path / "out").mkdir()
    study = stopped([str(BIN / "eme_ensemble"), "study.nml"], tmp_path / "out", tmp_path, stop_at=3)
    lock = tmp_path / "out" / "study.lock"
    lock.unlink()
    with open(lock, "w") as other:
        other.write("process 1 on host elsewhere\n")
        other.flush()
        fcntl.flock(other, fcntl.LOCK_EX | fcntl.LOCK_NB)
        study.send_signal(signal.SIGCONT)
        out, err = study.communicate(timeout=600)
        assert lock.read_text() == "process 1 on host elsewhere\n"
    assert study.returncode == 1, err
    assert "study.lock was replaced" in out + err and "process 1 on host elsewhere" in out + err, out + err


# ------------------------------------------------------------------ item 8: a continuation's status

def test_a_continuation_killed_between_writes_says_running(tmp_path):
    """A run stopped by its step budget (5,000 adaptive steps) is continued with writes every
    1,500 rows and killed before its second and its third exchange of names: FILE.part, grown
    by the continuation, says 'incomplete: running' (failure_kind 'none'), not the budget."""
    integrator = {"scheme": "eme", "dt": 0.01, "t_end": 100.0, "tolerance": 1e-6}
    namelist = tmp_path / "run.nml"
    namelist.write_text(namelist_text({"integrator": {**integrator, "max_steps": 5000}, "output": {"file": "run.h5"}}))
    stopped_run = eme_run(tmp_path, "run.nml")
    assert stopped_run.returncode == 3, stopped_run.stderr
    budget = tmp_path.parent / f"{tmp_path.name}-budget.h5"
    shutil.copy(tmp_path / "run.h5", budget)
    namelist.write_text(namelist_text({"integrator": {**integrator, "max_steps": 30000}, "output": {"file": "run.h5"}}))
    sequence = operations([str(BIN / "eme_run"), "run.nml", "-eme_continue"], tmp_path, tmp_path.parent / "ops.log",
                          EME_WRITE_EVERY_ROWS=1500)
    exchanges = sorted(number for number, name in sequence.items() if name == "renameat2")
    assert len(exchanges) >= 3
    for kill_at in exchanges[1:3]:
        for p in tmp_path.glob("run.h5*"):
            p.unlink()
        shutil.copy(budget, tmp_path / "run.h5")
        killed = subprocess.run([str(BIN / "eme_run"), "run.nml", "-eme_continue"], cwd=tmp_path, capture_output=True,
                                timeout=600, env=shim(tmp_path, EME_KILL_AT=kill_at, EME_WRITE_EVERY_ROWS=1500))
        assert killed.returncode == -signal.SIGKILL
        status, steps = check_run_file(tmp_path / "run.h5.part")
        assert steps > 5000
        with h5py.File(tmp_path / "run.h5.part", "r") as f:
            assert (status, f.attrs["failure_kind"]) == ("incomplete: running", "none"), kill_at


# ------------------------------------------------------------------ item 9: checksums

def one_step_run(folder):
    (folder / "one.nml").write_text(namelist_text({"integrator": {"scheme": "eme", "dt": 0.15, "t_end": 0.15},
                                                   "output": {"file": "one.h5"}}))
    result = eme_run(folder, "one.nml")
    assert result.returncode == 0, result.stderr
    return folder / "one.h5"


def flip_chunk_byte(path, dataset, at=None):
    """Flips one bit inside the (only) chunk of `dataset`'s values (in its middle by default)."""
    with h5py.File(path, "r") as f:
        chunk = f[dataset].id.get_chunk_info(0)
    data = bytearray(path.read_bytes())
    data[chunk.byte_offset + (chunk.size // 2 if at is None else at)] ^= 0x10
    path.write_bytes(bytes(data))


def test_every_dataset_of_one_value_has_its_checksum(tmp_path):
    """A 1-step run: each per-step dataset holds one value; a flipped byte in any of them fails
    its read, and summarize_runs.py, for those it reads (min dS among them), exits 2 naming the
    file instead of printing another number."""
    path = one_step_run(tmp_path)
    with h5py.File(path, "r") as f:
        numeric = [name for name in f if f[name].dtype.kind in "fiu"]
        single = [name for name in numeric if f[name].size == 1]
        assert all(f[name].fletcher32 and f[name].chunks for name in numeric)
    assert len(single) >= 12 and "min_entropy_increment" in single
    for name in single:
        damaged = tmp_path / f"damaged_{name}.h5"
        shutil.copy(path, damaged)
        flip_chunk_byte(damaged, name, at=1)
        with h5py.File(damaged, "r") as f:
            with pytest.raises(OSError, match="Fletcher32"):
                f[name][()]
        if name in (*POINT_DATASETS, *STEP_DATASETS, *OPTIONAL):
            result = summarize(damaged)
            assert result.returncode == 2 and str(damaged) in result.stderr, (name, result.stdout, result.stderr)


def heap_objects(data):
    """(offset, size) of the data of every object of the file's global heap collections, read by
    the HDF5 file format specification (III.E: 'GCOL', version, 3 reserved bytes, the collection's
    size; then objects: index (0: free space), reference count, 4 reserved bytes, size, the data
    padded to 8 bytes)."""
    found = []
    at = data.find(b"GCOL")
    while at >= 0:
        end = at + int.from_bytes(data[at + 8:at + 16], "little")
        cursor = at + 16
        while cursor + 16 <= end and int.from_bytes(data[cursor:cursor + 2], "little") != 0:
            size = int.from_bytes(data[cursor + 8:cursor + 16], "little")
            found.append((cursor + 16, size))
            cursor += 16 + (size + 7) // 8 * 8
        at = data.find(b"GCOL", end)
    return found


def texts(handle):
    """Every variable-length text of an open file as h5py reads it: {(object, attribute): values}."""
    result = {}
    for object_name, item in [("/", handle), *handle.items()]:
        for name, value in item.attrs.items():
            if h5py.check_string_dtype(item.attrs.get_id(name).dtype) is not None:
                result[object_name, name] = repr(value)
        if isinstance(item, h5py.Dataset) and h5py.check_string_dtype(item.dtype) is not None:
            result[object_name, ""] = repr(item[()])
    return result


def test_a_flipped_byte_in_any_text_fails_the_checksum(tmp_path):
    """Each object of the global heap of a run file, flipped in turn: wherever the texts h5py
    reads change (status, failure_kind, namelist, units, columns, the column names' scales, ...),
    the reader's check of text_checksum refuses the file; the undamaged file passes it."""
    path = one_step_run(tmp_path)
    data = path.read_bytes()
    with h5py.File(path, "r") as f:
        original = texts(f)
        assert text_checksum(f) == int(f.attrs["text_checksum"])
        check_texts(f, path)
    changed = caught = 0
    for offset, size in heap_objects(data):
        if size == 0:
            continue
        damaged = bytearray(data)
        damaged[offset + size // 2] ^= 0x01
        with h5py.File(io.BytesIO(bytes(damaged)), "r") as f:
            try:
                if texts(f) == original:
                    continue                  # not a text: a dimension scale's references
                changed += 1
                check_texts(f, path)
            except (DamagedFileError, OSError, UnicodeDecodeError):
                caught += 1
    assert changed > 150 and caught == changed, (changed, caught)


def object_headers(data):
    """(offset, size) of the messages of every version-2 object header of the file, read by the
    HDF5 file format specification (IV.A.1.b: 'OHDR', version, flags; the times if flags bit 5,
    the attribute phase change values if bit 4; the size of chunk 0 in 1 << (flags & 3) bytes;
    the messages)."""
    found = []
    for match in re.finditer(b"OHDR", data):
        flags = data[match.start() + 5]
        cursor = match.start() + 6 + (16 if flags & 0x20 else 0) + (4 if flags & 0x10 else 0)
        width = 1 << (flags & 0x03)
        found.append((cursor + width, int.from_bytes(data[cursor:cursor + width], "little")))
    return found


def test_a_damaged_object_header_is_refused_as_damage(tmp_path):
    """A flipped bit in the messages of any object header: the file does not open, or the check
    of its texts, which opens every object, raises DamagedFileError naming the file (before, an
    object h5py could not open came as None and the check died of an AttributeError: a traceback
    and exit 1 from summarize_runs.py); summarize_runs.py exits 2 naming the file."""
    path = one_step_run(tmp_path)
    data = path.read_bytes()
    headers = object_headers(data)
    refused = 0
    for offset, size in headers:
        damaged = bytearray(data)
        damaged[offset + size // 2] ^= 0x01
        try:
            handle = h5py.File(io.BytesIO(bytes(damaged)), "r")
        except OSError:
            continue                         # the root group's: the file does not open
        with handle:
            with pytest.raises(DamagedFileError, match=str(path)):
                check_texts(handle, path)
        refused += 1
        if refused == 1:
            copy = tmp_path / "damaged_header.h5"
            copy.write_bytes(bytes(damaged))
            result = summarize(copy)
            assert result.returncode == 2 and str(copy) in result.stderr, result.stderr
    assert len(headers) >= 25 and refused >= len(headers) - 1, (len(headers), refused)


def test_summarize_and_a_study_refuse_a_damaged_text(tmp_path):
    """The status of a run file, the namelist of a study's case file and case_1_input of its index,
    each with a flipped byte: summarize_runs.py exits 2 naming the file and the checksum; the
    study's restart runs that case again and rebuilds the index from the case files."""
    path = one_step_run(tmp_path)
    flip_text_byte(path, b"complete")
    result = summarize(path)
    assert result.returncode == 2 and str(path) in result.stderr and "checksum" in result.stderr, result.stderr
    make_study(tmp_path)
    assert ensemble(tmp_path).returncode == 0
    out = tmp_path / "out"
    with h5py.File(out / "case_00002.h5", "r") as f:
        namelist = f.attrs["namelist"].encode()
    with h5py.File(out / "index.h5", "r") as f:
        case_1_input = f.attrs["case_1_input"].encode()
    before = {p.name: p.stat().st_ino for p in out.glob("case_*.h5")}
    flip_text_byte(out / "case_00002.h5", namelist)
    flip_text_byte(out / "index.h5", case_1_input)
    again = ensemble(tmp_path)
    assert again.returncode == 0, again.stderr
    assert "rebuilt" in again.stdout and "1 to run" in again.stdout, again.stdout
    after = {p.name: p.stat().st_ino for p in out.glob("case_*.h5")}
    assert after["case_00001.h5"] == before["case_00001.h5"] and after["case_00002.h5"] != before["case_00002.h5"]
    with h5py.File(out / "index.h5", "r") as f:
        check_texts(f, out / "index.h5")
        assert [status.decode() for status in f["cases"]["status"]] == ["complete", "complete"]


def flip_text_byte(path, text):
    """Flips one bit in the middle of the global heap object that holds `text` (its only one)."""
    data = bytearray(path.read_bytes())
    (offset,) = [offset for offset, size in heap_objects(data) if data[offset:offset + size] == text]
    data[offset + len(text) // 2] ^= 0x01
    path.write_bytes(bytes(data))


def test_the_step_checks_records_are_under_the_checksums(tmp_path):
    """What every accepted step's check writes (docs/faults.md, Every accepted step checked): a
    flipped bit in the values of /balance or /resolved fails their read (Fletcher-32); in the
    stored value of a numeric root attribute of the check (balance_bound_ulps, balance_max_ulps,
    resume_balances), the attribute's read (the checksum of HDF5 1.8's attribute storage); in
    balance_guarantees, the check of text_checksum."""
    path = one_step_run(tmp_path)
    with h5py.File(path, "r") as f:
        assert f["balance"].shape == (1, 4) and f["resolved"].shape == (1,)
        attributes = {name: f.attrs[name] for name in ("balance_bound_ulps", "balance_max_ulps", "resume_balances")}
        guarantees = f.attrs["balance_guarantees"].encode()
    for name in ("balance", "resolved"):
        damaged = tmp_path / f"damaged_{name}.h5"
        shutil.copy(path, damaged)
        flip_chunk_byte(damaged, name, at=1)
        with h5py.File(damaged, "r") as f:
            with pytest.raises(OSError, match="Fletcher32"):
                f[name][()]
    data = path.read_bytes()
    for name, value in attributes.items():
        stored = np.asarray(value, dtype="<f8").tobytes()
        places = [match.start() for match in re.finditer(re.escape(stored), data)]
        refused = 0
        for at in places:                 # the attribute's bytes, and stale copies in free space
            damaged = bytearray(data)
            damaged[at + 3] ^= 0x10
            with h5py.File(io.BytesIO(bytes(damaged)), "r") as f:
                try:
                    read = f.attrs[name]
                except (OSError, KeyError):
                    refused += 1
                    continue
            assert np.array_equal(read, value), (name, at, read)
        assert places and refused >= 1, (name, places)
    changed = 0
    for offset, size in heap_objects(data):      # the text's heap object, and stale copies
        if data[offset:offset + size] != guarantees:
            continue
        damaged = bytearray(data)
        damaged[offset + size // 2] ^= 0x01
        with h5py.File(io.BytesIO(bytes(damaged)), "r") as f:
            if f.attrs["balance_guarantees"].encode() == guarantees:
                continue
            changed += 1
            with pytest.raises(DamagedFileError, match="text_checksum"):
                check_texts(f, path)
    assert changed == 1


def test_a_study_case_whose_balance_is_damaged_runs_again(tmp_path):
    """A study's restart reads each complete case file whole: a flipped bit in case_00001.h5's
    /balance makes that case run again, and only that one."""
    make_study(tmp_path)
    assert ensemble(tmp_path).returncode == 0
    out = tmp_path / "out"
    before = {p.name: p.stat().st_ino for p in out.glob("case_*.h5")}
    flip_chunk_byte(out / "case_00001.h5", "balance", at=1)
    again = ensemble(tmp_path)
    assert again.returncode == 0, again.stderr
    assert "1 to run" in again.stdout, again.stdout
    after = {p.name: p.stat().st_ino for p in out.glob("case_*.h5")}
    assert after["case_00001.h5"] != before["case_00001.h5"] and after["case_00002.h5"] == before["case_00002.h5"]
    with h5py.File(out / "case_00001.h5", "r") as f:
        f["balance"][()]


@pytest.mark.parametrize("damage", ["a chunk", "a balance chunk", "a text"])
def test_continuing_a_damaged_file_names_it_as_the_input(tmp_path, damage):
    """-eme_continue from a file with a damaged chunk (or text) is refused with exit 2 and one line
    naming that file as damaged, not as a write that failed; the file is left as it was."""
    integrator = {"scheme": "eme", "dt": 0.01, "t_end": 20.0, "tolerance": 1e-6}
    namelist = tmp_path / "run.nml"
    namelist.write_text(namelist_text({"integrator": {**integrator, "max_steps": 300}, "output": {"file": "run.h5"}}))
    assert eme_run(tmp_path, "run.nml").returncode == 3
    if damage == "a chunk":
        flip_chunk_byte(tmp_path / "run.h5", "state")
    elif damage == "a balance chunk":
        flip_chunk_byte(tmp_path / "run.h5", "balance")
    else:
        with h5py.File(tmp_path / "run.h5", "r") as f:
            flip_text_byte(tmp_path / "run.h5", f.attrs["namelist"].encode())
    namelist.write_text(namelist_text({"integrator": {**integrator, "max_steps": 600}, "output": {"file": "run.h5"}}))
    before = listing(tmp_path)
    result = eme_run(tmp_path, "run.nml", "-eme_continue")
    assert result.returncode == 2, result.stderr
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("eme_run: run.h5: a ") and "damaged" in lines[0], result.stderr
    assert "cannot write" not in result.stderr
    assert listing(tmp_path) == before
