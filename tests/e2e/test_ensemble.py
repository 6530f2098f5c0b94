"""eme_ensemble under mpirun: every case of a small study completes, a case's file equals the
same case run by eme_run, a failing case is isolated, a restarted study reruns only what is not
complete, a killed study leaves no file that looks finished, and bad study input is rejected."""
import os
import re
import signal
import subprocess
import time

import h5py
import numpy as np
import pytest

from conftest import BIN, ROOT, read_run, run_eme

BASE = ROOT / "inputs" / "paper_fig4_eme_theta.nml"
from faults import (check_run_file, held_process, is_stopped, mpirun_env_options, operation_shim,
                    processes_naming, signal_caught, wait_for)

MPIRUN = ["mpirun", "--allow-run-as-root", "--oversubscribe"]
# Cases zipped: two EME variants, a midpoint case, and a deliberately failing one: with one
# Newton iteration allowed per solve (newton_max_iterations = 1), no step can converge.
SMALL_STUDY = """&study
  base = '{base}'
  output_dir = '{output}'
  combine = 'zip'
/
&sweep field = 'scheme', texts = 'eme', 'eme', 'midpoint', 'eme' /
&sweep field = 'thermo_variable', texts = 'entropy', 'temperature', 'internal_energy', 'internal_energy' /
&sweep field = 'dt', values = 0.3, 0.15, 0.15, 0.15 /
&sweep field = 't_end', values = 3.0, 3.0, 3.0, 3.0 /
&sweep field = 'newton_max_iterations', values = 50, 50, 50, 1 /
"""


def write_study(tmp_path, text, name="study"):
    path = tmp_path / f"{name}.nml"
    path.write_text(text)
    return path


def ensemble(study, ranks=3, timeout=300):
    return subprocess.run([*MPIRUN, "-n", str(ranks), str(BIN / "eme_ensemble"), str(study)],
                          capture_output=True, text=True, timeout=timeout, cwd=ROOT)


def kill_processes_naming(text):
    """SIGKILL every process whose command line contains `text`. Open MPI puts its ranks in
    process groups of their own, so a process group kill misses them."""
    for pid in processes_naming(text):
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass


def read_index(output):
    with h5py.File(output / "index.h5", "r") as f:
        return f["cases"][:]


@pytest.fixture
def small_study(tmp_path, eme_run_binary):
    output = tmp_path / "out"
    study = write_study(tmp_path, SMALL_STUDY.format(base=ROOT / "inputs" / "paper_fig4_eme_theta.nml",
                                                     output=output))
    return study, output


def test_study_runs_every_case_and_isolates_the_failure(small_study):
    study, output = small_study
    result = ensemble(study)
    assert result.returncode == 0, result.stderr
    index = read_index(output)
    assert len(index) == 4
    statuses = [s.decode() for s in index["status"]]
    assert statuses[:3] == ["complete"] * 3
    assert statuses[3].startswith("failed: incomplete: step 1 (t = 0.1500 s)")
    assert "DIVERGED_MAX_IT" in statuses[3]
    assert [k.decode() for k in index["failure_kind"]] == ["none", "none", "none", "solver"]
    assert sorted(set(index["rank"])) != [0]                     # more than one rank worked
    assert not list(output.glob("*.part"))
    # The index rows are the case files' numbers.
    for row in index:
        data = read_run(output / row["file"].decode())
        steps = len(data["newton_iterations"])
        assert row["steps_completed"] == steps == data["attrs"]["steps_completed"]
        # The index counts the Newton iterations of the completed steps, as the file does.
        assert row["newton_iterations"] == data["newton_iterations"].sum() == data["attrs"]["newton_iterations_total"]
        assert row["scheme"].decode() == data["attrs"]["scheme"] and row["dt"] == data["attrs"]["dt"]
        energy = data["energy"]
        assert row["energy_drift"] == pytest.approx(np.max(np.abs(energy - energy[0])) / abs(energy[0]),
                                                    rel=1e-12, abs=1e-300)
        if steps == 0:
            assert np.isnan(row["min_entropy_increment"]) and np.isnan(row["max_lyapunov_increment"])
            continue
        assert row["min_entropy_increment"] == pytest.approx(np.diff(data["entropy"]).min(), rel=1e-12)
        assert row["max_lyapunov_increment"] == pytest.approx(np.diff(data["lyapunov"]).max(), rel=1e-12)
        assert row["solve_time_seconds"] == pytest.approx(data["attrs"]["solve_time_seconds"])
        # The stability map's figures come from the index: the lowest temperature of the file's
        # points, and the halvings (a step made of k substeps was halved k - 1 times).
        assert row["min_temperature"] == data["temperature"].min()
        assert row["halved_steps"] == (data["substeps"] - 1).sum()
    failed = read_run(output / "case_00004.h5")
    assert failed["attrs"]["status"].startswith("incomplete: step 1") and len(failed["time"]) == 1
    assert failed["attrs"]["failure_kind"] == "solver"
    # A case file names its study, case, overrides and rank, so that an index can be rebuilt.
    first = read_run(output / "case_00001.h5")["attrs"]
    assert first["study_case"] == 1 and first["study"] == str(study)
    overrides = first["study_overrides"].split("; ")
    assert overrides[:2] == ["scheme = 'eme'", "thermo_variable = 'entropy'"] and len(overrides) == 5
    assert float(overrides[2].split(" = ")[1]) == 0.3 and overrides[4] == "newton_max_iterations = 50"
    assert first["study_rank"] == index["rank"][0]


