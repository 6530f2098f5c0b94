"""The spring chain's input for large N (docs/input.md; docs/formulation.md section 10):
- the continuum family, &model family = 'rod': the springs', masses' and links' values the run
  uses are those of section 10's table, typed below (not src/'s rod_springs): E and S at t = 0 and
  the first step's difference quotient against tests/oracles/spring_chain.py's field with the
  typed springs; and refining N, the lowest frequency measured from a run (1D 'fixed-fixed', no
  thermal coupling, no gravity, small amplitude) converges to the rod's pi sqrt(EA/rho)/L at second
  order;
- &initial perturbation: 'mode' moves the masses along x by the shape typed from docs/input.md,
  'random' by SplitMix64's numbers (typed here from Steele, Lea and Flood 2014), the same on two
  runs and different for another seed;
- &initial file: an HDF5 file of q, p, gamma, theta is the run's first row, and each bad file is
  refused with exit status 2, the dataset and index named and nothing written;
- fields that conflict (a spring's value with a rod, a perturbation's parameter without it, a state
  value with a file) are refused by name."""
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

from conftest import BIN, run_eme

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "oracles"))
import spring_chain as oracle  # noqa: E402

AXES = "xyz"


def text(value):
    return value.decode() if isinstance(value, bytes) else str(value)


def chain_rows(path, n, dim, rung="thermoviscoelastic"):
    """The oracle's flat states (x, p, gamma, theta) of the rows of a temperature-variable run."""
    with h5py.File(path, "r") as f:
        names = [text(c) for c in f["state_column"][()]]
        state = f["state"][()]
    ns = len([name for name in names if name.startswith("theta_")]) if rung != "elastic" else None
    pick = lambda label: state[:, names.index(label)]  # noqa: E731
    columns = [pick(f"x{i}_{AXES[c]}") for i in range(1, n + 1) for c in range(dim)]
    columns += [pick(f"p{i}_{AXES[c]}") for i in range(1, n + 1) for c in range(dim)]
    if rung == "thermoviscoelastic":
        columns += [pick(f"gamma_{a}") for a in range(1, ns + 1)]
    if rung != "elastic":
        columns += [pick(f"theta_{a}") for a in range(1, ns + 1)]
    return np.stack(columns, axis=1)


# ---------------------------------------------------------------------------- the rod family
def rod_chain_typed(rod, n_springs, ends, gravity):
    """Section 10's table, typed: h = L/n_s; m_i = rho h (the free end's rho h/2); mu_eq_const = EA h,
    mu_eq_slope = h stiffness_slope (-d(EA)/dtheta), beta = h E A alpha, heat_capacity = c h, mu_neq_const = E^neq A/h,
    mu_neq_slope = slope/h, viscosity_const = eta A/h, beta_v, theta_ref and the activation as they
    are; each link kappa = k A/h."""
    h = rod["rod_length"] / n_springs
    spring = oracle.Spring(natural_length=h, mu_eq_const=rod["axial_stiffness"] * h,
                           mu_eq_slope=rod["stiffness_slope"] * h, beta=rod["thermal_stress"] * h,
                           heat_capacity=rod["rod_heat_capacity"] * h, theta_ref=rod["theta_ref"],
                           beta_v=rod["beta_v"], mu_neq_const=rod["maxwell_stiffness"] / h,
                           mu_neq_slope=rod["maxwell_slope"] / h, viscosity_const=rod["viscosity"] / h,
                           viscosity_activation=rod["viscosity_activation"])
    masses = np.full(n_springs if ends == "fixed-free" else n_springs - 1, rod["mass_per_length"] * h)
    if ends == "fixed-free":
        masses[-1] = rod["mass_per_length"] * h / 2
    return oracle.Chain(masses=masses, springs=[spring] * n_springs,
                        conductivity=np.full(n_springs - 1, rod["rod_conductivity"] / h),
                        gravity=np.asarray(gravity, dtype=float), ends=ends, span=rod["rod_length"])


