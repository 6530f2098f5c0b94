#!/usr/bin/env python3
"""Prints the summary table of one or more eme_run result files.

For each run: status, steps (accepted ones), the trial steps rejected by step-size control or
halving (integrators that reject steps: rejected_steps; '-' for the others), the relative energy
balance error max_n |E_n - E_0 - Q_n| / |E_0| (Q_n is the heat supplied through constraint g2, zero
without it, so this is the energy drift), the smallest entropy increment, the largest Lyapunov
increment, the conserved momentum's drift max_n |J_n - J_0| (the largest over the conserved
components: J_z, J_y, J_g along an oblique gravity, or J_x, J_y and J_z without gravity; the column
is titled by them), the largest constraint residual, the mean Newton iterations per step and the
wall time; for a spring chain's file split over ranks (docs/output.md, A chain's file) also the
smallest entropy production of any spring's viscous branch and of any conducting link over the
steps (its /min_viscous_production and /min_link_production; '-' where the chain has none, or the
file does not record them: the dense path's). Everything is read from the HDF5 files, and gives
eme_run's own summary line for any &output every or interval: the steps are the last step the rows reach (/step), the increments the
per-step records /min_entropy_increment and /max_lyapunov_increment (a row that stands for several
steps holds their least and largest), Newton/step the summed /newton_iterations over the steps; the
energy balance and the momentum drift of a complete file are its run_figures, which eme_run took
over every step (an incomplete file's: over the points written). Files without the per-step records
(older versions) give the increments between written points.

A complete file whose accuracy is in doubt (its attribute `warnings`: a fixed-step relaxed run that
halved steps, docs/integrators.md) has the status 'complete (warned)', and its warning follows the
table as a footnote. A file that a killed or stopped run left behind is summarised as far as it
goes, its status marked INCOMPLETE with what is missing; a file that cannot be used (not HDF5,
damaged, without the datasets) is named on stderr with the reason, and the exit status is then 2.

A study's folder (eme_ensemble's output_dir), or its index.h5, stands for the study's case files
(case_NNNNN.h5, in case order; each once, however often it is named), each a row with its swept
values (`study_overrides`) in the column 'case'; an index-only study has none, and is named on
stderr as unusable, pointing at study_table.py.

usage: summarize_runs.py FILE.h5|STUDY_DIR [FILE.h5|STUDY_DIR ...] [--markdown]
"""
import argparse
import math
import sys
from pathlib import Path

import h5py
import numpy as np

from trajectory import (IDENTITY_ATTRIBUTES, NO_VARIABLE, Run, RunFileError, conserved_momentum, conserved_values,
                        thermal, cut_to_common_length, root_attributes, run_file)

POINT_DATASETS = ("energy",)
# A split chain's per-step smallest entropy productions [W/K] (docs/output.md, A chain's file).
CHAIN_PRODUCTIONS = ("min_viscous_production", "min_link_production")
STEP_DATASETS = ("newton_iterations",)
# angular_momentum: only for a scene with momenta (not the gas containers, nor a planar pendulum
# under gravity); entropy and lyapunov: not for elastic springs (no thermal unknowns).
OPTIONAL = ("entropy", "lyapunov", "boundary_heat", "constraint_residual", "rejected_steps", "step",
            "min_entropy_increment", "max_lyapunov_increment", "angular_momentum", *CHAIN_PRODUCTIONS)
# run_figures (docs/output.md): what eme_run took over every step, in this order.
RUN_FIGURES = ("energy_drift", "min_entropy_increment", "max_lyapunov_increment", "angular_momentum_drift")


def read(path):
    """The datasets the table needs and every root attribute, cut to the steps they all hold."""
    with run_file(path) as f:
        # S and V belong to every file with thermal unknowns (not to elastic springs').
        thermal_points = ("entropy", "lyapunov") if thermal(f) else ()
        for name in (*POINT_DATASETS, *thermal_points, *STEP_DATASETS):
            if name not in f:
                raise RunFileError(f"{path}: dataset /{name} is missing; is this an eme_run file?")
        run = Run(Path(path), root_attributes(f))
        for name in (*POINT_DATASETS, *STEP_DATASETS, *OPTIONAL):
            if name in f:
                run.data[name] = f[name][()]
                rows = f[name].attrs.get("rows", "step" if name in (*STEP_DATASETS, "rejected_steps") else "point")
                run.rows[name] = rows.decode() if isinstance(rows, bytes) else str(rows)
        run.units = {name: text_of(f[name].attrs.get("units", "")) if name in f else ""
                     for name in ("energy", "entropy")}
        if "angular_momentum" in f and "columns" in f["angular_momentum"].attrs:
            run.columns["angular_momentum"] = text_of(f["angular_momentum"].attrs["columns"]).split()
        has_thermal = thermal(f)
    identity = [name for name in IDENTITY_ATTRIBUTES if name != "thermo_variable" or has_thermal]
    absent = [name for name in (*identity, "discrete_gradient") if name not in run.attrs]
    if absent:
        run.problems.append("root attributes " + ", ".join(absent) + " missing")
    cut_to_common_length(run)
    return run


