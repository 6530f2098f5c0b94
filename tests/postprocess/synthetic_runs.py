"""Run files built with h5py that follow docs/output.md exactly, with known numbers.

Used where eme_run cannot (yet) produce the case: constrained runs, missing datasets,
permuted state columns, hand-made values."""
from pathlib import Path

import h5py
import numpy as np

STATE_COLUMNS = ("q1_x q1_y q1_z q2_x q2_y q2_z p1_x p1_y p1_z p2_x p2_y p2_z gamma theta_1 theta_2").split()
UNITS = {"time": "s", "state": "SI", "temperature": "K", "energy": "J", "entropy": "J/K",
         "lyapunov": "J", "angular_momentum": "J s", "newton_iterations": "1",
         "scheme_temperature": "K", "solver_strategy": "1", "snes_solves": "1",
         "rejected_roots": "1", "boundary_heat": "J", "multiplier": "SI", "constraint_residual": "SI"}
PER_STEP = {"newton_iterations", "scheme_temperature", "solver_strategy", "snes_solves", "rejected_roots",
            "multiplier"}


def run_data(steps, dt=0.1):
    """Datasets of a run with `steps` completed steps and simple known values."""
    n = np.arange(steps + 1, dtype=float)
    time = dt * n
    q1 = np.column_stack([np.cos(time), np.sin(time), -0.5 * time])
    q2 = np.column_stack([2.0 + 0 * time, -time, 0.25 * time])
    state = np.column_stack([q1, q2, np.ones((steps + 1, 6)), 0.01 * n, 280 + n, 350 - n])
    energy = 600.0 + n ** 2 * 1e-13
    entropy = 1.7 + 0.01 * n
    return {
        "time": time,
        "state": state,
        "temperature": np.column_stack([280 + n, 350 - 2 * n]),
        "energy": energy,
        "entropy": entropy,
        "lyapunov": energy - 300.0 * entropy,
        "angular_momentum": np.column_stack([0 * n, 0 * n, -3.0 + 1e-14 * n ** 2]),
        "newton_iterations": np.full(steps, 4, dtype=np.int32),
        "scheme_temperature": np.column_stack([281 + n[:-1], 349 - n[:-1]]),
        "solver_strategy": np.ones(steps, dtype=np.int32),
        "snes_solves": np.ones(steps, dtype=np.int32),
        "rejected_roots": np.zeros(steps, dtype=np.int32),
        "boundary_heat": np.zeros(steps + 1),
    }


def run_attributes(steps, dt=0.1, thermo_variable="temperature", status="complete"):
    return {
        "scheme": "eme", "scheme_label": "EME", "scheme_family": "discrete_gradient_step",
        "thermo_variable": thermo_variable, "discrete_gradient": "gonzalez",
        "metric": "nondimensional", "dt": dt, "t_end": dt * steps, "theta_r": 300.0,
        "newton_tol": 1e-8, "status": status, "steps_planned": steps, "steps_completed": steps,
        "wall_time_seconds": 0.01, "code_version": "synthetic", "input_file": "synthetic.nml",
        "mass": np.array([1.0, 1.0]), "natural_length": np.array([1.5, 2.0]),
        "q1": np.array([1.0, 0, 0]), "theta": np.array([280.0, 350.0]),
    }


def constraint_attributes(fix_length, fix_temperature, length=2.5, temperature=300.0):
    names = [name for name, on in (("length", fix_length), ("temperature", fix_temperature)) if on]
    return {"constraints": ", ".join(names) or "none", "fix_length": int(fix_length),
            "length": length, "fix_temperature": int(fix_temperature), "temperature": temperature}


def write_run(path, steps=4, data=None, attributes=None, drop=(), columns=STATE_COLUMNS):
    """Writes a run file; `data`/`attributes` override the defaults, `drop` removes names.

    `columns` is the order of the /state columns in the file (the data are permuted to match).
    Returns the path and the datasets in the documented column order."""
    datasets = run_data(steps, attributes.get("dt", 0.1) if attributes else 0.1)
    datasets.update(data or {})
    attrs = run_attributes(steps)
    attrs.update(attributes or {})
    if "constraints" in attrs and attrs["constraints"] != "none":
        active = [c for c in ("length", "temperature") if attrs.get(f"fix_{c}")]
        datasets.setdefault("multiplier", np.full((steps, len(active)), 0.5))
        datasets.setdefault("constraint_residual", np.zeros((steps + 1, len(active))))
    order = [STATE_COLUMNS.index(name) for name in columns]
    with h5py.File(Path(path), "w") as f:
        for name, value in datasets.items():
            if name in drop:
                continue
            f[name] = value[:, order] if name == "state" else value
            f[name].attrs["units"] = UNITS[name]
            f[name].attrs["description"] = f"synthetic {name}"
            f[name].attrs["rows"] = "step" if name in PER_STEP else "point"
        if "state" in f:
            f["state"].attrs["columns"] = " ".join(columns)
        for name, names in (("temperature", "theta_1 theta_2"), ("angular_momentum", "J_x J_y J_z"),
                            ("scheme_temperature", "Theta_1 Theta_2")):
            if name in f:
                f[name].attrs["columns"] = names
        for name in ("multiplier", "constraint_residual"):
            if name in f:
                prefix = "lambda_" if name == "multiplier" else "g_"
                f[name].attrs["columns"] = " ".join(prefix + c for c in active)
        for name, value in attrs.items():
            if name not in drop:
                f.attrs[name] = value
    return Path(path), datasets


