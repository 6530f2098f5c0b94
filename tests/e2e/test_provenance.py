"""What a run file says about how it was made, and how it reads: provenance (the command line,
the PETSc options, the effective namelist, versions, host and dates), the stored namelist run
again gives the same file, xarray sees named dimensions and coordinates, every parameter carries
its units, &output every keeps every N-th point with step rows that combine their N steps, and
&output compression gzips the datasets without changing a bit. Each check is against something
the test knows by itself: the argv it passed, the clock, pkg-config, the table of docs/input.md, the
rows of a run written without a stride, a run written without compression."""
import os
import re
import shlex
import shutil
import socket
import subprocess
from datetime import datetime, timedelta, timezone

import h5py
import numpy as np
import pytest
import xarray

from conftest import BIN, ROOT, namelist_text, read_run, run_eme
from faults import shim_library

# Units of the table of docs/input.md, by field (the root attribute of the same name carries them in
# <name>_units).
INPUT_TABLE_UNITS = {
    "mass": "kg", "natural_length": "m", "mu_eq_const": "J", "mu_eq_slope": "J/K", "mu_neq_const": "J/m^2",
    "mu_neq_slope": "J/(K m^2)", "heat_capacity": "J/K", "viscosity_const": "J s/m^2", "viscosity_activation": "K",
    "conductivity": "J/(K s)", "theta_ref": "K", "beta": "J/K", "beta_v": "1", "gravity": "m/s^2",
    "q1": "m", "q2": "m", "p1": "N s", "p2": "N s", "gamma": "m", "theta": "K",
    "length": "m", "temperature": "K",
    "dt": "s", "t_end": "s", "newton_tol": "1", "newton_max_iterations": "1", "tolerance": "1",
    "theta_r": "K", "output_every": "1", "compression": "1"}

# What a file row standing for several steps holds of each per-step dataset, as the datasets'
# descriptions and &output every's help ("sums, extremes") say: counts and costs are summed, the
# extremes are the extremes of the steps', the multipliers (a step's mean rate) are averaged, and
# what describes the step's end (its number, the last solve's reason, the temperatures K0) is the
# last step's.
COMBINE = {
    "step": "last", "newton_iterations": "sum", "scheme_temperature": "last", "solver_strategy": "max",
    "snes_solves": "sum", "rejected_roots": "sum", "residual_norm": "max", "converged_reason": "last",
    "step_seconds": "sum", "min_entropy_increment": "min", "max_lyapunov_increment": "max",
    "multiplier": "mean", "substeps": "sum"}

# The symbol of the state's last two entries for each thermodynamic variable, and their units.
VARIABLE_COLUMNS = {"entropy": (["s_1", "s_2"], "J/K"), "temperature": (["theta_1", "theta_2"], "K"),
                    "internal_energy": (["u_1", "u_2"], "J")}


def text(value):
    return value.decode() if isinstance(value, bytes) else str(value)


def run_ok(directory, name, groups, *options):
    result, path = run_eme(directory, name, groups, *options)
    assert result.returncode == 0, result.stderr
    return path


def parse_namelist(source):
    """{group: {field: value text}} of the effective namelist: '&group', '  field = value' lines
    and '/', as the code writes it (any other line fails the test)."""
    groups, current = {}, None
    for line in source.splitlines():
        if not line.strip():
            continue
        if current is None:
            match = re.fullmatch(r"&(\w+)", line.strip())
            assert match, f"expected '&group', got {line!r}"
            current = groups.setdefault(match.group(1), {})
        elif line.strip() == "/":
            current = None
        else:
            match = re.fullmatch(r"\s*(\w+)\s*=\s*(.*?)\s*", line)
            assert match, f"expected 'field = value', got {line!r}"
            assert match.group(1) not in current, f"field {match.group(1)} twice"
            current[match.group(1)] = match.group(2)
    assert current is None, "a group is not closed by '/'"
    return groups


