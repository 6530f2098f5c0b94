"""eme_ensemble under mpirun: every case of a small study completes, a case's file equals the
same case run by eme_run, a failing case is isolated, a restarted study reruns only what is not
complete, a killed study leaves no file that looks finished, and bad study input is rejected."""
import os
import signal
import subprocess
import time
from pathlib import Path

import h5py
import numpy as np
import pytest

from conftest import BIN, ROOT, read_run, run_eme

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
    """SIGKILL every process whose command line contains `text` (Linux /proc; no procps needed).
    Open MPI puts its ranks in process groups of their own, so a process group kill misses them."""
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            command = (entry / "cmdline").read_bytes()
        except OSError:        # the process has ended meanwhile
            continue
        if text.encode() in command:
            try:
                os.kill(int(entry.name), signal.SIGKILL)
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
    assert sorted(set(index["rank"])) != [0]                     # more than one rank worked
    assert not list(output.glob("*.part"))
    # The index rows are the case files' numbers.
    for row in index:
        data = read_run(output / row["file"].decode())
        steps = len(data["newton_iterations"])
        assert row["steps_completed"] == steps == data["attrs"]["steps_completed"]
        # The index counts every Newton iteration, also those of a step that failed.
        if row["status"] == b"complete":
            assert row["newton_iterations"] == data["newton_iterations"].sum()
        else:
            assert row["newton_iterations"] > data["newton_iterations"].sum()
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
    failed = read_run(output / "case_00004.h5")
    assert failed["attrs"]["status"].startswith("incomplete: step 1") and len(failed["time"]) == 1


def assert_same_run(single_path, case_path):
    """The datasets and (but for timing and provenance) the attributes of two run files agree."""
    single, case = read_run(single_path), read_run(case_path)
    assert set(single) == set(case)
    for name in single:
        if name != "attrs":
            assert np.array_equal(single[name], case[name]), name
    timing = {"wall_time_seconds", "solve_time_seconds", "input_file", "code_version"}
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
    output = tmp_path / "out"
    study = write_study(tmp_path, f"""&study base = '{ROOT / "inputs" / "paper_fig4_eme_theta.nml"}',
  output_dir = '{output}' /
&sweep field = 'thermo_variable', texts = 'entropy', 'temperature', 'internal_energy' /
&sweep field = 'dt', values = 0.004, 0.002, 0.001 /
""")
    process = subprocess.Popen([*MPIRUN, "-n", "2", str(BIN / "eme_ensemble"), str(study)], cwd=ROOT,
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    # Kill as soon as the first case has finished: the largest ones are still running then.
    deadline = time.time() + 120
    while not list(output.glob("case_*.h5")) and time.time() < deadline:
        time.sleep(0.05)
    kill_processes_naming(str(study))
    process.wait()
    # No file under a final name may look finished unless it is.
    for path in output.glob("case_*.h5"):
        with h5py.File(path, "r") as f:
            assert f.attrs["status"] != "incomplete: running", path
    assert list(output.glob("*.part")), "the kill should have caught cases mid-run"
    result = ensemble(study, ranks=2)
    assert result.returncode == 0, result.stderr
    index = read_index(output)
    assert all(s == b"complete" for s in index["status"])


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
&sweep field = 'fix_temperature', texts = '.false.', '.true.' /
""")
    result = subprocess.run([str(BIN / "eme_ensemble"), str(study)], capture_output=True, text=True, cwd=ROOT)
    assert result.returncode == 0, result.stderr
    assert [s.decode() for s in read_index(output)["fix_temperature"]] == [".false.", ".true."]
    runs = [read_run(output / f"case_0000{c}.h5") for c in (1, 2)]
    assert [run["attrs"]["fix_temperature"] for run in runs] == [0, 1]
    assert [run["attrs"]["unknowns"] for run in runs] == [15, 16]


@pytest.mark.parametrize("text,words", [
    ("&study base = 'inputs/paper_fig4_eme_theta.nml' /\n&sweep field = 'dtt', values = 0.1 /\n",
     ["&sweep 'dtt'", "'dtt' is not a field of an eme_run namelist group"]),
    ("&study base = 'inputs/paper_fig4_eme_theta.nml' /\n&sweep field = 'dt', values = -0.1 /\n",
     ["&sweep 'dt'", "dt = -0.1 is not allowed", "case 1 of the study"]),
    ("&study base = 'inputs/paper_fig4_eme_theta.nml', combine = 'zip' /\n"
     "&sweep field = 'dt', values = 0.1, 0.2 /\n&sweep field = 't_end', values = 1.0 /\n",
     ["combine = 'zip' needs sweeps of equal length"]),
    ("&study combine = 'cartesian' /\n", ["&study", "base is missing"]),
    ("&study base = 'inputs/paper_fig4_eme_theta.nml', combine = 'cartesian' /\n",
     ["combine = 'cartesian' is not allowed", "'product' or 'zip'"]),
    ("&studdy base = 'x' /\n", ["unknown namelist group &studdy"]),
    ("&study base = 'inputs/missing.nml' /\n", ["inputs/missing.nml: cannot read the input file"]),
    ("&study base = 'inputs/paper_fig4_eme_theta.nml' /\n&sweep field = 'scheme', texts = 'eme', 'rk4' /\n",
     ["scheme = 'rk4' is not allowed", "case 2 of the study"]),
])
def test_bad_study_input(tmp_path, eme_run_binary, text, words):
    output = tmp_path / "out"
    study = write_study(tmp_path, text, name=f"bad_{tmp_path.name}")   # its default output_dir is unused
    result = subprocess.run([str(BIN / "eme_ensemble"), str(study)], capture_output=True, text=True, cwd=ROOT)
    assert result.returncode == 2
    assert str(study) in result.stderr or "inputs/missing.nml" in result.stderr
    for word in words:
        assert word in result.stderr, result.stderr
    assert not output.exists() and not (ROOT / "results" / study.stem).exists()
