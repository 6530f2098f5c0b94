"""The step solver's PETSc options (src/solver/snes_solver): the user's SNES, KSP and PC options
still do what they say when the solver drives SNES the lean way, PETSc's -help lists the code's
own -eme_* options, and switching each speed-up off leaves the trajectory and its invariants."""
import re

import numpy as np
import pytest

from conftest import read_run, run_eme

SCENE = {"integrator": {"t_end": 0.45}}          # 3 steps of the paper scene, EME_theta


def test_snes_monitor_reports_every_iteration(tmp_path, eme_run_binary):
    result, path = run_eme(tmp_path, "monitor", SCENE, "-snes_monitor")
    assert result.returncode == 0, result.stderr
    run = read_run(path)
    norms = [float(x) for x in re.findall(r"^\s*\d+ SNES Function norm ([0-9.eE+-]+)", result.stdout, re.M)]
    # Each solve prints its iterations 0..k: Newton iterations plus one line per solve.
    assert len(norms) == run["newton_iterations"].sum() + run["snes_solves"].sum()
    assert min(norms) < 1e-10          # the monitored norms reach the root


def test_pc_type_lu_is_petscs_lu(tmp_path, eme_run_binary):
    result, path = run_eme(tmp_path, "lu", SCENE, "-pc_type", "lu", "-ksp_view")
    assert result.returncode == 0, result.stderr
    assert re.search(r"PC Object: .*\n\s+type: lu", result.stdout)
    assert "type: shell" not in result.stdout
    _, default_path = run_eme(tmp_path, "default", SCENE)
    lu, default = read_run(path), read_run(default_path)
    np.testing.assert_allclose(lu["state"], default["state"], rtol=1e-10, atol=1e-12)


def test_snes_test_jacobian_tests_the_solved_jacobian(tmp_path, eme_run_binary):
    # The condensed system's Jacobian (9 unknowns) is the one SNES tests.
    result, _ = run_eme(tmp_path, "test", SCENE, "-snes_test_jacobian", "-snes_test_jacobian_view")
    ratios = [float(x) for x in re.findall(r"\|\|J - Jfd\|\|_F/\|\|J\|\|_F = ([0-9.eE+-]+)", result.stdout)]
    assert len(ratios) >= 3 and max(ratios) < 1e-5, ratios
    assert re.search(r"Hand-coded Jacobian ----------\nMat Object: 1 MPI process\n\s+type: seqdense\n(.*\n){9}", result.stdout)


def test_help_lists_the_eme_options(tmp_path, eme_run_binary):
    result, _ = run_eme(tmp_path, "help", SCENE, "-help")
    assert result.returncode == 0, result.stderr
    for option, words in [("-eme_chord_predictor", "chord step with the last step's LU factors"),
                          ("-eme_fused_kernel", "fused step on its condensed unknowns"),
                          ("-eme_lean_snes", "inside the shell preconditioner"),
                          ("-eme_direct_newton", "without SNESSolve"),
                          ("-eme_final_chord", "existing LU factors instead of a new Jacobian"),
                          ("-eme_modified_newton", "Keep the LU factors across the Newton iterations of a step"),
                          ("-eme_chord_iterations", "within this many chord iterations"),
                          ("-eme_max_halvings", "replaced by two half steps, recursively")]:
        # PETSc's own help line (the usage printed before it lists the options too, in its own form).
        line = next((l for l in result.stdout.splitlines() if l.strip().startswith(option + ":")
                     or (l.strip().startswith(option + " <") and ":" in l)), "")
        assert words in line, (option, line)


@pytest.mark.parametrize("option", ["-eme_fused_kernel", "-eme_lean_snes", "-eme_final_chord",
                                    "-eme_chord_predictor", "-eme_modified_newton"])
def test_each_speedup_leaves_the_trajectory(tmp_path, eme_run_binary, option):
    scene = {"integrator": {"t_end": 3.0}, "constraints": {"fix_length": True}}
    _, fast_path = run_eme(tmp_path, "fast", scene)
    result, slow_path = run_eme(tmp_path, "slow", scene, option, "false")
    assert result.returncode == 0, result.stderr
    fast, slow = read_run(fast_path), read_run(slow_path)
    # Both are roots of the same steps to the solver's tolerance (1e-8 on the residual).
    np.testing.assert_allclose(fast["state"], slow["state"], rtol=1e-8, atol=1e-9)
    for run in (fast, slow):
        energy = run["energy"]
        assert np.max(np.abs(energy - energy[0])) <= 1e-13 * abs(energy[0])
