"""The spring chain as a model of the engine (docs/formulation.md section 10, the dense path):
- N = 2, 'fixed-free', 3D with the paper's data (spring 1 without a viscous branch) IS the paper's
  double pendulum: EME (Gonzalez) in each thermodynamic variable gives the pendulum's run over
  about 2 s to 1e-9 (E, S, temperatures, positions), the pendulum's relative q2 and its momenta
  mapped to the chain's absolute positions and the masses' own momenta (derived below);
- a 3D chain of N = 5 runs EME and the midpoint rule to completion, its per-step balances within
  their bounds, and E and S recomputed from /state by tests/oracles/spring_chain.py (typed from
  section 10, not from src/): EME keeps E to round-off and S never falls;
- a dense chain of 400 unknowns runs under a 1 MB stack (its n x n work arrays are allocated);
- bad input: exit 2 with a message naming the file, group and field, and no file written."""
import resource
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

from conftest import BIN, ROOT, namelist_text, read_namelist, run_eme

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "oracles"))
import spring_chain as oracle  # noqa: E402

VARIABLES = {"entropy": "entropy", "internal_energy": "internal_energy", "theta": "temperature"}


def text(value):
    return value.decode() if isinstance(value, bytes) else str(value)


def columns(f, name):
    return [text(c) for c in f[f"{name}_column"][()]]


def pendulum_to_chain(q1, q2, p1, p2, masses):
    """The chain's absolute x_1 = q1, x_2 = q1 + q2 and the masses' own momenta P_i = m_i dx_i/dt
    from the pendulum's (q1, relative q2, p1, p2). Its kinetic energy is
    T = m1 |dq1/dt|^2/2 + m2 |dq1/dt + dq2/dt|^2/2, so p1 = dT/d(dq1/dt) = m1 dx1/dt + m2 dx2/dt
    = P1 + P2 and p2 = dT/d(dq2/dt) = m2 dx2/dt = P2: P1 = p1 - p2, P2 = p2 (masses unused: the map
    holds for any)."""
    del masses
    return np.array([q1, q1 + q2]), np.array([p1 - p2, p2])


@pytest.mark.parametrize("variable", sorted(VARIABLES))
def test_two_springs_are_the_paper_pendulum(tmp_path, variable):
    scene = read_namelist(ROOT / "inputs" / f"paper_fig4_eme_{variable}.nml")
    integrator = dict(scene["integrator"], t_end=2.1, newton_tol=1e-13)   # 14 steps of 0.15 s
    pendulum_result, pendulum_path = run_eme(tmp_path, "pendulum", {"integrator": integrator})
    assert pendulum_result.returncode == 0, pendulum_result.stderr
    with h5py.File(pendulum_path, "r") as f:
        a = f.attrs
        names = columns(f, "state")
        z0 = dict(zip(names, f["state"][0]))
        vector = {key: np.array([z0[f"{key}_{axis}"] for axis in "xyz"]) for key in ("q1", "q2", "p1", "p2")}
        theta0 = f["temperature"][0]
        # Table 1 as the pendulum's file records it: spring 1 has no Maxwell element.
        model = {"model_name": "spring_chain", "links": 2, "ends": "fixed-free", "dimension": 3,
                 "gravity": list(a["gravity"]), "mass": list(a["mass"]), "natural_length": list(a["natural_length"]),
                 "mu_eq_const": list(a["mu_eq_const"]), "mu_eq_slope": list(a["mu_eq_slope"]),
                 "heat_capacity": list(a["heat_capacity"]), "theta_ref": float(a["theta_ref"]),
                 "beta": float(a["beta"]), "beta_v": [0.0, float(a["beta_v"])],
                 "mu_neq_const": [0.0, float(a["mu_neq_const"])], "mu_neq_slope": [0.0, float(a["mu_neq_slope"])],
                 "viscosity_const": float(a["viscosity_const"]),
                 "viscosity_activation": float(a["viscosity_activation"]),
                 "conductivity": float(a["conductivity"])}
        pendulum = {"time": f["time"][()], "energy": f["energy"][()], "entropy": f["entropy"][()],
                    "temperature": f["temperature"][()],
                    "q1": np.stack([f["state"][:, names.index(f"q1_{c}")] for c in "xyz"], axis=1),
                    "q2": np.stack([f["state"][:, names.index(f"q2_{c}")] for c in "xyz"], axis=1)}
    x, p = pendulum_to_chain(vector["q1"], vector["q2"], vector["p1"], vector["p2"], model["mass"])
    initial = {"x": list(x.ravel()), "p": list(p.ravel()), "gamma": 0.0, "theta": list(theta0)}
    chain_result, chain_path = run_eme(tmp_path, "chain", {"model": model, "initial": initial,
                                                           "integrator": integrator})
    assert chain_result.returncode == 0, chain_result.stderr
    with h5py.File(chain_path, "r") as f:
        names = columns(f, "state")
        chain = {key: f[key][()] for key in ("time", "energy", "entropy", "temperature")}
        chain_x = [np.stack([f["state"][:, names.index(f"x{i}_{c}")] for c in "xyz"], axis=1) for i in (1, 2)]
        assert text(f.attrs["status"]) == "complete"
    assert len(chain["time"]) == len(pendulum["time"]) == 15
    np.testing.assert_allclose(chain["time"], pendulum["time"], rtol=1e-14)
    for key in ("energy", "entropy", "temperature"):
        np.testing.assert_allclose(chain[key], pendulum[key], rtol=1e-9, atol=1e-9 * np.max(np.abs(pendulum[key])),
                                   err_msg=key)
    scale = np.max(np.abs(pendulum["q1"] + pendulum["q2"]))
    np.testing.assert_allclose(chain_x[0], pendulum["q1"], rtol=0, atol=1e-9 * scale, err_msg="x1 = q1")
    np.testing.assert_allclose(chain_x[1], pendulum["q1"] + pendulum["q2"], rtol=0, atol=1e-9 * scale,
                               err_msg="x2 = q1 + q2")


