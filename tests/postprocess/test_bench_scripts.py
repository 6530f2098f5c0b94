"""The bench scripts' failures and the machine load they record: a program that fails ends
make bench with the program's own message; every timing records the load and the cores, and
warns when the machine was busy."""
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import BIN

ROOT = Path(__file__).resolve().parents[2]
POSTPROCESS = ROOT / "postprocess"
sys.path.insert(0, str(POSTPROCESS))

import machine_load  # noqa: E402


def test_bench_eme_run_shows_the_failing_programs_own_message(tmp_path):
    """eme_run, given a bad option by a wrapper, exits 2 with its message: the script prints that
    message (not a CalledProcessError) and exits 1."""
    binaries = tmp_path / "bin"
    binaries.mkdir()
    for program in ("eme_bench", "snes_overhead"):
        (binaries / program).symlink_to(BIN / program)
    wrapper = binaries / "eme_run"
    wrapper.write_text(f'#!/bin/sh\nexec "{BIN / "eme_run"}" "$@" -eme_chord_predictor maybe\n')
    wrapper.chmod(0o755)
    result = subprocess.run([sys.executable, str(POSTPROCESS / "bench_eme_run.py"), "--bin", str(binaries),
                             "--repeats", "1"], capture_output=True, text=True, timeout=300)
    assert result.returncode == 1, result.stderr
    assert "Traceback" not in result.stderr and "CalledProcessError" not in result.stderr, result.stderr
    assert "exited with status 2" in result.stderr, result.stderr
    # eme_run's own line, as it printed it.
    assert "eme_run: -eme_chord_predictor maybe: allowed: true or false" in result.stderr, result.stderr


@pytest.mark.parametrize("before, after, own, cores, busy", [
    (0.2, 0.9, 1, 2, False),      # our own process explains the load after
    (0.2, 2.6, 2, 2, False),      # two ranks of our own
    (1.2, 1.5, 1, 2, True),       # others ran before the measurement
    (0.1, 3.5, 1, 2, True),       # others joined during it
    (1.9, 2.0, 1, 4, False),      # 4 cores: half is 2
])
def test_busy_is_the_others_load_above_half_the_cores(before, after, own, cores, busy):
    load = machine_load.MachineLoad(before=before, after=after, cores=cores, own=own)
    assert load.busy == busy
    assert ("BUSY" in load.text()) == busy and bool(load.warning()) == busy
    assert f"{before:.2f} before" in load.text() and f"{cores} cores" in load.text()


def test_the_wrapper_records_the_load_and_keeps_the_commands_status(tmp_path):
    record = tmp_path / "study.load.json"
    result = subprocess.run([sys.executable, str(POSTPROCESS / "machine_load.py"), "--record", str(record),
                             "--own", "2", "--", "sh", "-c", "echo measured; exit 3"],
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 3
    assert result.stdout.splitlines()[0] == "measured"
    assert result.stdout.splitlines()[1].startswith("machine load: 1-minute load average")
    fields = json.loads(record.read_text())
    assert fields["cores"] == len(os.sched_getaffinity(0))
    assert fields["own_processes"] == 2 and fields["command"] == ["sh", "-c", "echo measured; exit 3"]
    assert fields["load_average_before"] >= 0 and fields["load_average_after"] >= 0
    load = machine_load.read(record)
    assert (load.before, load.after, load.cores, load.own) == (fields["load_average_before"],
                                                              fields["load_average_after"], fields["cores"], 2)
    assert machine_load.read(tmp_path / "absent.json") is None


def test_bench_cvode_baseline_says_when_valgrind_is_missing(tmp_path):
    """Without valgrind on PATH the instruction counts stop with one line that names it."""
    empty = tmp_path / "no_tools"
    empty.mkdir()
    result = subprocess.run([sys.executable, str(POSTPROCESS / "bench_cvode_baseline.py"), "--bin", str(BIN)],
                            capture_output=True, text=True, timeout=60, env=dict(os.environ, PATH=str(empty)))
    assert result.returncode == 1 and "Traceback" not in result.stderr, result.stderr
    assert "valgrind is not installed" in result.stderr, result.stderr


def test_bench_cvode_baseline_scenes_are_the_paper_scene_with_what_they_change(tmp_path):
    """The namelists of the instruction counts: the paper scene's input with another t_end and scheme."""
    import bench_cvode_baseline
    output = tmp_path / "scene.h5"
    namelist = tmp_path / "scene.nml"
    namelist.write_text(bench_cvode_baseline.scene_text(output, 0.3, "cvode_bdf"))
    result = subprocess.run([str(BIN / "eme_run"), str(namelist)], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    import h5py
    with h5py.File(output, "r") as f:
        assert f.attrs["scheme"] == "cvode_bdf" and f.attrs["steps_completed"] == 2
        assert f.attrs["dt"] == 0.15 and f["snes_solves"][()].sum() > 2
