"""A spring chain's run file (issue 39; docs/output.md, A chain's file) as one xarray Dataset, whichever
path wrote it:

  open_chain(path) -> xarray.Dataset

Dimensions: `time` (the file's points, /time), `snapshot_time` (the times at which the state is
held), `mass` (1 .. N, mass 1 next to the first support), `spring` (1 .. n_s, spring 1 from the
first support) and `component` ('x', 'y', 'z': the first d), each with its coordinate.

- The rows on `time`: every per-point dataset (`energy`, `entropy`, `lyapunov`, `boundary_heat`,
  `angular_momentum` with its column dimension `angular_momentum_column`, ...) and every per-step
  dataset (`newton_iterations`, `residual_norm`, `balance` on (time, balance_column),
  `min_viscous_production`, `min_link_production`, ...) on the point its step ends at, NaN at the
  first point (no step ends there; integer counts become floats for that NaN). `step` is a
  coordinate along `time`: the number of the last step a row stands for, 0 at the first point.
- The state on `snapshot_time`: `q` and `p` (snapshot_time, mass, component), `gamma` and `theta`
  (snapshot_time, spring), and the run's own variable when it is not theta as `spring_entropy` or
  `spring_internal_energy` (the file's /snapshots/entropy, /snapshots/internal_energy; the name
  `entropy` is the total S of the rows). A file split over ranks has them in /snapshots (read
  lazily: only what is used is read); a dense run's file in /state and /temperature, a snapshot at
  every point (snapshot_time then equals time, and `scheme_temperature`, the step's discrete
  temperatures, is on (time, spring)).
- Attributes: the file's root attributes, and `snapshot_source`: '/snapshots' or '/state'.

A file a killed run left is read as far as it goes: the rows (and a dense file's state) are cut to
the steps every dataset holds (a split file's snapshots are whole: docs/output.md). A file that cannot be used (not HDF5,
damaged texts, another model, no state) raises trajectory.RunFileError naming it and what is
missing. Another model's run file opens with xr.open_dataset(FILE, engine="h5netcdf",
phony_dims="access") (docs/output.md, xarray).

Example: open_chain("results/chain_rod_heat.h5").theta.sel(spring=10).plot()
"""
import re

import numpy as np
import xarray as xr

from trajectory import CHAIN_MODEL, RunFileError, root_attributes, run_file

# /snapshots/<name> of the run's thermodynamic variable -> its name in the Dataset.
SPRING_VARIABLES = {"entropy": "spring_entropy", "internal_energy": "spring_internal_energy"}
# A dense run's /state columns: x<i>_<c>, p<i>_<c> (mass i, component c), gamma_<a>, s_<a>,
# theta_<a>, u_<a> (spring a).
MASS_COLUMN = re.compile(r"([xp])([0-9]+)_([xyz])")
SPRING_COLUMN = re.compile(r"(gamma|s|theta|u)_([0-9]+)")
STATE_SPRING_VARIABLES = {"gamma": "gamma", "s": "spring_entropy", "u": "spring_internal_energy"}
COMPONENTS = "xyz"


def _text(value):
    return value.decode() if isinstance(value, bytes) else str(value)


def _rows(handle, dense):
    """The per-point and per-step datasets of the root group as xarray variables on `time`, cut to
    the steps every row dataset holds (a dense file's /state and /temperature too); returns
    (variables, time, step), time and step None for a file without rows (chain_bench's)."""
    if "time" not in handle:
        return {}, None, None
    every = {name: item for name, item in handle.items()
             if hasattr(item, "shape") and item.ndim in (1, 2) and "rows" in item.attrs}
    points = min([handle["time"].shape[0]] + [item.shape[0] + (_text(item.attrs["rows"]) == "step")
                                             for item in every.values()])
    time = handle["time"][:points]
    step = np.concatenate([[0], handle["step"][:points - 1]]) if "step" in handle else np.arange(points)
    skipped = {"time", "step", "step_end_time"} | ({"state", "temperature"} if dense else set())
    rows = {name: item for name, item in every.items() if name not in skipped}
    variables = {}
    for name, item in rows.items():
        per_step = _text(item.attrs["rows"]) == "step"
        values = item[:points - 1] if per_step else item[:points]
        if per_step:
            values = np.concatenate([np.full((1, *values.shape[1:]), np.nan), values.astype(float)])
        dims = ["time"]
        coords = {}
        if item.ndim == 2:
            column = "spring" if name == "scheme_temperature" else f"{name}_column"
            dims.append(column)
            labels = _text(item.attrs.get("columns", "")).split()
            if column != "spring" and len(labels) == item.shape[1]:
                coords[column] = labels
        attrs = {key: _text(item.attrs[key]) for key in ("units", "description", "rows") if key in item.attrs}
        variables[name] = xr.DataArray(values, dims=dims, coords=coords, attrs=attrs)
    return variables, time, step


