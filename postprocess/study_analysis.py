"""Analysis of the parameter studies of `make study` (docs/studies.md), and the work precision of
any study against a reference.

  study_analysis.py [--study-dir STUDY_DIR] [-o OUT] [--summary SUMMARY] [--models MODEL ...] [--time cpu|wall]
  study_analysis.py INDEX.h5 [INDEX.h5 ...] --reference REF.h5 [--reference-case N] [--cross-check FILE.h5]
                    [--cross-check-case N] [-o OUT] [--name NAME] [--summary SUMMARY] [--time cpu|wall]

The first reads STUDY_DIR/NAME/index.h5 of every study of the models chosen (MODELS; --models,
default all: the double pendulum's convergence, work-precision and stability studies, the gas
containers' work-precision and stability studies) and the case files the convergence and
work-precision indexes name (the stability studies keep only their index: &study index_only),
and writes to OUT:
  study_convergence        error at t = T against dt, with each fixed-step scheme's fitted order,
                           and the adaptive schemes' error at t = 5 s against their tolerance
  study_work_precision     error at t = 5 s against the solve time (median of the study's
                           repeats), fixed-step schemes over dt, adaptive ones over tolerance:
                           a column of panels per model
  study_structure_cost     energy error and entropy decrease against solve time (paper scene)
  study_stability_map      outcome of every case of the stability studies, a panel per scene
  study_stability_set      the pendulum's harder scene set (stability_sets.py)
(each as .png and .pdf; convergence, structure against cost and the scene set are the
pendulum's, drawn when it is chosen), one HDF5 file SUMMARY with the numbers behind every
figure, and prints the findings as plain lines.

The second charts any study with case files the same way as study_work_precision: the error at
t_end of every complete case of the INDEX.h5 studies against REF.h5 (a run file, or case N of a
study index), the largest difference of any mechanical entry and of any temperature over
theta_ref (the norm is named on the chart), against solve time, into OUT/NAME.png, .pdf and
.txt (NAME: work_precision_ and the first index's folder), its numbers into SUMMARY (default
OUT/NAME.h5). With a cross-check, points within 10 times its distance from the reference are
left out.

The timing charts' time is the CPU time of each case's process over its time loop (the index's
solve_cpu_time_seconds), which waiting for a core does not add to; `--time wall`
charts the time loop's wall time (solve_time_seconds) instead. Their axes and captions say which.
They state in their captions and in SUMMARY the machine's load while their studies ran, from the
STUDY_DIR/NAME.load.json that make study writes around each study (machine_load.py) or else from
the load averages each index records at its study's start and end, and a warning goes to stderr
when the machine was busy.

A scheme is a scheme and thermodynamic variable pair, named as in the paper (EME_theta, MP_u,
TS-midpoint_s, BDF2_theta, RK4_u) with the labels of the integrator registry, which every index
carries (/integrators).
"""
import argparse
import re
import sys
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

import integrators
import machine_load
import stability_sets
import study_plots
from file_checksums import DamagedFileError, check_texts
from plotting import run_script
from study_plots import SCENE_TITLES, curve_keys, key_rank, members, plain_name
from trajectory import THERMODYNAMIC_COLUMN, RunFileError, read_run

# study_convergence_reference.nml: case 1 (temperature variable, tolerance 1e-13) is the
# reference, case 2 (entropy variable, tolerance 1e-12) an independent cross-check of it.
REFERENCE_CASE, CROSS_CHECK_CASE = 1, 2
TEMPERATURE_COLUMNS = ("theta_1", "theta_2")
# Asymptotic range of the order fit: the FIT_POINTS smallest dt (a factor 4 in dt with the
# study's halving) among the errors above MEANINGFUL_FACTOR times the cross-check level;
# errors nearer that level measure the reference, not the scheme.
FIT_POINTS = 3
MEANINGFUL_FACTOR = 100.0
# Stability criteria (inputs/study_stability_*.nml).
ENERGY_TOLERANCE = 1e-6          # energy_drift, relative
LYAPUNOV_TOLERANCE = 1e-8        # max_lyapunov_increment [J]
# Failure reasons, matched in lower case. "no root" is our solver's report that every strategy
# failed (it names the last attempt); PETSc TS reports TS_DIVERGED_NONLINEAR_SOLVE (older
# builds: "TSConvergedReason -1") or rejected steps; the time loop reports a state outside
# the model's domain.
NO_ROOT = "no root"
NONPHYSICAL_REASONS = ("left the model's domain", "blow-up", "non-positive temperature", "nan")
SOLVER_REASONS = ("newton", "diverged", "did not converge", "rejected steps", "halved", "sundials cvode failed")
OUTCOMES = ("kept", "energy", "lyapunov", "solver", "nonphysical")
# Cell flags: V also rose (on a cell whose energy error decides it); the solver's last rejected
# root had a non-positive temperature (on a "no root" failure).
FLAG_LYAPUNOV, FLAG_TEMPERATURE = "V", "T"

# Work-precision (inputs/study_work_precision*.nml, inputs/study_gas_work_precision*.nml): fixed-step
# and adaptive cases at t = 5 against the model's reference study (case 1, cross-checked by case
# 2). Points within WORK_PRECISION_FACTOR of the cross-check level measure the reference and are
# left out; the findings name each scheme's cheapest case that meets each of TARGETS.
WORK_PRECISION = ("work_precision", "work_precision_adaptive", "work_precision_step_control")
WORK_PRECISION_FACTOR = 10.0
TARGETS = (1e-4, 1e-6)


@dataclass(frozen=True)
class ModelStudies:
    """The studies of one model in make study: its work-precision studies (timed) and their
    reference, its stability map's scenes (scene: study), what its summary group and findings
    are called, whether it is nondimensional (units 1, times without s) and its work-precision
    error norm (final_point, state_error), in words and in the figure's math text."""
    title: str
    work_precision: tuple
    reference: str
    scenes: dict
    summary_group: str
    finding_tag: str
    nondimensional: bool
    error_norm: str
    norm_label: str
    # Scenes drawn when their study is there (scene: study): the spring ladder's published scenes
    # (issue 32), whose studies need an eme_run with &model spring_law.
    optional_scenes: tuple = ()


