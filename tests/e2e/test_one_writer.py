"""One writer per output (docs/faults.md): a second eme_run of the same file, or a second
eme_ensemble on the same output_dir, is refused at start with exit status 2, one line naming
the file (or folder) and the process that holds it, and nothing written, while the first goes on
to write exactly what it would have written alone. The lock is one the operating system releases
when its process dies: a SIGKILLed writer's leftovers are no obstacle, and a rerun replaces them.

No test here depends on timing. The first writer is stopped (SIGSTOP) by the LD_PRELOAD shim
kill_at_write.c at its third file operation in the output folder, which comes after it took the
lock and wrote its name into the lock file; the test waits for that stop (waitpid WUNTRACED),
starts the second writer, and lets the first go on (SIGCONT)."""
import fcntl
import os
import signal
import socket
import subprocess

import h5py
import numpy as np
import pytest

from conftest import BIN, ROOT
from faults import check_run_file, shim_library

# The reporter's two runs: 60,000 steps of EME, then of the midpoint rule, into one file.
FIRST = "&integrator dt=0.001, t_end=60 /\n&output file='same.h5' /\n"
SECOND = "&integrator dt=0.001, t_end=60, scheme='midpoint' /\n&output file='same.h5' /\n"
STOP_AT = 3                                  # the third file operation: the lock is held and named
TIMED = {"step_seconds"}                     # datasets of wall-clock times
TIMED_ATTRIBUTES = {"start_time", "end_time", "history", "wall_time_seconds", "solve_time_seconds", "cpu_time_seconds",
                    "solve_cpu_time_seconds", "text_checksum"}   # (text_checksum: the times are among its texts)


def stopped_writer(command, folder, cwd=None, stop_at=STOP_AT, signal_number=signal.SIGSTOP):
    """Starts `command` (in `cwd`, default `folder`) with the shim, which sends it `signal_number`
    before its `stop_at`-th file operation in `folder`; returns the process once it has stopped."""
    env = dict(os.environ, LD_PRELOAD=str(shim_library("kill_at_write")), EME_KILL_DIR=str(folder),
               EME_KILL_AT=str(stop_at), EME_KILL_SIGNAL=str(int(signal_number)))
    process = subprocess.Popen(command, cwd=cwd or folder, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               text=True)
    if signal_number == signal.SIGSTOP:
        _, status = os.waitpid(process.pid, os.WUNTRACED)
        assert os.WIFSTOPPED(status), f"{command} ended before its file operation {stop_at}: {status}"
    return process


def listing(folder):
    """Every file under `folder` with its size and modification time."""
    return {str(p.relative_to(folder)): (p.stat().st_size, p.stat().st_mtime_ns) for p in folder.rglob("*")}


def holder_line(process):
    return f"process {process.pid} on host {socket.gethostname()}"


def run_file(path):
    with h5py.File(path, "r") as f:
        data = {name: f[name][()] for name in f if name not in TIMED}
        attributes = {k: v for k, v in f.attrs.items() if k not in TIMED_ATTRIBUTES}
    return data, attributes


def assert_same_run(path, reference):
    data, attributes = run_file(path)
    expected_data, expected_attributes = run_file(reference)
    assert sorted(data) == sorted(expected_data)
    for name in data:
        assert np.array_equal(data[name], expected_data[name]), name
    assert sorted(attributes) == sorted(expected_attributes)
    for name in attributes:
        assert np.array_equal(attributes[name], expected_attributes[name]), name


def test_a_second_run_of_the_same_file_is_refused_and_the_first_is_untouched(tmp_path):
    shared, alone = tmp_path / "shared", tmp_path / "alone"
    for folder in (shared, alone):
        folder.mkdir()
        (folder / "a.nml").write_text(FIRST)
    (shared / "b.nml").write_text(SECOND)
    first = stopped_writer([str(BIN / "eme_run"), "a.nml"], shared)
    try:
        before = listing(shared)
        second = subprocess.run([str(BIN / "eme_run"), "b.nml"], cwd=shared, capture_output=True, text=True,
                                timeout=300)
        after = listing(shared)
    finally:
        first.send_signal(signal.SIGCONT)
    out, err = first.communicate(timeout=600)
    assert second.returncode == 2, second.stderr
    assert after == before                                  # nothing written
    lines = second.stderr.splitlines()
    assert len(lines) == 1 and "same.h5" in lines[0] and holder_line(first) in lines[0], second.stderr
    assert second.stdout == ""
    assert first.returncode == 0, err
    solo = subprocess.run([str(BIN / "eme_run"), "a.nml"], cwd=alone, capture_output=True, text=True, timeout=600)
    assert solo.returncode == 0, solo.stderr
    assert sorted(p.name for p in shared.iterdir()) == ["a.nml", "b.nml", "same.h5"]
    with h5py.File(shared / "same.h5", "r") as f:
        assert f.attrs["scheme"] == "eme" and f.attrs["input_file"] == "a.nml"
    assert check_run_file(shared / "same.h5") == ("complete", 60000)
    assert_same_run(shared / "same.h5", alone / "same.h5")


