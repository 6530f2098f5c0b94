"""A SIGKILL between any two of a run's file operations. The LD_PRELOAD shim kill_at_write.c
kills eme_run just before its K-th operation on the output folder (a write, a rename, ...), so a
kill at that instant is reproduced exactly, without timing luck. Whatever K: the final name is
taken only by a complete file; otherwise FILE.part exists from the first write on; and whichever
file is there reads back with h5py, its points and steps agree in length, and its rows are the
first rows of the uninterrupted run, bit for bit.

The run (40,000 EME steps) makes its first write and then two windows, each of which appends
rows to the spare copy and exchanges the names (src/run/run_output.f90). Writes fall due every
15,000 rows here (the testing hook EME_WRITE_EVERY_ROWS), not by the clock: the killed runs must
meet the uninterrupted run's sequence of operations however busy the machine is. Before the spare copy,
windows wrote FILE.part in place, and 72 of the 189 kill points left it unreadable ('addr
overflow') or with datasets longer than its step_rows. The exchange is tested as the file
systems offer it: renameat2 RENAME_EXCHANGE, the hard link of NFS and Lustre (no exchange), and
the copy of file systems without hard links."""
import os
import subprocess
from concurrent.futures import ThreadPoolExecutor

import h5py
import numpy as np
import pytest

from conftest import BIN, namelist_text
from faults import check_run_file, shim_library

RUN = {"dt": 0.05, "t_end": 2000.0}
WRITE_EVERY_ROWS = "15000"
COMPARED = ["time", "state", "temperature", "energy", "newton_iterations", "converged_reason"]
FILE_SYSTEMS = {"exchange": {}, "hard link": {"EME_KILL_NO_EXCHANGE": "1"},
                "copy": {"EME_KILL_NO_EXCHANGE": "1", "EME_KILL_NO_LINK": "1"}}


def run_folder(base, label):
    """The folder `label` under `base`, its name padded to one length for every run: the file
    keeps its input's path (attributes input_file, command_line, ...), and a longer path changes
    how many writes HDF5 makes for its metadata (78 instead of 79 in the last window, from 55
    characters on), which would move the kill points."""
    return base / label.ljust(24, "_")


def run_killed(folder, at=None, log=None, extra=None, slow=False):
    """Runs eme_run with its output in `folder` (emptied first), killed before its `at`-th file
    operation there (with `slow`, on a machine that seems 100 times slower: the LD_PRELOAD shim
    fast_clock.c); the return code and the output path."""
    folder.mkdir(parents=True, exist_ok=True)
    for old in folder.iterdir():
        old.unlink()
    output = folder / "run.h5"
    namelist = folder.with_suffix(".nml")
    namelist.write_text(namelist_text({"integrator": RUN, "output": {"file": str(output)}}))
    shims = [shim_library("fast_clock")] if slow else []
    shims.append(shim_library("kill_at_write"))
    env = dict(os.environ, LD_PRELOAD=":".join(str(shim) for shim in shims), EME_KILL_DIR=str(folder),
               EME_WRITE_EVERY_ROWS=WRITE_EVERY_ROWS, **(extra or {}))
    if at is not None:
        env["EME_KILL_AT"] = str(at)
    if log is not None:
        env["EME_KILL_LOG"] = str(log)
    result = subprocess.run([str(BIN / "eme_run"), str(namelist)], env=env, capture_output=True, text=True,
                            timeout=300)
    return result.returncode, output


def rows(path):
    with h5py.File(path, "r") as f:
        return {name: f[name][()] for name in COMPARED}


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory):
    """The rows of the run without a kill, and its file operations per file system."""
    base = tmp_path_factory.mktemp("kill_points")
    operations = {}
    for name, extra in FILE_SYSTEMS.items():
        log = base / f"{name.replace(' ', '_')}.log"
        code, output = run_killed(run_folder(base, "whole"), log=log, extra=extra)
        assert code == 0 and check_run_file(output) == ("complete", 40000)
        assert sorted(p.name for p in output.parent.iterdir()) == ["run.h5"]
        operations[name] = [line.split()[1] for line in log.read_text().splitlines()]
        reference = rows(output)
    return base, reference, operations


def kill_points(operations, count):
    """About `count` operation numbers spread over the run, and every rename, link and unlink
    with the operation after it (where the file's name changes hands)."""
    spread = set(np.linspace(1, len(operations), count).round().astype(int).tolist())
    names = {k + 1 + step for k, op in enumerate(operations) if op in ("rename", "renameat2", "link", "unlink")
             for step in (0, 1)}
    return sorted(k for k in spread | names if k <= len(operations))


@pytest.mark.parametrize("file_system,count", [("exchange", 30), ("hard link", 10), ("copy", 10)])
def test_a_kill_at_any_file_operation_leaves_a_readable_file(uninterrupted, file_system, count):
    base, reference, operations = uninterrupted
    points = kill_points(operations[file_system], count)
    assert "posix_fallocate" in operations[file_system]   # the windows were reached
    assert operations[file_system].count("renameat2" if file_system == "exchange" else "rename") >= 2

    def check(at):
        folder = run_folder(base, f"{file_system.replace(' ', '_')}_{at}")
        code, output = run_killed(folder, at=at, extra=FILE_SYSTEMS[file_system])
        assert code == -9, (at, code)
        part = output.with_name(output.name + ".part")
        if output.exists():
            found = output
            assert check_run_file(output) == ("complete", 40000), at
        elif part.exists():
            found = part
            status, steps = check_run_file(part)
            assert status in ("incomplete: running", "complete"), (at, status)
        else:                                  # killed before the first write reached its name
            assert all(p.name.endswith((".tmp", ".lock")) for p in folder.iterdir()), (at, list(folder.iterdir()))
            return at, None
        got = rows(found)
        for name in COMPARED:
            n = got[name].shape[0]
            assert n >= 1 and np.array_equal(got[name], reference[name][:n]), (at, name, n)
        return at, got["time"].shape[0] - 1

    with ThreadPoolExecutor(max_workers=2) as pool:
        outcomes = dict(pool.map(check, points))
    kept = sorted({steps for steps in outcomes.values() if steps is not None})
    # The kills land before the first write, after it, after the window and after the run.
    assert None in outcomes.values() and len(kept) >= 3 and kept[-1] == 40000, kept


def test_the_file_operations_do_not_depend_on_the_clock(uninterrupted):
    """On a machine that seems 100 times slower (its monotonic clock runs 100 times faster) the
    run makes the same file operations in the same order: the kill points above are the same on
    a loaded machine. (With writes due by the clock, 205 operations became 2385.)"""
    base, _, operations = uninterrupted
    log = base / "slow.log"
    code, output = run_killed(run_folder(base, "slow"), log=log, slow=True)
    assert code == 0 and check_run_file(output) == ("complete", 40000)
    assert [line.split()[1] for line in log.read_text().splitlines()] == operations["exchange"]