MODELS = {
    "pendulum": ModelStudies(
        title="double pendulum", work_precision=WORK_PRECISION, reference="work_precision_reference",
        scenes={"paper": "stability_paper", "hard": "stability_hard"}, summary_group="work_precision",
        finding_tag="", nondimensional=False,
        error_norm="max(|q, p, gamma - reference| [SI], |theta_a - reference|/theta_ref)",
        norm_label=r"max(|$\Delta q$|, |$\Delta p$|, |$\Delta\gamma$|, |$\Delta\theta_a$|/$\theta_{ref}$)",
        optional_scenes=(("gonzalez", "stability_gonzalez_elastic"), ("romero", "stability_romero_thermoelastic"))),
    # Nondimensional (its units are 1, its temperatures compared unscaled), no momenta (its
    # index has no angular_momentum_drift; read_index gives NaN).
    "gas": ModelStudies(
        title="gas containers", work_precision=tuple(f"gas_{name}" for name in WORK_PRECISION),
        reference="gas_work_precision_reference", scenes={"gas": "gas_stability"},
        summary_group="gas_work_precision", finding_tag=" (gas containers)", nondimensional=True,
        error_norm="max(|q, p - reference|, |theta_a - reference|)",
        norm_label=r"max(|$\Delta q$|, |$\Delta p$|, |$\Delta\theta_a$|)"),
}
# The pendulum's own charts: convergence, structure against cost (of its paper scene), the harder set.
STRUCTURE_SCENE = "paper"
SCENES = {scene: study for model in MODELS.values()
          for scene, study in (*model.scenes.items(), *model.optional_scenes)}
STUDIES = ("convergence", "convergence_reference",
           *(study for model in MODELS.values() for study in (*model.work_precision, model.reference)),
           *(study for model in MODELS.values() for study in model.scenes.values()),
           *(f"stability_{scene}{kind}" for scene in stability_sets.SCENES
                               for kind in ("", "_tolerance")))
INDEX_FIELDS = ("case", "file", "status", "steps_completed", "solve_time_seconds", "energy_drift", "halved_steps")
# Fields a study need not sweep: a row without one takes case 1's value from case_1_input (every
# case shares it but for the swept fields). A study that sweeps no thermodynamic variable has
# "none" (the elastic rung has none): its curves are named by the scheme alone.
SHARED_FIELDS = ("scheme", "dt")
# The timing charts' time (--time): the index column of each kind.
TIME_COLUMNS = {"cpu": "solve_cpu_time_seconds", "wall": "solve_time_seconds"}
# Figures an index has only when its cases' model has them: no angular_momentum_drift without a
# conserved momentum (the gas containers, a planar pendulum with gravity), no thermal figures
# without temperatures (elastic springs). A row lacking one holds NaN, as older indexes did.
MODEL_FIELDS = ("min_entropy_increment", "max_lyapunov_increment", "angular_momentum_drift", "min_temperature")


class StudyError(RunFileError):
    """A study index or case file lacks what the analysis needs, or the studies disagree."""


def read_index(folder):
    """Rows of FOLDER/index.h5 (or of the index file FOLDER names) /cases as dicts (text fields
    decoded), each with its case 'path'."""
    path = Path(folder)
    if path.suffix != ".h5":
        path = path / "index.h5"
    try:
        handle = h5py.File(path, "r")
    except OSError as error:
        raise StudyError(f"{path}: cannot open as a study index ({error})") from None
    with handle:
        try:
            check_texts(handle, path)
        except DamagedFileError as error:
            raise StudyError(str(error)) from None
        if "cases" not in handle:
            raise StudyError(f"{path}: dataset '/cases' is missing")
        cases = handle["cases"][()]
        repeats = int(handle.attrs.get("repeats", 1))       # runs per case; the time is their median
        case_1_input = handle.attrs.get("case_1_input", "")
        if isinstance(case_1_input, bytes):
            case_1_input = case_1_input.decode()
        integrators.register_index(handle)
    missing = [name for name in INDEX_FIELDS if name not in (cases.dtype.names or ())]
    shared = {name: namelist_text_value(case_1_input, name) for name in SHARED_FIELDS
              if name not in (cases.dtype.names or ())}
    missing += [name for name, value in shared.items() if value is None]
    if missing:
        raise StudyError(f"{path}: /cases has no field {', '.join(missing)}")
    if "dt" in shared:
        shared["dt"] = float(shared["dt"].replace("d", "e").replace("D", "e"))
    rows = []
    for case in cases:
        row = {name: case[name].decode() if isinstance(case[name], bytes) else case[name].item()
               for name in cases.dtype.names}
        row.update(shared)
        row.setdefault("thermo_variable", "none")
        for name in MODEL_FIELDS:
            row.setdefault(name, float("nan"))
        # 1: a complete case whose accuracy is in doubt (its file's `warnings`); older indexes: 0.
        row.setdefault("warned", 0)
        if "tolerance" in row:
            row["scheme"] = integrators.tolerance_variant(row["scheme"])
        row["path"] = path.parent / row["file"]
        row["index"] = path
        row["repeats"] = repeats
        row["case_1_input"] = case_1_input
        rows.append(row)
    return rows


def namelist_text_value(text, name):
    """The value of field `name` in namelist text as the code writes it (one field a line), a
    quoted text unquoted; None if the field is not there."""
    match = re.search(rf"^\s*{re.escape(name)}\s*=\s*(.+?)\s*$", text, flags=re.MULTILINE | re.IGNORECASE)
    return match.group(1).strip("'\"") if match else None


def solve_times(rows, kind):
    """The solve times of index rows of the kind chosen (TIME_COLUMNS: 'cpu' or 'wall')."""
    column = TIME_COLUMNS[kind]
    for row in rows:
        if column not in row:
            raise StudyError(f"{row['index']}: /cases has no field {column} (an index written before CPU times "
                             "were recorded): run the study again, or chart wall times with --time wall")
    return np.array([row[column] for row in rows], dtype=float)


def row_by_case(rows, case):
    """The row of case number `case`."""
    for row in rows:
        if row["case"] == case:
            return row
    raise StudyError(f"{rows[0]['index'] if rows else 'index'}: no case {case}")


# ---------------------------------------------------------------- convergence
@dataclass
class FinalPoint:
    """The last state of a run: its mechanical entries (every /state column but the thermodynamic
    variable's, named by `columns`: q, p and gamma of the pendulum, q and p of the gas
    containers), the temperatures, and the scale theta_ref they are compared in."""
    path: Path
    time: float
    mechanical: np.ndarray
    temperatures: np.ndarray
    theta_ref: float
    columns: tuple
    time_units: str = "s"


