"""Running eme_run as a user does: PETSc options reach the solver, a run that cannot
continue stops cleanly and keeps its steps in a valid file marked incomplete, a killed run
leaves a readable file, a running file can be read, SIGTERM and SIGINT stop a run cleanly, a
complete result is not replaced unless asked, progress lines, and memory does not grow with the
number of steps."""
import os
import re
import signal
import subprocess
import sys
import time

import h5py
import numpy as np
import pytest

from conftest import BIN, namelist_text, read_run, run_eme
from faults import SIGNALS, check_run_file, signal_after, wait_for

POINT_DATASETS = ["time", "state", "temperature", "energy", "entropy", "lyapunov", "angular_momentum", "boundary_heat"]
STEP_DATASETS = ["newton_iterations", "scheme_temperature", "solver_strategy", "snes_solves", "rejected_roots"]


def assert_consistent(run, steps):
    """Every per-point dataset has steps+1 rows and every per-step dataset steps rows."""
    for name in POINT_DATASETS:
        assert run[name].shape[0] == steps + 1, name
    for name in STEP_DATASETS:
        assert run[name].shape[0] == steps, name
    assert run["attrs"]["steps_completed"] == steps


def test_run_that_cannot_continue_keeps_its_steps(tmp_path, eme_run_binary):
    # The midpoint rule with tau = u at dt = 2 s, halving switched off: on some step no strategy
    # finds a root with positive temperatures. (Whether one exists is the solver's verdict; halves
    # of the step find one, test_solver_robustness.py.)
    result, path = run_eme(tmp_path, "fails", {"integrator": {
        "scheme": "midpoint", "thermo_variable": "internal_energy", "dt": 2.0, "t_end": 60.0}},
        "-eme_max_halvings", "0")
    assert result.returncode == 3
    run = read_run(path)
    status = run["attrs"]["status"]
    failed = int(re.match(r"incomplete: step (\d+) \(t = ", status).group(1))
    assert status.startswith(f"incomplete: step {failed} (t = {2.0 * failed:.4f} s)") and 1 < failed < 30
    assert "no root" in status and status in result.stderr
    assert run["attrs"]["failure_kind"] == "solver"
    assert_consistent(run, failed - 1)
    assert np.all(run["temperature"] > 0)
    np.testing.assert_allclose(run["time"], 2.0 * np.arange(float(failed)))


def test_a_run_that_leaves_the_domain_says_so(tmp_path, eme_run_binary):
    # Explicit RK4 beyond its stability limit reaches a non-positive temperature at t = 17.25 s
    # (the stability study's RK4_theta at dt = 0.75 s): failure_kind 'domain', not 'solver'.
    result, path = run_eme(tmp_path, "domain", {"integrator": {"scheme": "ts_rk4", "dt": 0.75}})
    assert result.returncode == 3
    run = read_run(path)
    assert "domain" in run["attrs"]["status"] and run["attrs"]["failure_kind"] == "domain"
    assert_consistent(run, 22)


def test_petsc_options_reach_the_solver(tmp_path, eme_run_binary):
    scene = {"integrator": {"t_end": 0.45}}
    result, _ = run_eme(tmp_path, "reason", scene, "-snes_converged_reason")
    assert result.returncode == 0
    assert result.stdout.count("Nonlinear solve converged due to") >= 3
    # With one Newton iteration allowed, no strategy can solve the first step.
    result, path = run_eme(tmp_path, "max_it", scene, "-snes_max_it", "1")
    assert result.returncode == 3
    run = read_run(path)
    assert run["attrs"]["status"].startswith("incomplete: step 1 ")
    assert_consistent(run, 0)


@pytest.mark.parametrize("scheme,variable,gradient", [
    ("eme", "entropy", "gonzalez"), ("eme", "temperature", "partitioned"),
    ("eme", "internal_energy", "gonzalez"), ("midpoint", "temperature", "gonzalez")])