# A rod whose every datum is unlike the defaults and unlike the others.
ROD = {"rod_length": 3.0, "mass_per_length": 0.7, "axial_stiffness": 400.0, "stiffness_slope": 0.3,
       "thermal_stress": 0.08, "rod_heat_capacity": 12.0, "maxwell_stiffness": 30.0, "maxwell_slope": 0.05,
       "viscosity": 9.0, "rod_conductivity": 40.0, "beta_v": 0.4, "theta_ref": 290.0, "viscosity_activation": 20.0}


@pytest.mark.parametrize("ends, dim", [("fixed-free", 3), ("fixed-fixed", 2)])
def test_the_rod_familys_springs_are_section_10s(tmp_path, ends, dim):
    """E and S at t = 0 (masses, lengths, the equilibrium stiffness, its slope, beta, the capacity,
    the Maxwell stiffness through gamma, theta_ref) and one short EME step's (y1 - y0)/dt against
    the field at the midpoint (also viscosity, conductivity): a value off by a factor h^2 or 2 (a
    spring's value scaled with N/L instead of L/N, the free end's mass not halved) moves E or the
    quotient by far more than the 1e-12 and 1e-6 allowed."""
    links = 4
    n_springs = links if ends == "fixed-free" else links + 1
    h = ROD["rod_length"] / n_springs
    gravity = [0.0, -9.81, 0.0][:dim] if dim == 2 else [0.0, 0.3, -9.81]
    rng = np.random.default_rng(5)
    x = np.zeros((links, dim))
    x[:, 0] = h * np.arange(1, links + 1) * 1.02
    x += 0.05 * h * rng.standard_normal((links, dim))
    p = 0.3 * rng.standard_normal((links, dim))
    gamma = 0.01 * h * rng.standard_normal(n_springs)
    theta = 285.0 + 10.0 * rng.random(n_springs)
    model = {"model_name": "spring_chain", "family": "rod", "links": links, "ends": ends, "dimension": dim,
             "gravity": gravity, **ROD}
    if ends == "fixed-fixed":
        model["span"] = ROD["rod_length"] * 1.02
    dt = 1e-5
    initial = {"x": list(x.ravel()), "p": list(p.ravel()), "gamma": list(gamma), "theta": list(theta)}
    integrator = {"thermo_variable": "temperature", "dt": dt, "t_end": dt, "newton_tol": 1e-13}
    result, path = run_eme(tmp_path, "rod", {"model": model, "initial": initial, "integrator": integrator})
    assert result.returncode == 0, result.stderr
    chain = rod_chain_typed(ROD, n_springs, ends, gravity)
    if ends == "fixed-fixed":
        chain.span = model["span"]
    rows = chain_rows(path, links, dim)
    np.testing.assert_allclose(rows[0], oracle.join(x, p, gamma, theta), rtol=1e-15, atol=0)
    with h5py.File(path, "r") as f:
        energy, entropy = f["energy"][0], f["entropy"][0]
    expected_energy, expected_entropy = oracle.energy_entropy(chain, rows[0])
    assert energy == pytest.approx(expected_energy, rel=1e-12, abs=1e-12 * abs(expected_energy)), (energy, expected_energy)
    assert entropy == pytest.approx(expected_entropy, rel=1e-12), (entropy, expected_entropy)
    quotient = (rows[1] - rows[0]) / dt
    field = oracle.rhs(chain)(0.0, (rows[0] + rows[1]) / 2)
    # Each block (x, p, gamma, theta) to 1e-6 of its own scale: the discrete gradients differ from
    # the midpoint field by O(|dz|^2).
    nd = links * dim
    for name, block in (("x", slice(0, nd)), ("p", slice(nd, 2 * nd)), ("gamma", slice(2 * nd, 2 * nd + n_springs)),
                        ("theta", slice(2 * nd + n_springs, None))):
        scale = np.max(np.abs(field[block]))
        np.testing.assert_allclose(quotient[block], field[block], rtol=0, atol=1e-6 * scale, err_msg=name)