def _state_snapshots(path, handle, attrs):
    """The state of a dense run's file (/state's columns, /temperature) as snapshot variables at
    every point, and the coordinates mass, spring and component."""
    state = handle["state"]
    names = _text(state.attrs.get("columns", "")).split()
    units = [_text(unit) for unit in np.atleast_1d(state.attrs.get("column_units", []))]
    if len(names) != state.shape[1]:
        raise RunFileError(f"{path}: dataset /state has {state.shape[1]} columns but its 'columns' attribute "
                           f"names {len(names)}")
    masses = {index: match.groups() for index, name in enumerate(names) if (match := MASS_COLUMN.fullmatch(name))}
    springs = {index: match.groups() for index, name in enumerate(names)
               if (match := SPRING_COLUMN.fullmatch(name)) and match.group(1) != "theta"}
    if not masses:
        raise RunFileError(f"{path}: dataset /state has no columns x<i>_<c> and p<i>_<c> of a chain's masses "
                           f"(it names {' '.join(names[:6])} ...): not a spring chain's state")
    values = state[()]
    mass_count = max(int(mass) for _, mass, _ in masses.values())
    dimension = max(COMPONENTS.index(component) for _, _, component in masses.values()) + 1
    spring_count = max([int(attrs.get("links", mass_count)) + (attrs.get("ends") == "fixed-fixed"),
                        *(int(spring) for _, spring in springs.values())])
    arrays, variable_units = {}, {}
    for index, (kind, mass, component) in masses.items():
        name = "q" if kind == "x" else "p"
        array = arrays.setdefault(name, np.full((len(values), mass_count, dimension), np.nan))
        array[:, int(mass) - 1, COMPONENTS.index(component)] = values[:, index]
        variable_units.setdefault(name, units[index] if index < len(units) else "")
    for index, (kind, spring) in springs.items():
        name = STATE_SPRING_VARIABLES[kind]
        arrays.setdefault(name, np.full((len(values), spring_count), np.nan))[:, int(spring) - 1] = values[:, index]
        variable_units.setdefault(name, units[index] if index < len(units) else "")
    variables = {name: xr.DataArray(array, dims=("snapshot_time", "mass", "component") if array.ndim == 3
                                    else ("snapshot_time", "spring"),
                                    attrs={"units": variable_units[name], "description": f"{name} from /state"})
                 for name, array in arrays.items()}
    if "temperature" in handle:
        variables["theta"] = xr.DataArray(handle["temperature"][()], dims=("snapshot_time", "spring"),
                                          attrs={"units": _text(handle["temperature"].attrs.get("units", "K")),
                                                 "description": "temperature of each spring (/temperature)"})
    coords = {"mass": np.arange(1, mass_count + 1), "spring": np.arange(1, spring_count + 1),
              "component": list(COMPONENTS[:dimension])}
    return variables, coords


def _split_snapshots(path):
    """/snapshots opened lazily by xarray (h5netcdf), its time renamed snapshot_time, its components
    as text and its per-spring thermodynamic variable renamed."""
    try:
        snapshots = xr.open_dataset(path, engine="h5netcdf", group="snapshots")
    except (OSError, ValueError, KeyError) as error:
        raise RunFileError(f"{path}: cannot read /snapshots ({type(error).__name__}: {error})") from None
    snapshots = snapshots.rename(
        {"time": "snapshot_time", **{name: new for name, new in SPRING_VARIABLES.items() if name in snapshots}})
    components = [_text(value) for value in snapshots["component"].values]
    snapshots = snapshots.assign_coords(component=components)
    for variable in snapshots.variables.values():
        variable.attrs.pop("dims", None)          # the file's axes: the Dataset's dims say them
    return snapshots


def open_chain(path):
    """A spring chain's run file, from the dense or the split path, as an xarray Dataset with dims
    time, snapshot_time, mass, spring and component (module docstring)."""
    with run_file(path) as handle:
        attrs = root_attributes(handle)
        model = attrs.get("model_name")
        if model is not None and model != CHAIN_MODEL:
            raise RunFileError(f"{path}: model_name '{model}' is not a spring chain; open_chain reads '{CHAIN_MODEL}' "
                               "files; any run file opens with xr.open_dataset(FILE, engine='h5netcdf', "
                               "phony_dims='access') (docs/output.md, xarray)")
        split = "snapshots" in handle
        if not split and "state" not in handle:
            raise RunFileError(f"{path}: neither /snapshots (/snapshots/q, /snapshots/theta, ...: the split path) "
                               "nor /state and /temperature (the dense path): no chain state in this file")
        variables, time, step = _rows(handle, dense=not split)
        if not split and time is None:
            raise RunFileError(f"{path}: dataset /time is missing: /state has no times")
        if split:
            coords = {}
        else:
            state_variables, coords = _state_snapshots(path, handle, attrs)
            points = len(time)
            variables.update({name: value[:points] for name, value in state_variables.items()})
            coords["snapshot_time"] = time
    if split:
        dataset = _split_snapshots(path)
        close = dataset.close
    else:
        dataset, close = xr.Dataset(coords=coords), None
    if time is not None:
        dataset = dataset.assign_coords(time=time).assign_coords(step=("time", step))
    dataset = dataset.assign(variables)
    dataset.attrs = {**attrs, "snapshot_source": "/snapshots" if split else "/state"}
    if close is not None:
        dataset.set_close(close)
    return dataset