def five_chain():
    """A hanging 3D chain of five unlike springs, masses and links off equilibrium (the oracle's
    Chain and the &model fields of the same data)."""
    springs = [oracle.Spring(natural_length=1.0 + 0.1 * a, mu_eq_const=150.0 + 20 * a, mu_eq_slope=0.3, beta=0.05,
                             heat_capacity=5.0 + a, theta_ref=300.0, beta_v=0.2 * (a % 3), mu_neq_const=4.0 + a,
                             mu_neq_slope=0.05 * (a % 2), viscosity_const=3.0 + a, viscosity_activation=10.0)
               for a in range(1, 6)]
    chain = oracle.Chain(masses=[1.0, 0.8, 1.2, 0.9, 1.1], springs=springs, conductivity=[0.5, 1.2, 1.9, 2.6],
                         gravity=[0.0, 0.0, -9.81])
    model = {"model_name": "spring_chain", "links": 5, "ends": "fixed-free", "dimension": 3,
             "gravity": list(chain.gravity), "mass": list(chain.masses),
             "conductivity": list(chain.conductivity)}
    for name in ("natural_length", "mu_eq_const", "mu_eq_slope", "beta", "heat_capacity", "theta_ref", "beta_v",
                 "mu_neq_const", "mu_neq_slope", "viscosity_const", "viscosity_activation"):
        model[name] = [getattr(s, name) for s in springs]
    x = np.array([[1.1 * i, 0.3 * np.sin(i), -0.2 * i] for i in range(1, 6)])
    p = np.array([[0.2 * np.cos(i), 0.5, 0.1 * i] for i in range(1, 6)])
    initial = {"x": list(x.ravel()), "p": list(p.ravel()), "gamma": [0.01 * a for a in range(5)],
               "theta": [280.0 + 15.0 * a for a in range(5)]}
    return chain, model, initial


def oracle_state(chain, f):
    """The oracle's flat state (x, p, gamma, theta) of each row of a temperature-variable run file."""
    names = columns(f, "state")
    state = f["state"][()]
    pick = lambda label: state[:, names.index(label)]  # noqa: E731
    x = [pick(f"x{i}_{c}") for i in range(1, chain.n + 1) for c in "xyz"]
    p = [pick(f"p{i}_{c}") for i in range(1, chain.n + 1) for c in "xyz"]
    gamma = [pick(f"gamma_{a}") for a in range(1, chain.ns + 1)]
    theta = [pick(f"theta_{a}") for a in range(1, chain.ns + 1)]
    return np.stack(x + p + gamma + theta, axis=1)


