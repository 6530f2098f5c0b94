"""No false "complete": whatever PETSc was told, whatever stands at the output path, however long
the run. Each case here completed (or destroyed a file) before it was fixed:

- PETSc options that loosen the solve (-snes_atol 1e10 gave 0 Newton iterations and a state that
  never moved, marked complete) now change nothing: a step is accepted only if the project's
  own convergence test accepts it;
- PETSc options that PETSc refuses (an unknown type, a missing -options_file, a -log_view file
  that cannot be written) are bad input: exit 2, one line, nothing written, no case run;
- the output path must not be the input file, a directory, or a file that is not HDF5 (unless
  replacing was asked for);
- the step budget (&integrator max_steps) stops an adaptive run with exit 3 and failure_kind
  'step_budget' (a hidden cap of 1e6 steps said 'solver' before).
"""
import os
import subprocess

import h5py
import numpy as np
import pytest

from conftest import BIN, ROOT, namelist_text, read_run, run_eme

PAPER_SHORT = {"integrator": {"scheme": "eme", "dt": 0.15, "t_end": 1.5}}


def files_under(folder):
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*"))


# ------------------------------------------------------------------ options that would loosen the solve

@pytest.mark.parametrize("options", [["-snes_atol", "1e10"], ["-snes_stol", "1e10"], ["-snes_rtol", "0.9"],
                                     ["PETSC_OPTIONS=-snes_atol 1e10"]])
def test_loosening_options_change_nothing(tmp_path, eme_run_binary, options):
    """The run with the option is the run without it, bit for bit (min(newton_tol, snes_atol),
    and -snes_stol can only add a condition)."""
    plain, plain_file = run_eme(tmp_path, "plain", PAPER_SHORT)
    assert plain.returncode == 0, plain.stderr
    env = dict(os.environ)
    arguments = list(options)
    if options[0].startswith("PETSC_OPTIONS="):
        env["PETSC_OPTIONS"] = options[0].split("=", 1)[1]
        arguments = []
    output = tmp_path / "loose.h5"
    namelist = tmp_path / "loose.nml"
    namelist.write_text(namelist_text({**PAPER_SHORT, "output": {"file": str(output)}}))
    loose = subprocess.run([str(BIN / "eme_run"), str(namelist), *arguments], capture_output=True, text=True,
                           env=env, timeout=120)
    assert loose.returncode == 0, loose.stderr
    a, b = read_run(plain_file), read_run(output)
    assert a["attrs"]["newton_iterations_total"] > 0
    assert b["attrs"]["newton_iterations_total"] == a["attrs"]["newton_iterations_total"]
    np.testing.assert_array_equal(b["state"], a["state"])


def test_a_replaced_convergence_test_cannot_accept_a_step_that_is_not_solved(tmp_path, eme_run_binary):
    """PETSc's own test with a huge atol accepts the predictor; the project's check of the
    residual at the returned root refuses it: the run stops (exit 3), never 'complete'."""
    result, output = run_eme(tmp_path, "replaced", PAPER_SHORT, "-snes_convergence_test", "default",
                             "-snes_atol", "1e10")
    assert result.returncode == 3, result.stderr
    assert "by a test other than the project's" in result.stderr
    with h5py.File(output.with_name(output.name + ".part") if not output.exists() else output) as f:
        assert f.attrs["status"] != "complete"


@pytest.mark.parametrize("options", [[], ["-snes_type", "newtontr"], ["-snes_lag_jacobian", "2"],
                                     ["-ksp_type", "gmres", "-pc_type", "lu"], ["-snes_linesearch_type", "bt"],
                                     ["-snes_atol", "1e-12"]])
def test_documented_options_still_work(tmp_path, eme_run_binary, options):
    result, output = run_eme(tmp_path, "run", PAPER_SHORT, *options)
    assert result.returncode == 0, result.stderr
    data = read_run(output)
    assert data["attrs"]["status"] == "complete"
    energy = data["energy"]
    assert np.max(np.abs(energy - energy[0])) / abs(energy[0]) < 1e-12