def lowest_frequency(tmp_path, n_springs, rod, steps=80):
    """omega_1 of the rod family's 1D 'fixed-fixed' chain without thermal coupling
    (thermal_stress = stiffness_slope = 0: psi_ltheta = mu_eq_slope L + beta = 0, so the
    displacement modes are the elastic rung's; spring_law = 'elastic' itself fails the step's
    energy check at small amplitude, see the report), measured from an EME run started
    in mode 1 at small amplitude: the mode's amplitude U_n = 2/(N+1) sum_i u_i sin(pi i/(N+1))
    follows U_n = U_0 cos(n phi) under the midpoint rule (the step map of section 10, a rotation
    by phi = 2 arctan(omega dt/2) with P_0 = 0), so cos(phi) is the least-squares ratio
    sum U_n (U_{n+1} + U_{n-1}) / (2 sum U_n^2), and omega = (2/dt) tan(phi/2) undoes the time
    discretisation exactly, leaving the space discretisation's error alone."""
    links = n_springs - 1
    h = rod["rod_length"] / n_springs
    continuum = np.pi * np.sqrt(rod["axial_stiffness"] / rod["mass_per_length"]) / rod["rod_length"]
    dt = 2 * np.pi / continuum / 40
    model = {"model_name": "spring_chain", "family": "rod", "spring_law": "thermoelastic", "links": links,
             "ends": "fixed-fixed", "dimension": 1, "thermal_stress": 0.0, "stiffness_slope": 0.0,
             **{k: rod[k] for k in ("rod_length", "mass_per_length", "axial_stiffness")}}
    initial = {"perturbation": "mode", "mode_number": 1, "amplitude": 1e-5 * h}
    integrator = {"dt": dt, "t_end": steps * dt, "newton_tol": 1e-13}
    result, path = run_eme(tmp_path, f"rod_{n_springs}", {"model": model, "initial": initial,
                                                           "integrator": integrator}, "-eme_dense")
    assert result.returncode == 0, result.stderr
    x = chain_rows(path, links, 1, rung="thermoelastic")[:, :links]
    i = np.arange(1, links + 1)
    u = x - i * h
    amplitude = 2 / n_springs * u @ np.sin(np.pi * i / n_springs)
    middle = amplitude[1:-1]
    cos_phi = np.sum(middle * (amplitude[2:] + amplitude[:-2])) / (2 * np.sum(middle**2))
    phi = np.arccos(cos_phi)
    return 2 / dt * np.tan(phi / 2), continuum


def test_the_rod_familys_lowest_frequency_converges_to_the_rods_at_second_order(tmp_path):
    """omega_1(N) from runs at n_s = 4, 8, 16, 32 springs: equal to the lumped chain's
    (2/h) sin(pi/(2 n_s)) sqrt(EA/rho) (section 10's omega_k at k = 1, psi_ll = EA/h, m = rho h)
    to 1e-9, and its error against the rod's pi sqrt(EA/rho)/L falls like 1/N^2 (the error is
    (pi/(2 n_s))^2/6 to leading order: observed orders within 0.02 of 2)."""
    rod = {"rod_length": 2.0, "mass_per_length": 0.5, "axial_stiffness": 100.0}
    errors = []
    for n_springs in (4, 8, 16, 32):
        omega, continuum = lowest_frequency(tmp_path, n_springs, rod)
        h = rod["rod_length"] / n_springs
        lumped = 2 / h * np.sin(np.pi / (2 * n_springs)) * np.sqrt(rod["axial_stiffness"] / rod["mass_per_length"])
        assert omega == pytest.approx(lumped, rel=1e-9), (n_springs, omega, lumped)
        errors.append(abs(omega - continuum) / continuum)
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(np.abs(orders - 2) < 0.02), (errors, orders)


# ---------------------------------------------------------------------------- perturbations
def splitmix64(seed, count):
    """SplitMix64 (Steele, Lea and Flood 2014): state += 0x9e3779b97f4a7c15, then
    z = (z ^ z >> 30) * 0xbf58476d1ce4e5b9, z = (z ^ z >> 27) * 0x94d049bb133111eb, z ^ z >> 31,
    modulo 2^64; the numbers in [0, 1) are (z >> 11) 2^-53."""
    mask, state, numbers = (1 << 64) - 1, seed, []
    for _ in range(count):
        state = (state + 0x9E3779B97F4A7C15) & mask
        z = state
        z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & mask
        z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & mask
        z ^= z >> 31
        numbers.append(z)
    return numbers


