"""The spring ladder of issue 32: `&model spring_law = 'elastic' | 'thermoelastic' |
'thermoviscoelastic'` and `dimension = 2 | 3` of the double pendulum, each rung solving only its
own unknowns (docs/formulation.md section 9).

(i) The published scenes (inputs/romero_thermoelastic.nml, inputs/gonzalez_elastic.nml) against
    the oracle typed from the definitions (tests/oracles/spring_ladder.py; checked against today's
    full model by tests/e2e/test_spring_ladder_oracles.py): relaxed_dp853 at tolerance 1e-12 to
    1e-8 of each column's scale at every output time (the full model with the same parts
    switched off agrees to 2.2e-10 at worst, the oracle's own error is of that size), and EME
    converging at order 2 to the oracle.
(ii) Equivalence with fixed steps and newton_tol = 1e-12 over 2 s, to 1e-9 of each column's
    scale: a planar scene with dimension = 3 (z = 0) and dimension = 2; the thermoviscoelastic
    rung with its viscous branch inert (beta_v = 0, gamma = 0) and the thermoelastic rung; the
    thermoviscoelastic rung with its thermal coupling off (beta = 0, mu_eq_slope = 0,
    conductivity = 0, at theta_ref) and the elastic rung.
(iii) Each rung's EME keeps energy (a step's change within 8 eps of the scale E is rounded at,
    |E_0| plus the thermal energies sum_a c_a theta_ref: the bound of test_smooth_scene.py; the run's
    drift within 8 eps sqrt(N) of it, a random walk of such steps), the momenta its scene conserves
    (the root attribute conserved_momentum: J_z in 3D with gravity along z, the scalar J in 2D
    without gravity, none in 2D with gravity) to 64 eps of their scale, and on the thermal rungs
    dS >= -32 eps max|S| and dV <= 64 eps |E_0| on every step (the README's round-off bounds).
(iv) Input that a rung does not have is refused with exit 2, naming the field and the law.

Output conventions assumed (docs/output.md once the feature lands): /state's columns are named
by its `columns` attribute, planar q1_x q1_y q2_x q2_y p1_x p1_y p2_x p2_y, then gamma
(thermoviscoelastic only), then the two thermal columns; an elastic file has no /temperature and
no /entropy; /angular_momentum exists only when the scene has momenta (3D: J_x J_y J_z; 2D
without gravity: J).

The whole file is skipped until `eme_run --help` documents `spring_law` (issue 32's Fortran);
REMOVE THE SKIP (pytestmark below) once the feature has landed.
"""
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import h5py
import numpy as np
import pytest

from conftest import BIN, ROOT, read_namelist, run_eme

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "oracles"))
import spring_ladder as oracle  # noqa: E402


def help_text():
    try:
        return subprocess.run([str(BIN / "eme_run"), "--help"], capture_output=True, text=True, timeout=60).stdout
    except OSError:
        return ""


# Issue 32: remove this skip once spring_law and dimension have landed (the tests then must pass).
pytestmark = pytest.mark.skipif("spring_law" not in help_text(),
                                reason="eme_run has no &model spring_law yet (issue 32)")

EPS = np.finfo(float).eps
TOLERANCE = 1e-8            # against the oracle (relaxed_dp853 at 1e-12)
EQUIVALENCE = 1e-9          # rung against rung, fixed steps, newton_tol 1e-12, 2 s
PLANAR = ["q1_x", "q1_y", "q2_x", "q2_y", "p1_x", "p1_y", "p2_x", "p2_y"]
SPATIAL = ["q1_x", "q1_y", "q1_z", "q2_x", "q2_y", "q2_z", "p1_x", "p1_y", "p1_z", "p2_x", "p2_y", "p2_z"]
TEMPERATURES = ["theta_1", "theta_2"]
THERMAL_COLUMNS = {"entropy": ["s_1", "s_2"], "temperature": ["theta_1", "theta_2"], "internal_energy": ["u_1", "u_2"]}


