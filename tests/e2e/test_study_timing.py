"""A study's timings that a busy machine cannot falsify (issue 40 item 3): each case's CPU time
beside its wall time in the index and in its file, and the machine's load averages and cores at
the study's start and end, on one rank and on two. Every check is a property of the clocks, not
of the machine's speed: a CPU span nested in a wall span, no more CPU than the cores give in it,
the index's figures as the case files hold them."""
import math
import os
import subprocess

import h5py
import numpy as np
import pytest

from conftest import BIN, ROOT, read_run

MPIRUN = ["mpirun", "--allow-run-as-root", "--oversubscribe"]
BASE = ROOT / "inputs" / "paper_fig4_eme_theta.nml"
# Three cases on [0, 0.4] s: EME at two steps and RRK8, a few hundred microseconds each.
STUDY = """&study base = '{base}', output_dir = '{output}', combine = 'zip' /
&sweep field = 't_end', values = 3*0.4 /
&sweep field = 'scheme', texts = 'eme', 'eme', 'relaxed_rk8' /
&sweep field = 'dt', values = 0.02, 0.01, 0.05 /
"""
CPU_COLUMNS = ("cpu_time_seconds", "solve_cpu_time_seconds")
# cpu_time's resolution (gfortran: getrusage, to the microsecond), twice: a CPU span read as two
# truncated values may exceed the true one by up to this.
CPU_CLOCK_SLACK = 2e-6


def run_study(tmp_path, ranks):
    output = tmp_path / "out"
    study = tmp_path / "study.nml"
    study.write_text(STUDY.format(base=BASE, output=output))
    result = subprocess.run([*MPIRUN, "-n", str(ranks), str(BIN / "eme_ensemble"), str(study)],
                            capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert result.returncode == 0, result.stderr
    return study, output


@pytest.mark.parametrize("ranks", [1, 2])
def test_each_case_has_its_cpu_time_beside_its_wall_time(tmp_path, ranks):
    _, output = run_study(tmp_path, ranks)
    with h5py.File(output / "index.h5", "r") as index:
        cases = index["cases"][()]
        units = dict(zip(cases.dtype.names, index["cases"].attrs["column_units"]))
    names = list(cases.dtype.names)
    # Beside the wall times: wall, solve, CPU of the run, CPU of the time loop.
    first = names.index("wall_time_seconds")
    assert names[first:first + 4] == ["wall_time_seconds", "solve_time_seconds", *CPU_COLUMNS]
    assert all(units[name] == "s" for name in CPU_COLUMNS)
    cores = os.cpu_count()
    for row in cases:
        assert row["status"] == b"complete"
        cpu, solve_cpu = float(row["cpu_time_seconds"]), float(row["solve_cpu_time_seconds"])
        wall, solve_wall = float(row["wall_time_seconds"]), float(row["solve_time_seconds"])
        assert math.isfinite(cpu) and math.isfinite(solve_cpu)
        # The time loop took steps: CPU time was spent in it; it lies within the run.
        assert 0 < solve_cpu <= cpu
        # One process uses at most every core during a wall span that encloses its CPU span.
        assert solve_cpu <= cores * solve_wall + CPU_CLOCK_SLACK
        assert cpu <= cores * wall + CPU_CLOCK_SLACK
        # The case file holds the same time loop's CPU time, and the run up to closing the file
        # (the index's run goes on to its end).
        attrs = read_run(output / row["file"].decode())["attrs"]
        assert attrs["solve_cpu_time_seconds"] == solve_cpu
        assert 0 < attrs["cpu_time_seconds"] <= cpu
        assert attrs["solve_cpu_time_seconds"] <= attrs["cpu_time_seconds"]
        assert attrs["cpu_time_seconds_units"] == "s"


@pytest.mark.parametrize("ranks", [1, 2])
def test_the_index_records_the_machine_load_at_the_study_s_start_and_end(tmp_path, ranks):
    _, output = run_study(tmp_path, ranks)
    with h5py.File(output / "index.h5", "r") as index:
        attrs = dict(index.attrs)
    for name in ("load_average_start", "load_average_end"):
        loads = np.asarray(attrs[name], dtype=float)
        assert loads.shape == (3,), name                      # 1, 5 and 15 minutes
        assert np.all(np.isfinite(loads)) and np.all(loads >= 0), (name, loads)
    # The cores online (os.cpu_count: sysconf), not a bound rank's one core.
    assert attrs["cores_start"] == attrs["cores_end"] == os.cpu_count()
    assert attrs["ranks"] == ranks


def test_an_index_written_before_cpu_times_keeps_them_unknown(tmp_path):
    """A restart over an index without the CPU columns (as an older eme_ensemble wrote it) keeps
    its complete cases and says their CPU times are unknown (NaN), not 0."""
    study, output = run_study(tmp_path, 1)
    with h5py.File(output / "index.h5", "r+") as index:
        del index.attrs["text_checksum"]       # an index of that age has none (and the edits below would fail it)
        cases = index["cases"][()]
        attributes = dict(index["cases"].attrs)
        kept = [name for name in cases.dtype.names if name not in CPU_COLUMNS]
        del index["cases"]
        index["cases"] = cases[kept]
        for key, value in attributes.items():
            if key == "column_units":
                value = [unit for name, unit in zip(cases.dtype.names, value) if name not in CPU_COLUMNS]
            index["cases"].attrs[key] = value
    result = subprocess.run([str(BIN / "eme_ensemble"), str(study)], capture_output=True, text=True, timeout=300,
                            cwd=ROOT)
    assert result.returncode == 0, result.stderr
    assert "0 to run (3 complete from an earlier run)" in result.stdout
    with h5py.File(output / "index.h5", "r") as index:
        again = index["cases"][()]
    for name in CPU_COLUMNS:
        assert np.all(np.isnan(again[name])), (name, again[name])
    np.testing.assert_array_equal(again["solve_time_seconds"], cases["solve_time_seconds"])