def test_the_typed_splitmix64_gives_its_published_first_numbers():
    """The generator's reference outputs from seed 0 (Vigna's splitmix64.c), so the typed copy
    that the random perturbation is checked against is SplitMix64 itself."""
    assert splitmix64(0, 3) == [0xE220A8397B1DCDAF, 0x6E789E6AA1B965F4, 0x06C45D188009454F]


def start_positions(tmp_path, name, model, initial):
    """The masses' positions (N, dim) of a run's first row."""
    integrator = {"dt": 1e-3, "t_end": 1e-3}
    result, path = run_eme(tmp_path, name, {"model": model, "initial": initial, "integrator": integrator})
    assert result.returncode == 0, result.stderr
    rows = chain_rows(path, model["links"], model["dimension"])
    return rows[0, :model["links"] * model["dimension"]].reshape(model["links"], model["dimension"])


@pytest.mark.parametrize("ends, k", [("fixed-fixed", 3), ("fixed-free", 2)])
def test_a_mode_perturbation_moves_the_masses_along_x_by_the_modes_shape(tmp_path, ends, k):
    """x_i = (default x_i) + amplitude sin(k pi i/(N + 1)) ('fixed-fixed') or + amplitude
    sin((2k - 1) pi i/(2N)) ('fixed-free'), y and z unchanged (docs/input.md)."""
    links, amplitude = 6, 0.03
    model = {"model_name": "spring_chain", "links": links, "ends": ends, "dimension": 3, "natural_length": 1.5}
    moved = start_positions(tmp_path, "mode", model, {"perturbation": "mode", "mode_number": k, "amplitude": amplitude})
    i = np.arange(1, links + 1)
    rest = np.zeros((links, 3))
    rest[:, 0] = 1.5 * i
    shape = np.sin(k * np.pi * i / (links + 1)) if ends == "fixed-fixed" else np.sin((2 * k - 1) * np.pi * i / (2 * links))
    expected = rest.copy()
    expected[:, 0] += amplitude * shape
    np.testing.assert_allclose(moved, expected, rtol=0, atol=1e-14)


def test_a_random_perturbation_is_splitmix64s_the_same_on_two_runs_and_another_for_another_seed(tmp_path):
    """x_i = (default x_i) + amplitude (2 u_i - 1), u_i the i-th SplitMix64 number from the seed."""
    links, amplitude = 7, 0.02
    model = {"model_name": "spring_chain", "links": links, "ends": "fixed-free", "dimension": 2}
    initial = {"perturbation": "random", "seed": 12345, "amplitude": amplitude}
    first = start_positions(tmp_path, "random_a", model, initial)
    again = start_positions(tmp_path, "random_b", model, initial)
    other = start_positions(tmp_path, "random_c", model, dict(initial, seed=12346))
    np.testing.assert_array_equal(first, again)
    assert np.all(first[:, 0] != other[:, 0]), (first, other)
    u = np.array([(z >> 11) * 2.0**-53 for z in splitmix64(12345, links)])
    expected = np.zeros((links, 2))
    expected[:, 0] = 2.0 * np.arange(1, links + 1) + amplitude * (2 * u - 1)   # natural length 2 by default
    np.testing.assert_allclose(first, expected, rtol=0, atol=1e-14)


# ---------------------------------------------------------------------------- the &initial file
def file_chain(links=3, dim=3):
    """A hanging chain's &model and a state off its rest (x, p, gamma, theta), n_s = links."""
    model = {"model_name": "spring_chain", "links": links, "ends": "fixed-free", "dimension": dim}
    x = np.array([[2.1 * i, 0.2 * np.sin(i), -0.1 * i][:dim] for i in range(1, links + 1)])
    p = np.array([[0.1 * i, -0.3, 0.2][:dim] for i in range(1, links + 1)])
    gamma = np.array([0.01 * a for a in range(links)])
    theta = np.array([281.0 + 7.0 * a for a in range(links)])
    return model, {"q": x, "p": p, "gamma": gamma, "theta": theta}