def namelist_value(value):
    """A value text of the effective namelist: a text, a logical, or a list of numbers, where
    `r*x` stands for r copies of x (the namelist's repeat count)."""
    if value.startswith("'"):
        assert value.endswith("'") and len(value) >= 2, value
        return value[1:-1].replace("''", "'")
    if value.lower() in (".true.", ".false."):
        return value.lower() == ".true."
    numbers = []
    for item in value.split(","):
        count, _, number = item.strip().rpartition("*")
        numbers += [float(number)] * (int(count) if count else 1)
    return numbers


def run_with_argv(argv, **environment):
    before = datetime.now(timezone.utc).replace(microsecond=0)
    result = subprocess.run(argv, capture_output=True, text=True, timeout=120, env={**os.environ, **environment})
    after = datetime.now(timezone.utc)
    return result, before, after


# ---------------------------------------------------------------------------------- provenance


def test_provenance_attributes(tmp_path, eme_run_binary):
    """A run with PETSc options before and after its input file (in a folder whose name needs
    quoting) stores the argv as given, the options in force, the effective input, the versions,
    the host and its start and end."""
    folder = tmp_path / "with space"
    folder.mkdir()
    output = folder / "provenance.h5"
    namelist = folder / "provenance input.nml"
    namelist.write_text(namelist_text({"model": {"conductivity": 2.5},
                                       "integrator": {"scheme": "eme", "dt": 0.2, "t_end": 1.0},
                                       "output": {"file": str(output)}}))
    argv = [str(BIN / "eme_run"), "-snes_rtol", "1e-9", str(namelist), "-snes_max_it", "40"]
    # Local time 5 h 30 min east of UTC (POSIX TZ counts westward): the dates must say so.
    result, before, after = run_with_argv(argv, TZ="EME-05:30")
    assert result.returncode == 0, result.stderr
    with h5py.File(output, "r") as f:
        attrs = {name: f.attrs[name] for name in f.attrs}

    assert shlex.split(text(attrs["command_line"])) == argv, attrs["command_line"]
    assert text(attrs["input_file"]) == str(namelist)
    tokens = text(attrs["petsc_options"]).split()
    for option, value in (("-snes_max_it", 40.0), ("-snes_rtol", 1e-9)):
        assert option in tokens, (option, tokens)
        assert float(tokens[tokens.index(option) + 1]) == value, tokens
    # ... and they reached the solver, which reports its settings as used.
    assert attrs["solver_snes_max_it"] == 40 and attrs["solver_snes_rtol"] == 1e-9
    # Counts are stored as integers, not as floats.
    for name in ("solver_snes_max_it", "solver_snes_max_funcs", "solver_snes_lag_jacobian", "solver_eme_max_halvings"):
        assert np.asarray(attrs[name]).dtype.kind == "i", name

    groups = parse_namelist(text(attrs["namelist"]))
    assert {"model", "initial", "constraints", "integrator", "output"} <= set(groups), set(groups)
    assert namelist_value(groups["model"]["conductivity"]) == [2.5]
    assert namelist_value(groups["integrator"]["scheme"]) == "eme"
    assert namelist_value(groups["integrator"]["dt"]) == [0.2]
    assert namelist_value(groups["integrator"]["t_end"]) == [1.0]
    assert namelist_value(groups["output"]["file"]) == str(output)

    version = text(attrs["code_version"])
    assert version and version != "unknown"
    # The release of the file VERSION and, in a checkout, the git description.
    described = re.fullmatch(r"(\d+\.\d+\.\d+) \(git (?:.*-g)?([0-9a-f]{7,40})(?:-dirty)?\)", version)
    assert described, f"code_version {version!r} is not 'RELEASE (git DESCRIPTION)'"
    assert described.group(1) == (ROOT / "VERSION").read_text().strip()
    if shutil.which("git") and (ROOT / ".git").exists():
        known = subprocess.run(["git", "-C", str(ROOT), "cat-file", "-e", described.group(2) + "^{commit}"],
                               capture_output=True)
        assert known.returncode == 0, f"code_version {version!r} names no commit of {ROOT}"

    assert text(attrs["host"]) == socket.gethostname()
    start = datetime.fromisoformat(text(attrs["start_time"]))
    end = datetime.fromisoformat(text(attrs["end_time"]))
    offset = timedelta(hours=5, minutes=30)
    assert start.utcoffset() == offset and end.utcoffset() == offset, (attrs["start_time"], attrs["end_time"])
    assert before <= start <= end <= after, (before, attrs["start_time"], attrs["end_time"], after)

    for library in ("petsc", "hdf5", "mpi", "sundials", "compiler", "lapack"):
        value = text(attrs[f"version_{library}"])
        assert value.strip() and value != "unknown" and re.search(r"\d", value), (library, value)
    for library in ("petsc", "hdf5", "sundials", "lapack"):
        assert re.match(r"\d+\.\d+(\.\d+)?", text(attrs[f"version_{library}"])), (library, attrs[f"version_{library}"])
    # The HDF5 of h5py's wheel is its own copy, maybe another version: only the format is checked.
    if shutil.which("pkg-config"):
        petsc = subprocess.run(["pkg-config", "--modversion", "PETSc"], capture_output=True, text=True)
        if petsc.returncode == 0:
            assert text(attrs["version_petsc"]) == petsc.stdout.strip()