def assert_same_run(single_path, case_path):
    """The datasets and (but for timing and provenance) the attributes of two run files agree."""
    single, case = read_run(single_path), read_run(case_path)
    assert set(single) == set(case)
    assert set(case["attrs"]) - set(single["attrs"]) == {"study", "study_case", "study_overrides", "study_rank",
                                                          "study_case_units", "study_rank_units"}
    for name in single:
        if name not in ("attrs", "step_seconds"):
            assert np.array_equal(single[name], case[name]), name
    # Timing and provenance: the namelists differ in &output file, the command lines in the program.
    timing = {"wall_time_seconds", "solve_time_seconds", "cpu_time_seconds", "solve_cpu_time_seconds", "input_file", "code_version", "study", "study_case",
              "study_overrides", "study_rank", "start_time", "end_time", "command_line", "namelist", "history",
              "title", "text_checksum"}
    for name, value in single["attrs"].items():
        if name not in timing:
            assert np.array_equal(value, case["attrs"][name]), name


def test_case_file_equals_eme_run(small_study, tmp_path):
    study, output = small_study
    assert ensemble(study).returncode == 0
    result, path = run_eme(tmp_path, "same_case", {
        "integrator": {"scheme": "eme", "thermo_variable": "temperature", "dt": 0.15, "t_end": 3.0,
                       "discrete_gradient": "gonzalez", "newton_tol": 1e-8}})
    assert result.returncode == 0
    assert_same_run(path, output / "case_00002.h5")


def dataset_layout(path):
    """Each dataset's shape, type, storage, attributes (the scales' references aside) and
    dimension scales."""
    with h5py.File(path, "r") as f:
        return {name: (d.shape, d.dtype.str, d.chunks, d.compression,
                       [[scale.name for scale in dim.values()] for dim in d.dims],
                       {k: v for k, v in d.attrs.items() if k not in ("DIMENSION_LIST", "REFERENCE_LIST")})
                for name, d in f.items()}


def assert_same_layout(single_path, case_path):
    single, case = dataset_layout(single_path), dataset_layout(case_path)
    assert single.keys() == case.keys()
    for name, (*storage, attrs) in single.items():
        assert storage == list(case[name][:-1]), name
        assert attrs.keys() == case[name][-1].keys(), name
        for key, value in attrs.items():
            assert np.array_equal(value, case[name][-1][key]), (name, key)