def text_of(value):
    """An attribute as str (h5py gives bytes or str)."""
    return value.decode() if isinstance(value, bytes) else str(value)


def whole_run_figures(run):
    """run_figures by name when the file is complete (eme_run's figures over every step), else {}."""
    figures = run.attrs.get("run_figures")
    if run.incomplete or figures is None or len(figures) < len(RUN_FIGURES):
        return {}
    return dict(zip(RUN_FIGURES, (float(value) for value in figures)))


def least(values):
    """The smallest value that is not NaN; NaN when there is none."""
    values = np.asarray(values, float)
    values = values[~np.isnan(values)]
    return float(values.min()) if values.size else float("nan")


def summarize(path):
    """The table row of one run file, as a dict of numbers and strings."""
    run = read(path)
    data, attrs, steps = run.data, run.attrs, run.steps
    energy, entropy, lyapunov = data["energy"], data.get("entropy"), data.get("lyapunov")
    heat = data.get("boundary_heat", np.zeros_like(energy))
    # The conserved components of /angular_momentum (J_z, J_x J_y J_z, the planar J, ...), if any.
    momentum = conserved_momentum(run) if "angular_momentum" in data else None
    conserved = conserved_values(run) if momentum else {}
    constraint = data.get("constraint_residual")
    rejected = data.get("rejected_steps")
    gradient = attrs.get("discrete_gradient", "none")
    constraints = attrs.get("constraints", "none")
    whole = whole_run_figures(run)
    rows = run.rows_written
    # The per-step records cover every step, whatever the stride; the points' differences only
    # when every step has its row.
    # Without thermal unknowns (no /entropy) there is no dS and no V to report.
    if entropy is None:
        min_ds = max_dv = float("nan")
    elif rows and "min_entropy_increment" in data:
        min_ds = float(np.min(data["min_entropy_increment"][:rows]))
    else:
        min_ds = float(np.diff(entropy).min()) if rows else float("nan")
    if entropy is None:
        pass
    elif rows and "max_lyapunov_increment" in data:
        max_dv = float(np.max(data["max_lyapunov_increment"][:rows]))
    else:
        max_dv = float(np.diff(lyapunov).max()) if rows and lyapunov is not None else float("nan")
    variable = attrs.get("thermo_variable", "none" if entropy is None else "?")
    status = run.status
    warnings = attrs.get("warnings", "") if not run.incomplete else ""
    if run.incomplete:
        status = f"{run.incomplete_mark} ({'; '.join([run.status, *run.problems])})"
    elif warnings:
        status = f"{run.status} (warned)"
    return {
        # A study's case by its folder too: every study numbers its cases from case_00001.
        "file": f"{run.path.parent.name}/{run.path.stem}" if "study_overrides" in attrs else run.path.stem,
        "run": f"{attrs.get('scheme', '?')}" + ("" if variable in NO_VARIABLE else f"/{variable}")
               + (f"/{gradient}" if gradient != "none" else "")
               + (f" + {constraints}" if constraints != "none" else ""),
        "status": status,
        "steps": steps,
        "rejected": "-" if rejected is None else str(int(rejected[:rows].sum())),
        "energy_drift": whole.get("energy_drift", float(np.max(np.abs(energy - energy[0] - heat)) / abs(energy[0]))),
        "min_dS": min_ds,
        "max_dV": max_dv,
        "jz_drift": float("nan") if not conserved else
        whole.get("angular_momentum_drift", max(float(np.max(np.abs(values - values[0])))
                                                for values in conserved.values())),
        "momentum": " ".join(momentum) if momentum else None,
        "warnings": warnings,
        "has_entropy": entropy is not None,
        "energy_units": run.units["energy"], "entropy_units": run.units["entropy"],
        "constraint": "-" if constraint is None or constraint.size == 0 else f"{np.abs(constraint).max():.1e}",
        "newton_per_step": float(data["newton_iterations"][:rows].sum()) / steps if steps else float("nan"),
        "wall_s": f"{attrs['wall_time_seconds']:.3f}" if "wall_time_seconds" in attrs else "-",
        "case": str(attrs.get("study_overrides", "-")),
        **{name: least(data[name][:rows]) if name in data else float("nan") for name in CHAIN_PRODUCTIONS},
        "has_productions": any(name in data for name in CHAIN_PRODUCTIONS),
    }


COLUMNS = [("file", "file", "{}"), ("case", "case", "{}"), ("run", "scheme", "{}"), ("steps", "steps", "{}"),
           ("rejected", "rejected", "{}"),
           ("energy_drift", "energy balance", "{:.2e}"),
           ("min_dS", "min dS [J/K]", "{:.2e}"), ("max_dV", "max dV [J]", "{:.2e}"),
           ("jz_drift", "Jz drift [J s]", "{:.2e}"),
           ("min_viscous_production", "min visc. prod. [W/K]", "{:.2e}"),
           ("min_link_production", "min link prod. [W/K]", "{:.2e}"), ("constraint", "max |g|", "{}"),
           ("newton_per_step", "Newton/step", "{:.2f}"),
           ("wall_s", "wall [s]", "{}"), ("status", "status", "{}")]