def write_state(path, datasets):
    with h5py.File(path, "w") as f:
        for name, values in datasets.items():
            f[name] = values


@pytest.mark.parametrize("dim", [3, 1])
def test_an_initial_file_is_the_runs_first_row(tmp_path, dim):
    """q, p, gamma, theta written by h5py, named relative to the namelist's folder (the run starts
    elsewhere): one step later /state's first row is exactly them (1D: q and p of shape (N,))."""
    model, state = file_chain(dim=dim)
    if dim == 1:
        state["q"], state["p"] = state["q"][:, 0], state["p"][:, 0]
    write_state(tmp_path / "start.h5", state)
    integrator = {"thermo_variable": "temperature", "dt": 1e-3, "t_end": 1e-3}
    result, path = run_eme(tmp_path, "from_file", {"model": model, "initial": {"file": "start.h5"},
                                                   "integrator": integrator})
    assert result.returncode == 0, result.stderr
    rows = chain_rows(path, model["links"], dim)
    assert len(rows) == 2
    np.testing.assert_array_equal(rows[0], oracle.join(state["q"], state["p"], state["gamma"], state["theta"]))
    assert not np.array_equal(rows[1], rows[0])


def bad_states():
    """(what is wrong, the datasets, what the message names)."""
    model, good = file_chain()
    cases = []
    cases.append(("q has a wrong shape", dict(good, q=np.vstack([good["q"], [[9.0, 0, 0]]])), ["dataset q", "(4, 3)", "(3, 3)"]))
    cases.append(("theta has a wrong shape", dict(good, theta=good["theta"][:2]), ["dataset theta", "(2,)", "(3,)"]))
    nan_p = good["p"].copy()
    nan_p[1, 2] = np.nan
    cases.append(("a NaN", dict(good, p=nan_p), ["p[1, 2]", "mass 2", "component z", "NaN"]))
    inf_gamma = good["gamma"].copy()
    inf_gamma[2] = np.inf
    cases.append(("an infinite value", dict(good, gamma=inf_gamma), ["gamma[2]", "spring 3", "not finite"]))
    coincident = good["q"].copy()
    coincident[2] = coincident[1]
    cases.append(("two masses at one place", dict(good, q=coincident), ["dataset q", "spring 3", "q[1]", "q[2]",
                                                                          "length 0"]))
    at_support = good["q"].copy()
    at_support[0] = 0.0
    cases.append(("a mass at the support", dict(good, q=at_support), ["spring 1", "support", "length 0"]))
    for value in (0.0, -5.0):
        cold = good["theta"].copy()
        cold[1] = value
        cases.append((f"theta = {value}", dict(good, theta=cold), ["theta[1]", "spring 2", "> 0"]))
    hot = good["theta"].copy()
    hot[2] = 750.0       # above theta_ref + mu_eq_const/mu_eq_slope = 700 K
    cases.append(("theta above the stiffness bound", dict(good, theta=hot), ["theta[2]", "spring 3", "mu_eq"]))
    missing = {k: v for k, v in good.items() if k != "gamma"}
    cases.append(("no gamma", missing, ["no dataset 'gamma'"]))
    return model, cases


MODEL, BAD = bad_states()


@pytest.mark.parametrize("case", range(len(BAD)), ids=[c[0] for c in BAD])
def test_a_bad_initial_file_is_refused_naming_the_dataset_and_index(tmp_path, case):
    _, datasets, named = BAD[case]
    write_state(tmp_path / "state.h5", datasets)
    result, path = run_eme(tmp_path, "bad", {"model": MODEL, "initial": {"file": "state.h5"}})
    assert result.returncode == 2, (result.returncode, result.stderr)
    message = result.stderr
    for word in ["bad.nml", "&initial", "file = 'state.h5'", *named]:
        assert word in message, (word, message)
    assert not path.exists() and not Path(str(path) + ".part").exists()