@pytest.mark.parametrize("compression", [0, 4])
def test_case_files_of_one_rank_with_a_changing_shape(tmp_path, eme_run_binary, compression):
    """On one rank, a case file of the first case's shape starts from that case's image with its
    datasets, its own values put in place (src/io/hdf5_files, file_template): cases 2, 4 and 5
    (the longest cases run first: case 1 is the rank's first); case 3 has fewer rows and makes
    its datasets itself. Deflated datasets are chunked: no
    values to put in place, every file makes its own. Each must be the file eme_run writes for
    the case: the datasets' values, attributes, storage and dimension scales, and the root
    attributes."""
    output = tmp_path / "out"
    study = write_study(tmp_path, f"""&study base = '{BASE}', output_dir = '{output}', combine = 'zip' /
&sweep field = 't_end', values = 0.9, 0.9, 0.6, 0.9, 0.9 /
&sweep field = 'compression', values = {", ".join([str(compression)] * 5)} /
""")
    result = ensemble(study, ranks=1)
    assert result.returncode == 0, result.stderr
    assert read_index(output)["steps_completed"].tolist() == [6, 6, 4, 6, 6]
    references = {}
    for t_end in (0.6, 0.9):
        result, references[t_end] = run_eme(tmp_path, f"single_{t_end}", {
            "integrator": {"scheme": "eme", "thermo_variable": "temperature", "dt": 0.15, "t_end": t_end,
                           "discrete_gradient": "gonzalez", "newton_tol": 1e-8},
            "output": {"compression": compression}})
        assert result.returncode == 0, result.stderr
    for c, t_end in enumerate((0.9, 0.9, 0.6, 0.9, 0.9), start=1):
        assert_same_run(references[t_end], output / f"case_{c:05d}.h5")
        assert_same_layout(references[t_end], output / f"case_{c:05d}.h5")


def test_restart_reruns_only_what_is_not_complete(small_study):
    study, output = small_study
    assert ensemble(study).returncode == 0
    files = sorted(output.glob("case_*.h5"))
    before = {f.name: f.stat().st_mtime_ns for f in files}
    time.sleep(0.05)
    result = ensemble(study)
    assert result.returncode == 0 and "1 to run (3 complete from an earlier run)" in result.stdout
    after = {f.name: f.stat().st_mtime_ns for f in sorted(output.glob("case_*.h5"))}
    for name in ("case_00001.h5", "case_00002.h5", "case_00003.h5"):
        assert after[name] == before[name], name
    assert after["case_00004.h5"] != before["case_00004.h5"]
    index = read_index(output)
    assert index["run_count"].tolist() == [1, 1, 1, 2]


def test_killed_study_restarts_to_completion(tmp_path, eme_run_binary):
    """SIGKILL while a study has one case file complete and a second case half-written: no file
    under a final name looks finished unless it is, and the restart (on two ranks) completes the
    study, continuing the half-written case from its FILE.part. The kill comes from the LD_PRELOAD
    shim kill_at_write.c, at the second case's first window (writes every 1000 rows: the
    testing hook EME_WRITE_EVERY_ROWS), on one rank so that the cases run in order, the largest
    first: the same point on any machine. (Timed by the clock, the kill found no FILE.part on a
    busy machine, the second case having finished in the meantime.)"""
    output = tmp_path / "out"
    output.mkdir()
    study = write_study(tmp_path, f"""&study base = '{BASE}', output_dir = '{output}', combine = 'zip' /
&sweep field = 'thermo_variable', texts = 'entropy', 'temperature', 'internal_energy' /
&sweep field = 'dt', values = 0.001, 0.002, 0.004 /
""")
    env = dict(operation_shim(output, at=1, match="case_00002.h5.part.spare"), EME_WRITE_EVERY_ROWS="1000")
    killed = subprocess.run([str(BIN / "eme_ensemble"), str(study)], cwd=ROOT, env=env, capture_output=True, text=True,
                            timeout=600)
    assert killed.returncode == -signal.SIGKILL, killed.stdout + killed.stderr
    assert check_run_file(output / "case_00001.h5") == ("complete", 20000)
    status, steps = check_run_file(output / "case_00002.h5.part")
    assert status == "incomplete: running" and 0 < steps < 10000
    assert not (output / "case_00002.h5").exists() and not list(output.glob("case_00003.h5*"))
    result = ensemble(study, ranks=2)
    assert result.returncode == 0, result.stderr
    index = read_index(output)
    assert all(s == b"complete" for s in index["status"])
    assert not list(output.glob("*.part"))
    with h5py.File(output / "case_00002.h5", "r") as f:     # continued from its FILE.part, not run again
        assert len(f.attrs["history"].splitlines()) == 2 and f.attrs["steps_completed"] == 10000