def final_point(path):
    """The last point of a run file, columns found through the `columns` attributes. Temperatures
    in K are scaled by the root attribute theta_ref; a nondimensional model's (units 1) by 1; a run
    without temperatures (elastic springs) has none and needs no theta_ref."""
    run = read_run(path, ["state"], thermal_datasets=["temperature"])
    if not run.has("temperature"):
        theta_ref = 1.0
    elif run.units.get("temperature") == "1":
        theta_ref = 1.0
    elif "theta_ref" in run.attrs:
        theta_ref = float(run.attrs["theta_ref"])
    else:
        raise RunFileError(f"{path}: root attribute 'theta_ref' is missing")
    if "state" not in run.columns:
        raise RunFileError(f"{path}: dataset /state has no column names: its 'columns' attribute is missing")
    columns = tuple(name for name in run.columns["state"] if not THERMODYNAMIC_COLUMN.fullmatch(name))
    mechanical = np.array([run.column("state", name)[-1] for name in columns])
    temperatures = np.array([run.column("temperature", name)[-1] for name in TEMPERATURE_COLUMNS
                             if run.has("temperature")])
    return FinalPoint(Path(path), float(run.data["time"][-1]), mechanical, temperatures, theta_ref, columns,
                      run.units.get("time", "s"))


def state_error(point, reference):
    """max(|mechanical difference|, |theta_a difference| / theta_ref) at the common end time, the
    mechanical entries matched by name."""
    if abs(point.time - reference.time) > 1e-9 * max(1.0, abs(reference.time)):
        raise StudyError(f"{point.path} ends at t = {point.time:.10g} s but the reference "
                         f"{reference.path} at t = {reference.time:.10g} s: errors need the same T")
    if point.theta_ref != reference.theta_ref:
        raise StudyError(f"{point.path}: theta_ref = {point.theta_ref:g}, the reference "
                         f"{reference.path} has {reference.theta_ref:g}")
    if sorted(point.columns) != sorted(reference.columns):
        raise StudyError(f"{point.path}: /state columns {' '.join(point.columns)}, the reference "
                         f"{reference.path} has {' '.join(reference.columns)}: not the same model")
    mine = point.mechanical[[point.columns.index(name) for name in reference.columns]]
    mechanical = np.max(np.abs(mine - reference.mechanical))
    if point.temperatures.size != reference.temperatures.size:
        raise StudyError(f"{point.path}: {point.temperatures.size} temperatures, the reference "
                         f"{reference.path} has {reference.temperatures.size}: not the same model")
    thermal = (np.max(np.abs(point.temperatures - reference.temperatures)) / reference.theta_ref
               if point.temperatures.size else 0.0)
    return float(max(mechanical, thermal))


def asymptotic_range(dt, error, level):
    """Indices (ascending dt) of the FIT_POINTS smallest dt with error > MEANINGFUL_FACTOR * level."""
    dt, error = np.asarray(dt, float), np.asarray(error, float)
    usable = [i for i in np.argsort(dt) if error[i] > MEANINGFUL_FACTOR * level]
    return np.array(usable[:FIT_POINTS], dtype=int)


def fitted_order(dt, error):
    """Least-squares slope p and constant C of log(error) = log(C) + p log(dt)."""
    if len(dt) < 2:
        return float("nan"), float("nan")
    slope, intercept = np.polyfit(np.log(dt), np.log(error), 1)
    return float(slope), float(np.exp(intercept))


def convergence(study_dir):
    """Errors of every complete convergence case against the reference, and each scheme's fit."""
    reference, cross_check, level = reference_pair(Path(study_dir) / "convergence_reference")
    rows = read_index(Path(study_dir) / "convergence")
    complete = [row for row in rows if row["status"] == "complete"]
    if not complete:
        raise StudyError(f"{Path(study_dir) / 'convergence' / 'index.h5'}: no complete case")
    errors = np.array([state_error(final_point(row["path"]), reference) for row in complete])
    fits = {}
    for key in curve_keys(complete):
        chosen = members(complete, key)
        dt = np.array([complete[i]["dt"] for i in chosen])
        fit = asymptotic_range(dt, errors[chosen], level)
        order, constant = fitted_order(dt[fit], errors[chosen][fit])
        fits[key] = {"order": order, "constant": constant, "dt": dt[fit],
                     "cases": np.array([complete[chosen[i]]["case"] for i in fit], dtype=int)}
    return {"rows": complete, "errors": errors, "fits": fits, "level": level,
            "reference": reference, "cross_check": cross_check,
            "left_out": [row for row in rows if row["status"] != "complete"]}


def reference_pair(folder):
    """(reference, cross-check, level) of a reference study: its cases 1 and 2 and their error."""
    references = read_index(folder)
    reference = final_point(row_by_case(references, REFERENCE_CASE)["path"])
    cross_check = final_point(row_by_case(references, CROSS_CHECK_CASE)["path"])
    return reference, cross_check, state_error(cross_check, reference)


def setting(row):
    """What a work-precision case varies: its tolerance (adaptive schemes) or its dt."""
    return row["tolerance"] if "tolerance" in row else row["dt"]


def work_precision(study_dir, model="pendulum", time_kind="cpu"):
    """Errors at t = 5 of every complete work-precision case of a model (MODELS) against its
    reference, which of them stand clear of the reference's level, their solve times of the kind
    chosen (TIME_COLUMNS), and each scheme's cheapest case per target."""
    studies = MODELS[model]
    reference, cross_check, level = reference_pair(Path(study_dir) / studies.reference)
    rows, left_out = split_complete(read_index(Path(study_dir) / folder) for folder in studies.work_precision)
    if not rows:
        raise StudyError(f"{Path(study_dir)}: no complete work-precision case of the {studies.title}")
    return work_precision_result(rows, left_out, reference, cross_check, level, time_kind, model=model,
                                 title=studies.title, norm=studies.error_norm, norm_label=studies.norm_label,
                                 finding_tag=studies.finding_tag, summary_group=studies.summary_group,
                                 end=f"t = {reference.time:g}" + ("" if studies.nondimensional else " s"))


def split_complete(indexes):
    """The rows of several indexes (each a list of rows), split: (the complete ones, the others)."""
    rows, left_out = [], []
    for index_rows in indexes:
        for row in index_rows:
            (rows if row["status"] == "complete" else left_out).append(row)
    return rows, left_out


def work_precision_result(rows, left_out, reference, cross_check, level, time_kind, **described):
    """The work-precision figure's numbers of complete cases against a reference: errors, which
    of them stand clear of the cross-check's level (all non-zero ones without a cross-check:
    level None), the solve times of the kind chosen, each scheme's cheapest case per target; with
    `described` (model, title, norm, norm_label, finding_tag, end, summary_group, figure) as the
    figure, findings and summary name them."""
    errors = np.array([state_error(final_point(row["path"]), reference) for row in rows])
    shown = errors >= WORK_PRECISION_FACTOR * level if level is not None else errors > 0
    time = solve_times(rows, time_kind)
    cheapest = {}
    for key in curve_keys(rows):
        for target in TARGETS:
            meeting = [i for i in members(rows, key) if shown[i] and errors[i] <= target]
            if meeting:
                cheapest[key, target] = min(meeting, key=lambda i: time[i])
    return {"rows": rows, "errors": errors, "shown": shown, "level": level, "reference": reference,
            "cross_check": cross_check, "left_out": left_out, "cheapest": cheapest, "time": time,
            "time_kind": time_kind, "model": None, "finding_tag": "", "summary_group": "work_precision",
            "figure": "study_work_precision", **described}