def test_a_missing_or_foreign_initial_file_is_refused(tmp_path):
    (tmp_path / "text.h5").write_text("not HDF5")
    for name, reason in (("absent.h5", "no such file"), ("text.h5", "not an HDF5 file")):
        result, path = run_eme(tmp_path, "bad", {"model": MODEL, "initial": {"file": name}})
        assert result.returncode == 2 and reason in result.stderr and name in result.stderr, result.stderr
        assert not path.exists()


def test_a_run_files_snapshot_is_a_runs_start(tmp_path):
    """&initial file = a split run's file, snapshot = k: the run starts from its k-th snapshot (q, p,
    gamma, theta of /snapshots, row k from 0; -1 the last). A 20-spring chain in the temperature
    variable (the snapshot holds the state itself): 10 steps from snapshot 1 (step 5) give the
    first run's snapshot 2 (step 10) bit for bit; the last (-1) is snapshot 2. A snapshot beyond the
    file's, or asked of a file without /snapshots, is refused with nothing written."""
    chain = {"model_name": "spring_chain", "links": 20, "ends": "fixed-fixed", "dimension": 2}
    first = {"model": chain, "initial": {"theta": [320.0] * 10 + [290.0] * 11, "perturbation": "random"},
             "integrator": {"thermo_variable": "temperature", "dt": 0.01, "t_end": 0.1},
             "output": {"snapshot_every": 5}}
    result, source = run_eme(tmp_path, "first", first)
    assert result.returncode == 0, result.stderr
    again = {"model": chain, "initial": {"file": source.name, "snapshot": 1},
             "integrator": {"thermo_variable": "temperature", "dt": 0.01, "t_end": 0.05}}
    result, path = run_eme(tmp_path, "again", again)
    assert result.returncode == 0, result.stderr
    last = dict(again, initial={"file": source.name})
    result, from_last = run_eme(tmp_path, "last", last)
    assert result.returncode == 0, result.stderr
    with h5py.File(source, "r") as a, h5py.File(path, "r") as b, h5py.File(from_last, "r") as c:
        assert a["snapshots/time"].shape[0] == 3
        for name in ("q", "p", "gamma", "theta"):
            assert np.array_equal(b[f"snapshots/{name}"][0], a[f"snapshots/{name}"][1]), name
            assert np.array_equal(b[f"snapshots/{name}"][-1], a[f"snapshots/{name}"][2]), name
            assert np.array_equal(c[f"snapshots/{name}"][0], a[f"snapshots/{name}"][2]), name
    result, refused = run_eme(tmp_path, "beyond", dict(again, initial={"file": source.name, "snapshot": 3}))
    assert result.returncode == 2 and "snapshot = 3 is not allowed: the file has 3 snapshots; allowed: 0 to 2" \
        in result.stderr, result.stderr
    model, state = file_chain()
    write_state(tmp_path / "state.h5", state)
    result, plain = run_eme(tmp_path, "plain", {"model": model, "initial": {"file": "state.h5", "snapshot": 0}})
    assert result.returncode == 2 and "snapshot = 0 is not allowed: the file has no /snapshots" in result.stderr
    assert not refused.exists() and not plain.exists()


def test_a_dense_run_file_as_the_initial_file_is_named_as_one(tmp_path):
    """A dense-path run file (a small chain's: /state rows, no /snapshots) given as &initial file
    is refused as what it is, pointing at a split run's file; it said only that it had no q."""
    chain = {"model_name": "spring_chain", "links": 3, "dimension": 2}
    result, dense = run_eme(tmp_path, "dense", {"model": chain, "integrator": {"dt": 0.01, "t_end": 0.02}})
    assert result.returncode == 0, result.stderr
    with h5py.File(dense, "r") as f:
        assert "state" in f and "snapshots" not in f
    result, path = run_eme(tmp_path, "from_dense", {"model": chain, "initial": {"file": dense.name}})
    assert result.returncode == 2, result.stderr
    for words in ("from_dense.nml", f"&initial: file = '{dense.name}' is a run file of the dense path",
                  "allowed: a split run's file, which has /snapshots (run with -eme_split"):
        assert words in result.stderr, (words, result.stderr)
    assert not path.exists() and not Path(str(path) + ".part").exists()