# ---------------------------------------------------------------- helpers
def text(value):
    return value.decode() if isinstance(value, bytes) else value


def read(path):
    """A run file's datasets and root attributes, each 2-D dataset's column names under
    'columns' (dataset: names)."""
    with h5py.File(path, "r") as f:
        run = {name: f[name][()] for name in f}
        run["attrs"] = {key: text(value) for key, value in f.attrs.items()}
        run["columns"] = {name: text(f[name].attrs["columns"]).split() for name in f
                          if "columns" in f[name].attrs}
    return run


def column(run, dataset, names):
    """The named columns of a 2-D dataset, as an array (rows, len(names))."""
    all_names = run["columns"][dataset]
    missing = [name for name in names if name not in all_names]
    assert not missing, f"/{dataset} has no column {missing}; it has {all_names}"
    return run[dataset][:, [all_names.index(name) for name in names]]


def published(name):
    """The groups of inputs/NAME.nml (its &output dropped: run_eme sets the file)."""
    groups = read_namelist(ROOT / "inputs" / f"{name}.nml")
    groups.pop("output", None)
    return groups


def run_ok(tmp_path, name, groups):
    result, path = run_eme(tmp_path, name, groups)
    assert result.returncode == 0, result.stderr
    return read(path)


def relative_error(got, expected):
    """max |got - expected| over rows, per column divided by the column's largest |expected|."""
    return float(np.max(np.abs(got - expected) / np.maximum(np.abs(expected).max(axis=0), 1e-300)))


def spatial(groups):
    """The same planar scene as dimension = 3: a third component 0 for every vector, gravity too."""
    groups = {key: dict(fields) for key, fields in groups.items()}
    groups["model"]["dimension"] = 3
    for group, names in (("model", ["gravity"]), ("initial", ["q1", "q2", "p1", "p2"])):
        for name in names:
            if name in groups[group]:
                groups[group][name] = list(groups[group][name]) + [0.0]
    if "gravity" not in groups["model"]:
        groups["model"]["gravity"] = [0.0, -9.81, 0.0]
    return groups


def fixed_eme(groups, t_end=2.0, dt=0.01, variable="entropy"):
    """The scene with EME at fixed dt and newton_tol 1e-12, in `variable` unless its springs are
    elastic (which have none)."""
    groups = {key: dict(fields) for key, fields in groups.items()}
    groups["integrator"] = {"scheme": "eme", "dt": dt, "t_end": t_end, "newton_tol": 1e-12}
    if variable and groups["model"].get("spring_law", "thermoviscoelastic") != "elastic":
        groups["integrator"]["thermo_variable"] = variable
    return groups


def tight_dp853(groups, t_end, interval, variable=None):
    groups = {key: dict(fields) for key, fields in groups.items()}
    groups["integrator"] = {"scheme": "relaxed_dp853", "dt": interval, "t_end": t_end, "tolerance": 1e-12}
    if variable:
        groups["integrator"]["thermo_variable"] = variable
    groups["output"] = {"interval": interval}
    return groups


# ---------------------------------------------------------------- (i) the published scenes
def test_romero_scene_matches_the_oracle(tmp_path):
    """inputs/romero_thermoelastic.nml with relaxed_dp853 at 1e-12 in temperature variables: q, p
    and the temperatures every 0.3 s to 30 s agree with the oracle to 1e-8 of each column's scale;
    the file has 8 mechanical and 2 thermal columns and the scalar J."""
    run = run_ok(tmp_path, "romero", tight_dp853(published("romero_thermoelastic"), 30.0, 0.3, "temperature"))
    assert run["columns"]["state"] == PLANAR + TEMPERATURES, run["columns"]["state"]
    assert run["columns"]["angular_momentum"] == ["J"], run["columns"]["angular_momentum"]
    expected = oracle.reference(oracle.ROMERO, oracle.state_vector(oracle.ROMERO_INITIAL, 2, True), run["time"], True)
    error = relative_error(column(run, "state", PLANAR + TEMPERATURES), expected)
    assert error < TOLERANCE, f"got {error:.3g}, expected < {TOLERANCE:g}"