@pytest.mark.parametrize("scheme", ["eme", "midpoint"])
def test_five_springs_keep_their_balances(tmp_path, scheme):
    chain, model, initial = five_chain()
    integrator = {"scheme": scheme, "thermo_variable": "temperature", "dt": 0.01, "t_end": 0.5, "newton_tol": 1e-12}
    result, path = run_eme(tmp_path, scheme, {"model": model, "initial": initial, "integrator": integrator})
    assert result.returncode == 0, result.stderr
    with h5py.File(path, "r") as f:
        assert text(f.attrs["status"]) == "complete"
        assert len(f["time"]) == 51
        bounds = np.asarray(f.attrs["balance_bound_ulps"], dtype=float)
        guaranteed = text(f.attrs["balance_guarantees"]).split()
        balance_columns = columns(f, "balance")
        balance = f["balance"][()]
        states = oracle_state(chain, f)
        energy, entropy = f["energy"][()], f["entropy"][()]
        np.testing.assert_allclose(states[0], oracle.join(np.reshape(initial["x"], (5, 3)),
                                                          np.reshape(initial["p"], (5, 3)), initial["gamma"],
                                                          initial["theta"]), rtol=1e-14, atol=1e-15)
    assert guaranteed, "a run of a discrete-gradient family guarantees some balances"
    for name in guaranteed:   # |dE - Q|, max |dJ_k|, -dS, dV in ulps of their scales: each at most its bound
        column = balance_columns.index(name)
        assert np.all(balance[:, column] <= bounds[column]), (name, np.max(balance[:, column]))
    recomputed = np.array([oracle.energy_entropy(chain, y) for y in states])
    scale = np.max(np.abs(recomputed[:, 0]))
    np.testing.assert_allclose(energy, recomputed[:, 0], rtol=0, atol=1e-11 * scale)
    np.testing.assert_allclose(entropy, recomputed[:, 1], rtol=1e-12)
    if scheme == "eme":
        assert np.max(np.abs(recomputed[:, 0] - recomputed[0, 0])) <= 1e-11 * scale, "E conserved to round-off"
        assert np.all(np.diff(recomputed[:, 1]) >= -1e-12 * np.abs(recomputed[:, 1]).max()), "S never falls"
        assert np.diff(recomputed[:, 1]).sum() > 0, "the viscous branches and links produce entropy"


def limited_stack(megabytes):
    """A preexec_fn that sets the process's stack limit."""
    def limit():
        resource.setrlimit(resource.RLIMIT_STACK, (megabytes << 20, megabytes << 20))
    return limit


@pytest.mark.parametrize("scheme", ["relaxed_rk4", "relaxed_gauss6", "cvode_bdf"])
def test_a_large_dense_chain_needs_no_large_stack(tmp_path, scheme):
    """The dense path takes chains up to 1000 unknowns; its n x n work arrays (the field's
    Jacobian and its derivatives through the partials, a collocation stage's df, CVODE's
    Jacobian) are allocated, not automatic: 1000 unknowns are 8 MB an array, Linux's default
    stack (a 1D rod of 250 springs crashed with SIGSEGV in relaxed_rk4 and relaxed_gauss6).
    Here 100 springs (400 unknowns, 1.3 MB an array) under a 1 MB stack limit, one step: each
    completes. Planted: the arrays automatic again, all three die of SIGSEGV."""
    groups = {"model": {"model_name": "spring_chain", "family": "rod", "links": 100, "ends": "fixed-free",
                        "dimension": 1},
              "initial": {"perturbation": "random", "amplitude": 0.01},
              "integrator": {"scheme": scheme, "dt": 1e-3, "t_end": 1e-3}}
    groups["output"] = {"file": str(tmp_path / "stack.h5")}
    namelist = tmp_path / "stack.nml"
    namelist.write_text(namelist_text(groups))
    result = subprocess.run([str(BIN / "eme_run"), str(namelist), "-eme_dense"], capture_output=True, text=True, timeout=300,
                            preexec_fn=limited_stack(1))
    assert result.returncode == 0, (result.returncode, result.stderr)
    with h5py.File(tmp_path / "stack.h5", "r") as f:
        assert text(f.attrs["status"]) == "complete" and f.attrs["unknowns"] == 400 and "state" in f


BAD_INPUT = [
    ({"links": 3, "natural_length": [1.0, 2.0]}, {}, "&model: natural_length has 2 values; allowed: 1 or 3"),
    ({"links": 0}, {}, "&model: links = 0 is not allowed"),
    ({"dimension": 4}, {}, "&model: dimension = 4 is not allowed"),
    ({"links": 2, "ends": "fixed-fixed"}, {"theta": [300.0, 310.0]}, "&initial: theta has 2 values; allowed: 1 or 3"),
    ({"links": 2}, {"x": [1.0, 0.0, 0.0]}, "&initial: x has 3 values; allowed: 6"),
    ({"spring_law": "thermoelastic", "beta_v": 0.5}, {}, "&model: beta_v is not a field of spring_law = 'thermoelastic'"),
    ({"span": 3.0}, {}, "&model: span is not a field of spring_law = 'thermoviscoelastic', ends = 'fixed-free'"),
]


@pytest.mark.parametrize("model, initial, message", BAD_INPUT)
def test_bad_input_is_refused(tmp_path, model, initial, message):
    groups = {"model": dict(model_name="spring_chain", **model), "integrator": {"t_end": 0.3}}
    if initial:
        groups["initial"] = initial
    result, path = run_eme(tmp_path, "bad", groups)
    assert result.returncode == 2, result.stderr
    assert message in result.stderr, result.stderr
    assert str(tmp_path / "bad.nml") in result.stderr, "the message names the file"
    assert not path.exists() and not Path(str(path) + ".part").exists()