def ladder_columns(law, dimension):
    """/state's columns of a rung of the spring ladder (issue 32): the planar or spatial q1, q2,
    p1, p2, then gamma (thermoviscoelastic only), then the two thermal columns (not elastic)."""
    axes = "xyz"[:dimension]
    names = [f"{vector}_{axis}" for vector in ("q1", "q2", "p1", "p2") for axis in axes]
    if law == "thermoviscoelastic":
        names.append("gamma")
    if law != "elastic":
        names += ["theta_1", "theta_2"]
    return names


def write_ladder_run(path, law="elastic", dimension=2, gravity=False, steps=4, dt=0.1, thermo_variable=True):
    """A run file of one rung as the ladder's files are laid out: no /temperature, /entropy or
    /lyapunov for elastic springs, /angular_momentum only where the scene has momenta (3D:
    J_x J_y J_z; 2D without gravity: J; 2D with gravity: none) with the root attribute
    conserved_momentum naming the conserved one. thermo_variable=False leaves that attribute out
    (an elastic run may not write it). Returns the path and the datasets written."""
    n = np.arange(steps + 1, dtype=float)
    time = dt * n
    columns = ladder_columns(law, dimension)
    state = np.zeros((steps + 1, len(columns)))
    values = {"q1_x": np.cos(time), "q1_y": np.sin(time) - 1.0, "q1_z": 0.1 * time,
              "q2_x": 1.0 + 0 * time, "q2_y": -time, "q2_z": 0.05 * time,
              "p1_x": 0.5 + 0 * time, "p1_y": 0.25 * n, "p2_x": -n, "gamma": 0.01 * n,
              "theta_1": 280 + n, "theta_2": 350 - n}
    for i, name in enumerate(columns):
        state[:, i] = values.get(name, 0 * time)
    energy = 3.9 + n ** 2 * 1e-15
    datasets = {"time": time, "state": state, "energy": energy,
                "newton_iterations": np.full(steps, 3, dtype=np.int32),
                "solver_strategy": np.ones(steps, dtype=np.int32), "snes_solves": np.ones(steps, dtype=np.int32),
                "rejected_roots": np.zeros(steps, dtype=np.int32), "boundary_heat": np.zeros(steps + 1)}
    thermal = law != "elastic"
    if thermal:
        datasets["temperature"] = np.column_stack([280 + n, 350 - 2 * n])
        datasets["entropy"] = 1.7 + 0.01 * n
        datasets["lyapunov"] = energy - 300.0 * datasets["entropy"]
        datasets["scheme_temperature"] = np.column_stack([281 + n[:-1], 349 - n[:-1]])
    momentum_columns = ["J_x", "J_y", "J_z"] if dimension == 3 else (["J"] if not gravity else [])
    if momentum_columns:
        datasets["angular_momentum"] = np.column_stack([4.3 + 1e-14 * n ** 2 * (k + 1)
                                                        for k in range(len(momentum_columns))])
    conserved = {3: "J_z", 2: "none" if gravity else "J"}[dimension]
    attrs = run_attributes(steps, dt)
    attrs.update(spring_law=law, dimension=dimension, conserved_momentum=conserved,
                 q1=np.zeros(dimension), mass=np.array([1.0, 1.0]), natural_length=np.array([1.0, 1.0]))
    if not thermal:
        attrs.pop("theta")
        attrs.pop("theta_r")
        attrs["thermo_variable"] = "none"
        if not thermo_variable:
            attrs.pop("thermo_variable")
    units = dict(UNITS, state="SI")
    with h5py.File(Path(path), "w") as f:
        for name, value in datasets.items():
            f[name] = value
            f[name].attrs["units"] = units[name]
            f[name].attrs["description"] = f"synthetic {name}"
            f[name].attrs["rows"] = "step" if name in PER_STEP else "point"
        f["state"].attrs["columns"] = " ".join(columns)
        if thermal:
            f["temperature"].attrs["columns"] = "theta_1 theta_2"
            f["scheme_temperature"].attrs["columns"] = "Theta_1 Theta_2"
        if momentum_columns:
            f["angular_momentum"].attrs["columns"] = " ".join(momentum_columns)
        for name, value in attrs.items():
            f.attrs[name] = value
    return Path(path), datasets