def test_gonzalez_scene_matches_the_oracle(tmp_path):
    """inputs/gonzalez_elastic.nml with relaxed_dp853 at 1e-12: q and p every 0.5 s to 10 s agree
    with the oracle to 1e-8 of each column's scale; the file has the 8 planar columns and no
    thermal dataset; E(0) is the oracle's elastic energy to 1e-14."""
    run = run_ok(tmp_path, "gonzalez", tight_dp853(published("gonzalez_elastic"), 10.0, 0.5))
    assert run["columns"]["state"] == PLANAR, run["columns"]["state"]
    assert "temperature" not in run and "entropy" not in run, sorted(run)
    y0 = oracle.state_vector(oracle.GONZALEZ_INITIAL, 2, False)
    expected = oracle.reference(oracle.GONZALEZ, y0, run["time"], False)
    error = relative_error(column(run, "state", PLANAR), expected)
    assert error < TOLERANCE, f"got {error:.3g}, expected < {TOLERANCE:g}"
    energy = oracle.elastic_energy(oracle.GONZALEZ, y0)
    assert abs(run["energy"][0] - energy) <= 1e-14 * energy, (run["energy"][0], energy)


@pytest.mark.parametrize("name", ["romero_thermoelastic", "gonzalez_elastic"])
def test_eme_converges_to_the_oracle_at_order_two(tmp_path, name):
    """EME as the published input sets it (Gonzalez's discrete gradient; Romero's in entropy
    variables, the temperatures compared through /temperature), at dt = 0.01, 0.005, 0.0025 s to
    t = 2 s: the error against the oracle falls by 4 per halving (order within 0.15 of 2). The
    full model with the same parts off gave orders 1.97 (elastic, from 0.01 to 0.005 s; 1.87 from
    0.02 s, not yet asymptotic) and 2.000 (thermoelastic)."""
    scene, initial, thermal = ((oracle.ROMERO, oracle.ROMERO_INITIAL, True) if name.startswith("romero")
                               else (oracle.GONZALEZ, oracle.GONZALEZ_INITIAL, False))
    exact = oracle.reference(scene, oracle.state_vector(initial, 2, thermal), [2.0], thermal)[0]
    groups = published(name)
    variable = groups["integrator"].get("thermo_variable")
    errors = []
    for dt in (0.01, 0.005, 0.0025):
        run = run_ok(tmp_path, f"eme_{dt}", fixed_eme(groups, dt=dt, variable=variable))
        got = column(run, "state", PLANAR)[-1]
        if thermal:
            got = np.concatenate([got, column(run, "temperature", TEMPERATURES)[-1]])
        errors.append(np.max(np.abs(got - exact) / np.maximum(np.abs(exact), 1.0)))
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(np.abs(orders - 2.0) < 0.15), f"errors {errors}, orders {orders}, expected 2"


# ---------------------------------------------------------------- (ii) equivalence
def romero_thermoviscoelastic(dimension):
    """Romero's scene as the thermoviscoelastic rung with its viscous branch inert."""
    groups = published("romero_thermoelastic")
    groups["model"].update(spring_law="thermoviscoelastic", beta_v=0.0)
    groups["initial"]["gamma"] = 0.0
    return groups if dimension == 2 else spatial(groups)


def gonzalez_thermoviscoelastic():
    """The elastic scene as the spatial thermoviscoelastic rung with its thermal coupling off."""
    groups = spatial(published("gonzalez_elastic"))
    model, initial = oracle.full_model(oracle.GONZALEZ, oracle.GONZALEZ_INITIAL, elastic=True)
    groups["model"] = {"spring_law": "thermoviscoelastic", "dimension": 3, **model}
    groups["initial"] = initial
    return groups


