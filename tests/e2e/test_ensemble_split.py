"""eme_ensemble on chain cases beyond the dense path's 1000 unknowns (issue 39, item 3): each runs
on the split path (src/run/distributed_simulation.f90) on its own rank, as `eme_run` runs it on
one process, beside small chain cases on the dense path in the same study.
- the large case's file is eme_run's split file of the same input, bit for bit in every per-step
  dataset and snapshot (both are one process on the same code), and names its study, case,
  overrides and rank; the small case's file is a dense one (/state);
- the large case's index row holds its file's summary, every metric of the index;
- a study killed while its large case is half written continues that case from its FILE.part
  (its last snapshot) when run again, and ends with the uninterrupted run's file;
- an index-only study runs the large case without a file, with the same index row."""
import signal
import subprocess

import h5py
import numpy as np
import pytest

from conftest import BIN, ROOT, namelist_text, run_eme
from faults import operation_shim
from test_ensemble import MPIRUN, read_index

LARGE, SMALL = 300, 15        # springs: 4 N unknowns in 1D fixed-free, 1200 (split) and 60 (dense: EME splits beyond 64)
DT, STEPS, SNAPSHOT_EVERY = 1.0e-3, 60, 5


def rod(links, snapshot_every=SNAPSHOT_EVERY):
    """inputs/chain_rod.nml's rod (the continuum family) with `links` springs, STEPS steps of DT."""
    return {"model": {"model_name": "spring_chain", "family": "rod", "links": links, "ends": "fixed-free",
                      "dimension": 1},
            "initial": {"theta": 280.0, "perturbation": "random", "amplitude": 2.0e-4, "seed": 7},
            "integrator": {"scheme": "eme", "thermo_variable": "temperature", "dt": DT, "t_end": DT * STEPS,
                           "newton_tol": 1.0e-9},
            "output": {"snapshot_every": snapshot_every}}


def write_study(folder, links=(LARGE, SMALL), index_only=False, snapshot_every=SNAPSHOT_EVERY):
    """A study in `folder` of the rod with each of `links` springs; the study file and its
    output_dir."""
    folder.mkdir(exist_ok=True)
    base = folder / "base.nml"
    groups = rod(SMALL, snapshot_every)
    groups["output"]["file"] = str(folder / "base.h5")
    base.write_text(namelist_text(groups))
    output = folder / "out"
    study = folder / "study.nml"
    study.write_text(f"""&study base = '{base}', output_dir = '{output}', index_only = {'.true.' if index_only else '.false.'} /
&sweep field = 'links', values = {', '.join(str(n) for n in links)} /
""")
    return study, output


def ensemble(study, ranks=2, env=None):
    launcher = [*MPIRUN, "-n", str(ranks)] if ranks > 1 else []
    return subprocess.run([*launcher, str(BIN / "eme_ensemble"), str(study)], capture_output=True, text=True,
                          timeout=600, cwd=ROOT, env=env)


def per_step_datasets(f):
    """The root datasets with a row per point or step, but the steps' wall-clock seconds."""
    rows = (f["time"].shape[0], f["step"].shape[0])
    return sorted(name for name, item in f.items()
                  if isinstance(item, h5py.Dataset) and item.shape[:1] and item.shape[0] in rows
                  and name != "step_seconds")