def test_restart_checks_complete_case_files(small_study):
    """A restart trusts no file blindly: a case recorded complete whose file is gone, damaged or
    no longer complete runs again; the others are kept."""
    study, output = small_study
    assert ensemble(study).returncode == 0
    (output / "case_00001.h5").unlink()
    (output / "case_00002.h5").write_bytes(b"not an HDF5 file")
    with h5py.File(output / "case_00003.h5", "r+") as f:
        f.attrs["status"] = "incomplete: edited"
    result = ensemble(study)
    assert result.returncode == 0, result.stderr
    assert "3 cases recorded complete whose files do not check out" in result.stdout
    assert "4 to run (0 complete from an earlier run)" in result.stdout
    index = read_index(output)
    assert index["run_count"].tolist() == [2, 2, 2, 2]
    assert [s.decode() for s in index["status"][:3]] == ["complete"] * 3


@pytest.mark.parametrize("damage", ["garbage", "removed"])
def test_a_damaged_index_is_rebuilt_from_the_case_files(small_study, damage):
    """index.h5 unreadable or gone: the case files, which name their case and overrides and
    hold its figures, give back every complete row; only the failed case runs again."""
    study, output = small_study
    assert ensemble(study).returncode == 0
    before = read_index(output)
    if damage == "garbage":
        (output / "index.h5").write_bytes(b"\0" * 100)
    else:
        (output / "index.h5").unlink()
    result = ensemble(study)
    assert result.returncode == 0, result.stderr
    assert "3 complete cases recovered from their files" in result.stdout
    assert "1 to run (3 complete from an earlier run)" in result.stdout
    after = read_index(output)
    for name in before.dtype.names:
        if name in ("run_count", "wall_time_seconds", "cpu_time_seconds"):
            continue
        equal_nan = before[name].dtype.kind == "f"
        assert np.array_equal(before[name][:3], after[name][:3], equal_nan=equal_nan), name
    for row in after[:3]:     # the file's wall and CPU times: the run up to closing its file
        for name in ("wall_time_seconds", "cpu_time_seconds"):
            assert row[name] == read_run(output / row["file"].decode())["attrs"][name]
    assert after["run_count"].tolist() == [1, 1, 1, 1]     # the failed case's earlier run is not on record


def test_a_study_from_elsewhere_is_refused(small_study, tmp_path):
    """A finished case (case 1, complete) whose value changed: bad input, exit 2, nothing written.
    (A changed value of a case that did not finish is no loss: tests/e2e/test_damaged_studies.py
    has the grown and changed studies.)"""
    study, output = small_study
    assert ensemble(study).returncode == 0
    before = {p.name: p.stat().st_mtime_ns for p in output.iterdir()}
    other = write_study(tmp_path, SMALL_STUDY.replace("0.3, 0.15, 0.15, 0.15", "0.25, 0.15, 0.15, 0.15").format(
        base=ROOT / "inputs" / "paper_fig4_eme_theta.nml", output=output), name="other")
    result = ensemble(other)
    assert result.returncode == 2
    assert "case 1 (" in result.stderr and "is complete, but" in result.stderr
    assert {p.name: p.stat().st_mtime_ns for p in output.iterdir()} == before


INDEX_ONLY_STUDY = """&study base = '{base}', output_dir = '{output}', index_only = {index_only} /
&sweep field = 'theta(2)', values = {values} /
"""
# 60 paper-scene cases: the tests below stop the study at a chosen file operation (the LD_PRELOAD
# shim kill_at_write.c) after a few of them, so that cases are left whatever the machine's speed.
# (Signalled by the clock, 0.3 s after its second case, the study needed 2400 cases to be still
# running on an idle machine, and could still finish first on a busy one.)
LARGE_STUDY = """&study base = '{base}', output_dir = '{output}', index_only = .false. /
&sweep field = 'theta(1)', values = {values1} /
&sweep field = 'theta(2)', values = {values2} /
"""


def large_study(tmp_path, output):
    return write_study(tmp_path, LARGE_STUDY.format(
        base=ROOT / "inputs" / "paper_fig4_eme_theta.nml", output=output,
        values1=", ".join(f"{270 + 0.5 * i:.1f}" for i in range(10)),
        values2=", ".join(f"{340 + 0.5 * i:.1f}" for i in range(6))))


