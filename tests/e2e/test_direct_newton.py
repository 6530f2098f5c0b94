"""The direct way of the step solver (src/solver/snes_solver, -eme_direct_newton true; SNESSolve by default):
EME's lean Newton iteration run by src/solver/hand_newton's newton_iterate without SNESSolve. It
must be SNESSolve's lean way bit for bit (the same iterates, tests and LU factors), and a solve it
does not converge is solved again by SNES, so that a failure's reason and residual are PETSc's:
every dataset of a run is the same both ways, on the paper scene and on a stiff scene whose steps
fail, are retried by the strategies and are replaced by halves. Any -snes_, -ksp_, -pc_, -info or
-log_ option keeps SNES."""
import numpy as np
import pytest

from conftest import read_run, run_eme

# Stiff springs at dt = 0.5 s (test_solver_robustness): some steps have no root from any strategy
# and are halved, so solves fail and SNES solves them again.
STIFF = {"model": {"mu_eq_const": [5000.0, 5000.0]}, "constraints": {"fix_length": True, "fix_temperature": True},
         "integrator": {"thermo_variable": "internal_energy", "dt": 0.5, "t_end": 10.0}}
PAPER = {"integrator": {"thermo_variable": "temperature", "t_end": 10.0}}
MIDPOINT = {"integrator": {"scheme": "midpoint", "thermo_variable": "entropy", "t_end": 10.0}}
TIMED = {"step_seconds"}     # wall time, the only dataset that may differ


@pytest.mark.parametrize("scene", [PAPER, MIDPOINT, STIFF], ids=["paper_eme_theta", "midpoint_entropy", "stiff_halved"])
def test_direct_way_is_snes_bit_for_bit(tmp_path, eme_run_binary, scene):
    runs = {}
    for name, options in (("direct", ["-eme_direct_newton", "true"]), ("snes", [])):
        result, path = run_eme(tmp_path, name, scene, *options)
        assert result.returncode == 0, result.stderr
        runs[name] = read_run(path)
    direct, snes = runs["direct"], runs["snes"]
    assert direct["attrs"]["solver_eme_direct_newton"] == "true"
    assert snes["attrs"]["solver_eme_direct_newton"] == "false"
    datasets = sorted(name for name in direct if name != "attrs")
    assert datasets == sorted(name for name in snes if name != "attrs")
    for name in set(datasets) - TIMED:
        np.testing.assert_array_equal(direct[name], snes[name], err_msg=name, strict=True)
    if scene is STIFF:
        # Solves failed (more solves than substeps) and steps were halved: SNES solved them again.
        assert np.sum(snes["snes_solves"]) > np.sum(snes["substeps"])
        assert np.any(snes["substeps"] > 1)


@pytest.mark.parametrize("options", [["-snes_max_it", "50"], ["-ksp_type", "preonly"], ["-snes_monitor"],
                                     ["-eme_lean_snes", "false"]], ids=["snes", "ksp", "monitor", "not_lean"])
def test_snes_options_keep_snes(tmp_path, eme_run_binary, options):
    result, path = run_eme(tmp_path, "option", {"integrator": {"t_end": 0.3}}, "-eme_direct_newton", "true", *options)
    assert result.returncode == 0, result.stderr
    assert read_run(path)["attrs"]["solver_eme_direct_newton"] == "false"


@pytest.mark.parametrize("variable", ["entropy", "internal_energy"])
def test_a_failed_run_fails_as_through_snes(tmp_path, eme_run_binary, variable):
    # Without halving the stiff scene stops at a step no strategy solves: the solves' failures
    # (DIVERGED_MAX_IT and DIVERGED_LOCAL_MIN decided the direct way, the others by SNES again)
    # give the same message and the same file.
    scene = {**STIFF, "integrator": {**STIFF["integrator"], "thermo_variable": variable}}
    runs, messages = {}, {}
    for name, options in (("direct", ["-eme_direct_newton", "true"]), ("snes", [])):
        result, path = run_eme(tmp_path, name, scene, "-eme_max_halvings", "0", *options)
        assert result.returncode == 3 and "no root" in result.stderr, result.stderr
        messages[name] = [line.replace(str(path), "FILE") for line in result.stderr.splitlines() if "no root" in line]
        runs[name] = read_run(path if path.exists() else path.with_name(path.name + ".part"))
    assert messages["direct"] == messages["snes"] and messages["direct"]
    for name in set(runs["direct"]) - TIMED - {"attrs"}:
        np.testing.assert_array_equal(runs["direct"][name], runs["snes"][name], err_msg=name, strict=True)
