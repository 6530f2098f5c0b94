"""Reads eme_run output files (docs/output.md) and extracts what the plots show.

Every dataset and attribute is looked up by its documented name; columns of 2-D datasets are
found through their `columns` attribute, never by position. A file that cannot be used (not
HDF5, unreadable, without a dataset or identity attribute a plot needs) raises RunFileError
naming the file and what is missing. A file that a killed or stopped run left behind is read
as far as it goes: a missing descriptive attribute is named, datasets of different lengths are
cut to the steps they all hold, and the run counts as incomplete (Run.problems says why).
"""
import re
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np

import integrators
from file_checksums import DamagedFileError, check_texts

# The run's identity: a figure cannot name or colour a run without them. A run without thermal
# unknowns (the elastic springs, docs/formulation.md section 9: no /temperature) may lack
# thermo_variable or give it as 'none': it is then 'none', and its names carry no subscript.
IDENTITY_ATTRIBUTES = ("scheme", "thermo_variable")
NO_VARIABLE = ("none", "")
# Attributes every figure states when the file has them (a killed run may lack some).
DESCRIPTION_ATTRIBUTES = ("discrete_gradient", "dt", "theta_r", "input_file", "status", "code_version")
CONSTRAINT_ATTRIBUTES = ("constraints", "fix_length", "length", "fix_temperature", "temperature")

# A /state column of the thermodynamic variable: s_1, theta_2, u_1 (older files: s1, theta2, u1).
THERMODYNAMIC_COLUMN = re.compile(r"(s|theta|u)_?([0-9]+)")

# The spring chain's model_name (issue 39): its file holds N masses and n_s springs, not the double
# pendulum's q1, q2 and two temperatures, and split over ranks no /state at all (docs/output.md,
# A chain's file).
CHAIN_MODEL = "spring_chain"

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
    units: dict = field(default_factory=dict)    # dataset name -> its `units` attribute
    problems: list = field(default_factory=list)  # why the file is incomplete beyond its status

    @property
    def status(self):
        """The file's status attribute, or what its absence means."""
        return str(self.attrs.get("status", "incomplete: no status attribute (the run was killed?)"))

    @property
    def incomplete(self):
        """True unless the file says 'complete' and has everything the plots read."""
        return self.status != "complete" or bool(self.problems)

    @property
    def rows_written(self):
        """Step rows in the file: the per-point datasets hold one more (after cut_to_common_length)."""
        return min(len(values) for name, values in self.data.items() if self.rows.get(name) != "step") - 1

    @property
    def steps(self):
        """Completed steps N: the number of the last step the rows reach (/step; with &output every
        or interval a row stands for several steps), else the rows written (files without /step)."""
        step = self.data.get("step")
        if step is not None and len(step) and self.rows_written:
            return int(step[min(len(step), self.rows_written) - 1])
        return self.rows_written

    @property
    def strided(self):
        """True when a row stands for more than one step (&output every or interval)."""
        step = self.data.get("step")
        return step is not None and len(step) > 0 and self.steps != self.rows_written

    def column(self, dataset, name):
        """Column `name` of a 2-D dataset, located through the dataset's `columns` attribute; the
        state's thermodynamic columns in either spelling (theta_1, and theta1 of older files)."""
        names = self.columns.get(dataset)
        if names is not None and name not in names:
            name = next((other for other in column_spellings(name) if other in names), name)
        if names is None or name not in names:
            raise RunFileError(f"{self.path}: dataset /{dataset} has no column '{name}' "
                               f"in its 'columns' attribute (it names: {names})")
        return self.data[dataset][:, names.index(name)]

    @property
    def name(self):
        """Plain scheme name as in the paper, e.g. EME_theta or MP_u (EME without thermal unknowns)."""
        scheme = integrators.label(self.attrs["scheme"])
        variable = self.attrs["thermo_variable"]
        if variable in NO_VARIABLE:
            return scheme
        return f"{scheme}_{VARIABLE_NAMES.get(variable, variable)}"

    @property
    def short_label(self):
        """The paper's notation, e.g. EME_theta, in math text (EME without thermal unknowns)."""
        scheme = integrators.label(self.attrs["scheme"])
        if self.attrs["thermo_variable"] in NO_VARIABLE:
            return scheme
        symbol = VARIABLE_SYMBOLS.get(self.attrs["thermo_variable"], self.attrs["thermo_variable"])
        return rf"{scheme}$_{{{symbol}}}$"

    def has(self, dataset):
        """True when the dataset was read (an optional one the file has)."""
        return dataset in self.data

    @property
    def incomplete_mark(self):
        """'' for a complete run, else e.g. 'INCOMPLETE after 3 steps' (FAILED for a failed case)."""
        if not self.incomplete:
            return ""
        word = "FAILED" if self.status.startswith("failed") else "INCOMPLETE"
        return f"{word} after {self.steps} steps"

    @property
    def label(self):
        """Legend name in the paper's notation with the time step, e.g. EME_theta, dt = 0.15 s,
        and the incomplete mark; or the label a plot's --labels gave the run."""
        if getattr(self, "custom_label", None):
            return self.custom_label
        text = self.short_label
        if "dt" in self.attrs:
            text += rf", $\Delta t$ = {self.attrs['dt']:g} s"
        if self.incomplete:
            text += f" ({self.incomplete_mark})"
        return text

    @property
    def description(self):
        """One line stating scheme, thermodynamic variable, dt, input file, file and status."""
        a = {name: self.attrs.get(name, "(missing)") for name in DESCRIPTION_ATTRIBUTES}
        if self.attrs.get("thermo_variable") in NO_VARIABLE and "theta_r" not in self.attrs:
            a["theta_r"] = "none"
        for name, unit in (("dt", "s"), ("theta_r", "K")):
            if name in self.attrs:
                a[name] = f"{self.attrs[name]:g} {unit}"
        text = (f"{self.attrs['scheme']}, thermo_variable={self.attrs['thermo_variable']}, "
                f"discrete_gradient={a['discrete_gradient']}, dt={a['dt']}, theta_r={a['theta_r']}, "
                f"input {a['input_file']}, file {self.path}, code {a['code_version']}, "
                f"status: {self.status}")
        if self.incomplete:
            text += f"; {self.incomplete_mark}" + "".join(f"; {problem}" for problem in self.problems)
        return text