def test_loosening_options_do_not_reach_a_study(tmp_path, eme_run_binary):
    base = tmp_path / "base.nml"
    base.write_text(namelist_text(PAPER_SHORT))
    outputs = {}
    for name, extra in (("plain", []), ("loose", ["-snes_atol", "1e10"])):
        study = tmp_path / f"{name}.nml"
        study.write_text(f"&study base = 'base.nml', output_dir = '{tmp_path / name}' /\n"
                         "&sweep field = 'dt', values = 0.15 /\n")
        result = subprocess.run([str(BIN / "eme_ensemble"), str(study), *extra], capture_output=True, text=True,
                                timeout=120, cwd=tmp_path)
        assert result.returncode == 0, result.stderr
        (case,) = [p for p in (tmp_path / name).glob("*.h5") if p.name != "index.h5"]
        outputs[name] = read_run(case)
    np.testing.assert_array_equal(outputs["loose"]["state"], outputs["plain"]["state"])


# ------------------------------------------------------------------ options PETSc refuses

REFUSED = {
    "missing options file": (["-options_file", "/nonexistent/options"], "Unable to open options file"),
    "unknown SNES type": (["-snes_type", "bogus"], "SNES type bogus"),
    "unknown KSP type": (["-ksp_type", "bogus"], "KSP type bogus"),
    "unknown line search": (["-snes_linesearch_type", "bogus"], "Line Search type bogus"),
    "log file that cannot be written": (["-log_view", ":/proc/nope/x.txt"], "could not write the file '/proc/nope/x.txt'"),
    "viewer file in a missing folder": (["-snes_view", "ascii:/nonexistent/dir/view.txt"], "/nonexistent/dir/view.txt"),
    "more options than PETSc holds": ([f"-unused_{i}" for i in range(600)], "options"),
}


@pytest.mark.parametrize("case", sorted(REFUSED))
def test_options_petsc_refuses_are_bad_input_with_nothing_written(tmp_path, eme_run_binary, case):
    options, words = REFUSED[case]
    (tmp_path / "run.nml").write_text(namelist_text({**PAPER_SHORT, "output": {"file": "out/run.h5"}}))
    before = files_under(tmp_path)
    result = subprocess.run([str(BIN / "eme_run"), "run.nml", *options], capture_output=True, text=True, timeout=60,
                            cwd=tmp_path)
    assert result.returncode == 2, (result.returncode, result.stderr)
    assert result.stderr.count("\n") == 1 and result.stderr.startswith("eme_run: "), result.stderr
    assert words in result.stderr
    assert "PETSC ERROR" not in result.stderr + result.stdout
    assert files_under(tmp_path) == before


def test_a_study_with_a_refused_option_runs_no_case(tmp_path, eme_run_binary):
    (tmp_path / "base.nml").write_text(namelist_text(PAPER_SHORT))
    (tmp_path / "study.nml").write_text("&study base = 'base.nml', output_dir = 'study' /\n"
                                        "&sweep field = 'scheme', texts = 'eme', 'relaxed_gauss6' /\n")
    result = subprocess.run([str(BIN / "eme_ensemble"), "study.nml", "-snes_type", "bogus"], capture_output=True,
                            text=True, timeout=60, cwd=tmp_path)
    assert result.returncode == 2, result.stderr
    assert "SNES type bogus" in result.stderr and "PETSC ERROR" not in result.stderr
    assert not (tmp_path / "study").exists()


# ------------------------------------------------------------------ what stands at the output path

def test_the_input_file_is_never_the_output(tmp_path, eme_run_binary):
    namelist = tmp_path / "self.h5"
    text = "&integrator t_end = 0.3 /\n&output file = 'self.h5', overwrite = .true. /\n"
    namelist.write_text(text)
    result = subprocess.run([str(BIN / "eme_run"), "self.h5"], capture_output=True, text=True, cwd=tmp_path)
    assert result.returncode == 2 and "is the input file itself" in result.stderr
    assert namelist.read_text() == text
    assert files_under(tmp_path) == ["self.h5"]


def test_a_file_that_is_not_hdf5_is_kept_unless_replacing_was_asked(tmp_path, eme_run_binary):
    precious = tmp_path / "notes.h5"
    precious.write_text("my notes\n")
    (tmp_path / "run.nml").write_text("&integrator t_end = 0.3 /\n&output file = 'notes.h5' /\n")
    result = subprocess.run([str(BIN / "eme_run"), "run.nml"], capture_output=True, text=True, cwd=tmp_path)
    assert result.returncode == 2 and "is not an HDF5 file, and is kept" in result.stderr
    assert precious.read_text() == "my notes\n"
    assert files_under(tmp_path) == ["notes.h5", "run.nml"]
    replaced = subprocess.run([str(BIN / "eme_run"), "run.nml", "-eme_overwrite"], capture_output=True, text=True,
                              cwd=tmp_path)
    assert replaced.returncode == 0, replaced.stderr
    assert read_run(precious)["attrs"]["status"] == "complete"


