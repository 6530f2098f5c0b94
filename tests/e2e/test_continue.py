"""eme_run FILE.nml -eme_continue: a run stopped early (SIGTERM, the step budget, a SIGKILL that
left FILE.part) goes on from the state its file stores after its last row, appending to the file.
For the one-step integrators (EME, the midpoint rule, the relaxed Runge-Kutta schemes, PETSc's
TS midpoint, RK4 and RK5DP) the continued file's datasets equal those of the uninterrupted run
bit for bit (the per-step wall times aside): the file stores the unknowns, the predictor's
previous state, the summary's accumulators and what each integrator carries from step to step
(EME: its step-size controller and the LU factors of the last Newton iteration; relaxed RK: its
state in entropy variables, next trial step, stages and factors; TS: its next step). The
integrators with a history (PETSc's BDF2, CVODE) start again from the stored state without it,
and are correct to their tolerance, not bit for bit. Input that cannot be continued is refused
with exit status 2, and the file is left as it was."""
import os
import signal
import subprocess

import h5py
import numpy as np
import pytest

from conftest import BIN, ROOT, namelist_text
from faults import held_process, operation_shim, signal_caught, wait_for

NOT_COMPARED = {"step_seconds"}          # wall-clock times of the steps


def write_namelist(folder, name, integrator, output):
    path = folder / f"{name}.nml"
    output = dict(output, file=str(folder / f"{name}.h5"))
    path.write_text(namelist_text({"integrator": integrator, "output": output}))
    return path, folder / f"{name}.h5"


def eme_run(namelist, *options, env=None):
    return subprocess.run([str(BIN / "eme_run"), str(namelist), *options], capture_output=True, text=True,
                          timeout=600, env=env)


def datasets(path):
    with h5py.File(path, "r") as f:
        return {name: f[name][()] for name in f if name not in NOT_COMPARED}, dict(f.attrs)


def assert_same_datasets(continued, reference):
    got, got_attrs = datasets(continued)
    expected, expected_attrs = datasets(reference)
    assert sorted(got) == sorted(expected)
    for name, values in expected.items():
        assert got[name].shape == values.shape, name
        if values.dtype.kind == "O":
            assert list(got[name]) == list(values), name
        else:
            # bit for bit (NaN included): the bytes, not the values
            assert got[name].tobytes() == values.tobytes(), f"{name} differs in " \
                f"{np.count_nonzero(got[name] != values)} entries"
    for name in ("status", "steps_completed", "step_rows", "newton_iterations_total", "run_figures"):
        assert np.array_equal(got_attrs[name], expected_attrs[name]), name
    # The step check's totals (NaN for a balance the model has not): bit for bit too.
    for name in ("resolved_steps", "balance_max_ulps"):
        assert np.asarray(got_attrs[name]).tobytes() == np.asarray(expected_attrs[name]).tobytes(), \
            (name, got_attrs[name], expected_attrs[name])


def test_sigterm_then_continue_is_bit_identical_with_every(tmp_path):
    """SIGTERM once the run's file exists, with every = 7, then -eme_continue: the continued file
    equals the uninterrupted run's. The run sends itself the SIGTERM (the LD_PRELOAD shim
    kill_at_write.c) at its first window, after its first write (writes every 1000 rows: the
    testing hook EME_WRITE_EVERY_ROWS), so the signal finds it running on any machine."""
    integrator = {"scheme": "eme", "dt": 0.0002, "t_end": 20.0}
    output = {"every": 7}
    reference_nml, reference = write_namelist(tmp_path, "reference", integrator, output)
    assert eme_run(reference_nml).returncode == 0
    folder = tmp_path / "run"
    folder.mkdir()
    namelist, path = write_namelist(folder, "run", integrator, output)
    stopped = eme_run(namelist, env=dict(operation_shim(folder, at=1, match=".part.spare", signal_number=signal.SIGTERM),
                                         EME_WRITE_EVERY_ROWS="1000"))
    assert stopped.returncode == 128 + signal.SIGTERM, stopped.stderr
    with h5py.File(path, "r") as f:
        stopped_at = int(f.attrs["steps_completed"])
        assert f.attrs["status"] == "incomplete: interrupted by SIGTERM"
    assert 0 < stopped_at < 100000
    result = eme_run(namelist, "-eme_continue")
    assert result.returncode == 0, result.stderr
    assert_same_datasets(path, reference)
    with h5py.File(path, "r") as f:
        history = f.attrs["history"].splitlines()
    assert len(history) == 2 and history[1].endswith("run.nml -eme_continue"), history