def test_an_index_only_study_matches_the_full_one(tmp_path, eme_run_binary):
    """index_only = .true.: no case files, and every figure of the index as the study with files
    gives it (timings aside)."""
    indexes = {}
    for index_only in (".true.", ".false."):
        output = tmp_path / index_only.strip(".")
        study = write_study(tmp_path, INDEX_ONLY_STUDY.format(
            base=ROOT / "inputs" / "paper_fig4_eme_theta.nml", output=output, index_only=index_only,
            values="340, 345, 350, 355"), name=index_only.strip("."))
        assert ensemble(study, ranks=2).returncode == 0
        indexes[index_only] = read_index(output)
        with h5py.File(output / "index.h5", "r") as f:
            assert f.attrs["index_only"] == (1 if index_only == ".true." else 0)
    assert sorted(p.name for p in (tmp_path / "true").iterdir()) == ["index.h5"]
    lean, full = indexes[".true."], indexes[".false."]
    assert lean["file"].tolist() == [b""] * 4 and full["file"].tolist()[0] == b"case_00001.h5"
    for name in lean.dtype.names:
        if name not in ("file", "wall_time_seconds", "solve_time_seconds", "cpu_time_seconds", "solve_cpu_time_seconds",
                        "rank"):
            assert np.array_equal(lean[name], full[name]), name


@pytest.mark.parametrize("given, kept_files", [("", False), ("index_only = .false.", True)])
def test_a_study_of_1000_cases_keeps_only_its_index_unless_told(tmp_path, eme_run_binary, given, kept_files):
    """From 1000 cases on, index_only is on by default; &study index_only = .false. keeps the files."""
    output = tmp_path / "out"
    study = write_study(tmp_path, f"""&study
  base = '{ROOT / "inputs" / "paper_fig4_eme_theta.nml"}'
  output_dir = '{output}'
  {given}
/
&sweep field = 't_end', values = 0.15 /
&sweep field = 'theta(1)', values = {", ".join(f"{270 + i:.1f}" for i in range(40))} /
&sweep field = 'theta(2)', values = {", ".join(f"{340 + i:.1f}" for i in range(25))} /
""")
    result = ensemble(study, ranks=2)
    assert result.returncode == 0, result.stderr
    assert ("only the index is kept" in result.stdout) != kept_files
    assert len(read_index(output)) == 1000
    assert len(list(output.glob("case_*.h5"))) == (1000 if kept_files else 0)