def test_snes_test_jacobian_is_quiet(tmp_path, eme_run_binary, scheme, variable, gradient):
    result, _ = run_eme(tmp_path, "jacobian", {"integrator": {
        "scheme": scheme, "thermo_variable": variable, "discrete_gradient": gradient, "t_end": 0.6}},
        "-snes_test_jacobian")
    ratios = [float(x) for x in re.findall(r"\|\|J - Jfd\|\|_F/\|\|J\|\|_F = ([0-9.eE+-]+)", result.stdout)]
    assert len(ratios) >= 4
    # PETSc differences one-sidedly; its truncation error alone is ~1e-7 here.
    assert max(ratios) < 1e-5, ratios


def long_run(tmp_path, name, integrator=None, output=None):
    """A namelist of a run far too long to finish (EME, 20 million steps of 0.05 s)."""
    output = output or tmp_path / f"{name}.h5"
    namelist = tmp_path / f"{name}.nml"
    namelist.write_text(namelist_text({"integrator": integrator or {"dt": 0.05, "t_end": 1.0e6},
                                       "output": {"file": str(output), "overwrite": True}}))
    return namelist, output


def test_killed_run_leaves_a_readable_file(tmp_path, eme_run_binary):
    """SIGKILL mid-run: the final name is never taken; FILE.part holds every row written up to its
    last write, with points and steps of equal length and steps_completed saying how many."""
    namelist, output = long_run(tmp_path, "killed")
    part = output.with_name(output.name + ".part")
    process = subprocess.Popen([str(BIN / "eme_run"), str(namelist)])
    # Whatever the machine's speed: wait for the first write, then for a later window.
    assert wait_for(lambda: part.exists() or process.poll() is not None)
    first = readable_steps(part)
    assert wait_for(lambda: readable_steps(part) > first)
    process.send_signal(signal.SIGKILL)
    process.wait()
    assert not output.exists()
    status, steps = check_run_file(part)
    assert status == "incomplete: running"
    run = read_run(part)
    assert steps > first and run["attrs"]["failure_kind"] == "none"
    assert_consistent(run, steps)
    np.testing.assert_allclose(run["time"], 0.05 * np.arange(steps + 1))
    energy = run["energy"]
    assert np.max(np.abs(energy - energy[0])) <= 1e-8 * abs(energy[0])


SLOW_RUN = {"scheme": "ts_rk5dp", "tolerance": 1e-14, "dt": 1.0, "t_end": 4000.0}   # about 30 steps/s here


def buffer_rows(path):
    """The rows a run's buffer of 4 MiB holds (docs/output.md): a row of every dataset with rows,
    8 bytes a number."""
    with h5py.File(path, "r") as f:
        numbers = sum(d.shape[1] if d.ndim == 2 else 1 for d in f.values() if "rows" in d.attrs)
    return 4 * 1024 * 1024 // (8 * numbers)


def test_a_running_file_is_read_while_it_grows(tmp_path, eme_run_binary):
    """The file is written every second (by wall time: this run takes far fewer steps than the
    row buffer holds), each time to the spare copy that then takes the name FILE.part, so h5py
    reads FILE.part while eme_run runs: never refused, consistent each time, growing, marked
    running. A reader that keeps the file open does not stop the run. The test waits for events
    (reads, writes), never for a time."""
    namelist, output = long_run(tmp_path, "running", integrator=SLOW_RUN)
    part = output.with_name(output.name + ".part")
    process = subprocess.Popen([str(BIN / "eme_run"), str(namelist)], stderr=subprocess.PIPE, text=True)
    try:
        assert wait_for(lambda: part.exists() or process.poll() is not None)
        seen, refused = [], 0

        def read_once():
            nonlocal refused
            try:
                status, steps = check_run_file(part)
            except OSError:       # FILE.part is never written in place, so never locked
                refused += 1
                return False
            assert status == "incomplete: running"
            seen.append(steps)
            return len(seen) >= 10 and len(set(seen)) >= 3 or process.poll() is not None

        assert wait_for(read_once, interval=0.1)
        assert process.poll() is None, process.stderr.read()
        assert seen == sorted(seen) and refused == 0, (seen, refused)
        # written by wall time, long before the row buffer fills (SLOW_RUN needs minutes to fill it)
        assert seen[0] < buffer_rows(part) / 10
        # A reader holding the file open for 2.5 s: the writer waits for it to close the spare.
        with h5py.File(part, "r"):
            time.sleep(2.5)
        assert wait_for(lambda: readable_steps(part) > seen[-1])
    finally:
        process.send_signal(signal.SIGTERM)
        process.wait()