@contextmanager
def run_file(path):
    """The run file open for reading, its texts checked against their checksum
    (file_checksums); failures to open or read it raise RunFileError naming it."""
    try:
        handle = h5py.File(path, "r")
    except OSError as error:
        raise RunFileError(f"{path}: cannot open as an HDF5 run file ({error})") from None
    try:
        with handle:
            check_texts(handle, path)
            yield handle
    except DamagedFileError as error:
        raise RunFileError(str(error)) from None
    except (OSError, RuntimeError, KeyError) as error:
        # HDF5 reports a truncated or damaged file only when its data are read.
        raise RunFileError(f"{path}: cannot read the file ({type(error).__name__}: {error}); "
                           "it may be truncated or damaged") from None


def root_attributes(handle):
    """Every root attribute of an open file as plain Python values."""
    return {name: _plain(value) for name, value in handle.attrs.items()}


def thermal(handle):
    """True when an open run file has thermal unknowns: its thermo_variable is not 'none' (eme_run
    writes 'none' for elastic springs); a file without the attribute, by its /temperature."""
    variable = handle.attrs.get("thermo_variable")
    if variable is not None:
        return _plain(variable) != "none"
    return "temperature" in handle


def chain_refusal(path, handle, datasets, attributes, instead):
    """The RunFileError of a figure of the double pendulum given a spring chain's file: one line
    naming the file, the `datasets` or root `attributes` the figure needs that it lacks (or that its
    datasets are a chain's), and `instead`, what draws it ({file} stands for the file)."""
    springs = int(handle.attrs.get("links", 0)) + (_plain(handle.attrs.get("ends", "")) == "fixed-fixed")
    missing = [f"/{name}" for name in datasets if name not in handle]
    absent = [name for name in attributes if name not in handle.attrs]
    if missing:
        lack = (f"it has no {' or '.join(missing)}: split over ranks, a chain keeps its state in /snapshots "
                "(docs/output.md, A chain's file)")
    elif absent:
        lack = f"it has no root attribute {', '.join(absent)}"
    else:
        lack = "its /state and /temperature hold a chain's masses and springs, not the double pendulum's"
    return RunFileError(f"{path}: a spring chain's file ({springs} springs): {lack}; this figure draws the double "
                        f"pendulum: use {instead.format(file=path)}")


