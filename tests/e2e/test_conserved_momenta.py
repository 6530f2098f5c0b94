"""Which components of the angular momentum J = q1 x p1 + q2 x p2 a run conserves, names and
reports (docs/formulation.md sections 2 and 9). Gravity's torque ((m1 + m2) q1 + m2 q2) x g is
perpendicular to g, so J.g/|g| is a first integral for any direction of g, and without gravity
all of J is: the run file names the components (root attribute conserved_momentum: J_y for
gravity along y, J_g off the axes, J_x J_y J_z without gravity, the planar J, none in a plane
under gravity) with their axes (conserved_momentum_axes), run_figures' drift is the largest
over them, and eme_run's summary line names them. Each case runs EME and a relaxed scheme (whose
projection keeps every component on every step); the expected components and axes are typed here
from that law, the drifts computed from /angular_momentum, and each scene is checked to move the
components that are not conserved."""
import re

import numpy as np
import pytest

from conftest import read_run, run_eme

EPS = np.finfo(float).eps
OFF_PLANE = {"q1": [1.0, 0.0, 0.5]}      # the state: J has all three components
SUMMARY = re.compile(r"(\|dJ\w*\|(?:, \|dJ\w*\|)*) <= +(\S+),")

# scene: (model group, initial group, components, their axes, components the scene moves)
SCENES = {
    "gravity along y": ({"gravity": [0.0, -9.81, 0.0]}, OFF_PLANE, ["J_y"], [[0, 1, 0]], ["J_x", "J_z"]),
    "gravity along -z (the paper's)": ({}, OFF_PLANE, ["J_z"], [[0, 0, 1]], ["J_x", "J_y"]),
    "gravity off the axes": ({"gravity": [3.0, -4.0, -8.0]}, OFF_PLANE, ["J_g"],
                             [np.array([3.0, -4.0, -8.0]) / np.sqrt(89.0)], ["J_x", "J_y", "J_z"]),
    "no gravity": ({"gravity": [0.0, 0.0, 0.0]}, OFF_PLANE, ["J_x", "J_y", "J_z"],
                   [[1, 0, 0], [0, 1, 0], [0, 0, 1]], []),
    "planar, no gravity": ({"dimension": 2, "gravity": [0.0, 0.0]}, {}, ["J"], [[0, 0, 1]], []),
}


def components(run, names, axes):
    """{name: J_n.a}: from the columns J_x J_y J_z dotted with each axis typed above (the planar J
    is its own column)."""
    momenta = run["angular_momentum"]
    if momenta.shape[1] == 1:
        return {names[0]: momenta[:, 0]}
    return {name: momenta @ np.asarray(axis, float) for name, axis in zip(names, axes)}


@pytest.mark.parametrize("scheme", ["eme", "relaxed_rk4"])
@pytest.mark.parametrize("scene", SCENES)
def test_the_conserved_components_are_named_kept_and_reported(tmp_path, eme_run_binary, scene, scheme):
    model, initial, names, axes, moved = SCENES[scene]
    result, path = run_eme(tmp_path, "run", {"model": model, "initial": initial,
                                             "integrator": {"scheme": scheme, "dt": 0.05, "t_end": 5.0}})
    assert result.returncode == 0, result.stderr
    run = read_run(path)
    assert run["attrs"]["status"] == "complete"
    assert run["attrs"]["conserved_momentum"] == " ".join(names)
    np.testing.assert_allclose(np.reshape(run["attrs"]["conserved_momentum_axes"], (-1, 3)), axes, rtol=0,
                               atol=4 * EPS)
    scale = max(np.abs(run["angular_momentum"]).max(), 1.0)
    drifts = {name: np.abs(values - values[0]).max() for name, values in components(run, names, axes).items()}
    # Kept on every step to round-off (EME: at the root; the relaxed scheme: by its projection).
    assert max(drifts.values()) <= 64 * EPS * scale, drifts
    # run_figures' drift is the largest over the components (the time loop's figure, from every point).
    assert run["attrs"]["run_figures"][3] == pytest.approx(max(drifts.values()), rel=1e-12, abs=4 * EPS * scale)
    # The summary line names every component and gives that figure.
    match = SUMMARY.search(result.stdout)
    assert match, result.stdout
    assert match.group(1) == ", ".join(f"|d{name.replace('_', '')}|" for name in names)
    assert float(match.group(2)) == pytest.approx(run["attrs"]["run_figures"][3], rel=0.01)
    # What the scene does not conserve moves (so the checks above could fail).
    columns = run["angular_momentum"]
    for name in moved:
        values = columns[:, "xyz".index(name[-1])]
        assert np.abs(values - values[0]).max() > 1e-3, name


def test_a_planar_scene_under_gravity_conserves_none(tmp_path, eme_run_binary):
    result, path = run_eme(tmp_path, "run", {"model": {"dimension": 2},
                                             "integrator": {"scheme": "relaxed_rk4", "dt": 0.05, "t_end": 1.0}})
    assert result.returncode == 0, result.stderr
    run = read_run(path)
    assert run["attrs"]["conserved_momentum"] == "none" and "conserved_momentum_axes" not in run["attrs"]
    assert "angular_momentum" not in run and np.isnan(run["attrs"]["run_figures"][3])
    assert "|dJ" not in result.stdout


def test_a_straight_pendulum_without_gravity_keeps_its_momenta(tmp_path, eme_run_binary):
    """q1, q2 and the momenta along one line: J = 0 and its component along the line has a zero
    gradient in p; the relaxed projection leaves that condition out (it holds whatever p) and keeps
    the other two, rather than failing on a singular system."""
    result, path = run_eme(tmp_path, "run", {
        "model": {"gravity": [0.0, 0.0, 0.0]},
        "initial": {"q1": [1.0, 0.0, 0.0], "q2": [3.0, 0.0, 0.0], "p1": [0.5, 0.0, 0.0], "p2": [-0.2, 0.0, 0.0]},
        "integrator": {"scheme": "relaxed_rk4", "dt": 0.05, "t_end": 2.0}})
    assert result.returncode == 0, result.stderr
    run = read_run(path)
    assert run["attrs"]["status"] == "complete"
    assert np.abs(run["angular_momentum"]).max() <= 64 * EPS