# ---------------------------------------------------------------- structure and stability
def entropy_violation(min_entropy_increment):
    """The largest entropy decrease in one step, max(0, -min_n (S_{n+1} - S_n)) [J/K]."""
    return np.maximum(0.0, -np.asarray(min_entropy_increment, dtype=float))


def temperatures_positive(min_temperature):
    """True when the case's lowest temperature (the index's min_temperature, NaN once a
    temperature was not finite) is finite and positive."""
    return bool(np.isfinite(min_temperature) and min_temperature > 0)


def classify(status, energy_drift, max_lyapunov_increment, positive_temperatures=True):
    """(outcome, flags) of one case; outcome is one of OUTCOMES.

    Precedence: a failed case is a failure whatever its metrics before the failure; among
    failures "no root" (our solver rejected or missed every root, so no state left the domain)
    is a solver failure, flagged T when the last root it rejected had a non-positive
    temperature; then a non-physical state or blow-up; then Newton divergence. A finished case
    with a non-positive or non-finite temperature, or non-finite metrics, is non-physical; else
    an energy error > ENERGY_TOLERANCE decides (flagged V when V also rose), then V rising
    by more than LYAPUNOV_TOLERANCE; otherwise everything was kept."""
    reason = status.lower()
    if status.startswith("failed"):
        if NO_ROOT in reason:
            return "solver", FLAG_TEMPERATURE if "non-positive temperature" in reason else ""
        if any(text in reason for text in NONPHYSICAL_REASONS):
            return "nonphysical", ""
        if any(text in reason for text in SOLVER_REASONS):
            return "solver", ""
        raise StudyError(f"unknown failure reason: {status!r}")
    if status != "complete":
        raise StudyError(f"a case is neither complete nor failed (status {status!r}): "
                         "finish the study first")
    if not (positive_temperatures and np.isfinite(energy_drift) and np.isfinite(max_lyapunov_increment)):
        return "nonphysical", ""
    lyapunov_rose = max_lyapunov_increment > LYAPUNOV_TOLERANCE
    if energy_drift > ENERGY_TOLERANCE:
        return "energy", FLAG_LYAPUNOV if lyapunov_rose else ""
    return ("lyapunov" if lyapunov_rose else "kept"), ""


def without_temperatures(row):
    """True for a study of elastic springs (its case_1_input's spring_law): no temperatures to
    check and no V beside E (V = E), so its cells are judged by the energy alone."""
    return bool(re.search(r"^\s*spring_law\s*=\s*'elastic'", row.get("case_1_input", ""),
                          flags=re.MULTILINE | re.IGNORECASE))


def stability_map(rows, nondimensional=False):
    """Outcome grid of one stability study: rows = schemes, columns = dt (-1 where not run); a
    nondimensional model's (units 1) says so. A study of elastic springs has no temperatures to
    check and no V of its own: its lyapunov figures, NaN in the index, are not held against it."""
    keys = curve_keys(rows)
    steps = sorted({row["dt"] for row in rows})
    outcome = np.full((len(keys), len(steps)), -1, dtype=int)
    flags = np.full(outcome.shape, "", dtype=object)
    case = np.zeros(outcome.shape, dtype=int)
    failed_at = np.full(outcome.shape, np.nan)   # end time of the step that failed [s]
    status = np.full(outcome.shape, "", dtype=object)
    energy, lyapunov = np.full(outcome.shape, np.nan), np.full(outcome.shape, np.nan)
    positive_grid = np.full(outcome.shape, -1, dtype=int)    # 1 / 0: checked; -1: not checked
    halved = np.zeros(outcome.shape, dtype=int)
    checked = 0
    for row in rows:
        i, j = keys.index((row["scheme"], row["thermo_variable"])), steps.index(row["dt"])
        if case[i, j]:
            raise StudyError(f"{row['index']}: cases {case[i, j]} and {row['case']} are both "
                             f"{plain_name(*keys[i])} at dt = {row['dt']:g} s")
        positive = True
        halved[i, j] = row["halved_steps"]
        mechanical = without_temperatures(row)
        if row["status"] == "complete" and not mechanical:
            positive = temperatures_positive(row["min_temperature"])
            positive_grid[i, j] = int(positive)
            checked += 1
        lyapunov_increment = row["max_lyapunov_increment"]
        if mechanical and not np.isfinite(lyapunov_increment):
            lyapunov_increment = 0.0            # V = E: the energy error decides
        name, flag = classify(row["status"], row["energy_drift"], lyapunov_increment, positive)
        outcome[i, j], flags[i, j], case[i, j] = OUTCOMES.index(name), flag, row["case"]
        status[i, j], energy[i, j], lyapunov[i, j] = (row["status"], row["energy_drift"],
                                                      row["max_lyapunov_increment"])
        if row["status"].startswith("failed"):
            failed_at[i, j] = (row["steps_completed"] + 1) * row["dt"]
    return {"keys": keys, "dt": np.array(steps), "outcome": outcome, "flags": flags, "case": case,
            "failed_at": failed_at, "status": status, "energy_drift": energy,
            "max_lyapunov_increment": lyapunov, "temperatures_positive": positive_grid,
            "temperatures_checked": checked, "halved": halved,
            "source": rows[0]["index"].parent if rows else "-",
            "scene": scene_description(rows[0]) if rows else "-", "nondimensional": nondimensional}


def namelist_values(text, name):
    """The values of field `name` in namelist text as the code writes it (one field a line,
    'name = v1, v2'), as floats; [] if the field is not there."""
    match = re.search(rf"^\s*{re.escape(name)}\s*=\s*(.+?)\s*$", text, flags=re.MULTILINE | re.IGNORECASE)
    return namelist_numbers(match.group(1)) if match else []


def namelist_numbers(value_text):
    """A namelist list of reals as floats, `r*x` standing for r copies of x (the repeat count the
    code writes runs of equal values with: 'theta = 3*300.0, 310.0')."""
    numbers = []
    for item in value_text.split(","):
        count, _, number = item.strip().rpartition("*")
        numbers += [float(number.replace("d", "e").replace("D", "e"))] * (int(count) if count else 1)
    return numbers


def namelist_group(text, group):
    """The fields of one group of namelist text as the code writes it ('&group', one field a
    line, '/'), each as 'name = value', or [] if the group is not there."""
    match = re.search(rf"^\s*&{re.escape(group)}\s*$(.*?)^\s*/\s*$", text,
                      flags=re.MULTILINE | re.DOTALL | re.IGNORECASE)
    return [line.strip() for line in match.group(1).splitlines() if line.strip()] if match else []


