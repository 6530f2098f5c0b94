"""The fused step kernel on the reduced thermal rungs (issue 32): EME through the kernel and through
the generic residual (-eme_fused_kernel false, its oracle) give the same trajectory.

The kernel (src/model/pendulum/pendulum_step_kernel.f90) serves every thermal layout, planar or
spatial, with or without gamma, and condenses the positions away, so the two paths solve different
Newton systems for the same step equations; at a tight newton_tol both land on the same root to
rounding. The double pendulum amplifies rounding, so the horizon is stated: 2 s of dt = 0.01 s.
Scenes: Romero's planar thermoelastic double pendulum (issue 32 item 5's data, one trajectory's
first snapshot as its initial state) in every thermodynamic variable and with the partitioned
discrete gradient and the midpoint rule, and the paper's Table 1 data on the other reduced rungs,
one of them under both constraints (g1 and g2). Each fused run's file must say the kernel served it.
"""
import numpy as np
import pytest

from conftest import read_run, run_eme

# newton_tol 1e-10: the final chord step still takes every root to rounding. At 1e-12 the
# internal-energy variable on Romero's scene sits at its residual's rounding floor: Newton stalls
# for hundreds of iterations a step on either path (on main's generic path too, 293 a step) and
# the iterates it stops at differ by 1e-6.
HORIZON = {"dt": 0.01, "t_end": 2.0, "newton_tol": 1.0e-10}
RTOL = 1.0e-12

# Romero's thermoelastic double pendulum as fitted to the dataset of Hernandez et al. (issue 32
# item 5): constant stiffness, no gravity, planar.
ROMERO = {
    "model": {"spring_law": "thermoelastic", "dimension": 2, "mass": [1.0, 2.0],
              "natural_length": [1.99986286, 0.999926771], "mu_eq_const": [0.0189210127, 0.188568578],
              "mu_eq_slope": [0.0, 0.0], "heat_capacity": [4.99137876, 4.99137876], "conductivity": 300.0,
              "theta_ref": 299.451937, "beta": 0.086863612, "gravity": [0.0, 0.0]},
    "initial": {"q1": [4.6695264660334814, 4.7505354853332937], "q2": [-2.427088459820355, -0.054687203651120342],
                "p1": [0.86841516403954477, 1.2001605776636948], "p2": [1.4634168524405062, -0.18753872949487485],
                "theta": [294.0516585031142, 294.07872994307326]},
}
# The paper's Table 1 data on the other reduced rungs (the planar ones in the x-y plane of its
# initial state, gravity along -y); the last under both constraints, which hold at t = 0 (|q1| = 1,
# theta_1 = 280 K).
PLANAR_INITIAL = {"q1": [1.0, 0.0], "q2": [3.0, 0.0], "p1": [0.0, 0.0], "p2": [-1.0, -1.0]}
PAPER_RUNGS = {
    "planar_thermoviscoelastic": {"model": {"dimension": 2}, "initial": PLANAR_INITIAL},
    "spatial_thermoelastic": {"model": {"spring_law": "thermoelastic"}},
    "planar_thermoelastic": {"model": {"spring_law": "thermoelastic", "dimension": 2}, "initial": PLANAR_INITIAL},
    "planar_thermoelastic_both_constraints": {
        "model": {"spring_law": "thermoelastic", "dimension": 2}, "initial": PLANAR_INITIAL,
        "constraints": {"fix_length": True, "length": 1.0, "fix_temperature": True, "temperature": 280.0}},
}

CASES = [("romero", variable, "eme", "gonzalez") for variable in ("temperature", "entropy", "internal_energy")] + [
    ("romero", "temperature", "eme", "partitioned"), ("romero", "entropy", "midpoint", "gonzalez")] + [
    (rung, variable, "eme", "gonzalez") for rung in PAPER_RUNGS for variable in ("temperature", "internal_energy")]


def scene(name):
    return ROMERO if name == "romero" else PAPER_RUNGS[name]


def run_both(directory, name, variable, scheme, gradient):
    """The scene's run through the fused kernel and through the generic residual."""
    groups = {group: dict(fields) for group, fields in scene(name).items()}
    groups["integrator"] = {"scheme": scheme, "thermo_variable": variable, "discrete_gradient": gradient, **HORIZON}
    runs = {}
    for path_name, options in (("fused", ()), ("generic", ("-eme_fused_kernel", "false"))):
        result, output = run_eme(directory, f"{name}_{variable}_{scheme}_{gradient}_{path_name}", groups, *options)
        assert result.returncode == 0, result.stderr
        runs[path_name] = read_run(output)
    return runs


@pytest.mark.parametrize("name, variable, scheme, gradient", CASES)
def test_fused_kernel_follows_the_generic_residual(tmp_path, name, variable, scheme, gradient):
    runs = run_both(tmp_path, name, variable, scheme, gradient)
    fused, generic = runs["fused"], runs["generic"]
    assert fused["attrs"]["solver_eme_fused_kernel"] == "true", "the fused kernel did not serve this rung"
    assert generic["attrs"]["solver_eme_fused_kernel"] == "false"
    assert fused["attrs"]["status"] == generic["attrs"]["status"] == "complete"
    assert fused["state"].shape == generic["state"].shape
    # Each column against its own size over the run (a planar pendulum's columns differ by orders
    # of magnitude: Romero's momenta against its temperatures).
    scale = np.max(np.abs(generic["state"]), axis=0)
    error = np.max(np.abs(fused["state"] - generic["state"]), axis=0) / scale
    assert np.all(error <= RTOL), f"largest relative difference per column {error}"
    # The motion is not trivial over the horizon: the positions move by far more than the tolerance.
    moved = np.max(np.abs(generic["state"][-1] - generic["state"][0]) / scale)
    assert moved > 1.0e-3