def test_a_reader_keeps_its_file_as_it_was(tmp_path, eme_run_binary):
    """A reader that holds FILE.part open while a fast run fills its row buffer: after the next
    exchange its file is the writer's spare, which the writer then replaces by a copy instead of
    writing in it. The reader's file does not change under it, and the run goes on meanwhile.
    The test waits for these events (the writer letting go of the reader's file, a later write),
    not for a time: it asserted about 10^5 EME steps a second before, which a busy machine
    missed (11,682 steps in 3 s)."""
    namelist, output = long_run(tmp_path, "held")
    part = output.with_name(output.name + ".part")
    process = subprocess.Popen([str(BIN / "eme_run"), str(namelist)], stderr=subprocess.PIPE, text=True)
    try:
        assert wait_for(lambda: part.exists() or process.poll() is not None)
        with h5py.File(part, "r") as f, open(part, "rb") as same:   # h5py caches: read the bytes too
            content = same.read()
            before = {name: f[name][()] for name in ("time", "state", "newton_iterations")}
            steps = int(f.attrs["steps_completed"])
            # the writer let go of it: replaced the spare (this file) by a copy when its buffer filled
            assert wait_for(lambda: os.fstat(same.fileno()).st_nlink == 0 or process.poll() is not None)
            assert wait_for(lambda: readable_steps(part) > steps or process.poll() is not None)
            assert process.poll() is None, process.stderr.read()      # the run went on
            same.seek(0)
            assert same.read() == content
            for name, values in before.items():
                assert np.array_equal(f[name][()], values), name
            assert int(f.attrs["steps_completed"]) == steps and f.attrs["status"] == "incomplete: running"
        with h5py.File(part, "r") as f:
            assert np.array_equal(f["state"][:steps + 1], before["state"])
    finally:
        process.send_signal(signal.SIGTERM)
        process.wait()


def readable_steps(path):
    """steps_completed of a running file, or -1 while a write holds its lock."""
    try:
        return check_run_file(path)[1]
    except OSError:
        return -1


@pytest.mark.parametrize("name", ["SIGTERM", "SIGINT"])
def test_a_signal_stops_the_run_and_marks_its_file(tmp_path, eme_run_binary, name):
    """SIGTERM (a batch scheduler) and SIGINT (Ctrl-C): the run stops after its current step,
    writes every step and every attribute, marks the file and exits with 128 + the signal."""
    number = SIGNALS[name]
    namelist, output = long_run(tmp_path, "signal")
    part = output.with_name(output.name + ".part")
    process = subprocess.Popen([str(BIN / "eme_run"), str(namelist)], stderr=subprocess.PIPE, text=True)
    # After the first write and a later one, whatever the machine's speed.
    assert wait_for(lambda: part.exists() or process.poll() is not None)
    first = readable_steps(part)
    assert wait_for(lambda: readable_steps(part) > first)
    written = readable_steps(part)
    process.send_signal(number)
    _, err = process.communicate(timeout=300)
    code = process.returncode
    assert code == 128 + number, err
    assert f"interrupted by {name}" in err
    status, steps = check_run_file(output)
    assert status == f"incomplete: interrupted by {name}" and steps >= written
    assert not part.exists()
    run = read_run(output)
    assert run["attrs"]["failure_kind"] == "interrupted"
    result, complete = run_eme(tmp_path, "complete", {"integrator": {"t_end": 0.3}})
    assert result.returncode == 0
    assert set(run["attrs"]) == set(read_run(complete)["attrs"])     # every attribute written
    np.testing.assert_allclose(run["time"], 0.05 * np.arange(steps + 1))


