"""Reads eme_run output files (README, "Output layout (HDF5)") and extracts what the plots show.

Every dataset and attribute is looked up by its documented name; columns of 2-D datasets are
found through their `columns` attribute, never by position. A missing one raises
RunFileError naming the file and what is missing.
"""
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np

import integrators

# Attributes every figure states (scheme, thermodynamic variable, dt, input file, status).
DESCRIPTION_ATTRIBUTES = ("scheme", "thermo_variable", "discrete_gradient", "dt", "input_file",
                          "status", "theta_r")
CONSTRAINT_ATTRIBUTES = ("constraints", "fix_length", "length", "fix_temperature", "temperature")

# Subscripts of the paper's scheme names EME_s, EME_theta, EME_u.
VARIABLE_SYMBOLS = {"entropy": "s", "temperature": r"\theta", "internal_energy": "u"}
VARIABLE_NAMES = {"entropy": "s", "temperature": "theta", "internal_energy": "u"}


class RunFileError(Exception):
    """A run file cannot be read, or lacks a documented dataset, attribute or column."""


def _plain(value):
    """An HDF5 attribute value as a Python str, number, list of str or numpy array."""
    if isinstance(value, bytes):
        return value.decode()
    if isinstance(value, np.ndarray) and value.dtype.kind in "SO":
        return [v.decode() if isinstance(v, bytes) else str(v) for v in value.ravel()]
    if isinstance(value, np.generic):
        return value.item()
    return value


@dataclass
class Run:
    """The datasets and attributes of one run file that a plot asked for."""
    path: Path
    attrs: dict
    data: dict = field(default_factory=dict)
    columns: dict = field(default_factory=dict)  # dataset name -> its `columns` attribute, split
    rows: dict = field(default_factory=dict)     # dataset name -> its `rows` attribute: point or step

    @property
    def incomplete(self):
        """True when the run stopped early (status 'incomplete: <reason>')."""
        return str(self.attrs["status"]).startswith("incomplete")

    @property
    def steps(self):
        """Completed steps N (the datasets hold N+1 states)."""
        return len(self.data["time"]) - 1

    def column(self, dataset, name):
        """Column `name` of a 2-D dataset, located through the dataset's `columns` attribute."""
        names = self.columns.get(dataset)
        if names is None or name not in names:
            raise RunFileError(f"{self.path}: dataset /{dataset} has no column '{name}' "
                               f"in its 'columns' attribute (it names: {names})")
        return self.data[dataset][:, names.index(name)]

    @property
    def name(self):
        """Plain scheme name as in the paper, e.g. EME_theta or MP_u."""
        scheme = integrators.label(self.attrs["scheme"])
        variable = self.attrs["thermo_variable"]
        return f"{scheme}_{VARIABLE_NAMES.get(variable, variable)}"

    @property
    def label(self):
        """Short legend name in the paper's notation, e.g. EME_theta, with an incomplete marker."""
        scheme = integrators.label(self.attrs["scheme"])
        symbol = VARIABLE_SYMBOLS.get(self.attrs["thermo_variable"], self.attrs["thermo_variable"])
        text = rf"{scheme}$_{{{symbol}}}$, $\Delta t$ = {self.attrs['dt']:g} s"
        if self.incomplete:
            text += f" (INCOMPLETE after {self.steps} steps)"
        return text

    @property
    def description(self):
        """One line stating scheme, thermodynamic variable, dt, input file, file and status."""
        a = self.attrs
        return (f"{a['scheme']}, thermo_variable={a['thermo_variable']}, "
                f"discrete_gradient={a['discrete_gradient']}, dt={a['dt']:g} s, "
                f"theta_r={a['theta_r']:g} K, input {a['input_file']}, file {self.path}, "
                f"status: {a['status']}")