BUDGET_CASES = {
    # Adaptive EME and midpoint rule (&integrator tolerance): the step-size controller's state.
    "eme": {"scheme": "eme", "tolerance": 1e-4, "t_end": 6.0},
    "midpoint": {"scheme": "midpoint", "tolerance": 1e-4, "t_end": 6.0},
    # The relaxed schemes: their state in entropy variables (the file's state is in the run's own
    # variable, which converts back only to rounding), next trial step, last stages and factors.
    "relaxed_rk4": {"scheme": "relaxed_rk4"},
    "relaxed_rk8": {"scheme": "relaxed_rk8"},
    "relaxed_gauss6": {"scheme": "relaxed_gauss6"},
    "relaxed_dp853": {"scheme": "relaxed_dp853", "tolerance": 1e-6},
}


@pytest.mark.parametrize("case", list(BUDGET_CASES))
def test_step_budget_then_continue_with_interval(tmp_path, case):
    """An integrator that chooses its steps, with &output interval, stopped by max_steps between
    two output times, then continued with a larger max_steps: what it carries from step to step
    is restored, so the continued steps are those of the uninterrupted run, bit for bit."""
    integrator = {"dt": 0.01, "t_end": 3.0, "thermo_variable": "temperature", "max_steps": 1000000,
                  **BUDGET_CASES[case]}
    output = {"interval": 0.25}
    reference_nml, reference = write_namelist(tmp_path, "reference", integrator, output)
    assert eme_run(reference_nml).returncode == 0
    with h5py.File(reference, "r") as f:
        total = int(f.attrs["steps_completed"])
    assert total > 30
    namelist, path = write_namelist(tmp_path, "run", dict(integrator, max_steps=total // 3), output)
    stopped = eme_run(namelist)
    assert stopped.returncode == 3, stopped.stderr
    with h5py.File(path, "r") as f:
        assert f.attrs["failure_kind"] == "step_budget"
        assert f.attrs["resume_numbers"][0] <= total // 3
    write_namelist(tmp_path, "run", integrator, output)
    result = eme_run(namelist, "-eme_continue")
    assert result.returncode == 0, result.stderr
    assert_same_datasets(path, reference)


def test_the_summary_line_counts_the_steps_done(tmp_path):
    """An integrator that chooses its steps has no plan of steps: eme_run's line says "N steps",
    N the file's steps_completed, when the step budget stops it, when it is continued and stopped
    again, and when it completes. Before, it printed t_end/dt, a fixed step's plan, as the plan:
    "3000/600 steps". A fixed-step run still says "N/M steps", M = ceiling(t_end/dt)."""
    adaptive = {"scheme": "eme", "tolerance": 1e-4, "dt": 0.01, "t_end": 6.0}
    for budget, options, code in ((20, (), 3), (3000, ("-eme_continue",), 3), (1000000, ("-eme_continue",), 0)):
        namelist, path = write_namelist(tmp_path, "adaptive", dict(adaptive, max_steps=budget), {})
        result = eme_run(namelist, *options)
        assert result.returncode == code, result.stderr
        with h5py.File(path, "r") as f:
            steps = int(f.attrs["steps_completed"])
        assert steps == budget or code == 0
        assert f"{path}: {'complete' if code == 0 else 'incomplete: the step budget is spent'}" in result.stdout
        assert f", {steps} steps, energy balance" in result.stdout, result.stdout
    assert steps > 3000
    namelist, path = write_namelist(tmp_path, "fixed", {"scheme": "eme", "dt": 0.15, "t_end": 0.5}, {})
    result = eme_run(namelist)
    assert result.returncode == 0 and f"{path}: complete, 4/4 steps, energy balance" in result.stdout, result.stdout


def killed_and_continued(tmp_path, integrator, write_every_rows, options=()):
    """The uninterrupted run of `integrator` and the same run SIGKILLed at two thirds of its file
    operations (writes fall due every `write_every_rows` rows, not by the clock), then continued
    with -eme_continue, each with the command-line `options`: the two files' paths, the step the
    kill left the file at and the killed file's root attributes."""
    folder = tmp_path / "runs"
    folder.mkdir()
    log = tmp_path / "operations.log"
    shim = dict(operation_shim(folder), EME_WRITE_EVERY_ROWS=str(write_every_rows))
    reference_nml, reference = write_namelist(folder, "reference", integrator, {})
    assert eme_run(reference_nml, *options, env=dict(shim, EME_KILL_LOG=str(log))).returncode == 0
    operations = len(log.read_text().splitlines())
    namelist, path = write_namelist(folder, "run", integrator, {})
    killed = eme_run(namelist, *options, env=dict(shim, EME_KILL_AT=str(operations * 2 // 3)))
    assert killed.returncode == -signal.SIGKILL
    with h5py.File(path.with_name(path.name + ".part"), "r") as f:
        stopped = dict(f.attrs)
    result = eme_run(namelist, "-eme_continue", *options)
    assert result.returncode == 0, result.stderr
    with h5py.File(path, "r") as f:
        assert f.attrs["status"] == "complete" and len(f.attrs["history"].splitlines()) == 2
    return reference, path, int(stopped["resume_numbers"][0]), stopped


@pytest.mark.parametrize("scheme, extra, write_every", [("ts_midpoint", {}, 4), ("ts_rk4", {}, 4),
                                                        ("ts_rk5dp", {"dt": 0.1, "tolerance": 1e-8}, 4),
                                                        ("ts_rk5dp", {"dt": 0.1, "tolerance": 1e-8}, 2)])
def test_ts_one_step_methods_continue_bit_for_bit(tmp_path, scheme, extra, write_every):
    """PETSc's one-step TS methods killed and continued: the state and (ts_rk5dp, with several
    of its steps in an output step) the next step TS held are restored, so the continued file
    equals the uninterrupted run's. ts_rk5dp at two kill points (its writes every 4 and every 2
    rows): Dormand-Prince's first stage is the last one's f, which TS carried from one output
    step to the next, so that a continued run differed in the last bits where the stored state
    and the last stage's differ (killed at step 13, not at 15); every output step now starts
    afresh."""
    integrator = {"scheme": scheme, "dt": 0.01, "t_end": 2.0, **extra}
    reference, path, stopped_at, _ = killed_and_continued(tmp_path, integrator, write_every)
    assert 0 < stopped_at < 200
    assert_same_datasets(path, reference)


@pytest.mark.parametrize("scheme, extra", [("ts_bdf2", {}), ("cvode_bdf", {"tolerance": 1e-8}),
                                           ("cvode_adams", {"tolerance": 1e-8}), ("cvode_bdf", {"tolerance": 1e-6})])
def test_history_methods_continue_to_their_tolerance(tmp_path, scheme, extra):
    """BDF2 and CVODE start again from the stored state without their history (order 1, a step
    of their choice): the rows before the kill are the uninterrupted run's, and at t_end the
    continued run's error against a CVODE solution at 1e-13 is within twice the uninterrupted
    run's (measured: 0.83 to 1.09 times it)."""
    integrator = {"scheme": scheme, "dt": 0.01, "t_end": 2.0, **extra}
    reference, path, stopped_at, _ = killed_and_continued(tmp_path, integrator, 40)
    assert 0 < stopped_at < 200
    truth_nml, truth = write_namelist(tmp_path, "truth", {"scheme": "cvode_bdf", "dt": 0.01, "t_end": 2.0,
                                                          "tolerance": 1e-13}, {})
    assert eme_run(truth_nml).returncode == 0
    with h5py.File(reference, "r") as f, h5py.File(path, "r") as g, h5py.File(truth, "r") as t:
        uninterrupted, continued, exact = f["state"][()], g["state"][()], t["state"][()]
    assert continued[:stopped_at + 1].tobytes() == uninterrupted[:stopped_at + 1].tobytes()
    assert not np.array_equal(continued, uninterrupted), "continued without restarting its history?"
    error = np.abs(uninterrupted[-1] - exact[-1]).max()
    assert np.abs(continued[-1] - exact[-1]).max() <= 2 * error, (error, np.abs(continued[-1] - exact[-1]).max())


def test_the_step_check_s_records_continue_with_the_run(tmp_path):
    """The step check's records across a continuation: with a lagged Jacobian the paper scene's
    steps 1 and 5 (of 20) break a balance and are solved again (/resolved 1), and a balance's
    largest figure lies before the kill (the momentum's, 14.8 ulps at step 6). Killed (after step 15)
    and continued, the file's /balance and /resolved rows, resolved_steps and balance_max_ulps
    equal the uninterrupted run's: the continuation took the killed file's totals from its
    resume_balances, which are those of its rows, resolved steps, then each balance's largest
    figure."""
    integrator = {"scheme": "eme", "thermo_variable": "temperature", "dt": 0.05, "t_end": 1.0}
    reference, path, stopped_at, stopped = killed_and_continued(tmp_path, integrator, 4,
                                                                ("-snes_lag_jacobian", "100"))
    assert_same_datasets(path, reference)
    with h5py.File(reference, "r") as f:
        resolved, figures = f["resolved"][()], f["balance"][()]
        assert f["balance"].attrs["columns"] == "energy momentum entropy lyapunov"
    assert 0 < resolved[:stopped_at].sum() == resolved.sum() == stopped["resolved_steps"]
    assert np.any(figures[:stopped_at].max(axis=0) > figures[stopped_at:].max(axis=0))
    assert stopped["resume_balances"].tolist() == [resolved[:stopped_at].sum(), *figures[:stopped_at].max(axis=0)]


KILL_RUN = {"scheme": "eme", "dt": 0.05, "t_end": 2000.0}


def test_sigkill_part_is_continued(tmp_path):
    """A SIGKILL (the LD_PRELOAD shim kill_at_write.c, at a chosen file operation) leaves only
    FILE.part; -eme_continue goes on from it, and the file takes its final name complete. Writes
    fall due every 15,000 rows (the testing hook EME_WRITE_EVERY_ROWS), not by the clock, so the
    killed run makes the logged run's operations on any machine (by the clock, a busy logged run
    made more windows than a quick killed one reached)."""
    reference_nml, reference = write_namelist(tmp_path, "reference", KILL_RUN, {})
    assert eme_run(reference_nml).returncode == 0
    folder = tmp_path / "killed"
    folder.mkdir()
    log = tmp_path / "operations.log"
    namelist, path = write_namelist(folder, "run", KILL_RUN, {})
    shim = dict(operation_shim(folder), EME_WRITE_EVERY_ROWS="15000")
    assert eme_run(namelist, env=dict(shim, EME_KILL_LOG=str(log))).returncode == 0
    operations = len(log.read_text().splitlines())
    path.unlink()
    killed = eme_run(namelist, env=dict(shim, EME_KILL_AT=str(operations * 2 // 3)))
    assert killed.returncode == -signal.SIGKILL
    part = path.with_name(path.name + ".part")
    assert part.exists() and not path.exists()
    with h5py.File(part, "r") as f:
        assert 0 < f.attrs["resume_numbers"][0] < 40000
    result = eme_run(namelist, "-eme_continue")
    assert result.returncode == 0, result.stderr
    assert path.exists() and not part.exists()
    assert_same_datasets(path, reference)


def test_refusals_keep_the_file(tmp_path):
    """A complete file, another input, no file, or an integrator that cannot continue: exit 2, one
    line naming the file and what is allowed, and the file unchanged."""
    integrator = {"scheme": "eme", "dt": 0.01, "t_end": 3.0, "tolerance": 1e-4, "max_steps": 50}
    namelist, path = write_namelist(tmp_path, "run", integrator, {})
    assert eme_run(namelist).returncode == 3
    before = path.read_bytes()

    write_namelist(tmp_path, "run", dict(integrator, dt=0.02, max_steps=100000), {})
    result = eme_run(namelist, "-eme_continue")
    assert result.returncode == 2
    assert "dt = 0.02" in result.stderr and "t_end and max_steps" in result.stderr, result.stderr
    assert path.read_bytes() == before

    write_namelist(tmp_path, "run", dict(integrator, scheme="relaxed_dp853", max_steps=100000), {})
    result = eme_run(namelist, "-eme_continue")
    assert result.returncode == 2
    assert "scheme = 'relaxed_dp853'" in result.stderr and "allowed" in result.stderr, result.stderr
    assert path.read_bytes() == before

    other, _ = write_namelist(tmp_path, "absent", integrator, {})
    result = eme_run(other, "-eme_continue")
    assert result.returncode == 2 and "absent.h5" in result.stderr, result.stderr

    write_namelist(tmp_path, "run", dict(integrator, max_steps=100000), {})
    assert eme_run(namelist, "-eme_continue").returncode == 0
    complete = path.read_bytes()
    result = eme_run(namelist, "-eme_continue")
    assert result.returncode == 2 and "complete" in result.stderr, result.stderr
    assert path.read_bytes() == complete


def test_the_step_budget_counts_the_whole_run_and_the_file_says_which_applied(tmp_path):
    """max_steps is the whole run's budget, continued or not (issue 41 item 7: a run stopped at 50
    steps, continued with max_steps = 10, ran 104,849 steps to completion and its file still said
    50). A budget at or below the steps taken is refused (exit 2, file unchanged); a larger one
    stops the run at that total, and the file's namelist and attributes say the budget and end
    time that applied: the namelist that, run from t = 0, gives the same file."""
    integrator = {"scheme": "eme", "dt": 0.01, "t_end": 5.0, "tolerance": 1.0e-7, "max_steps": 50}
    namelist, path = write_namelist(tmp_path, "run", integrator, {})
    assert eme_run(namelist).returncode == 3
    before = path.read_bytes()
    for budget in (10, 50):
        write_namelist(tmp_path, "run", dict(integrator, max_steps=budget), {})
        result = eme_run(namelist, "-eme_continue")
        assert result.returncode == 2, result.stderr
        assert f"max_steps = {budget}" in result.stderr and "allowed: max_steps > 50" in result.stderr, result.stderr
        assert path.read_bytes() == before

    write_namelist(tmp_path, "run", dict(integrator, t_end=6.0, max_steps=80), {})
    result = eme_run(namelist, "-eme_continue")
    assert result.returncode == 3, result.stderr
    reference_nml, reference = write_namelist(tmp_path, "reference", dict(integrator, t_end=6.0, max_steps=80), {})
    assert eme_run(reference_nml).returncode == 3
    assert_same_datasets(path, reference)
    with h5py.File(path, "r") as f, h5py.File(reference, "r") as g:
        assert f.attrs["failure_kind"] == "step_budget" and f.attrs["steps_completed"] == 80
        assert f.attrs["max_steps"] == 80 and f.attrs["t_end"] == 6.0
        # The namelists differ in the output file's name alone.
        lines = [line for line in f.attrs["namelist"].splitlines() if not line.strip().startswith("file =")]
        assert "  max_steps = 80" in lines and "  t_end = 6.0" in lines
        assert lines == [line for line in g.attrs["namelist"].splitlines() if not line.strip().startswith("file =")]


def test_the_slurm_run_example_continues_after_requeue(tmp_path):
    """inputs/slurm_run.sbatch run as Slurm would: SIGTERM to the batch script stops the run and
    requeues the job (a stand-in scontrol records the call); the requeued job continues the run
    from its file, which ends complete and equal to the uninterrupted run. The run holds at its
    first window (the LD_PRELOAD shim kill_at_write.c) until it has caught the SIGTERM the script
    passes on, so the signal finds it running on any machine."""
    root = ROOT
    if not (root / "build" / "bin" / "eme_run").exists():
        pytest.skip("the script runs build/bin/eme_run of the checkout")
    integrator = {"scheme": "eme", "dt": 0.0002, "t_end": 20.0}
    reference_nml, reference = write_namelist(tmp_path, "reference", integrator, {})
    assert eme_run(reference_nml).returncode == 0
    folder = tmp_path / "run"
    folder.mkdir()
    namelist, path = write_namelist(folder, "run", integrator, {})
    tools = tmp_path / "bin"
    tools.mkdir()
    (tools / "scontrol").write_text(f"#!/bin/sh\necho \"$@\" >> {tmp_path / 'scontrol.log'}\n")
    (tools / "scontrol").chmod(0o755)
    env = dict(os.environ, PATH=f"{tools}:{os.environ['PATH']}", SLURM_JOB_ID="4242")
    script = ["bash", str(root / "inputs" / "slurm_run.sbatch"), str(namelist)]
    release = tmp_path / "release"
    held = dict(operation_shim(folder, at=1, match=".part.spare", hold=release, env=env), EME_WRITE_EVERY_ROWS="1000")
    job = subprocess.Popen(script, cwd=root, env=held, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        run = held_process(release)
        assert wait_for(lambda: signal_caught(job.pid, signal.SIGTERM)), "the script set no trap for SIGTERM"
        job.send_signal(signal.SIGTERM)
        assert wait_for(lambda: not signal_caught(run, signal.SIGTERM)), "the held run never caught SIGTERM"
    finally:
        release.touch()
    out, err = job.communicate(timeout=600)
    assert job.returncode == 0, out + err
    assert "time limit near" in out
    assert (tmp_path / "scontrol.log").read_text() == "requeue 4242\n"
    with h5py.File(path, "r") as f:
        assert f.attrs["status"] == "incomplete: interrupted by SIGTERM"
        started = f.attrs["start_time"]
    result = subprocess.run(script, cwd=root, env=env, capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stdout + result.stderr
    assert (tmp_path / "scontrol.log").read_text() == "requeue 4242\n"
    assert_same_datasets(path, reference)
    with h5py.File(path, "r") as f:      # continued, not run again from t = 0
        assert f.attrs["start_time"] == started
        assert f.attrs["history"].endswith("-eme_continue")


def test_an_interrupted_study_case_continues(tmp_path):
    """A study stopped by SIGTERM during its only case: run again, the case continues from its
    file (its history says so) and ends equal to the same run made at once. The study sends
    itself the SIGTERM (the LD_PRELOAD shim kill_at_write.c) at the case's first window, after
    its first write (every 1000 rows: the testing hook EME_WRITE_EVERY_ROWS)."""
    integrator = {"scheme": "eme", "dt": 0.0002, "t_end": 20.0}
    reference_nml, reference = write_namelist(tmp_path, "reference", integrator, {"every": 3})
    assert eme_run(reference_nml).returncode == 0
    base, _ = write_namelist(tmp_path, "base", dict(integrator, dt=0.1), {"every": 3})
    output = tmp_path / "study"
    output.mkdir()
    study = tmp_path / "study.nml"
    study.write_text(f"&study base = '{base}', output_dir = '{output}' /\n&sweep field = 'dt', values = 0.0002 /\n")
    env = dict(operation_shim(output, at=1, match="case_00001.h5.part.spare", signal_number=signal.SIGTERM),
               EME_WRITE_EVERY_ROWS="1000")
    stopped = subprocess.run([str(BIN / "eme_ensemble"), str(study)], capture_output=True, text=True, timeout=600,
                             env=env)
    assert stopped.returncode == 128 + signal.SIGTERM, stopped.stdout + stopped.stderr
    case = output / "case_00001.h5"
    with h5py.File(case, "r") as f:
        assert f.attrs["status"] == "incomplete: interrupted by SIGTERM", stopped.stdout + stopped.stderr
        assert len(f.attrs["history"].splitlines()) == 1
    result = subprocess.run([str(BIN / "eme_ensemble"), str(study)], capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stdout + result.stderr
    with h5py.File(case, "r") as f:
        assert len(f.attrs["history"].splitlines()) == 2
    assert_same_datasets(case, reference)


def test_refused_when_nothing_is_left_or_the_step_failed(tmp_path):
    """t_end lowered below the time the file reached: exit 2, file unchanged. A run that stopped at
    a step it could not solve (failure_kind solver) would stop there again: refused as well."""
    integrator = {"scheme": "eme", "dt": 0.001, "t_end": 3.0, "tolerance": 1e-4, "max_steps": 50}
    namelist, path = write_namelist(tmp_path, "run", integrator, {})
    assert eme_run(namelist).returncode == 3
    with h5py.File(path, "r") as f:
        reached = f.attrs["resume_numbers"][1]
    assert reached > 0.002
    before = path.read_bytes()
    write_namelist(tmp_path, "run", dict(integrator, t_end=0.002), {})
    result = eme_run(namelist, "-eme_continue")
    assert result.returncode == 2 and "a later t_end" in result.stderr, result.stderr
    assert path.read_bytes() == before

    write_namelist(tmp_path, "run", dict(integrator, max_steps=100000), {})
    with h5py.File(path, "r+") as f:
        f.attrs["failure_kind"] = "solver"
    result = eme_run(namelist, "-eme_continue")
    assert result.returncode == 2 and "holds no run to continue" in result.stderr, result.stderr