def read_run(path, datasets, attributes=(), optional=(), thermal_datasets=(), chain_instead=None):
    """Reads the named datasets and every root attribute of a run file; `attributes` are required
    besides IDENTITY_ATTRIBUTES; the `optional` datasets are read where the file has them (a scene
    may have no /angular_momentum), and the `thermal_datasets` are required of a file with thermal
    unknowns (a /temperature) and absent from one without (elastic springs: no /temperature,
    /entropy or /lyapunov). `chain_instead`, of a figure that draws only the double pendulum: a
    spring chain's file is refused (chain_refusal), the message saying what to use instead."""
    path = Path(path)
    with run_file(path) as handle:
        if chain_instead is not None and _plain(handle.attrs.get("model_name", "")) == CHAIN_MODEL:
            raise chain_refusal(path, handle, [*datasets, *(thermal_datasets if thermal(handle) else ())],
                                attributes, chain_instead)
        identity = [name for name in IDENTITY_ATTRIBUTES if name != "thermo_variable" or thermal(handle)]
        missing = [name for name in (*identity, *attributes) if name not in handle.attrs]
        if missing:
            raise RunFileError(f"{path}: root attribute{'s' if len(missing) > 1 else ''} "
                               + ", ".join(f"'{name}'" for name in missing)
                               + (" are" if len(missing) > 1 else " is") + " missing")
        run = Run(path, root_attributes(handle))
        run.attrs.setdefault("thermo_variable", "none")
        integrators.register_run(run.attrs)
        # theta_r is the Lyapunov function's: a run without thermal unknowns has none.
        absent = [name for name in DESCRIPTION_ATTRIBUTES if name not in run.attrs and name != "status"
                  and (name != "theta_r" or thermal(handle))]
        if absent:
            run.problems.append("root attributes " + ", ".join(absent) + " missing")
        # /step says which steps the rows stand for (files of older versions may lack it).
        if thermal(handle):
            datasets = (*datasets, *thermal_datasets)
        wanted = ("time", *datasets, *(("step",) if "step" in handle and "step" not in datasets else ()),
                  *(name for name in optional if name in handle and name not in datasets))
        for name in wanted:
            if name not in handle or not isinstance(handle[name], h5py.Dataset):
                raise RunFileError(f"{path}: dataset '/{name}' is missing")
            run.data[name] = handle[name][()]
            if "columns" in handle[name].attrs:
                run.columns[name] = _column_names(handle[name].attrs["columns"])
            if "units" in handle[name].attrs:
                run.units[name] = _plain(handle[name].attrs["units"])
            if "rows" in handle[name].attrs:
                run.rows[name] = _plain(handle[name].attrs["rows"])
            elif name != "time":
                raise RunFileError(f"{path}: dataset '/{name}' has no 'rows' attribute (point or step)")
        # The other datasets' lengths count too: a file whose datasets disagree is incomplete.
        others = {name: (_plain(item.attrs["rows"]), item.shape[0]) for name, item in handle.items()
                  if name not in run.data and isinstance(item, h5py.Dataset) and item.shape
                  and "rows" in item.attrs}
    cut_to_common_length(run, others)
    return run


def column_spellings(name):
    """A column's name and its other spelling: theta_1 and theta1, s_2 and s2 (older files wrote
    /state's thermodynamic columns without the underscore)."""
    match = THERMODYNAMIC_COLUMN.fullmatch(name)
    if not match:
        return [name]
    symbol, number = match.groups()
    return [name, *(other for other in (f"{symbol}_{number}", f"{symbol}{number}") if other != name)]


def _column_names(value):
    """The `columns` attribute as a list of names, whether a string of names or an array of them."""
    value = _plain(value)
    return value.replace(",", " ").split() if isinstance(value, str) else list(value)