STUDY = """&study base = '{base}', output_dir = 'out', index_only = .true. /
&sweep field = 't_end', values = 0.3 /
&sweep field = 'theta(2)', values = {values} /
"""


def test_a_second_study_in_the_same_output_dir_is_refused(tmp_path):
    values = ", ".join(f"{340 + i:.1f}" for i in range(20))
    (tmp_path / "study.nml").write_text(STUDY.format(base=ROOT / "inputs" / "paper_fig4_eme_theta.nml",
                                                     values=values))
    output = tmp_path / "out"
    output.mkdir()
    command = [str(BIN / "eme_ensemble"), "study.nml"]
    first = stopped_writer(command, output, cwd=tmp_path)
    try:
        before = listing(tmp_path)
        second = subprocess.run(command, cwd=tmp_path, capture_output=True, text=True, timeout=300)
        after = listing(tmp_path)
    finally:
        first.send_signal(signal.SIGCONT)
    out, err = first.communicate(timeout=600)
    assert second.returncode == 2, second.stderr
    assert after == before                                  # nothing written
    lines = second.stderr.splitlines()
    assert len(lines) == 1 and "out" in lines[0] and holder_line(first) in lines[0], second.stderr
    assert first.returncode == 0, err
    with h5py.File(output / "index.h5", "r") as f:
        cases = f["cases"][:]
    assert all(s == b"complete" for s in cases["status"])
    assert cases["run_count"].tolist() == [1] * 20
    assert not (output / "study.lock").exists()


def test_a_held_lock_is_released_when_its_writer_is_killed(tmp_path):
    (tmp_path / "a.nml").write_text(FIRST)
    lock = tmp_path / "same.h5.lock"
    first = stopped_writer([str(BIN / "eme_run"), "a.nml"], tmp_path)
    with open(lock, "rb") as probe:
        try:
            with pytest.raises(BlockingIOError):                 # held by the stopped writer
                fcntl.flock(probe, fcntl.LOCK_EX | fcntl.LOCK_NB)
        finally:
            first.kill()
            first.communicate()
        fcntl.flock(probe, fcntl.LOCK_EX | fcntl.LOCK_NB)        # released by the OS at SIGKILL
        fcntl.flock(probe, fcntl.LOCK_UN)
    assert first.returncode == -signal.SIGKILL
    assert lock.exists()                                          # left behind, and no obstacle:
    rerun = subprocess.run([str(BIN / "eme_run"), "a.nml"], cwd=tmp_path, capture_output=True, text=True,
                           timeout=600)
    assert rerun.returncode == 0, rerun.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.nml", "same.h5"]


def test_a_killed_writers_leftovers_are_replaced_by_a_rerun(tmp_path):
    """Killed after its first write and its first window (writes every 15,000 rows: the testing
    hook EME_WRITE_EVERY_ROWS), the run leaves FILE.part, its spare and the lock file; run
    again, it replaces them and leaves the complete file alone."""
    (tmp_path / "a.nml").write_text(FIRST)
    env = dict(os.environ, LD_PRELOAD=str(shim_library("kill_at_write")), EME_KILL_DIR=str(tmp_path),
               EME_WRITE_EVERY_ROWS="15000")
    log = tmp_path.parent / "operations.log"
    whole = subprocess.run([str(BIN / "eme_run"), "a.nml"], cwd=tmp_path, env=dict(env, EME_KILL_LOG=str(log)),
                           capture_output=True, text=True, timeout=600)
    assert whole.returncode == 0, whole.stderr
    operations = [line.split()[1] for line in log.read_text().splitlines()]
    exchanges = [k + 1 for k, op in enumerate(operations) if op == "renameat2"]
    assert len(exchanges) >= 2
    for p in tmp_path.glob("same.h5*"):
        p.unlink()
    killed = subprocess.run([str(BIN / "eme_run"), "a.nml"], cwd=tmp_path,
                            env=dict(env, EME_KILL_AT=str(exchanges[0] + 1)), capture_output=True, timeout=600)
    assert killed.returncode == -signal.SIGKILL
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.nml", "same.h5.lock", "same.h5.part",
                                                          "same.h5.part.spare"]
    status, steps = check_run_file(tmp_path / "same.h5.part")
    assert status == "incomplete: running" and 15000 <= steps < 60000
    rerun = subprocess.run([str(BIN / "eme_run"), "a.nml"], cwd=tmp_path, capture_output=True, text=True,
                           timeout=600)
    assert rerun.returncode == 0, rerun.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.nml", "same.h5"]
    assert check_run_file(tmp_path / "same.h5") == ("complete", 60000)