def gonzalez_with_gravity(dimension):
    groups = published("gonzalez_elastic")
    groups["model"]["gravity"] = [0.0, -9.81]
    return groups if dimension == 2 else spatial(groups)


EQUIVALENT = {
    # name: (first scene, its compared columns, second scene, its compared columns), same order
    "elastic planar, dimension 3 and 2": (
        lambda: spatial(published("gonzalez_elastic")), PLANAR, lambda: published("gonzalez_elastic"), PLANAR),
    "elastic with gravity in the plane, dimension 3 and 2": (
        lambda: gonzalez_with_gravity(3), PLANAR, lambda: gonzalez_with_gravity(2), PLANAR),
    "thermoelastic planar, dimension 3 and 2": (
        lambda: spatial(published("romero_thermoelastic")), PLANAR + ["s_1", "s_2"],
        lambda: published("romero_thermoelastic"), PLANAR + ["s_1", "s_2"]),
    "thermoviscoelastic with an inert viscous branch and thermoelastic, planar": (
        lambda: romero_thermoviscoelastic(2), PLANAR + ["s_1", "s_2"],
        lambda: published("romero_thermoelastic"), PLANAR + ["s_1", "s_2"]),
    "thermoviscoelastic spatial with an inert viscous branch and thermoelastic planar": (
        lambda: romero_thermoviscoelastic(3), PLANAR + ["s_1", "s_2"],
        lambda: published("romero_thermoelastic"), PLANAR + ["s_1", "s_2"]),
    "thermoviscoelastic spatial without thermal coupling and elastic planar": (
        gonzalez_thermoviscoelastic, PLANAR, lambda: published("gonzalez_elastic"), PLANAR),
}


@pytest.mark.parametrize("case", EQUIVALENT)
def test_rungs_and_dimensions_give_the_same_trajectory(tmp_path, case):
    """EME at dt = 0.01 s with newton_tol 1e-12 over 2 s (entropy variables where the rung has
    them): the compared columns agree at every step to 1e-9 of each column's scale, and the
    columns the smaller scene lacks stay exactly 0 in the larger (z, gamma)."""
    first, first_columns, second, second_columns = EQUIVALENT[case]
    big = run_ok(tmp_path, "first", fixed_eme(first()))
    small = run_ok(tmp_path, "second", fixed_eme(second()))
    np.testing.assert_array_equal(big["time"], small["time"])
    error = relative_error(column(big, "state", first_columns), column(small, "state", second_columns))
    assert error < EQUIVALENCE, f"{case}: got {error:.3g}, expected < {EQUIVALENCE:g}"
    extra = [name for name in big["columns"]["state"] if name.endswith("_z") or name == "gamma"]
    if extra:
        assert not column(big, "state", extra).any(), extra


# ---------------------------------------------------------------- (iii) structure on every step
STRUCTURE = {
    # name: (scene, conserved momentum column, /angular_momentum columns or None)
    "elastic planar without gravity": (lambda: published("gonzalez_elastic"), "J", ["J"]),
    "elastic planar with gravity": (lambda: gonzalez_with_gravity(2), "none", None),
    "elastic spatial with gravity along z": (
        lambda: {**spatial(published("gonzalez_elastic")),
                 "model": {**spatial(published("gonzalez_elastic"))["model"], "gravity": [0.0, 0.0, -9.81]}},
        "J_z", ["J_x", "J_y", "J_z"]),
    "thermoelastic planar without gravity": (lambda: published("romero_thermoelastic"), "J", ["J"]),
    "thermoelastic planar with gravity": (
        lambda: {**published("romero_thermoelastic"),
                 "model": {**published("romero_thermoelastic")["model"], "gravity": [0.0, -9.81]}}, "none", None),
    "thermoelastic spatial with gravity along z": (
        lambda: {**spatial(published("romero_thermoelastic")),
                 "model": {**spatial(published("romero_thermoelastic"))["model"], "gravity": [0.0, 0.0, -9.81]}},
        "J_z", ["J_x", "J_y", "J_z"]),
    "thermoviscoelastic planar with gravity": (
        lambda: {"model": {"dimension": 2}, "initial": {}}, "none", None),
}