def scene_description(row):
    """Interval and initial state of a study's scene, from its index's case_1_input (every case
    shares all but the swept fields), so a study without case files has one too: the pendulum's
    p2 and theta with their units, another model's name, parameters and &initial as written."""
    text = row["case_1_input"]
    t_end, p2, theta = (namelist_values(text, name) for name in ("t_end", "p2", "theta"))
    model = namelist_group(text, "model")
    if not t_end or not (p2 and theta or model):
        raise StudyError(f"{row['index']}: attribute case_1_input lacks t_end, or the pendulum's p2 and "
                         "theta and a &model group")
    if p2 and theta:
        return (f"[0, {t_end[0]:g}] s, p2(0) = ({', '.join(f'{v:g}' for v in p2)}) N s, theta(0) = "
                f"({', '.join(f'{v:g}' for v in theta)}) K")
    fields = [field.split("=", 1) for field in model + namelist_group(text, "initial")]
    return f"[0, {t_end[0]:g}], " + ", ".join(
        f"{name.strip()} = " + (f"({value.strip()})" if "," in value else value.strip()) for name, value in fields)


def structure_cost(rows, time_kind="cpu"):
    """Complete cases of one study: solve time (of the kind chosen), energy error and entropy
    violation per scheme."""
    complete = [row for row in rows if row["status"] == "complete"]
    return {"rows": complete, "time_kind": time_kind,
            "solve_time": solve_times(complete, time_kind),
            "energy": np.array([row["energy_drift"] for row in complete]),
            "violation": entropy_violation([row["min_entropy_increment"] for row in complete])}


# ---------------------------------------------------------------- summary file and findings
def write_dataset(group, name, values, units, description):
    """One dataset with its units and description attributes; text as UTF-8 strings."""
    values = np.asarray(values)
    if values.dtype.kind in "UO":
        values = np.array([str(v) for v in values.ravel()], dtype=h5py.string_dtype()).reshape(values.shape)
    dataset = group.create_dataset(name, data=values)
    dataset.attrs["units"] = units
    dataset.attrs["description"] = description


def timed_charts(models):
    """The timing charts of the chosen models and the studies each one times."""
    charts = {"study_work_precision": tuple(study for model in models for study in MODELS[model].work_precision)}
    if "pendulum" in models:
        charts["study_structure_cost"] = (SCENES[STRUCTURE_SCENE],)
    return charts


def study_loads(study_dir, charts):
    """The machine's load while the timed studies ran, per timing chart ({chart: studies}): a
    MachineLoad over its studies (the highest loads), or None when a study has none recorded."""
    return {chart: studies_load(Path(study_dir) / name for name in names) for chart, names in charts.items()}


def studies_load(folders):
    """The highest load over studies (their folders), each from the NAME.load.json beside its
    folder (make study records it around the study's mpirun) or else from its index (eme_ensemble
    records it at the study's start and end); None when a study has neither."""
    records = []
    for folder in folders:
        record = machine_load.read(folder.parent / f"{folder.name}.load.json")
        if record is None and (folder / "index.h5").exists():
            record = machine_load.from_index(folder / "index.h5")
        records.append(record)
    return None if None in records else machine_load.combined(records)


def load_caption(load, names):
    """The caption line of a timing chart's machine load."""
    if load is None:
        return (f"Machine load: not recorded (no {', '.join(f'{name}.load.json' for name in names)} beside the "
                "studies, as make study writes, and no load averages in their indexes, as eme_ensemble writes at "
                "a study's end): the timings' conditions are unknown.")
    return f"Studies {', '.join(names)}: {load.text()}."


def write_summary(path, conv, wps, structure, maps, sets, loads=None):
    """The numbers behind every figure, one group per figure (per model for work precision, per
    scene for the stability map); the timing groups carry the machine's load as attributes
    (load_recorded 0 when it was not). conv, structure and sets may be None (pendulum not chosen)."""
    loads = loads or {}
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with h5py.File(path, "w") as f:
        f.attrs["description"] = "numbers behind the study figures of postprocess/study_analysis.py"
        if conv is not None:
            write_convergence(f.create_group("convergence"), conv)
        for model, wp in wps.items():
            g = f.create_group(wp["summary_group"])
            write_work_precision(g, wp)
            write_load(g, loads.get("study_work_precision"))
        if structure is not None:
            g = f.create_group("structure_cost")
            write_structure(g, structure)
            write_load(g, loads.get("study_structure_cost"))
        for scene, grid in maps.items():
            write_stability(f.create_group(f"stability/{scene}"), scene, grid)
        if sets is not None:
            stability_sets.write_summary(f, sets, write_dataset)
    print(f"wrote {path}")


def write_convergence(g, conv):
    """The convergence figure's numbers."""
    rows = conv["rows"]
    g.attrs["description"] = ("error at t = T against the reference, and against solve time "
                              "(figures study_convergence, study_work_precision)")
    write_dataset(g, "scheme", [plain_name(row["scheme"], row["thermo_variable"]) for row in rows], "1",
                  "scheme and thermodynamic variable of each case")
    write_dataset(g, "case", [row["case"] for row in rows], "1", "case number in convergence/index.h5")
    write_dataset(g, "dt", [row["dt"] for row in rows], "s", "time step")
    write_dataset(g, "error", conv["errors"], "1", "max(|q, p, gamma - reference| [SI], "
                  "|theta_a - reference|/theta_ref) at t = T")
    write_times(g, rows, "the time loop of the case")
    write_dataset(g, "end_time", conv["reference"].time, "s", "T, where errors are taken")
    write_dataset(g, "cross_check_level", conv["level"], "1",
                  "the same error norm between the cross-check and the reference")
    fit_names = [plain_name(*key) for key in conv["fits"]]
    fits = list(conv["fits"].values())
    write_dataset(g, "fit_scheme", fit_names, "1", "scheme of each fitted order")
    write_dataset(g, "fitted_order", [fit["order"] for fit in fits], "1",
                  f"least-squares slope of log(error) on log(dt) over the {FIT_POINTS} smallest dt "
                  f"with error > {MEANINGFUL_FACTOR:g} x cross_check_level")
    write_dataset(g, "fit_constant", [fit["constant"] for fit in fits], "1", "C of error = C dt^order")
    write_dataset(g, "fit_dt_min", [fit["dt"].min() if len(fit["dt"]) else np.nan for fit in fits], "s",
                  "smallest dt of the fit")
    write_dataset(g, "fit_dt_max", [fit["dt"].max() if len(fit["dt"]) else np.nan for fit in fits], "s",
                  "largest dt of the fit")