def table_columns(rows):
    """COLUMNS for these rows: no momentum column when no run has a conserved momentum, titled by
    the runs' conserved components (Jz; Jx,Jy,Jz; the planar scalar J; 'J (conserved)' where they
    differ); no dS and dV columns when no run has an entropy (elastic springs); and the units of dS
    and dV the runs' models give (the pendulum's J/K and J; none in the header where models differ);
    the chain's production columns when some run has them, the case column when some run is a
    study's case."""
    entropy = any(row["has_entropy"] for row in rows) or not rows
    productions = any(row["has_productions"] for row in rows)
    has = {"jz_drift": any(not math.isnan(row["jz_drift"]) for row in rows), "min_dS": entropy, "max_dV": entropy,
           "case": any(row["case"] != "-" for row in rows), "min_viscous_production": productions,
           "min_link_production": productions}
    columns = [column for column in COLUMNS if has.get(column[0], True)]
    units = {key: {row[key] for row in rows if row[key]} for key in ("entropy_units", "energy_units")}
    momenta = {row.get("momentum") for row in rows if row.get("momentum")}
    titled = []
    for key, title, fmt in columns:
        if key in ("min_dS", "max_dV"):
            kind = units["entropy_units" if key == "min_dS" else "energy_units"]
            title = title.split(" [")[0] + (f" [{kind.pop()}]" if len(kind) == 1 else "")
        if key == "jz_drift" and momenta:
            names = momenta.pop().replace("_", "").replace(" ", ",") if len(momenta) == 1 else "J (conserved)"
            title = f"{names} drift [J s]"
        titled.append((key, title, fmt))
    return titled


def cell(value, fmt):
    """A figure as the table prints it; '-' where a run has none (no step completed), never 'nan'."""
    if isinstance(value, float) and math.isnan(value):
        return "-"
    return fmt.format(value)


def markdown_row(cells):
    """One Markdown table row; a '|' inside a cell (as in 'max |g|') is escaped."""
    return "| " + " | ".join(cell.replace("|", "\\|") for cell in cells) + " |"


def study_folder(path):
    """The study folder that `path` names (the folder itself, or its index.h5: a file with /cases),
    else None."""
    path = Path(path)
    if path.is_dir():
        return path
    try:
        with h5py.File(path, "r") as handle:
            is_index = "cases" in handle and "energy" not in handle
    except (OSError, RuntimeError, KeyError, ValueError):
        return None                       # not HDF5, or damaged: summarize() names what is wrong with it
    return path.parent if is_index else None


def run_files(arguments):
    """The run files the arguments name, each once, a study's folder or index standing for its case
    files; and the messages of the studies that have none."""
    files, unusable = [], []
    for argument in arguments:
        folder = study_folder(argument)
        if folder is None:
            found = [Path(argument)]
        else:
            found = sorted(folder.glob("case_*.h5"))
            if not found:
                unusable.append(f"{argument}: a study folder without case files (case_NNNNN.h5; an index-only "
                                f"study?): study_table.py {folder / 'index.h5'} reads its index")
        files += [path for path in found if path.resolve() not in {other.resolve() for other in files}]
    return files, unusable


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("files", nargs="+", help="eme_run HDF5 files, or study folders (their case files)")
    parser.add_argument("--markdown", action="store_true", help="print a Markdown table")
    args = parser.parse_args(argv)
    rows, warned = [], []
    files, studies_without_cases = run_files(args.files)
    for message in studies_without_cases:
        print(f"summarize_runs.py: error: {message}", file=sys.stderr)
    unusable = len(studies_without_cases)
    for path in files:
        try:
            row = summarize(path)
        except RunFileError as error:
            print(f"summarize_runs.py: error: {error}", file=sys.stderr)
            unusable += 1
            continue
        rows.append(row)
        if row["warnings"]:
            warned.append(f"{row['file']}: warned: {row['warnings']}")
    columns = table_columns(rows)
    headers = [title for _, title, _ in columns]
    rows = [[cell(row[key], fmt) for key, _, fmt in columns] for row in rows]
    if rows and args.markdown:
        print(markdown_row(headers))
        print("|" + "---|" * len(headers))
        for row in rows:
            print(markdown_row(row))
    elif rows:
        widths = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(headers)]
        print("  ".join(h.ljust(w) for h, w in zip(headers, widths)).rstrip())
        for row in rows:
            print("  ".join(c.ljust(w) for c, w in zip(row, widths)).rstrip())
    if rows and warned:
        print()
        for line in warned:
            print(line)
    return 2 if unusable else 0


if __name__ == "__main__":
    sys.exit(main())