# ----------------------------------------------------------------- the namelist reproduces runs

SCENES = {
    # The paper's scene as given (dt 0.15 s by default), shortened.
    "paper_eme": ({"integrator": {"scheme": "eme", "t_end": 3.0}}, ["-snes_max_it", "40"]),
    # Unequal masses, a stronger conduction, other initial temperatures, g2 and tau = s.
    "model_and_constraint": ({"model": {"conductivity": 2.5, "mass": [1.3, 0.7]},
                              "initial": {"theta": [290.0, 340.0]},
                              "constraints": {"fix_temperature": True},
                              "integrator": {"scheme": "eme", "thermo_variable": "entropy", "dt": 0.2,
                                             "t_end": 2.0}}, ["-snes_max_it", "40"]),
    # A relaxed scheme: the method chooses the times (gamma h per step).
    "relaxed_rk8": ({"integrator": {"scheme": "relaxed_rk8", "dt": 0.25, "t_end": 2.0}}, []),
}


@pytest.fixture(scope="module")
def scene_runs(tmp_path_factory, eme_run_binary):
    """The three scenes' files, run once for the tests below."""
    folder = tmp_path_factory.mktemp("scenes")
    return {name: run_ok(folder, name, groups, *options) for name, (groups, options) in SCENES.items()}


@pytest.mark.parametrize("scene", list(SCENES))
def test_namelist_text_agrees_with_the_attributes(scene_runs, scene):
    """Every field of the stored namelist has the value of the root attribute of its name (the
    input the run used), and the groups and fields given are there with their values."""
    path = scene_runs[scene]
    attrs = read_run(path)["attrs"]
    groups = parse_namelist(text(attrs["namelist"]))
    compared, differing = [], []
    for group, fields in groups.items():
        for field, raw in fields.items():
            value = namelist_value(raw)
            if field == "file":
                assert value == str(path), (value, path)
                continue
            if field == "overwrite":        # how the file may be written, not the run: no attribute
                continue
            name = {"every": "output_every", "interval": "output_interval"}.get(field, field)
            assert name in attrs, f"&{group} {field} has no root attribute {name}"
            attribute = attrs[name]
            compared.append(field)
            if isinstance(value, bool):
                same = int(attribute) == int(value)
            elif isinstance(value, str):
                stored = text(attribute)
                # Schemes without a discrete gradient record 'none' for it and its metric
                # (docs/output.md); the nondimensional metric adds its scales.
                same = stored == value or stored.startswith(value + ":") or (
                    field in ("discrete_gradient", "metric") and stored == "none"
                    and text(attrs["scheme_family"]) != "discrete_gradient_step")
            else:
                same = np.array_equal(np.atleast_1d(np.asarray(attribute, dtype=float)), np.array(value))
            if not same:
                differing.append(f"&{group} {field}: the namelist says {raw}, the attribute {attribute!r}")
    assert not differing, "\n".join(differing)
    assert {"dt", "t_end", "theta", "mass", "conductivity", "q1", "p2", "newton_tol", "every"} <= set(compared)
    given, _ = SCENES[scene]
    for group, fields in given.items():
        for field, value in fields.items():
            stored = namelist_value(groups[group][field])
            expected = value if isinstance(value, (str, bool)) else [float(x) for x in np.atleast_1d(value)]
            assert stored == expected, f"&{group} {field}: given {value!r}, the namelist says {groups[group][field]}"