def write_work_precision(g, wp):
    """One model's work-precision numbers."""
    wrows, title, end = wp["rows"], wp["title"], wp["end"]
    g.attrs["description"] = (f"{title}: error at {end} against the reference, and against solve time "
                              f"(figure {wp['figure']}"
                              + ("; right panel of study_convergence)" if wp["model"] == "pendulum" else ")"))
    g.attrs["chart_time"] = f"{wp['time_kind']}: {study_plots.TIME_AXES[wp['time_kind']][1]}"
    write_dataset(g, "scheme", [plain_name(r["scheme"], r["thermo_variable"]) for r in wrows], "1",
                  "scheme and thermodynamic variable of each case")
    write_dataset(g, "study", [r["index"].parent.name for r in wrows], "1", "the study of each case")
    write_dataset(g, "case", [r["case"] for r in wrows], "1", "case number in the study's index.h5")
    write_dataset(g, "dt", [r["dt"] for r in wrows], "s", "time step (adaptive schemes: output interval)")
    write_dataset(g, "tolerance", [r.get("tolerance", np.nan) for r in wrows], "1",
                  "tolerance of an adaptive scheme (NaN for fixed-step schemes)")
    write_dataset(g, "error", wp["errors"], "1", f"{wp['norm']} at {end}")
    write_dataset(g, "shown", wp["shown"].astype(int), "1",
                  f"1: error >= {WORK_PRECISION_FACTOR:g} x cross_check_level, drawn in the figure"
                  if wp["level"] is not None else "1: error > 0, drawn in the figure (no cross-check)")
    write_times(g, wrows, "the time loop of the case (median of the repeats)")
    write_dataset(g, "energy_drift", [r["energy_drift"] for r in wrows], "1", "max_n |E_n - E_0| / |E_0|")
    if wp["level"] is not None:
        write_dataset(g, "cross_check_level", wp["level"], "1",
                      "the same error norm between the cross-check and the reference")


def write_times(g, rows, what):
    """The rows' solve times, wall and (where the index has them) CPU, as the index gives them."""
    write_dataset(g, "solve_time_seconds", [row["solve_time_seconds"] for row in rows], "s",
                  f"solve_time_seconds of the index: the wall time of {what}")
    if all(TIME_COLUMNS["cpu"] in row for row in rows):
        write_dataset(g, "solve_cpu_time_seconds", [row[TIME_COLUMNS["cpu"]] for row in rows], "s",
                      f"solve_cpu_time_seconds of the index: the CPU time of the case's process over {what}")


def write_structure(g, structure):
    """The structure-against-cost figure's numbers (the pendulum's paper scene)."""
    g.attrs["description"] = "complete cases of stability_paper (figure study_structure_cost)"
    srows = structure["rows"]
    write_dataset(g, "scheme", [plain_name(r["scheme"], r["thermo_variable"]) for r in srows], "1",
                  "scheme and thermodynamic variable of each case")
    write_dataset(g, "case", [r["case"] for r in srows], "1", "case number in stability_paper/index.h5")
    write_dataset(g, "dt", [r["dt"] for r in srows], "s", "time step")
    write_times(g, srows, "the time loop of the case")
    g.attrs["chart_time"] = f"{structure['time_kind']}: {study_plots.TIME_AXES[structure['time_kind']][1]}"
    write_dataset(g, "energy_drift", structure["energy"], "1", "max_n |E_n - E_0| / |E_0|")
    write_dataset(g, "entropy_violation", structure["violation"], "J/K",
                  "max(0, -min_n (S_{n+1} - S_n)): the largest entropy decrease in a step")
    write_dataset(g, "plot_floor", study_plots.LOG_FLOOR, "1 (energy), J/K (entropy)",
                  "values below it, exact zeros included, are drawn at it on the log axes")


def write_stability(g, scene, grid):
    """One scene's panel of the stability map, in its model's units."""
    energy_unit, time_unit = ("1", "1") if grid["nondimensional"] else ("J", "s")
    g.attrs["description"] = (f"outcome of each case of {SCENES[scene]} (figure study_stability_map); "
                              "rows: scheme, columns: dt")
    write_dataset(g, "scheme", [plain_name(*key) for key in grid["keys"]], "1", "row: scheme")
    write_dataset(g, "dt", grid["dt"], time_unit, "column: time step")
    write_dataset(g, "outcome", grid["outcome"], "1", "index into outcome_names; -1: not run")
    write_dataset(g, "outcome_names", [study_plots.OUTCOME_TEXT[o] for o in OUTCOMES], "1",
                  "outcome classes, in the order of the outcome codes")
    write_dataset(g, "flags", grid["flags"], "1", f"{FLAG_LYAPUNOV}: V also rose; "
                  f"{FLAG_TEMPERATURE}: the last root the solver rejected had a non-positive temperature")
    write_dataset(g, "case", grid["case"], "1", f"case number in {SCENES[scene]}/index.h5")
    write_dataset(g, "failed_at", grid["failed_at"], time_unit, "end time of the step that failed (NaN: finished)")
    write_dataset(g, "status", grid["status"], "1", "status of the case in the index")
    write_dataset(g, "energy_drift", grid["energy_drift"], "1",
                  f"max_n |E_n - E_0| / |E_0| over the completed steps; kept: <= {ENERGY_TOLERANCE:g}")
    write_dataset(g, "max_lyapunov_increment", grid["max_lyapunov_increment"], energy_unit,
                  f"max_n (V_{{n+1}} - V_n) over the completed steps; kept: <= {LYAPUNOV_TOLERANCE:g} {energy_unit}")
    write_dataset(g, "temperatures_positive", grid["temperatures_positive"], "1",
                  "1: every temperature of the finished case was finite and > 0 (the index's "
                  "min_temperature); 0: not; -1: not checked (failed case, or not run)")
    write_dataset(g, "halved_steps", grid["halved"], "1",
                  "failed attempts replaced by two halves (EME and the midpoint rule, the relaxed "
                  "Runge-Kutta schemes; the index's halved_steps)")
    write_dataset(g, "kept_count", (grid["outcome"] == 0).sum(axis=1), "1",
                  "dt values at which the scheme finished with everything kept")


def write_load(group, load):
    """The machine's load during the group's timings as attributes of the group."""
    group.attrs["load_recorded"] = int(load is not None)
    if load is not None:
        for name, value in load.attributes().items():
            group.attrs[name] = value
        group.attrs["load_description"] = load.text()