def gravity_potential_size(run, groups):
    """The largest |m1 g.x1| + |m2 g.x2| over the run's rows (x1 = q1, x2 = q1 + q2)."""
    model = groups["model"]
    dimension = model.get("dimension", 3)
    gravity = np.array(model.get("gravity", [0.0, 0.0, -9.81] if dimension == 3 else [0.0, -9.81]))
    masses = model.get("mass", [1.0, 1.0])
    axes = "xyz"[:dimension]
    q1 = column(run, "state", [f"q1_{a}" for a in axes])
    q2 = column(run, "state", [f"q2_{a}" for a in axes])
    return float(np.max(np.abs(masses[0] * q1 @ gravity) + np.abs(masses[1] * (q1 + q2) @ gravity)))


@pytest.mark.parametrize("case", STRUCTURE)
def test_each_rungs_eme_keeps_its_structure_on_every_step(tmp_path, case):
    """EME as the published input sets it (the thermoviscoelastic scene: the paper's, planar),
    over 20 s: E, the scene's conserved momentum, dS >= 0 and dV <= 0 to the stated round-off
    bounds on every step; the momentum dataset as the scene has it; an elastic file has no
    temperatures and no entropy."""
    scene, conserved, momentum_columns = STRUCTURE[case]
    groups = scene()
    groups.setdefault("integrator", {}).update(t_end=20.0)
    run = run_ok(tmp_path, "run", groups)
    assert run["attrs"]["status"] == "complete"
    assert run["attrs"].get("conserved_momentum", "none") == conserved, run["attrs"].get("conserved_momentum")
    thermal = not case.startswith("elastic")
    energy = run["energy"]
    steps = len(energy) - 1
    law = groups["model"].get("spring_law", "thermoviscoelastic")
    capacities = groups["model"].get("heat_capacity", [10.0, 10.0]) if thermal else [0.0, 0.0]
    theta_ref = groups["model"].get("theta_ref", 300.0)
    # E's rounding is relative to its largest terms: the thermal energies c theta_ref and, where a
    # mass falls far (the soft springs of Romero's scene under gravity fall about 2 km in 20 s),
    # gravity's potential, |m1 g.x1| + |m2 g.x2| with x1 = q1, x2 = q1 + q2.
    scale = abs(energy[0]) + sum(capacities) * theta_ref + gravity_potential_size(run, groups)
    step_change = np.abs(np.diff(energy)).max()
    assert step_change <= 8 * EPS * scale, f"{law}: a step changed E by {step_change:.3g}, bound {8 * EPS * scale:.3g}"
    drift = np.abs(energy - energy[0]).max()
    assert drift <= 8 * EPS * scale * np.sqrt(steps), f"{law}: E drifted {drift:.3g} over {steps} steps"
    if momentum_columns is None:
        assert "angular_momentum" not in run, run["columns"].get("angular_momentum")
    else:
        assert run["columns"]["angular_momentum"] == momentum_columns, run["columns"]["angular_momentum"]
        values = column(run, "angular_momentum", [conserved])[:, 0]
        bound = 64 * EPS * max(np.abs(run["angular_momentum"]).max(), 1.0)
        assert np.abs(values - values[0]).max() <= bound, (np.abs(values - values[0]).max(), bound)
    if thermal:
        entropy_bound = 32 * EPS * np.abs(run["entropy"]).max()
        lyapunov_bound = 64 * EPS * abs(energy[0])
        assert run["min_entropy_increment"].min() >= -entropy_bound, run["min_entropy_increment"].min()
        assert np.diff(run["entropy"]).min() >= -entropy_bound, np.diff(run["entropy"]).min()
        assert run["max_lyapunov_increment"].max() <= lyapunov_bound, run["max_lyapunov_increment"].max()
        assert np.diff(run["lyapunov"]).max() <= lyapunov_bound, np.diff(run["lyapunov"]).max()
    else:
        assert "temperature" not in run and "entropy" not in run, sorted(run)
        assert run["columns"]["state"] == (PLANAR if "planar" in case else SPATIAL), run["columns"]["state"]