def test_a_killed_index_only_study_resumes_from_its_journal(tmp_path, eme_run_binary):
    """SIGKILL to every rank of an index-only study: index.h5 lags behind (it is rewritten every
    2 s), the journal does not; the restart takes every recorded result from it and runs only
    the rest, so no case runs twice."""
    output = tmp_path / "out"
    values = ", ".join(f"{340 + 0.1 * i:.1f}" for i in range(200))
    study = write_study(tmp_path, INDEX_ONLY_STUDY.format(base=ROOT / "inputs" / "paper_fig4_eme_theta.nml",
                                                         output=output, index_only=".true.", values=values))
    # Rank 0 keeps the journal: the shim stops it (SIGSTOP) before its 25th operation on it (the
    # removal of an old one, the header, then a line per result), so the study cannot end before
    # the kill, however fast it runs.
    output.mkdir()
    env = operation_shim(output, at=25, match="index.journal", signal_number=signal.SIGSTOP)
    process = subprocess.Popen([*MPIRUN, "-n", "2", *mpirun_env_options(env), str(BIN / "eme_ensemble"), str(study)],
                               cwd=ROOT, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    journal = output / "index.journal"
    assert wait_for(lambda: any(is_stopped(pid) for pid in processes_naming(str(study))))
    kill_processes_naming(str(study))
    process.wait()
    recorded = journal.read_text().count("\n") - 1
    assert recorded >= 20
    result = ensemble(study, ranks=2)
    assert result.returncode == 0, result.stderr
    match = re.search(r"(\d+) results taken from .*index.journal", result.stdout)
    assert match and int(match.group(1)) >= recorded - 1, result.stdout
    index = read_index(output)
    assert all(s == b"complete" for s in index["status"])
    assert index["run_count"].tolist() == [1] * 200
    assert not journal.exists()


def test_sigterm_stops_a_study_cleanly(tmp_path, eme_run_binary):
    """SIGTERM (one rank, no mpirun: its exit status is ours): no new case, the running one ends
    marked interrupted, the index is written and the journal emptied; exit 143; a restart
    finishes the study. The study sends itself the SIGTERM (the LD_PRELOAD shim kill_at_write.c)
    at its first file operation on case 3's file: cases 1 and 2 are complete by then."""
    output = tmp_path / "out"
    output.mkdir()
    study = large_study(tmp_path, output)
    result = subprocess.run([str(BIN / "eme_ensemble"), str(study)], cwd=ROOT, capture_output=True, text=True,
                            timeout=600, env=operation_shim(output, at=1, match="case_00003.h5",
                                                            signal_number=signal.SIGTERM))
    code, out, err = result.returncode, result.stdout, result.stderr
    assert code == 143, err
    assert "SIGTERM received: no new cases" in out
    index = read_index(output)
    statuses = [s.decode() for s in index["status"]]
    assert 2 <= statuses.count("complete") <= 3 and statuses.count("incomplete: interrupted by SIGTERM") <= 1
    assert statuses.count("pending") >= 57
    assert set(statuses) <= {"complete", "pending", "incomplete: interrupted by SIGTERM"}
    assert not (output / "index.journal").exists() and not list(output.glob("*.part"))
    for row in index:
        if row["status"] != b"pending":
            status, steps = check_run_file(output / row["file"].decode())
            assert status == row["status"].decode() and steps == row["steps_completed"]
    result = ensemble(study, ranks=2)
    assert result.returncode == 0, result.stderr
    assert all(s == b"complete" for s in read_index(output)["status"])


def slurm_job(tmp_path, scontrol):
    """The Slurm example on a study of 60 cases, with a stand-in `scontrol` (the script's text)
    first on PATH, run as Slurm would up to its warning: SIGTERM to the batch script while the
    study runs. Rank 0 holds at its fifth operation on the journal (the LD_PRELOAD shim
    kill_at_write.c: three cases recorded), so the study cannot end first; the test sends the
    SIGTERM once the script's trap is set, waits until the held rank has caught it (Open MPI's
    mpirun passes it on 1 s later), and lets the rank go on. The script's (return code, stdout,
    stderr), the output folder, and the script's command and environment (without the shim)."""
    output = tmp_path / "out"
    output.mkdir()
    study = large_study(tmp_path, output)
    tools = tmp_path / "bin"
    tools.mkdir()
    (tools / "scontrol").write_text(scontrol)
    (tools / "scontrol").chmod(0o755)
    env = dict(os.environ, PATH=f"{tools}:{os.environ['PATH']}", SLURM_JOB_ID="4242",
               EME_LAUNCHER=" ".join([*MPIRUN, "-n", "2"]))
    script = ["bash", str(ROOT / "inputs" / "slurm_study.sbatch"), str(study)]
    release = tmp_path / "release"
    held = operation_shim(output, at=5, match="index.journal", hold=release, env=env)
    held["EME_LAUNCHER"] = " ".join([*MPIRUN, "-n", "2", *mpirun_env_options(held)])
    job = subprocess.Popen(script, env=held, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        rank = held_process(release)
        assert wait_for(lambda: signal_caught(job.pid, signal.SIGTERM)), "the script set no trap for SIGTERM"
        job.send_signal(signal.SIGTERM)
        assert wait_for(lambda: not signal_caught(rank, signal.SIGTERM)), "the held rank never caught SIGTERM"
    finally:
        release.touch()
    out, err = job.communicate(timeout=600)
    return (job.returncode, out, err), output, script, env


def test_the_slurm_example_requeues_a_study_stopped_by_its_time_limit(tmp_path, eme_run_binary):
    """inputs/slurm_study.sbatch run as Slurm would: SIGTERM to the batch script before the time
    limit stops the study cleanly and requeues the job (a stand-in scontrol records the call);
    the requeued job finishes the study and does not requeue."""
    (code, out, err), output, script, env = slurm_job(tmp_path, f"#!/bin/sh\necho \"$@\" >> {tmp_path / 'scontrol.log'}\n")
    assert code == 0, out + err
    assert "time limit near" in out
    assert (tmp_path / "scontrol.log").read_text() == "requeue 4242\n"
    assert "pending" in {s.decode() for s in read_index(output)["status"]}
    result = subprocess.run(script, capture_output=True, text=True, env=env, cwd=ROOT, timeout=300)
    assert result.returncode == 0, result.stdout + result.stderr
    assert all(s == b"complete" for s in read_index(output)["status"])
    assert (tmp_path / "scontrol.log").read_text() == "requeue 4242\n"


def test_the_slurm_example_fails_when_the_requeue_fails(tmp_path, eme_run_binary):
    """If scontrol cannot requeue the job (a stand-in that fails), the script exits non-zero, so
    that Slurm reports the unfinished study as failed. Before: it exited 0."""
    (code, out, err), output, _, _ = slurm_job(tmp_path, "#!/bin/sh\necho 'scontrol: error: Invalid job id' >&2\nexit 1\n")
    assert code == 1, out + err
    assert "scontrol requeue 4242 failed: the study is unfinished" in err
    assert "pending" in {s.decode() for s in read_index(output)["status"]}


def test_single_rank_without_mpirun(small_study, tmp_path):
    study, output = small_study
    result = subprocess.run([str(BIN / "eme_ensemble"), str(study)], capture_output=True, text=True, cwd=ROOT)
    assert result.returncode == 0, result.stderr
    assert read_index(output)["rank"].tolist() == [0, 0, 0, 0]
    # Case 1 has the fewest steps, so it runs last, on a solver the other cases used before:
    # it must still be the run eme_run makes.
    result, path = run_eme(tmp_path, "last_case", {
        "integrator": {"scheme": "eme", "thermo_variable": "entropy", "dt": 0.3, "t_end": 3.0}})
    assert result.returncode == 0
    assert_same_run(path, output / "case_00001.h5")


def test_a_logical_field_is_swept(tmp_path, eme_run_binary):
    output = tmp_path / "out"
    study = write_study(tmp_path, f"""&study base = '{ROOT / "inputs" / "paper_fig4_eme_theta.nml"}',
  output_dir = '{output}' /
&sweep field = 't_end', values = 0.6 /
&sweep field = 'fix_temperature', texts = '.true.', '.false.', '.true.' /
""")
    result = subprocess.run([str(BIN / "eme_ensemble"), str(study)], capture_output=True, text=True, cwd=ROOT)
    assert result.returncode == 0, result.stderr
    assert [s.decode() for s in read_index(output)["fix_temperature"]] == [".true.", ".false.", ".true."]
    runs = [read_run(output / f"case_0000{c}.h5") for c in (1, 2, 3)]
    assert [run["attrs"]["fix_temperature"] for run in runs] == [1, 0, 1]
    assert [run["attrs"]["unknowns"] for run in runs] == [16, 15, 16]
    # On one rank each case's file starts from the first's root attributes (the rank's
    # template): the constrained cases' constraint_meanings must not reach the unconstrained one.
    assert ["constraint_meanings" in run["attrs"] for run in runs] == [True, False, True]


@pytest.mark.parametrize("text,words", [
    ("&study base = '{BASE}' /\n&sweep field = 'dtt', values = 0.1 /\n",
     ["&sweep 'dtt'", "'dtt' is not a field of an eme_run namelist group"]),
    ("&study base = '{BASE}' /\n&sweep field = 'dt', values = -0.1 /\n",
     ["&sweep 'dt'", "dt = -0.1 is not allowed", "case 1 of the study"]),
    ("&study base = '{BASE}', combine = 'zip' /\n"
     "&sweep field = 'dt', values = 0.1, 0.2 /\n&sweep field = 't_end', values = 1.0 /\n",
     ["combine = 'zip' needs sweeps of equal length"]),
    ("&study combine = 'cartesian' /\n", ["&study", "base is missing"]),
    ("&study base = '{BASE}', combine = 'cartesian' /\n",
     ["combine = 'cartesian' is not allowed", "'product' or 'zip'"]),
    ("&studdy base = 'x' /\n", ["unknown namelist group &studdy"]),
    ("&study base = 'inputs/missing.nml' /\n", ["inputs/missing.nml: cannot read the input file"]),
    ("&study base = '{BASE}' /\n&sweep field = 'scheme', texts = 'eme', 'rk4' /\n",
     ["scheme = 'rk4' is not allowed", "case 2 of the study"]),
])
def test_bad_study_input(tmp_path, eme_run_binary, text, words):
    output = tmp_path / "out"
    study = write_study(tmp_path, text.replace("{BASE}", str(BASE)), name=f"bad_{tmp_path.name}")   # its default output_dir is unused
    result = subprocess.run([str(BIN / "eme_ensemble"), str(study)], capture_output=True, text=True, cwd=ROOT)
    assert result.returncode == 2
    assert str(study) in result.stderr or "inputs/missing.nml" in result.stderr
    for word in words:
        assert word in result.stderr, result.stderr
    assert not output.exists() and not (ROOT / "results" / study.stem).exists()


def test_array_sweeps_and_the_one_path_rule(tmp_path, eme_run_binary):
    """Sweeps over a section ('p2(1:2)') and a whole array ('mass'), two values per case, in a
    product and in a zip; run from another folder, base (an input the study file names) is found
    beside the study file and output_dir (an output) in the current folder, as eme_run's &output
    file. Before: every such sweep was refused ('p2(1:2)' took one value per case); output_dir
    was relative to the study file while its default and eme_run's outputs were not."""
    folder = tmp_path / "studies"
    folder.mkdir()
    (folder / "scene.nml").write_text("&integrator t_end = 0.3 /\n")
    for combine, count in (("product", 4), ("zip", 2)):
        study = folder / f"{combine}.nml"
        study.write_text(f"&study base = 'scene.nml', output_dir = 'out_{combine}', combine = '{combine}' /\n"
                         "&sweep field = 'p2(1:2)', values = -1, -1,  -2, -3 /\n"
                         "&sweep field = 'mass', values = 1, 1,  2, 3 /\n")
        result = subprocess.run([str(BIN / "eme_ensemble"), str(study.relative_to(tmp_path))], capture_output=True,
                                text=True, cwd=tmp_path, timeout=120)
        assert result.returncode == 0, result.stderr
        assert not (folder / f"out_{combine}").exists()
        assert f"index out_{combine}/index.h5" in result.stdout
        index = read_index(tmp_path / f"out_{combine}")
        assert len(index) == count
        pairs = [((r["p2(1)"], r["p2(2)"]), (r["mass(1)"], r["mass(2)"])) for r in index]
        expected = [((-1, -1), (1, 1)), ((-1, -1), (2, 3)), ((-2, -3), (1, 1)), ((-2, -3), (2, 3))]
        assert pairs == (expected if combine == "product" else [expected[0], expected[3]])
        for row in index:
            run = read_run(tmp_path / f"out_{combine}" / row["file"].decode())
            assert list(run["attrs"]["mass"]) == [row["mass(1)"], row["mass(2)"]]
            np.testing.assert_array_equal(run["state"][0, 9:11], [row["p2(1)"], row["p2(2)"]])
    bad = folder / "bad.nml"
    bad.write_text("&study base = 'scene.nml' /\n&sweep field = 'mass', values = 1, 2, 3 /\n")
    result = subprocess.run([str(BIN / "eme_ensemble"), str(bad)], capture_output=True, text=True, timeout=120)
    assert result.returncode == 2
    assert "&sweep 'mass': 3 values for 2 elements; allowed: a multiple of 2" in result.stderr


def test_the_index_carries_units_and_the_run_files_provenance(small_study, tmp_path):
    """The index, the only record of a large study, says the unit of every column (one per
    column, in order: the swept field's from the input tables, seconds for times, '' for texts)
    and carries the provenance a run file carries (CF global attributes, command line, PETSc
    options, versions, host, start time), with a history naming the study. Before: no units and
    only the study's settings."""
    study, output = small_study
    result = ensemble(study, ranks=2)
    assert result.returncode == 0, result.stderr
    run, _ = run_eme(tmp_path, "single", {"integrator": {"t_end": 0.3}})
    assert run.returncode == 0, run.stderr
    with h5py.File(output / "index.h5", "r") as f, h5py.File(tmp_path / "single.h5", "r") as single:
        cases = f["cases"]
        units = dict(zip(cases.dtype.names, [u.decode() if isinstance(u, bytes) else u
                                             for u in cases.attrs["column_units"]]))
        assert len(units) == len(cases.dtype.names)
        assert units["dt"] == "s" and units["wall_time_seconds"] == "s" and units["min_temperature"] == "K"
        assert units["status"] == "" and units["scheme"] == "" and units["case"] == "1"
        provenance = ["Conventions", "title", "institution", "source", "history", "references", "command_line",
                      "petsc_options", "code_version", "host", "start_time"]
        versions = sorted(name for name in single.attrs if name.startswith("version_"))
        assert versions and set(provenance + versions) <= set(f.attrs)
        assert f.attrs["Conventions"] == single.attrs["Conventions"] == "CF-1.8"
        assert str(study) in f.attrs["history"] and "eme_ensemble" in f.attrs["command_line"]
        assert all(f.attrs[name] == single.attrs[name] for name in versions + ["code_version", "references"])