@pytest.mark.parametrize("name", ["SIGTERM", "SIGINT", "SIGKILL"])
def test_signals_at_random_moments_of_short_runs(tmp_path, eme_run_binary, name):
    """The paper scene (134 steps, done in a few ms after start-up) hit by a signal anywhere from
    start-up to its end: the output file is absent, FILE.part (SIGKILL only), or it reads back with
    a status that tells the truth: complete only if it ran to the end."""
    number = SIGNALS[name]
    rng = np.random.default_rng(13)
    for attempt in range(8):
        folder = tmp_path / f"{attempt}"
        folder.mkdir()
        output = folder / "paper.h5"
        namelist = folder / "paper.nml"
        namelist.write_text(namelist_text({"output": {"file": str(output)}}))
        start = time.time()
        code, _, err = signal_after([str(BIN / "eme_run"), str(namelist)], float(rng.uniform(0.0, 0.6)), number)
        if output.exists():
            status, steps = check_run_file(output)
            if status == "complete":
                assert steps == 134 and code in (0, -number), (code, err)
            else:
                assert status == f"incomplete: interrupted by {name}" and code == 128 + number, (status, code)
        else:
            assert code in (-number, 128 + number), (code, err, time.time() - start)
        part = output.with_name("paper.h5.part")
        if part.exists():
            assert name == "SIGKILL"
            # complete only when the kill fell between the run's last write and the rename
            # (test_kill_points reproduces that instant)
            status, steps = check_run_file(part)
            assert status == "incomplete: running" or (status, steps) == ("complete", 134), (status, steps)


def test_a_complete_result_is_not_replaced_unless_asked(tmp_path, eme_run_binary):
    scene = {"integrator": {"t_end": 0.3}}
    result, path = run_eme(tmp_path, "kept", scene)
    assert result.returncode == 0
    before = path.stat().st_mtime_ns
    result, _ = run_eme(tmp_path, "kept", scene)
    assert result.returncode == 2
    assert f"{path} holds a complete run" in result.stderr and "overwrite" in result.stderr
    assert path.stat().st_mtime_ns == before and not path.with_name("kept.h5.part").exists()
    result, _ = run_eme(tmp_path, "kept", scene, "-eme_overwrite")
    assert result.returncode == 0 and path.stat().st_mtime_ns != before
    before = path.stat().st_mtime_ns
    result, _ = run_eme(tmp_path, "kept", {"integrator": {"t_end": 0.3}, "output": {"overwrite": True}})
    assert result.returncode == 0 and path.stat().st_mtime_ns != before


def test_a_new_run_that_ends_early_keeps_the_old_result(tmp_path, eme_run_binary):
    """With overwrite asked, a new run that is killed, or stops early, leaves the earlier complete
    file as it was; the new run's file stays FILE.part."""
    result, path = run_eme(tmp_path, "old", {"integrator": {"t_end": 0.3}})
    assert result.returncode == 0
    old = read_run(path)
    namelist, _ = long_run(tmp_path, "old", output=path)
    part = path.with_name("old.h5.part")
    for number in (signal.SIGKILL, signal.SIGTERM):
        part.unlink(missing_ok=True)
        code, _, err = signal_after([str(BIN / "eme_run"), str(namelist)], 0.0, number, start_marker=part)
        assert code in (-signal.SIGKILL, 128 + signal.SIGTERM), err
        assert check_run_file(path) == ("complete", 2) and np.array_equal(read_run(path)["state"], old["state"])
        assert part.exists()
    assert "keeps the earlier complete run" in err and str(part) in err