SPRING_ARRAYS = {"mu_eq_const": np.linspace(300.0, 200.0, 6), "mass": np.linspace(1.0, 2.0, 6),
                 "conductivity": np.full(5, 2.0), "beta_v": np.array([0.0, 0.5, 0.5, 0.4, 0.3, 0.5])}


def spring_file_chain(**model):
    return {"model": {"model_name": "spring_chain", "links": 6, "dimension": 2, **model},
            "initial": {"theta": 300.0, "perturbation": "random"},
            "integrator": {"dt": 0.01, "t_end": 0.05}}


def test_per_spring_values_from_an_hdf5_file_are_the_namelists(tmp_path):
    """&model spring_file: 1-D datasets named as the per-spring (per-mass, per-link) fields give
    the same run, bit for bit, as the same values typed in the namelist; the run's stored namelist
    names the file instead of its values, and run again gives the same run."""
    write_state(tmp_path / "springs.h5", SPRING_ARRAYS)
    result, from_file = run_eme(tmp_path, "from_file", spring_file_chain(spring_file="springs.h5"))
    assert result.returncode == 0, result.stderr
    typed = {name: [float(v) for v in values] for name, values in SPRING_ARRAYS.items()}
    result, from_namelist = run_eme(tmp_path, "typed", spring_file_chain(**typed))
    assert result.returncode == 0, result.stderr
    with h5py.File(from_file, "r") as a, h5py.File(from_namelist, "r") as b:
        assert np.array_equal(a["state"][()], b["state"][()]) and a["state"].shape[0] == 6
        stored = text(a.attrs["namelist"])
    assert "spring_file = 'springs.h5'" in stored
    assert not any(line.strip().startswith(tuple(SPRING_ARRAYS)) for line in stored.splitlines()), stored
    (tmp_path / "again.nml").write_text(stored.replace(f"file = '{from_file}'", f"file = '{tmp_path / 'again.h5'}'"))
    result = subprocess.run([str(BIN / "eme_run"), str(tmp_path / "again.nml")], capture_output=True, text=True,
                            timeout=120)
    assert result.returncode == 0, result.stderr
    with h5py.File(from_file, "r") as a, h5py.File(tmp_path / "again.h5", "r") as c:
        assert np.array_equal(a["state"][()], c["state"][()])


def bad_spring_files():
    """(what is wrong, the datasets, the namelist's own &model fields, what the message names)."""
    cases = [("a field in both", SPRING_ARRAYS, {"mass": 1.0}, ["dataset mass and the namelist's mass both give"]),
             ("a wrong length", dict(SPRING_ARRAYS, conductivity=np.full(6, 2.0)), {},
              ["dataset conductivity has 6 values", "a 1-D dataset of 5 values"])]
    negative = SPRING_ARRAYS["mu_eq_const"].copy()
    negative[3] = -1.0
    cases.append(("a value below its bound", dict(SPRING_ARRAYS, mu_eq_const=negative), {},
                  ["dataset mu_eq_const[3] = -1.0 is not allowed"]))
    nan = SPRING_ARRAYS["beta_v"].copy()
    nan[4] = np.nan
    cases.append(("a NaN", dict(SPRING_ARRAYS, beta_v=nan), {}, ["dataset beta_v[4] = NaN is not allowed"]))
    misspelt = {("conductivty" if name == "conductivity" else name): values for name, values in SPRING_ARRAYS.items()}
    cases.append(("a misspelt name", misspelt, {},
                  ["conductivty is not a per-spring field of this chain's &model (spring_law = 'thermoviscoelastic'",
                   "allowed: members named ", ", beta_v, conductivity (docs/input.md)"]))
    return cases


