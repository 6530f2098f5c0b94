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


# bench_rungs.py under a fake valgrind: each run's "instructions" follow from what its file holds
# (1000 a step for each state column, 500 more a step on the generic path; 100 a step outside the
# stepper; fixed start-up and set-up counts), so a misparsed count or a scene measured under
# another scene's name shows as a wrong number on that scene's line.
FAKE_VALGRIND = '''#!{python}
import json, re, subprocess, sys
import h5py
arguments = sys.argv[1:]
out = next(a.split("=", 1)[1] for a in arguments if a.startswith("--callgrind-out-file="))
command = [a for a in arguments if not a.startswith("--")]
status = subprocess.run(command).returncode
if status:
    sys.exit(status)
namelist = next(a for a in command if a.endswith(".nml"))
output = re.search(r"file = '([^']*)'", open(namelist).read()).group(1)
with h5py.File(output, "r") as f:
    steps, columns = int(f.attrs["steps_completed"]), f["state"].shape[1]
step = 1000 * columns + (500 if "-eme_fused_kernel" in command else 0)
json.dump({{"advance": steps * step + 77_000, "total": steps * (step + 100) + 5_000_000}}, open(out, "w"))
'''
FAKE_ANNOTATE = '''#!{python}
import json, sys
counts = json.load(open(sys.argv[-1]))
print("-" * 80)
print("Ir")
print("-" * 80)
print(f"{{counts['total']:,}} (100.0%)  PROGRAM TOTALS")
print()
print("Ir                  file:function")
print(f"{{counts['total'] - counts['advance']:,}} (50.00%)  ???:main [/bin/eme_run]")
print(f"{{counts['advance']:,}} (40.00%)  src/integrator/discrete_gradient_stepper.f90:"
      "__discrete_gradient_stepper_MOD_advance [/bin/eme_run]")
'''


def fake_callgrind_path(tmp_path):
    """A PATH whose valgrind and callgrind_annotate are the fakes above, then this one's."""
    tools = tmp_path / "fake_tools"
    tools.mkdir()
    for name, text in (("valgrind", FAKE_VALGRIND), ("callgrind_annotate", FAKE_ANNOTATE)):
        (tools / name).write_text(text.format(python=sys.executable))
        (tools / name).chmod(0o755)
    return f"{tools}{os.pathsep}{os.environ['PATH']}"


def test_bench_rungs_labels_each_rungs_counts_and_ratios(tmp_path):
    """Each scene's line carries its own unknowns and counts (from its own file, through the
    callgrind parsing), the ratios are to the full model, and the target lines are the planar
    thermoelastic's: 10 columns against 15, 10,000 against 15,000 instructions a step."""
    result = subprocess.run([sys.executable, str(POSTPROCESS / "bench_rungs.py"), "--bin", str(BIN), "--repeats", "1"],
                            capture_output=True, text=True, timeout=600,
                            env=dict(os.environ, PATH=fake_callgrind_path(tmp_path)))
    assert result.returncode == 0, result.stderr + result.stdout
    rungs = {}
    for line in result.stdout.splitlines():
        if line.startswith("rung="):
            fields = dict(field.split("=", 1) for field in line.split())
            rungs[fields["rung"]] = fields
    expected = {"full": (15, 15000), "spatial_thermoelastic": (14, 14000), "planar_thermoviscoelastic": (11, 11000),
                "planar_thermoelastic": (10, 10000), "spatial_elastic": (12, 12000), "planar_elastic": (8, 8000),
                "full_generic": (15, 15500)}
    assert list(rungs) == list(expected)
    for name, (unknowns, step) in expected.items():
        fields = rungs[name]
        assert int(fields["unknowns"]) == unknowns, (name, fields)
        assert float(fields["step_instructions"]) == step, (name, fields)
        assert float(fields["process_instructions"]) == step + 100, (name, fields)
        assert float(fields["instructions_over_full"]) == pytest.approx(step / 15000, abs=6e-4), (name, fields)
        newton = float(fields["newton_per_step"])
        assert 1 < newton < 10 and 1 < float(fields["timed_newton_per_step"]) < 10, (name, fields)
        assert float(fields["instructions_per_newton"]) == pytest.approx(step / newton, abs=1), (name, fields)
    # The time ratios are to the full model: its own are 1 whatever the machine does.
    assert rungs["full"]["wall_over_full"] == "1.000" and rungs["full"]["cpu_over_full"] == "1.000"
    assert "planar_thermoelastic_over_full_instructions=0.667  (target 0.7: met)" in result.stdout
    time_line = next(line for line in result.stdout.splitlines()
                     if line.startswith("planar_thermoelastic_over_full_time="))
    assert float(time_line.split("=")[1].split()[0]) == pytest.approx(
        float(rungs["planar_thermoelastic"]["wall_over_full"]), abs=1e-3)
    assert "(target 0.7: " in time_line
    # The table: one row per scene, in order, with its unknowns.
    rows = [line for line in result.stdout.splitlines() if line.startswith("  (") and "unknowns" not in line]
    assert [row.split()[0] for row in rows[:7]] == ["(a)", "(b)", "(c)", "(d)", "(e)", "(f)", "(a)"]
    assert "planar thermoelastic" in rows[3] and rows[3].split()[3] == "10"
    assert result.stdout.count("load_average_before=") == 2


def test_bench_rungs_refuses_a_scene_without_its_columns(tmp_path):
    """An eme_run that ignores spring_law: the thermoelastic scene has 15 columns, not 14, and the
    script says so before it measures anything."""
    binaries = tmp_path / "bin"
    binaries.mkdir()
    wrapper = binaries / "eme_run"
    wrapper.write_text(f"#!/bin/sh\nsed -i \"s/, spring_law = 'thermoelastic'//\" \"$1\"\n"
                       f'exec "{BIN / "eme_run"}" "$@"\n')
    wrapper.chmod(0o755)
    result = subprocess.run([sys.executable, str(POSTPROCESS / "bench_rungs.py"), "--bin", str(binaries),
                             "--repeats", "1"], capture_output=True, text=True, timeout=300)
    assert result.returncode == 1 and "Traceback" not in result.stderr, result.stderr
    assert "scene spatial_thermoelastic" in result.stderr, result.stderr
    assert "state columns 15 (expected 14)" in result.stderr, result.stderr
    assert "spring_law thermoviscoelastic (expected thermoelastic)" in result.stderr, result.stderr
    assert "rung=" not in result.stdout