@pytest.mark.parametrize("scene", list(SCENES))
def test_stored_namelist_reproduces_the_run(scene_runs, scene):
    """The `namelist` attribute, with only its &output file changed, run with the stored PETSc
    options, gives the same points bit for bit and stores the same namelist again."""
    path = scene_runs[scene]
    with h5py.File(path, "r") as f:
        stored = text(f.attrs["namelist"])
        options = text(f.attrs["petsc_options"]).split()
    copy = path.with_name(f"{scene}_again.h5")
    rerun_text, replaced = re.subn(r"(?m)^(\s*file\s*=\s*)'[^']*'", lambda m: f"{m.group(1)}'{copy}'", stored)
    assert replaced == 1, stored
    rerun_input = path.with_name(f"{scene}_again.nml")
    rerun_input.write_text(rerun_text)
    result = subprocess.run([str(BIN / "eme_run"), str(rerun_input), *options], capture_output=True, text=True,
                            timeout=120)
    assert result.returncode == 0, result.stderr
    first, again = read_run(path), read_run(copy)
    assert text(again["attrs"]["namelist"]) == rerun_text
    for name in ("time", "state", "temperature"):
        assert np.array_equal(first[name], again[name]), (
            f"/{name} differs: {first[name].shape[0]} rows up to t = {first['time'][-1]} s in the run, "
            f"{again[name].shape[0]} rows up to t = {again['time'][-1]} s from its stored namelist")