@pytest.mark.parametrize("case", bad_spring_files(), ids=lambda case: case[0])
def test_a_bad_spring_file_is_refused_naming_the_dataset_and_index(tmp_path, case):
    _, datasets, fields, named = case
    write_state(tmp_path / "springs.h5", datasets)
    result, path = run_eme(tmp_path, "bad", spring_file_chain(spring_file="springs.h5", **fields))
    assert result.returncode == 2, (result.returncode, result.stderr)
    for word in ["bad.nml", "&model: spring_file = 'springs.h5'", *named]:
        assert word in result.stderr, (word, result.stderr)
    assert not path.exists() and not Path(str(path) + ".part").exists()


COLLAPSED = [
    ({"links": 2, "dimension": 1}, {"x": [1.0, 1.0]}, "&initial: x", "spring 2 (from mass 1 to mass 2)"),
    ({"links": 3, "dimension": 1, "ends": "fixed-fixed", "span": 3.0}, {"x": [1.0, 2.0, 3.0]}, "&initial: x",
     "spring 4 (from mass 3 to the second support at span)"),
    ({"links": 3, "dimension": 1, "ends": "fixed-fixed", "span": 1e-200}, {}, "&model: span",
     "spring 1 (from the support at the origin to mass 1)"),
    ({"links": 1, "dimension": 1, "natural_length": 1.0}, {"stretch": 1.0, "perturbation": "mode",
                                                            "mode_number": 1, "amplitude": -1.0},
     "&initial: amplitude", "spring 1 (from the support at the origin to mass 1)"),
]


@pytest.mark.parametrize("model, initial, field, spring", COLLAPSED, ids=[c[2] for c in COLLAPSED])
def test_positions_that_leave_a_spring_no_length_are_refused_naming_field_and_spring(tmp_path, model, initial,
                                                                                     field, spring):
    """Positions from &initial x, from the default ones (span of a 'fixed-fixed' chain, here so
    small that the length squared underflows), or moved there by the perturbation (the one mass,
    at x = 1 m, moved by -1 m sin(pi/2)): exit 2, the
    file, the field that put the masses there and the spring of length 0 named, nothing written
    (the message said "the initial state is not allowed" and named x even where x was not given)."""
    groups = {"model": {"model_name": "spring_chain", **model}, "initial": initial}
    result, path = run_eme(tmp_path, "collapsed", groups)
    assert result.returncode == 2, result.stderr
    for words in ("collapsed.nml", field, spring, "the length 0"):
        assert words in result.stderr, (words, result.stderr)
    assert not path.exists() and not Path(str(path) + ".part").exists()


# ---------------------------------------------------------------------------- conflicting fields
CONFLICTS = [
    ({"family": "rod", "natural_length": 1.0}, {}, "natural_length", "family = 'rod'"),
    ({"family": "rod", "conductivity": 1.0}, {}, "conductivity", "family = 'rod'"),
    ({"family": "rod", "mass": 1.0}, {}, "mass", "family = 'rod'"),
    ({"axial_stiffness": 10.0}, {}, "axial_stiffness", "family = 'springs'"),
    ({}, {"seed": 3}, "seed", "perturbation = 'none'"),
    ({}, {"perturbation": "mode", "seed": 3}, "seed", "perturbation = 'mode'"),
    ({}, {"perturbation": "random", "mode_number": 2}, "mode_number", "perturbation = 'random'"),
    ({}, {"file": "x.h5", "theta": 300.0}, "theta", "file = 'x.h5'"),
    ({}, {"file": "x.h5", "perturbation": "mode"}, "perturbation", "file = 'x.h5'"),
    ({}, {"perturbation": "mode", "mode_number": 4}, "mode_number", "1 to N = 3"),
]


@pytest.mark.parametrize("model, initial, field, reason", CONFLICTS, ids=[c[2] + "-" + c[3] for c in CONFLICTS])
def test_conflicting_fields_are_refused_by_name(tmp_path, model, initial, field, reason):
    groups = {"model": {"model_name": "spring_chain", "links": 3, **model}, "initial": initial}
    result, path = run_eme(tmp_path, "conflict", groups)
    assert result.returncode == 2, result.stderr
    assert "conflict.nml" in result.stderr and field in result.stderr and reason in result.stderr, result.stderr
    assert "allowed" in result.stderr, result.stderr
    assert not path.exists()