def convergence_findings(conv):
    """The convergence study's findings."""
    reference, cross_check = conv["reference"], conv["cross_check"]
    lines = [f"convergence: reference {reference.path} at T = {reference.time:g} s; cross-check "
             f"{cross_check.path}: |reference - cross-check| = {conv['level']:.2e}"]
    lines += [f"convergence: left out (not complete): case {row['case']} {row['status']}"
              for row in conv["left_out"]]
    for key, fit in conv["fits"].items():
        finest = members(conv["rows"], key)[0]
        lines.append(f"convergence {plain_name(*key)}: fitted order {fit['order']:.2f} over dt = "
                     + ", ".join(f"{dt:g}" for dt in fit["dt"]) + f" s; error {conv['errors'][finest]:.2e} "
                     f"at dt = {conv['rows'][finest]['dt']:g} s in {conv['rows'][finest]['solve_time_seconds']:.2e} s "
                     "(wall)")
    return lines


def work_precision_findings(wp):
    """One model's work-precision findings: each scheme's cheapest case per target."""
    prefix = f"work precision{wp['finding_tag']}"
    lines = [f"{prefix}: reference {wp['reference'].path} at {wp['end']}; "
             + (f"cross-check {wp['cross_check'].path}: |reference - cross-check| = {wp['level']:.2e}"
                if wp["level"] is not None else "no cross-check")
             + f"; times: {study_plots.TIME_AXES[wp['time_kind']][0]}"]
    wrows, cheapest, time = wp["rows"], wp["cheapest"], wp["time"]
    for target in TARGETS:
        for key in curve_keys(wrows):
            if (key, target) not in cheapest:
                lines.append(f"{prefix} {plain_name(*key)}: no case reached {target:.0e}")
                continue
            i = cheapest[key, target]
            text = (f"{prefix} {plain_name(*key)}: error <= {target:.0e} at "
                    f"{'tolerance' if 'tolerance' in wrows[i] else 'dt'} {setting(wrows[i]):g}: error "
                    f"{wp['errors'][i]:.2e} in {time[i]:.2e} s, energy error {wrows[i]['energy_drift']:.1e}")
            for anchor in (("cvode_bdf", "temperature"), ("eme", "temperature")):
                if (anchor, target) in cheapest:
                    ratio = time[i] / time[cheapest[anchor, target]]
                    text += f"; {ratio:.3g} x {plain_name(*anchor)}'s time"
            lines.append(text)
    return lines


def structure_findings(structure):
    """The paper scene's structure against cost, per scheme."""
    srows = structure["rows"]
    lines = []
    for key in curve_keys(srows):
        chosen = members(srows, key)
        lines.append(f"structure (paper scene, {len(chosen)} finished cases) {plain_name(*key)}: max energy "
                     f"error {structure['energy'][chosen].max():.2e}, max entropy decrease "
                     f"{structure['violation'][chosen].max():.2e} J/K")
    return lines


def stability_findings(maps):
    """Per scheme the dt it kept everything at on each scene; every failed case; per scene the counts."""
    lines = []
    for key in sorted({key for grid in maps.values() for key in grid["keys"]}, key=key_rank):
        parts = []
        for scene, grid in maps.items():
            row = grid["outcome"][grid["keys"].index(key)] if key in grid["keys"] else np.array([])
            parts.append(f"{(row == 0).sum()} of {(row >= 0).sum()} dt ({SCENE_TITLES[scene]})")
        lines.append(f"stability {plain_name(*key)}: finished with everything kept at " + ", ".join(parts))
    for scene, grid in maps.items():
        for i, j in zip(*np.nonzero(np.isfinite(grid["failed_at"]))):
            flag = f" ({grid['flags'][i, j]})" if grid["flags"][i, j] else ""
            unit = "" if grid["nondimensional"] else " s"
            lines.append(f"stability {SCENE_TITLES[scene]}: {plain_name(*grid['keys'][i])} at dt = {grid['dt'][j]:g}{unit} "
                         f"failed in the step ending at t = {grid['failed_at'][i, j]:g}{unit}: "
                         f"{OUTCOMES[grid['outcome'][i, j]]}{flag} (case {grid['case'][i, j]})")
        counts = ", ".join(f"{o} {(grid['outcome'] == k).sum()}" for k, o in enumerate(OUTCOMES))
        lines.append(f"stability {SCENE_TITLES[scene]}: {counts}; temperatures checked in "
                     f"{grid['temperatures_checked']} finished cases")
    return lines


def stability_scenes(study_dir, model):
    """(scene, study folder) pairs of a model's stability map: its scenes, then its optional scenes
    whose study index is in study_dir (the spring ladder's, once issue 32's eme_run made them)."""
    return [*MODELS[model].scenes.items(),
            *((scene, folder) for scene, folder in MODELS[model].optional_scenes
              if (Path(study_dir) / folder / "index.h5").exists())]


def analyse(study_dir, models, time_kind="cpu"):
    """(conv, wps, structure, maps, sets) of the chosen models' studies: the convergence study, the
    work precision of each model ({model: result}), structure against cost, the stability map's
    grids ({scene: grid}) and the harder scene set; conv, structure and sets are the pendulum's,
    None when it is not chosen. The timing charts' time is of the kind chosen (TIME_COLUMNS)."""
    study_dir = Path(study_dir)
    pendulum = "pendulum" in models
    conv = convergence(study_dir) if pendulum else None
    wps = {model: work_precision(study_dir, model, time_kind) for model in models}
    structure = structure_cost(read_index(study_dir / SCENES[STRUCTURE_SCENE]), time_kind) if pendulum else None
    maps = {scene: stability_map(read_index(study_dir / folder), MODELS[model].nondimensional)
            for model in models for scene, folder in stability_scenes(study_dir, model)}
    sets = stability_sets.analyse(study_dir, read_index, classify, temperatures_positive) if pendulum else None
    return conv, wps, structure, maps, sets


# ---------------------------------------------------------------- any study against a reference
def solution_point(path, case):
    """The final point of a solution given as a run file, or as case `case` of a study index."""
    path = Path(path)
    try:
        with h5py.File(path, "r") as handle:
            is_index = "cases" in handle
    except OSError as error:
        raise StudyError(f"{path}: cannot open as an HDF5 file ({error})") from None
    if not is_index:
        return final_point(path)
    row = row_by_case(read_index(path), case)
    if row["status"] != "complete":
        raise StudyError(f"{path}: case {case} is not complete ({row['status']}): it cannot be the reference")
    if not row["file"]:
        raise StudyError(f"{path}: an index-only study keeps no case files: case {case} has no final state")
    return final_point(row["path"])


GREEK = ("alpha", "beta", "gamma", "theta", "lambda", "mu")       # column names drawn as their letter