def read_run(path, datasets, attributes=()):
    """Reads the named datasets and attributes (plus those every figure states) of a run file."""
    path = Path(path)
    try:
        handle = h5py.File(path, "r")
    except OSError as error:
        raise RunFileError(f"{path}: cannot open as an HDF5 run file ({error})") from None
    with handle:
        attrs = {}
        for name in (*DESCRIPTION_ATTRIBUTES, *attributes):
            if name not in handle.attrs:
                raise RunFileError(f"{path}: root attribute '{name}' is missing")
            attrs[name] = _plain(handle.attrs[name])
        for name in ("scheme_label", "scheme_family"):
            if name in handle.attrs:
                attrs[name] = _plain(handle.attrs[name])
        integrators.register_run(attrs)
        run = Run(path, attrs)
        for name in ("time", *datasets):
            if name not in handle or not isinstance(handle[name], h5py.Dataset):
                raise RunFileError(f"{path}: dataset '/{name}' is missing")
            run.data[name] = handle[name][()]
            if "columns" in handle[name].attrs:
                run.columns[name] = _column_names(handle[name].attrs["columns"])
            if "rows" in handle[name].attrs:
                run.rows[name] = _plain(handle[name].attrs["rows"])
    _check_lengths(run, datasets)
    return run


def _column_names(value):
    """The `columns` attribute as a list of names, whether a string of names or an array of them."""
    value = _plain(value)
    return value.replace(",", " ").split() if isinstance(value, str) else list(value)


def _check_lengths(run, datasets):
    """Per-point datasets have N+1 rows and per-step ones N, as each dataset's `rows` attribute
    says (README, Output layout)."""
    rows = len(run.data["time"])
    for name in datasets:
        if name not in run.rows:
            raise RunFileError(f"{run.path}: dataset '/{name}' has no 'rows' attribute (point or step)")
        expected = rows - 1 if run.rows[name] == "step" else rows
        if len(run.data[name]) != expected:
            raise RunFileError(f"{run.path}: dataset '/{name}' has {len(run.data[name])} rows, "
                               f"expected {expected} (/time has {rows})")


def increments(values):
    """Per-step increments X_{n+1} - X_n of a per-state series (length N)."""
    values = np.asarray(values)
    return values[1:] - values[:-1]


def mass_positions(run):
    """Positions of m1 and m2, each (N+1, 3): m1 is at q1, m2 at q1 + q2 (q2 is relative to m1)."""
    q1 = np.column_stack([run.column("state", f"q1_{axis}") for axis in "xyz"])
    q2 = np.column_stack([run.column("state", f"q2_{axis}") for axis in "xyz"])
    return q1, q1 + q2


def jz_drift(run):
    """J_z,n - J_z,0 from the J_z column of /angular_momentum."""
    jz = run.column("angular_momentum", "J_z")
    return jz - jz[0]


def snapshot_steps(time, requested):
    """Step indices nearest to the requested times, each once, in the order asked; times past
    the last step + dt/2 are dropped. Returns (indices, dropped times)."""
    time = np.asarray(time)
    half_step = 0.5 * (time[1] - time[0]) if len(time) > 1 else 0.0
    kept = [t for t in requested if t <= time[-1] + half_step]
    dropped = [t for t in requested if t > time[-1] + half_step]
    nearest = [int(np.argmin(np.abs(time - t))) for t in kept]
    return list(dict.fromkeys(nearest)), dropped


def constraint_summary(run):
    """Readable list of the active constraints, from the constraint attributes."""
    a = run.attrs
    parts = []
    if _flag(a["fix_length"]):
        parts.append(rf"$g_1$: $l_1$ = {a['length']:g} m")
    if _flag(a["fix_temperature"]):
        parts.append(rf"$g_2$: $\theta_1$ = {a['temperature']:g} K")
    return ", ".join(parts) if parts else f"no constraint ({a['constraints']})"


def _flag(value):
    """A logical attribute written as a number, a boolean or a Fortran/text logical."""
    if isinstance(value, str):
        return value.strip().lower() in ("true", ".true.", "t", "1", "yes")
    return bool(value)