def test_progress_lines(tmp_path, eme_run_binary):
    """-eme_progress: a line on stderr at most every 2 s with simulated time, steps, rate and the
    time left; without it (stderr is not a terminal here) none. The test reads lines until it has
    three, then stops the run; the 2 s are checked on the run's own clock, which each line gives
    (the time left over the simulated time left is the time loop's seconds over the time
    simulated)."""
    namelist, _ = long_run(tmp_path, "progress")
    process = subprocess.Popen([str(BIN / "eme_run"), str(namelist), "-eme_progress"], stderr=subprocess.PIPE,
                               text=True)
    lines = []
    try:
        for line in process.stderr:
            if " steps/s, about " in line:
                lines.append(line.rstrip("\n"))
            if len(lines) == 3:
                break
    finally:
        process.send_signal(signal.SIGTERM)
        process.communicate(timeout=300)
    assert len(lines) == 3, lines
    elapsed = []
    for line in lines:
        match = re.fullmatch(r"eme_run: t = ([0-9.]+) of 1000000\.000 s, (\d+) steps, (\d+) steps/s, about ([0-9.]+) s left",
                             line)
        assert match, line
        time_reached, steps, rate, left = (float(match.group(k)) for k in (1, 2, 3, 4))
        assert time_reached == pytest.approx(0.05 * steps, abs=1e-6)
        assert rate > 0 and left > 0
        elapsed.append(left * time_reached / (1.0e6 - time_reached))
    # At most every 2 s: 2 s apart or more (the time left is printed to 0.1 s, a few 1e-4 s of these).
    assert min(np.diff(elapsed)) >= 2.0 - 0.01, (elapsed, lines)
    result, _ = run_eme(tmp_path, "quiet", {"integrator": {"t_end": 0.3}})
    assert "steps/s" not in result.stderr


def peak_memory_kib(tmp_path, name, t_end):
    """Peak RSS of one eme_run, measured by a fresh Python process that starts it (the RSS of
    children is a maximum over all of them, so it must be a process with no other child). Its
    rows reach the disk only when the row buffer is full (the testing hook EME_WRITE_EVERY_ROWS
    set beyond the run's rows), never by the clock, so the buffer is as full at the peak on any
    machine."""
    result, path = run_eme(tmp_path, name, {"integrator": {"scheme": "midpoint", "thermo_variable": "entropy",
                                                            "dt": 0.01, "t_end": 0.01}})
    namelist = path.with_suffix(".nml")
    namelist.write_text(namelist_text({"integrator": {"scheme": "midpoint", "thermo_variable": "entropy", "dt": 0.01,
                                                      "t_end": t_end}, "output": {"file": str(path), "overwrite": True}}))
    probe = ("import resource, subprocess, sys; code = subprocess.run(sys.argv[1:]).returncode; "
             "print(code, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)")
    result = subprocess.run([sys.executable, "-c", probe, str(BIN / "eme_run"), str(namelist)], capture_output=True,
                            text=True, env=dict(os.environ, EME_WRITE_EVERY_ROWS="1000000000"))
    code, peak = result.stdout.split()[-2:]
    assert code == "0", result.stderr
    return int(peak)


def test_memory_does_not_grow_with_steps(tmp_path, eme_run_binary):
    """Rows wait in a buffer of at most 4 MiB between writes: beyond it, memory stays flat. Five
    times the steps may add at most one buffer; rows kept for the whole run would add 30 MB.
    (With writes due by the clock as well, how full the buffer was at the peak depended on the
    machine's load: growth 1.0 to 2.1 MiB was measured.)"""
    short = peak_memory_kib(tmp_path, "short", 300.0)    # 30000 steps: the buffer is full
    long = peak_memory_kib(tmp_path, "long", 1500.0)     # 150000 steps: 150000 rows x 31 values = 37 MB
    assert long - short < 4096, f"peak RSS grew from {short} KiB to {long} KiB"