def error_metric(reference):
    """state_error's norm for the model of `reference` (a FinalPoint), in words and as the chart's
    math text: the largest difference of any mechanical entry, and of any temperature scaled by
    theta_ref (unscaled when theta_ref is 1: a nondimensional model's)."""
    groups = list(dict.fromkeys(re.match(r"[A-Za-z]*", name).group(0) or name for name in reference.columns))
    words = f"max over the {len(reference.columns)} mechanical entries ({', '.join(groups)}) of |z - z_ref|"
    symbols = [rf"|$\Delta\{group}$|" if group in GREEK else rf"|$\Delta {group}$|" for group in groups]
    if reference.temperatures.size and reference.theta_ref != 1.0:
        words += (" and over the temperatures of |theta_a - theta_a,ref| / theta_ref (theta_ref = "
                  f"{reference.theta_ref:g} K)")
        symbols.append(r"|$\Delta\theta_a$|/$\theta_{ref}$")
    elif reference.temperatures.size:
        words += " and over the temperatures of |theta_a - theta_a,ref| (unscaled)"
        symbols.append(r"|$\Delta\theta_a$|")
    return words, f"max({', '.join(symbols)})"


def any_study(args):
    """The work-precision chart, summary and findings of the studies args.indexes names against
    args.reference (and args.cross_check), on the time args.time."""
    folders = [Path(path).parent if Path(path).suffix == ".h5" else Path(path) for path in args.indexes]
    rows, left_out = split_complete(read_index(path) for path in args.indexes)
    if not rows:
        raise StudyError(f"{', '.join(map(str, args.indexes))}: no complete case")
    for row in rows:
        if not row["file"]:
            raise StudyError(f"{row['index']}: an index-only study keeps no case files: its cases' errors cannot "
                             "be computed (run it with &study index_only = .false.)")
    reference = solution_point(args.reference, args.reference_case)
    cross_check = solution_point(args.cross_check, args.cross_check_case) if args.cross_check else None
    level = state_error(cross_check, reference) if cross_check else None
    norm, norm_label = error_metric(reference)
    model = namelist_text_value(rows[0]["case_1_input"], "model_name") or "model"
    name = args.name or f"work_precision_{folders[0].name}"
    wp = work_precision_result(
        rows, left_out, reference, cross_check, level, args.time, figure=name,
        title=f"{model.replace('_', ' ')}: {', '.join(folder.name for folder in folders)}", norm=norm,
        norm_label=norm_label, end=f"t = {reference.time:g}" + ("" if reference.time_units == "1" else
                                                                 f" {reference.time_units}"))
    load = studies_load(folders)
    output = Path(args.output)
    study_plots.save_chart(output / name, study_plots.work_precision_figure({name: wp}, WORK_PRECISION_FACTOR),
                           load_caption(load, [str(folder) for folder in folders]))
    write_summary(args.summary or output / f"{name}.h5", None, {name: wp}, None, {}, None,
                  {"study_work_precision": load})
    if load is not None and load.busy:
        print(f"study_analysis.py: {name}: {load.warning()}", file=sys.stderr)
    for line in work_precision_findings(wp):
        print(line)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("indexes", nargs="*", metavar="INDEX.h5",
                        help="study indexes (or their folders) of any study with case files: chart their complete "
                        "cases' error against --reference over their solve time, instead of make study's studies")
    parser.add_argument("--reference", metavar="REF.h5",
                        help="with INDEX.h5: the reference solution, a run file or a study index (its case "
                        "--reference-case)")
    parser.add_argument("--reference-case", type=int, default=1, metavar="N",
                        help="the reference's case when REF.h5 is an index (default: %(default)s)")
    parser.add_argument("--cross-check", metavar="FILE.h5",
                        help="with INDEX.h5: an independent second solution (run file or index, its case "
                        "--cross-check-case); its distance from the reference is drawn as a level, and points "
                        f"within {WORK_PRECISION_FACTOR:g} times it are left out")
    parser.add_argument("--cross-check-case", type=int, default=1, metavar="N",
                        help="the cross-check's case when FILE.h5 is an index (default: %(default)s)")
    parser.add_argument("--name", metavar="NAME",
                        help="with INDEX.h5: the chart's file name in OUT (default: work_precision_ and the first "
                        "index's folder name)")
    parser.add_argument("--time", choices=tuple(TIME_COLUMNS), default="cpu",
                        help="the timing charts' time: cpu, the CPU time of the case's process over its time loop "
                        "(default; waiting for a core that other work holds does not add to it), or wall, the time "
                        "loop's wall time")
    parser.add_argument("--study-dir", default="results/study", metavar="STUDY_DIR",
                        help="folder holding the study folders (default: %(default)s)")
    parser.add_argument("-o", "--output", default="results/figures", metavar="OUT",
                        help="folder for the figures (default: %(default)s)")
    parser.add_argument("--summary", metavar="SUMMARY",
                        help="HDF5 file of the numbers behind the figures (default: results/study/summary.h5; with "
                        "INDEX.h5, OUT/NAME.h5)")
    parser.add_argument("--models", nargs="+", choices=list(MODELS), default=list(MODELS), metavar="MODEL",
                        help="the models whose studies to analyse, of " + ", ".join(MODELS)
                        + " (default: all; each needs every one of its studies)")
    args = parser.parse_args(argv)
    if bool(args.indexes) != bool(args.reference):
        parser.error("INDEX.h5 and --reference go together: a study is charted against a reference")
    if args.indexes:
        any_study(args)
        return
    study_dir, output = Path(args.study_dir), Path(args.output)
    models = [model for model in MODELS if model in args.models]
    pendulum = "pendulum" in models
    conv, wps, structure, maps, sets = analyse(study_dir, models, args.time)
    charts = timed_charts(models)
    loads = study_loads(study_dir, charts)
    load_lines = {chart: load_caption(loads[chart], names) for chart, names in charts.items()}
    study_plots.save_all(output, conv, wps, structure, maps, fit_rule=(FIT_POINTS, MEANINGFUL_FACTOR),
                         work_precision_factor=WORK_PRECISION_FACTOR, load_lines=load_lines)
    if pendulum:
        stability_sets.figure(sets, output / "study_stability_set")
    write_summary(args.summary or "results/study/summary.h5", conv, wps, structure, maps, sets, loads)
    for chart, load in loads.items():
        if load is not None and load.busy:
            print(f"study_analysis.py: {chart}: {load.warning()}", file=sys.stderr)
    lines = [*(convergence_findings(conv) if pendulum else []),
             *(line for wp in wps.values() for line in work_precision_findings(wp)),
             *(structure_findings(structure) if pendulum else []), *stability_findings(maps),
             *(stability_sets.findings(sets) if pendulum else [])]
    for line in lines:
        print(line)


if __name__ == "__main__":
    run_script(main)