def test_a_directory_at_the_output_path_is_refused_before_the_run(tmp_path, eme_run_binary):
    (tmp_path / "out.h5").mkdir()
    (tmp_path / "run.nml").write_text("&integrator t_end = 0.3 /\n&output file = 'out.h5' /\n")
    result = subprocess.run([str(BIN / "eme_run"), "run.nml", "-eme_overwrite"], capture_output=True, text=True,
                            cwd=tmp_path)
    assert result.returncode == 2 and "is a directory" in result.stderr
    assert files_under(tmp_path) == ["out.h5", "run.nml"]


# ------------------------------------------------------------------ the step budget

def test_an_adaptive_run_stops_at_its_step_budget(tmp_path, eme_run_binary):
    groups = {"integrator": {"scheme": "eme", "dt": 0.001, "t_end": 20.0, "tolerance": 1e-6, "max_steps": 40}}
    result, output = run_eme(tmp_path, "budget", groups)
    assert result.returncode == 3, result.stderr
    assert "max_steps" in result.stderr
    data = read_run(output)
    assert data["attrs"]["failure_kind"] == "step_budget"
    assert data["attrs"]["status"].startswith("incomplete: the step budget is spent: 40 steps")
    assert data["attrs"]["steps_completed"] == 40
    assert len(data["time"]) == 41 and data["time"][-1] < 20.0


def test_a_budget_the_run_does_not_reach_changes_nothing(tmp_path, eme_run_binary):
    """134 planned steps within a budget of exactly 134."""
    result, output = run_eme(tmp_path, "exact", {"integrator": {"max_steps": 134}})
    assert result.returncode == 0, result.stderr
    assert read_run(output)["attrs"]["steps_completed"] == 134


@pytest.mark.parametrize("scheme, extra", [("relaxed_dp853", {}), ("eme", {"tolerance": 1e-6})])
def test_an_adaptive_first_step_longer_than_the_run_is_capped(tmp_path, eme_run_binary, scheme, extra):
    """dt is the first trial step of an integrator that chooses its steps: capped at t_end, the
    run takes at least one step and prints no NaN."""
    result, output = run_eme(tmp_path, "capped", {"integrator": {"scheme": scheme, "dt": 1e308, "t_end": 0.05,
                                                                 **extra}})
    assert result.returncode == 0, result.stderr
    assert "NaN" not in result.stdout
    data = read_run(output)
    assert data["attrs"]["steps_completed"] >= 1
    assert data["time"][-1] == pytest.approx(0.05, rel=1e-12)


def test_a_run_that_completes_no_step_prints_no_nan(tmp_path, eme_run_binary):
    """A run that fails its first step (here: one Newton iteration allowed) says it completed no
    step; its summary line printed 'min dS = NaN' before. So does summarize_runs.py on its file."""
    result, output = run_eme(tmp_path, "first_step", PAPER_SHORT, "-snes_max_it", "1")
    assert result.returncode == 3, result.stderr
    assert "0/10 steps: no step completed" in result.stdout
    assert "NaN" not in result.stdout + result.stderr
    summary = subprocess.run([str(ROOT / ".venv" / "bin" / "python"), str(ROOT / "postprocess" / "summarize_runs.py"),
                              str(output)], capture_output=True, text=True)
    assert "nan" not in summary.stdout.lower(), summary.stdout


def test_a_huge_step_prints_its_time(tmp_path, eme_run_binary):
    """dt = t_end = 1e300: the first step leaves the domain; the status line says at which time
    (issue 41 item 11: 't = ' and 40 stars), and no printed figure is stars."""
    result, output = run_eme(tmp_path, "huge", {"integrator": {"scheme": "eme", "dt": 1e300, "t_end": 1e300}})
    assert result.returncode == 3, result.stderr
    assert "(t = 1.0000E+300 s)" in result.stderr, result.stderr
    assert "*" not in result.stdout + result.stderr
    assert read_run(output)["attrs"]["status"].startswith("incomplete: step 1 (t = 1.0000E+300 s)")