def assert_same_split_file(reference, case):
    """`case` holds `reference`'s per-step datasets and snapshots, bit for bit."""
    with h5py.File(reference, "r") as a, h5py.File(case, "r") as b:
        assert b.attrs["status"] == "complete", b.attrs["status"]
        assert "state" not in b and "snapshots" in b
        names = per_step_datasets(a)
        assert per_step_datasets(b) == names and "energy" in names and "min_link_production" in names
        for name in names:
            assert np.array_equal(a[name][()], b[name][()], equal_nan=True), name
        assert sorted(a["snapshots"]) == sorted(b["snapshots"])
        for name in a["snapshots"]:
            assert np.array_equal(a["snapshots"][name][()], b["snapshots"][name][()]), name
        assert b["snapshots/time"].shape == (STEPS // SNAPSHOT_EVERY + 1,)


def eme_run_reference(tmp_path, links=LARGE):
    result, path = run_eme(tmp_path, "reference", rod(links), timeout=600)
    assert result.returncode == 0, result.stderr
    return path


def test_a_large_chain_case_is_eme_runs_split_run(tmp_path, eme_run_binary):
    study, output = write_study(tmp_path)
    result = ensemble(study)
    assert result.returncode == 0, result.stdout + result.stderr
    index = read_index(output)
    assert [s.decode() for s in index["status"]] == ["complete", "complete"]
    assert_same_split_file(eme_run_reference(tmp_path), output / "case_00001.h5")
    with h5py.File(output / "case_00001.h5", "r") as f:
        assert f.attrs["unknowns"] == 4 * LARGE
        assert f.attrs["study"] == str(study) and f.attrs["study_case"] == 1
        assert f.attrs["study_overrides"] == f"links = {LARGE}"
        assert f.attrs["study_rank"] == index["rank"][0]
    with h5py.File(output / "case_00002.h5", "r") as f:      # the small chain: the dense path
        assert f.attrs["unknowns"] == 4 * SMALL and f["state"].shape == (STEPS + 1, 4 * SMALL)
        assert "snapshots" not in f and f.attrs["study_overrides"] == f"links = {SMALL}"


def test_a_study_run_again_keeps_its_finished_large_case(tmp_path, eme_run_binary):
    """docs/studies.md: running the same study again keeps what an earlier run completed. The
    restart trusts a finished file whose summary figures its rows give; the split path's energy
    drift is max_n |E_n - E_0|/|E_0| of its /energy rows as the dense path's (it was the running
    sum of the steps' changes, below what the rows give, and every finished large case ran again).
    Planted: that running sum back, the figure is 4.2e-16 where the rows give 1.5e-15."""
    study, output = write_study(tmp_path)
    first = ensemble(study)
    assert first.returncode == 0, first.stdout + first.stderr
    large = output / "case_00001.h5"
    with h5py.File(large, "r") as f:
        energy = f["energy"][()]
        assert f.attrs["run_figures"][0] == np.max(np.abs(energy - energy[0])) / abs(energy[0])
    written = large.read_bytes()
    again = ensemble(study)
    assert again.returncode == 0, again.stdout + again.stderr
    assert "run again" not in again.stdout + again.stderr
    assert read_index(output)["run_count"].tolist() == [1, 1]
    assert large.read_bytes() == written


def assert_row_is_file_summary(row, path):
    """Every metric of the index row against the case file's summary attributes, and those
    against its datasets where they follow from them."""
    with h5py.File(path, "r") as f:
        attrs = dict(f.attrs)
        newton, entropy, energy = f["newton_iterations"][()], f["entropy"][()], f["energy"][()]
        theta = f["snapshots/theta"][()]
    # run_figures: energy_drift, min_entropy_increment, max_lyapunov_increment,
    # angular_momentum_drift, min_temperature, halved_steps, rejected_steps (docs/output.md)
    figures = dict(zip(["energy_drift", "min_entropy_increment", "max_lyapunov_increment", "angular_momentum_drift",
                        "min_temperature", "halved_steps", "rejected_steps"], attrs["run_figures"]))
    expected = dict(figures, steps_completed=attrs["steps_completed"], steps_planned=attrs["steps_planned"],
                    newton_iterations=attrs["newton_iterations_total"], wall_time_seconds=attrs["wall_time_seconds"],
                    solve_time_seconds=attrs["solve_time_seconds"], cpu_time_seconds=attrs["cpu_time_seconds"],
                    solve_cpu_time_seconds=attrs["solve_cpu_time_seconds"], warned=int("warnings" in attrs),
                    rank=attrs["study_rank"], run_count=1)
    metrics = [name for name in row.dtype.names if name not in ("case", "file", "links", "status", "failure_kind")]
    assert sorted(metrics) == sorted(name for name in expected if name in row.dtype.names)
    assert "angular_momentum_drift" not in metrics        # a 1D chain has no momentum
    for name in metrics:
        if name in ("wall_time_seconds", "cpu_time_seconds"):
            # The file's: the run up to its last write; the index's: to its end, the write included.
            assert expected[name] <= row[name] < expected[name] + 60, name
        else:
            assert np.array_equal(row[name], expected[name], equal_nan=True), name
    assert row["status"] == b"complete" and row["failure_kind"] == b"none"
    # The figures from the datasets (the split path sums each step's differences spring by spring,
    # so E_n - E_0 and S_n - S_(n-1) agree with the totals' to rounding only).
    assert row["steps_completed"] == row["steps_planned"] == newton.size == STEPS
    assert row["newton_iterations"] == newton.sum()
    assert row["min_temperature"] == theta.min()                    # a snapshot every step: every state
    scale = np.abs(energy).max() * 1e-13
    assert abs(row["energy_drift"] * abs(energy[0]) - np.abs(energy - energy[0]).max()) <= scale
    assert row["min_entropy_increment"] == pytest.approx(np.diff(entropy).min(), rel=1e-6, abs=1e-15)
    assert row["min_entropy_increment"] > 0


def test_a_large_chain_cases_index_row_is_its_files_summary(tmp_path, eme_run_binary):
    study, output = write_study(tmp_path, links=(LARGE,), snapshot_every=1)
    result = ensemble(study, ranks=1)
    assert result.returncode == 0, result.stdout + result.stderr
    index = read_index(output)
    assert_row_is_file_summary(index[0], output / "case_00001.h5")
    # An index-only study: no file, and the same row but for the timings.
    lean_study, lean_output = write_study(tmp_path / "lean", links=(LARGE,), index_only=True, snapshot_every=1)
    result = ensemble(lean_study, ranks=1)
    assert result.returncode == 0, result.stdout + result.stderr
    assert sorted(p.name for p in lean_output.iterdir()) == ["index.h5"]
    lean = read_index(lean_output)
    for name in index.dtype.names:
        if name not in ("file", "wall_time_seconds", "solve_time_seconds", "cpu_time_seconds",
                        "solve_cpu_time_seconds"):
            assert np.array_equal(lean[name], index[name], equal_nan=index[name].dtype.kind == "f"), name


def test_a_killed_study_continues_its_large_case_from_its_last_snapshot(tmp_path, eme_run_binary):
    """SIGKILL (the LD_PRELOAD shim kill_at_write.c) amid the large case's writes: its file is
    written every 3 rows (EME_WRITE_EVERY_ROWS), each window about 55 operations on its spare
    (HDF5's and MPI-IO's writes of the rows and snapshots, the rename), and the 420th of them,
    in the seventh window or so, kills the study, on one rank so that the large case runs first:
    the same point on any machine. Its FILE.part is left incomplete with some snapshots; the
    study run again on two ranks goes on from the last of them (the file's history gains a
    line) and ends with eme_run's uninterrupted file, bit for bit."""
    study, output = write_study(tmp_path)
    output.mkdir()
    env = dict(operation_shim(output, at=420, match="case_00001.h5.part.spare"), EME_WRITE_EVERY_ROWS="3")
    killed = ensemble(study, ranks=1, env=env)
    assert killed.returncode == -signal.SIGKILL, killed.stdout + killed.stderr
    with h5py.File(output / "case_00001.h5.part", "r") as f:
        assert f.attrs["status"] == "incomplete: running"
        assert 0 < f["step"].shape[0] < STEPS
        assert 1 < f["snapshots/time"].shape[0] < STEPS // SNAPSHOT_EVERY + 1
    assert not (output / "case_00001.h5").exists()
    result = ensemble(study, ranks=2)
    assert result.returncode == 0, result.stdout + result.stderr
    assert all(s == b"complete" for s in read_index(output)["status"])
    assert not list(output.glob("*.part*"))
    with h5py.File(output / "case_00001.h5", "r") as f:      # continued, not run again
        assert len(f.attrs["history"].splitlines()) == 2
    assert_same_split_file(eme_run_reference(tmp_path), output / "case_00001.h5")


def test_a_case_the_split_path_cannot_run_is_refused_naming_the_case(tmp_path, eme_run_binary):
    """A study of the large rod (split) whose second case asks for CVODE, which the split path
    cannot run: exit 2 before any case runs, the base file named once, the case named (the message
    read "base.nml: base.nml, &integrator: ..." without the case)."""
    study, output = write_study(tmp_path, links=(LARGE,))
    study.write_text(study.read_text() + "&sweep field = 'scheme', texts = 'eme', 'cvode_adams' /\n")
    result = ensemble(study)
    assert result.returncode == 2, result.stdout + result.stderr
    base = str(tmp_path / "base.nml")
    line = next(line for line in result.stderr.splitlines() if "cvode_adams" in line)
    assert line.count(base) == 1 and line.startswith(f"eme_ensemble: {base}, &integrator: scheme: "), line
    assert line.endswith("(case 2 of the study)"), line
    assert not (output / "case_00001.h5").exists() and not (output / "case_00002.h5").exists()