def test_a_chain_namelist_writes_runs_of_equal_values_once(tmp_path, eme_run_binary):
    """A chain's per-spring and per-mass lists keep their runs of equal values as `r*x` (a chain
    of 10^5 springs at one temperature spelled every value: megabytes that eme_run then refused
    to read back, built in time like the square of the count), and the text still gives the same
    run bit for bit."""
    groups = {"model": {"model_name": "spring_chain", "links": 5, "dimension": 3, "mass": 1.0,
                        "mu_eq_const": [300.0, 300.0, 250.0, 250.0, 250.0]},
              "initial": {"theta": [300.0, 300.0, 300.0, 310.0, 300.0]},
              "integrator": {"dt": 0.01, "t_end": 0.1}}
    path = run_ok(tmp_path, "chain", groups)
    stored = text(read_run(path)["attrs"]["namelist"])
    fields = {field: value for section in parse_namelist(stored).values() for field, value in section.items()}
    assert fields["theta"] == "3*300.0, 310.0, 300.0", stored
    assert fields["mu_eq_const"] == "2*300.0, 3*250.0" and fields["p"] == "15*0.0", stored
    assert namelist_value(fields["theta"]) == [300.0, 300.0, 300.0, 310.0, 300.0]
    copy = tmp_path / "chain_again.h5"
    rerun_text = stored.replace(f"file = '{path}'", f"file = '{copy}'")     # &output's, not &initial's
    assert rerun_text != stored
    (tmp_path / "chain_again.nml").write_text(rerun_text)
    result = subprocess.run([str(BIN / "eme_run"), str(tmp_path / "chain_again.nml")], capture_output=True,
                            text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    first, again = read_run(path), read_run(copy)
    assert text(again["attrs"]["namelist"]) == rerun_text
    assert first["state"].shape[0] == 11 and np.array_equal(first["state"], again["state"])


# -------------------------------------------------------------------------------------- xarray


def open_with_xarray(path):
    return xarray.open_dataset(path, engine="h5netcdf", phony_dims="access")


def test_xarray_sees_time_and_step(tmp_path, eme_run_binary):
    """Per-point datasets run along `time` (N+1), per-step ones along `step` (N), vector columns
    along `<name>_column`; the coordinates are h5py's /time, /step and the `columns` names."""
    path = run_ok(tmp_path, "xarray", {"constraints": {"fix_length": True, "fix_temperature": True},
                                       "initial": {"p1": [-0.5, 0.0, 0.0], "p2": [-0.5, -1.0, 0.0]},
                                       "integrator": {"dt": 0.2, "t_end": 1.0}})
    with h5py.File(path, "r") as f, open_with_xarray(path) as ds:
        steps = int(f.attrs["steps_completed"])
        assert steps == 5
        assert ds.sizes["time"] == steps + 1 and ds.sizes["step"] == steps
        assert not [d for d in ds.dims if str(d).startswith("phony_dim")], dict(ds.sizes)
        assert "time" in ds.coords and "step" in ds.coords
        assert np.array_equal(ds["time"].values, f["time"][()])
        np.testing.assert_array_equal(ds["time"].values, 0.2 * np.arange(steps + 1))
        assert np.array_equal(ds["step"].values, np.arange(1, steps + 1))
        kinds = {"point": [], "step": []}
        for name, dataset in f.items():
            if "rows" not in dataset.attrs or name in ("time", "step"):
                continue
            rows = text(dataset.attrs["rows"])
            kinds[rows].append(name)
            variable = ds[name]
            assert variable.dims[0] == ("time" if rows == "point" else "step"), (name, variable.dims)
            # Units as the file has them; none on a dataset of columns of different units (state).
            assert variable.attrs.get("units") == (text(dataset.attrs["units"]) if "units" in dataset.attrs
                                                   else None), name
            assert np.array_equal(variable.values, dataset[()], equal_nan=True), name
            if rows == "step" and name != "step_end_time":
                # Per-step data have the steps' end times as a time coordinate.
                np.testing.assert_array_equal(variable["step_end_time"].values, f["time"][1:])
            if dataset.ndim == 2:
                columns = text(dataset.attrs["columns"])
                assert columns == " ".join(columns.split()), f"{name}: blanks in columns {columns!r}"
                assert variable.dims[1] == f"{name}_column", (name, variable.dims)
                entries = [str(c) for c in ds[f"{name}_column"].values]
                assert all(entry == entry.strip() and entry for entry in entries), (name, entries)
                assert entries == columns.split(), (name, entries, columns)
        assert {"energy", "temperature", "state", "constraint_residual"} <= set(kinds["point"]), kinds
        assert {"newton_iterations", "residual_norm", "converged_reason", "step_seconds",
                "multiplier"} <= set(kinds["step"]), kinds
        assert ds["energy"].attrs["units"] == "J" and ds["temperature"].attrs["units"] == "K"
        assert "units" not in ds["state"].attrs and len(f["state"].attrs["column_units"]) == 15
        # CF global attributes: what the file is, who made it how, after which paper.
        assert ds.attrs["Conventions"] == "CF-1.8" and "Valdes y Beck" in ds.attrs["references"]
        assert ds.attrs["title"].startswith("EME run of ") and ds.attrs["source"].startswith("eme ")
        assert ds.attrs["history"].endswith(text(f.attrs["command_line"])) and "institution" in ds.attrs
        assert list(ds["multiplier_column"].values) == ["lambda_length", "lambda_temperature"]
        assert np.array_equal(ds["temperature"].sel(temperature_column="theta_2").values, f["temperature"][:, 1])


@pytest.mark.parametrize("variable", list(VARIABLE_COLUMNS))
def test_state_columns_name_the_thermodynamic_variable(tmp_path, eme_run_binary, variable):
    """/state's last two columns are the run's variable (s, theta or u of each spring) with its
    units; xarray selects a column by that name."""
    path = run_ok(tmp_path, variable, {"integrator": {"thermo_variable": variable, "dt": 0.2, "t_end": 0.6}})
    names, units = VARIABLE_COLUMNS[variable]
    with h5py.File(path, "r") as f, open_with_xarray(path) as ds:
        columns = text(f["state"].attrs["columns"])
        assert columns.split()[:13] == ["q1_x", "q1_y", "q1_z", "q2_x", "q2_y", "q2_z", "p1_x", "p1_y", "p1_z",
                                        "p2_x", "p2_y", "p2_z", "gamma"]
        assert columns.split()[13:] == names, columns
        assert [text(u) for u in f["state"].attrs["column_units"]][13:] == [units, units]
        assert [str(c) for c in ds["state_column"].values] == columns.split()
        assert np.array_equal(ds["state"].sel(state_column=names[-1]).values, f["state"][:, -1])
        assert np.array_equal(ds["state"].sel(state_column="p2_y").values, f["state"][:, 10])
        # The stored variable of spring 2 at t = 0 from the given initial temperature (350 K):
        # the temperature itself, or a different number for s and u.
        assert (f["state"][0, -1] == 350.0) == (variable == "temperature")


# --------------------------------------------------------------------------------------- units


def test_every_parameter_has_units(tmp_path, eme_run_binary):
    """Each numeric root attribute has <name>_units; those of the table of docs/input.md say its unit;
    no units attribute anywhere is the non-unit 'SI' or empty."""
    path = run_ok(tmp_path, "units", {"constraints": {"fix_temperature": True},
                                      "integrator": {"dt": 0.2, "t_end": 0.6}})
    with h5py.File(path, "r") as f:
        attrs = dict(f.attrs)
        wrong = {name: text(attrs.get(f"{name}_units")) for name, unit in INPUT_TABLE_UNITS.items()
                 if text(attrs.get(f"{name}_units")) != unit}
        assert not wrong, f"units differing from the table of docs/input.md: {wrong}"
        groups = parse_namelist(text(attrs["namelist"]))
        for fields in groups.values():
            for field, raw in fields.items():
                if isinstance(namelist_value(raw), list):
                    name = {"every": "output_every", "interval": "output_interval"}.get(field, field)
                    assert f"{name}_units" in attrs, f"parameter {field} has no {name}_units"
        missing = [name for name, value in attrs.items() if not name.endswith("_units") and name != "text_checksum"
                   and np.asarray(value).dtype.kind in "iuf" and f"{name}_units" not in attrs]
        assert not missing, f"numeric root attributes without units: {missing}"
        units = [(f"/{name}", value) for name, value in attrs.items() if name.endswith("_units")]
        for name, dataset in f.items():
            for key in ("units", "column_units"):
                if key in dataset.attrs:
                    units.append((f"/{name}:{key}", dataset.attrs[key]))
        assert len(units) > 40
        for where, value in units:
            for unit in np.atleast_1d(value):
                assert text(unit).strip() and text(unit).strip() != "SI", (where, value)


# -------------------------------------------------------------------------------------- stride


def point_rows(steps, every):
    """The points a file written with `every` keeps: every N-th and the last."""
    rows = list(range(0, steps + 1, every))
    return rows if rows[-1] == steps else rows + [steps]


def check_stride(full_path, stride_path, every, schema):
    """The stride file against the file of every step: its points are rows of the full file, bit
    for bit; each step row combines its steps as COMBINE says."""
    full, stride = read_run(full_path), read_run(stride_path)
    steps = int(full["attrs"]["steps_completed"])
    keep = point_rows(steps, every)
    groups = [(start, min(start + every, steps)) for start in range(0, steps, every)]
    assert stride["attrs"]["output_every"] == every and full["attrs"]["output_every"] == 1
    assert stride["attrs"]["steps_completed"] == steps and stride["attrs"]["step_rows"] == len(groups)
    assert stride["attrs"]["newton_iterations_total"] == full["attrs"]["newton_iterations_total"] \
        == full["newton_iterations"].sum()
    with h5py.File(stride_path, "r") as f:
        rows = {name: text(d.attrs["rows"]) for name, d in f.items() if "rows" in d.attrs}
    for name in (n for n, r in rows.items() if r == "point"):
        assert np.array_equal(stride[name], full[name][keep]), f"/{name}: not rows {keep} of the full file"
    for name in ("time", "state", "temperature", "energy"):
        assert rows[name] == "point", name
    combined = []
    for name in (n for n, r in rows.items() if r == "step"):
        rule = COMBINE.get(name, schema.get(name))
        assert rule, f"/{name}: a per-step dataset of unknown combine rule"
        if name in COMBINE and name in schema:
            assert schema[name] == rule, f"/{name}: --output-schema says {schema[name]}, the description {rule}"
        assert stride[name].shape[0] == len(groups), name
        if name == "step_seconds":
            continue        # measured, not reproducible: below
        pieces = [full[name][a:b] for a, b in groups]
        expected = {"sum": lambda p: p.sum(axis=0), "last": lambda p: p[-1], "min": lambda p: p.min(axis=0),
                    "max": lambda p: p.max(axis=0), "mean": lambda p: p.mean(axis=0)}[rule]
        expected = np.array([expected(p) for p in pieces])
        if rule == "mean":
            np.testing.assert_allclose(stride[name], expected, rtol=1e-13, atol=0, err_msg=name)
        else:
            assert np.array_equal(stride[name], expected.astype(stride[name].dtype)), (
                f"/{name} ({rule} of {every} steps): {stride[name].tolist()} in the file, {expected.tolist()} "
                f"from the full file")
        combined.append(name)
    assert {"step", "newton_iterations", "snes_solves", "residual_norm", "converged_reason", "solver_strategy",
            "min_entropy_increment", "max_lyapunov_increment", "scheme_temperature"} <= set(combined)
    return full, stride


@pytest.fixture(scope="module")
def schema_combine():
    result = subprocess.run([str(BIN / "eme_run"), "--output-schema"], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    lines = result.stdout.rstrip("\n").split("\n")
    header = lines[0].split("\t")
    rows = [dict(zip(header, line.split("\t"))) for line in lines[1:]]
    return {row["name"]: row["combine"] for row in rows}


def test_every_n_steps(tmp_path, eme_run_binary, schema_combine, monkeypatch):
    """EME on the paper scene, 80 steps of 1/32 s, a row every 4 steps (and every 16)."""
    # Step times are measured. Under a clock that counts its readings (the LD_PRELOAD shim
    # fast_clock.c with EME_CLOCK_TICK: each reading is the last plus 1 ms) every step takes the
    # same time on any machine, and a row of N steps must hold their sum, N ms; their last, mean
    # or largest would be 1 ms. (Timed by the real clock, two runs differed by +-35 %, and a busy
    # machine could make them differ more.)
    monkeypatch.setenv("LD_PRELOAD", str(shim_library("fast_clock")))
    monkeypatch.setenv("EME_CLOCK_TICK", "0.001")
    scene = {"integrator": {"scheme": "eme", "dt": 0.03125, "t_end": 2.5}}
    full_path = run_ok(tmp_path, "full", scene)
    stride_path = run_ok(tmp_path, "stride", {**scene, "output": {"every": 4}})
    full, stride = check_stride(full_path, stride_path, 4, schema_combine)
    assert full["attrs"]["steps_completed"] == 80 and stride["time"].shape == (21,)
    np.testing.assert_array_equal(stride["time"], 0.125 * np.arange(21))
    np.testing.assert_array_equal(stride["step"], 4 * np.arange(1, 21))
    assert stride["newton_iterations"].sum() == full["newton_iterations"].sum()
    wide = check_stride(full_path, run_ok(tmp_path, "wide", {**scene, "output": {"every": 16}}), 16,
                        schema_combine)[1]
    np.testing.assert_allclose(full["step_seconds"], 0.001, rtol=1e-5)
    np.testing.assert_allclose(stride["step_seconds"], 4 * 0.001, rtol=1e-5)
    np.testing.assert_allclose(wide["step_seconds"], 16 * 0.001, rtol=1e-5)


def test_every_n_steps_with_a_shorter_last_row(tmp_path, eme_run_binary, schema_combine):
    """22 steps with a row every 4: the last row stands for steps 21 and 22 and ends on t_end;
    with g2, the multiplier (the steps' mean heat rate) is averaged over the row's own steps."""
    scene = {"constraints": {"fix_temperature": True},
             "integrator": {"scheme": "eme", "thermo_variable": "entropy", "dt": 0.125, "t_end": 2.75}}
    full_path = run_ok(tmp_path, "full", scene)
    stride_path = run_ok(tmp_path, "stride", {**scene, "output": {"every": 4}})
    full, stride = check_stride(full_path, stride_path, 4, schema_combine)
    assert full["attrs"]["steps_completed"] == 22
    assert stride["time"][-1] == 2.75 and stride["time"].shape == (7,)
    np.testing.assert_array_equal(stride["step"], [4, 8, 12, 16, 20, 22])
    assert stride["newton_iterations"][-1] == full["newton_iterations"][20:].sum()
    np.testing.assert_allclose(stride["multiplier"][-1], full["multiplier"][20:].mean(axis=0), rtol=1e-13)
    assert stride["boundary_heat"][-1] == full["boundary_heat"][-1] != 0


# --------------------------------------------------------------------------------- compression


def test_compression_keeps_every_bit(tmp_path, eme_run_binary):
    scene = {"constraints": {"fix_temperature": True}, "integrator": {"dt": 0.2, "t_end": 1.0}}
    plain_path = run_ok(tmp_path, "plain", scene)
    packed_path = run_ok(tmp_path, "packed", {**scene, "output": {"compression": 4}})
    with h5py.File(plain_path, "r") as plain, h5py.File(packed_path, "r") as packed:
        assert packed.attrs["compression"] == 4 and plain.attrs["compression"] == 0
        # Every numeric dataset; the columns' scales (a few variable-length names each) are not
        # filtered, as deflate would only pack their heap references.
        numeric = [name for name, d in packed.items() if d.dtype.kind in "iuf"]
        assert sorted(set(packed) - set(numeric)) == sorted(n for n in packed if n.endswith("_column"))
        assert {"time", "state", "temperature", "energy", "newton_iterations", "multiplier"} <= set(numeric)
        for name in numeric:
            dataset = packed[name]
            assert dataset.compression == "gzip" and dataset.compression_opts == 4, (name, dataset.compression)
            assert dataset.shuffle, name
            assert plain[name].compression is None, name
            if name != "step_seconds":       # measured
                assert np.array_equal(dataset[()], plain[name][()], equal_nan=True), name
        assert set(plain) == set(packed)


@pytest.mark.parametrize("level", [10, -1])
def test_compression_out_of_range_is_refused(tmp_path, eme_run_binary, level):
    result, path = run_eme(tmp_path, "refused", {"output": {"compression": level}})
    assert result.returncode == 2, result.stderr
    message = result.stderr
    namelist = str(path.with_suffix(".nml"))
    for word in (namelist, "&output", f"compression = {level}"):
        assert word in message, (word, message)
    assert re.search(r"allowed: .*\b0\b.*\b9\b", message), message
    assert not path.exists() and not path.with_name(path.name + ".part").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["refused.nml"]