def cut_to_common_length(run, others=None):
    """Per-point datasets have N+1 rows and per-step ones N, as each dataset's `rows` attribute
    says (docs/output.md). A file killed while writing may hold more rows in some; the
    datasets read are cut to the steps that every dataset holds (those read and `others`, name:
    (rows, length) of datasets not read), and the cut is recorded as a problem."""
    lengths = {name: (run.rows.get(name, "point"), len(values)) for name, values in run.data.items()}
    lengths.update(others or {})
    steps = min(length - (0 if rows == "step" else 1) for rows, length in lengths.values())
    if steps < 0:
        raise RunFileError(f"{run.path}: no state written ("
                           + ", ".join(f"/{name} has {length} rows" for name, (_, length) in lengths.items()) + ")")
    if any(length != steps + (0 if rows == "step" else 1) for rows, length in lengths.values()):
        run.problems.append("datasets of different lengths ("
                            + ", ".join(f"/{name} {length} rows" for name, (_, length) in lengths.items())
                            + f"); read up to step {steps}")
        for name in run.data:
            run.data[name] = run.data[name][:steps + (0 if lengths[name][0] == "step" else 1)]


def increments(values):
    """Per-step increments X_{n+1} - X_n of a per-state series (length N)."""
    values = np.asarray(values)
    return values[1:] - values[:-1]


def dimension(run):
    """3 for a spatial pendulum (/state has q1_z), 2 for a planar one (q1_x q1_y, y vertical)."""
    names = run.columns.get("state")
    if names is None:
        raise RunFileError(f"{run.path}: dataset /state has no column names: its 'columns' attribute is missing")
    return 3 if any(other in names for other in ("q1_z",)) else 2


def mass_positions(run):
    """Positions of m1 and m2, each (N+1, d) with d = dimension(run) (x y z, or x y of a planar
    run): m1 is at q1, m2 at q1 + q2 (q2 is relative to m1)."""
    axes = "xyz"[:dimension(run)]
    q1 = np.column_stack([run.column("state", f"q1_{axis}") for axis in axes])
    q2 = np.column_stack([run.column("state", f"q2_{axis}") for axis in axes])
    return q1, q1 + q2


def jz_drift(run):
    """J_z,n - J_z,0 from the J_z column of /angular_momentum."""
    jz = run.column("angular_momentum", "J_z")
    return jz - jz[0]


def conserved_momentum(run):
    """The names of the run's conserved momentum components, a tuple: the root attribute
    conserved_momentum, names separated by blanks (('J_z',) in 3D with gravity along z, ('J_g',) off
    the axes, ('J_x', 'J_y', 'J_z') without gravity, ('J',) in a plane without gravity); in files of
    earlier versions the column J_z (or the planar J); None when the run has none."""
    names = run.attrs.get("conserved_momentum")
    if names is not None:
        return None if names in NO_VARIABLE else tuple(str(names).split())
    names = run.columns.get("angular_momentum")
    if names is None:
        # Earlier versions wrote J = (J_x, J_y, J_z) without column names.
        momenta = run.data.get("angular_momentum")
        if momenta is None or momenta.ndim != 2 or momenta.shape[1] != 3:
            return None
        run.columns["angular_momentum"] = ["J_x", "J_y", "J_z"]
        return ("J_z",)
    name = next((other for other in ("J_z", "J") if other in names), None)
    return None if name is None else (name,)


def conserved_values(run):
    """{name: J_n.a} of each conserved component: /angular_momentum's column of that name, else
    its columns J_x J_y J_z dotted with the component's axis (root attribute
    conserved_momentum_axes, three numbers a component: J_g); {} when the run has none."""
    names = conserved_momentum(run)
    if names is None or "angular_momentum" not in run.data:
        return {}
    axes = np.reshape(np.asarray(run.attrs.get("conserved_momentum_axes", np.zeros(3 * len(names))), float), (-1, 3))
    values = {}
    for name, axis in zip(names, axes):
        if name in (run.columns.get("angular_momentum") or ()):
            values[name] = run.column("angular_momentum", name)
        else:
            j = [run.column("angular_momentum", f"J_{letter}") for letter in "xyz"]
            values[name] = j[0] * axis[0] + j[1] * axis[1] + j[2] * axis[2]
    return values


def momentum_drift(run):
    """(name, J_n - J_0) of the run's conserved momentum component that drifts furthest, or
    (None, None) when it has none."""
    drifts = {name: values - values[0] for name, values in conserved_values(run).items()}
    if not drifts:
        return None, None
    name = max(drifts, key=lambda other: np.max(np.abs(drifts[other])))
    return name, drifts[name]


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