# ---------------------------------------------------------------- (iv) what a rung does not have
REFUSED = {
    # name: (changes to the published scene, words the message must hold)
    "elastic with theta": ("gonzalez_elastic", {"initial": {"theta": [300.0, 300.0]}}, ["theta", "elastic"]),
    "elastic with conductivity": ("gonzalez_elastic", {"model": {"conductivity": 1.0}}, ["conductivity", "elastic"]),
    "elastic with heat_capacity": ("gonzalez_elastic", {"model": {"heat_capacity": [1.0, 1.0]}},
                                   ["heat_capacity", "elastic"]),
    "elastic with thermo_variable": ("gonzalez_elastic", {"integrator": {"thermo_variable": "entropy"}},
                                     ["thermo_variable", "elastic"]),
    "elastic with theta_r": ("gonzalez_elastic", {"output": {"theta_r": 300.0}}, ["theta_r", "elastic"]),
    "elastic with fix_temperature": ("gonzalez_elastic", {"constraints": {"fix_temperature": True}},
                                     ["fix_temperature", "elastic"]),
    "thermoelastic with beta_v": ("romero_thermoelastic", {"model": {"beta_v": 0.5}}, ["beta_v", "thermoelastic"]),
    "thermoelastic with viscosity_const": ("romero_thermoelastic", {"model": {"viscosity_const": 100.0}},
                                           ["viscosity_const", "thermoelastic"]),
    "thermoelastic with gamma": ("romero_thermoelastic", {"initial": {"gamma": 0.0}}, ["gamma", "thermoelastic"]),
    "dimension 2 with three values of q1": ("gonzalez_elastic", {"initial": {"q1": [1.1, 0.0, 0.0]}}, ["q1"]),
    "dimension 2 with three values of gravity": ("romero_thermoelastic", {"model": {"gravity": [0.0, 0.0, 0.0]}},
                                                 ["gravity"]),
    "dimension 2 with a third component": ("gonzalez_elastic", {"initial": {"p2(3)": 0.0}}, ["p2(3)"]),
    "an unknown law": ("gonzalez_elastic", {"model": {"spring_law": "plastic"}},
                       ["spring_law", "elastic", "thermoelastic", "thermoviscoelastic"]),
    "dimension 4": ("gonzalez_elastic", {"model": {"dimension": 4}}, ["dimension"]),
}


@pytest.mark.parametrize("case", REFUSED)
def test_what_a_rung_does_not_have_is_refused(tmp_path, case):
    """Exit status 2, nothing written, and the message names the field (and the law, where the
    law is what refuses it)."""
    name, changes, words = REFUSED[case]
    groups = published(name)
    for group, fields in changes.items():
        groups.setdefault(group, {}).update(fields)
    result, path = run_eme(tmp_path, "refused", groups)
    assert result.returncode == 2, f"{case}: exit {result.returncode}, expected 2; stderr {result.stderr}"
    for word in words:
        assert word in result.stderr, f"{case}: {word!r} not in {result.stderr!r}"
    assert not path.exists() and not Path(f"{path}.part").exists()


def test_help_documents_the_ladder():
    """eme_run --help names both fields and every law."""
    help_ = help_text()
    for word in ("spring_law", "dimension", "'elastic'", "'thermoelastic'", "'thermoviscoelastic'"):
        assert word in help_, word
