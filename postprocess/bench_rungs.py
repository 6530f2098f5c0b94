#!/usr/bin/env python3
"""Issue 32 item 4: the cost per step of each rung of the pendulum's ladder beside the full model
(make bench).

Every rung is the paper's Table 1 data integrated as inputs/paper_fig4_eme_theta.nml does (EME,
thermo_variable 'temperature' (EME_theta), Gonzalez's discrete gradient, dt = 0.15 s, newton_tol
1e-8), the namelist being that file's with a &model and an &initial group in front:
  full                       the paper scene as it is: spatial, thermoviscoelastic, gravity (0, 0,
                             -9.81); 15 unknowns; its EME step runs the fused, hand-optimised kernel
                             (src/model/pendulum/pendulum_step_kernel.f90), as every thermal rung's does
  spatial_thermoelastic      spring_law = 'thermoelastic': the same initial state without gamma; 14
  planar_thermoviscoelastic  dimension = 2: the x and y components of the paper's initial state (q1 =
                             (1, 0), q2 = (3, 0), p1 = (0, 0), p2 = (-1, -1)), gravity (0, -9.81); 11
  planar_thermoelastic       both; 10 unknowns
  spatial_elastic            spring_law = 'elastic': no thermal unknowns (springs of stiffness
                             mu_eq_const, no thermo_variable); 12 unknowns, the generic path (the
                             fused kernel is written for thermal springs)
  planar_elastic             elastic and planar; 8 unknowns
  full_generic               not a rung: the full model with -eme_fused_kernel false, the generic path
                             (src/scheme/step_residual.f90 through the model interface) that the
                             reduced rungs took before the kernel served them (the elastic rung's
                             still), so that the fused kernel's worth shows beside them
The scenes share their data, not their motion: with gravity along z the spatial pendulum starts
swinging out of the x-y plane of its initial state, while the planar one falls in its plane under
gravity along -y, and the thermoelastic springs lose the viscous branch's dissipation. Their
Newton iterations per step differ a little, so each cost is printed beside its Newton iterations
per step and divided by them too (per Newton iteration).

Before measuring, each scene is run to t = 10 s and its file must have the rung's spring_law,
dimension and state columns (15, 14, 11, 10, 12, 8; 15 for full_generic), and the planar scenes the x and
y components of the full scene's initial state; else the script ends with exit status 1 naming
the scene.

Instructions per step (valgrind's callgrind, as bench_cvode_baseline.py counts them): the
difference of two runs of each scene, to t = 10 s and 20 s (67 steps), over the difference of
their steps; both the stepper's `advance` (EME_theta's step: the kernel or the generic residual
through SNES, with the predictor and the retry strategies) and the whole eme_run process (the
step, its rows and records, the file), the writes at the end (EME_WRITE_EVERY_ROWS).

Time per step: the process wall time and CPU time (user and system) of runs to t = 300 s (2000
steps) minus runs to t = 10 s, over the difference of their steps (the writes at the end as
above); every repeat runs every scene's pair, the scenes' order rotated by one every repeat, in
this one process; printed are the medians over the repeats and the medians of the per-repeat
ratios to the full model (with the time loop alone, the files' solve_time_seconds, beside).

Printed: one line per scene (unknowns, Newton iterations per step, instructions per step and per
Newton iteration, us per step, the ratios to the full model), its machine-readable line
`rung=NAME unknowns=... newton_per_step=...`, and the two lines of the target (the format of
bench_eme_run.py):
  planar_thermoelastic_over_full_instructions  advance's instructions per step, (d) / (a)  (target 0.7)
  planar_thermoelastic_over_full_time          process wall per step, median ratio (d) / (a) (target 0.7)
Each part ends with the machine's load around it (machine_load.py). A program that fails, a scene
with the wrong columns, or a missing valgrind end the script with the message and exit status 1.
"""
import re
import shutil
import statistics
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

import machine_load
from bench_cvode_baseline import NO_CLOCKED_WRITES, callgrind, per_step, scene_text, wall_and_cpu
from bench_eme_run import ProgramFailed, bench_main, run_program, target_line

SHORT, LONG = 10.0, 20.0          # the instruction counts' run lengths, s
LONG_TIMED = 300.0                # the timed long runs, s (2000 steps; the short ones are SHORT)
ADVANCE = "__discrete_gradient_stepper_MOD_advance"
TARGETS = {"planar_thermoelastic_over_full_instructions": 0.7, "planar_thermoelastic_over_full_time": 0.7}
PLANAR_INITIAL = "q1 = 1.0, 0.0, q2 = 3.0, 0.0, p1 = 0.0, 0.0, p2 = -1.0, -1.0"


@dataclass(frozen=True)
class Rung:
    """A scene of the ladder: its name, what it is, the &model fields it adds to the paper scene,
    its &initial group, eme_run's options, and what its file must show."""
    name: str
    label: str
    model: str
    initial: str
    columns: int
    spring_law: str
    dimension: int
    options: tuple = ()


RUNGS = (
    Rung("full", "(a) spatial thermoviscoelastic, the paper scene (fused kernel)", "", "", 15,
         "thermoviscoelastic", 3),
    Rung("spatial_thermoelastic", "(b) spatial thermoelastic", "spring_law = 'thermoelastic'", "", 14,
         "thermoelastic", 3),
    Rung("planar_thermoviscoelastic", "(c) planar thermoviscoelastic", "dimension = 2, gravity = 0.0, -9.81",
         PLANAR_INITIAL, 11, "thermoviscoelastic", 2),
    Rung("planar_thermoelastic", "(d) planar thermoelastic",
         "spring_law = 'thermoelastic', dimension = 2, gravity = 0.0, -9.81", PLANAR_INITIAL, 10,
         "thermoelastic", 2),
    Rung("spatial_elastic", "(e) spatial elastic (generic path)", "spring_law = 'elastic'", "", 12, "elastic", 3),
    Rung("planar_elastic", "(f) planar elastic (generic path)", "spring_law = 'elastic', dimension = 2, gravity = 0.0, -9.81",
         PLANAR_INITIAL, 8, "elastic", 2),
    Rung("full_generic", "(a) on the generic path (-eme_fused_kernel false)", "", "", 15,
         "thermoviscoelastic", 3, ("-eme_fused_kernel", "false")),
)
FULL, PLANAR_THERMOELASTIC = "full", "planar_thermoelastic"


def rung_text(rung, file, t_end):
    """The rung's namelist: its &model and &initial groups, then inputs/paper_fig4_eme_theta.nml
    with its file in `file` and t_end."""
    model = ", ".join(["model_name = 'double_pendulum'"] + ([rung.model] if rung.model else []))
    initial = f"&initial {rung.initial} /\n" if rung.initial else ""
    text = scene_text(file, t_end)
    if rung.spring_law == "elastic":      # elastic springs have no thermodynamic variable to choose
        text = re.sub(r"^\s*thermo_variable\s*=.*\n", "", text, flags=re.MULTILINE)
    return f"&model {model} /\n{initial}{text}"


def run_rung(bin_dir, folder, rung, t_end, under=None):
    """Writes the rung's namelist for a run to t_end and returns (command, output file); `under`
    names the run's files (default: the rung's name and t_end)."""
    name = under or f"{rung.name}_{t_end:g}"
    output = folder / f"{name}.h5"
    namelist = folder / f"{name}.nml"
    namelist.write_text(rung_text(rung, output, t_end))
    return [bin_dir / "eme_run", namelist, *rung.options], output


def file_figures(output):
    """The steps, Newton iterations and time loop (s) that a run's file records."""
    with h5py.File(output, "r") as f:
        return {"steps": int(f.attrs["steps_completed"]), "newton": int(f.attrs["newton_iterations_total"]),
                "loop": float(f.attrs["solve_time_seconds"])}


def check_rungs(bin_dir, folder, rungs=RUNGS):
    """Runs each scene to SHORT and checks its file: its spring_law, dimension and number of state
    columns, and (planar) the x, y components of the full scene's initial state. Returns the
    columns of each; ProgramFailed naming the scene otherwise."""
    columns, initial = {}, {}
    for rung in rungs:
        command, output = run_rung(bin_dir, folder, rung, SHORT, under=f"check_{rung.name}")
        run_program(command, env=NO_CLOCKED_WRITES)
        with h5py.File(output, "r") as f:
            names = f["state"].attrs["columns"]
            names = (names.decode() if isinstance(names, bytes) else str(names)).split()
            found = {"state columns": f["state"].shape[1], "spring_law": str(f.attrs["spring_law"]),
                     "dimension": int(f.attrs["dimension"])}
            initial[rung.name] = {key: np.asarray(f.attrs[key], dtype=float) for key in ("q1", "q2", "p1", "p2")}
        expected = {"state columns": rung.columns, "spring_law": rung.spring_law, "dimension": rung.dimension}
        wrong = [f"{key} {found[key]} (expected {expected[key]})" for key in expected if found[key] != expected[key]]
        if len(names) != found["state columns"]:
            wrong.append(f"{len(names)} column names for {found['state columns']} columns")
        if wrong:
            raise ProgramFailed(f"scene {rung.name} ({rung.label}): its file {output.name} has " + ", ".join(wrong)
                                + f"; columns: {' '.join(names)}")
        columns[rung.name] = names
    if FULL in initial:
        for rung in rungs:
            if rung.dimension == 2:
                for key, value in initial[rung.name].items():
                    if not np.array_equal(value, initial[FULL][key][:2]):
                        raise ProgramFailed(f"scene {rung.name}: initial {key} = {value.tolist()}, not the x, y "
                                            f"components of the full scene's {initial[FULL][key].tolist()}")
    return columns


def instructions(bin_dir, folder, rungs=RUNGS):
    """callgrind of every scene to SHORT and LONG: per step, the stepper's advance and the whole
    process, the Newton iterations per step in that window, and the steps of the window."""
    for tool in ("valgrind", "callgrind_annotate"):
        if shutil.which(tool) is None:
            raise ProgramFailed(f"{tool} is not installed: make bench installs it (Debian: apt-get install valgrind)")
    counts = {}
    with machine_load.measured(own=1) as load:
        for rung in rungs:
            runs = []
            for t_end in (SHORT, LONG):
                command, output = run_rung(bin_dir, folder, rung, t_end)
                run, _ = callgrind(command, folder, f"{rung.name}_{t_end:g}", (ADVANCE,))
                run.update(file_figures(output))
                runs.append(run)
            counts[rung.name] = {"step": per_step(*runs, ADVANCE), "process": per_step(*runs),
                                 "newton": per_step(*runs, "newton"), "steps": runs[1]["steps"] - runs[0]["steps"]}
    return counts, load


def times(bin_dir, folder, repeats, rungs=RUNGS):
    """The timed pairs (to SHORT and LONG_TIMED) of every scene, the scenes' order rotated every
    repeat: per scene the lists over the repeats of wall, CPU and time-loop us per step and Newton
    iterations per step, and of the wall and CPU ratios to the full model."""
    runs = {rung.name: {key: [] for key in ("wall", "cpu", "loop", "newton")} for rung in rungs}
    with machine_load.measured(own=1) as load:
        for repeat in range(repeats):
            shift = repeat % len(rungs)
            for rung in rungs[shift:] + rungs[:shift]:
                figures = []
                for t_end in (SHORT, LONG_TIMED):
                    command, output = run_rung(bin_dir, folder, rung, t_end, under=f"timed_{rung.name}_{t_end:g}")
                    wall, cpu = wall_and_cpu(command, env=NO_CLOCKED_WRITES)
                    figures.append(dict(file_figures(output), wall=wall, cpu=cpu))
                for key in ("wall", "cpu", "loop"):
                    runs[rung.name][key].append(1e6 * per_step(*figures, key))
                runs[rung.name]["newton"].append(per_step(*figures, "newton"))
    for name in runs:
        for key in ("wall", "cpu"):
            runs[name][f"{key}_ratio"] = [value / full for value, full in zip(runs[name][key], runs[FULL][key])]
    return runs, load


def report(columns, counts, timed, repeats):
    """Prints the table, the machine-readable lines and the target lines from the measurements:
    `columns` (check_rungs), `counts` (instructions) and `timed` (times); returns the target ratios."""
    median = statistics.median
    full = counts[FULL]
    steps = next(iter(counts.values()))["steps"]
    print(f"cost per step of each rung (EME_theta, Gonzalez, dt = 0.15 s, newton_tol 1e-8, Table 1 data; "
          f"instructions: callgrind, runs to t = {LONG:g} s minus runs to {SHORT:g} s, {steps} steps; time: "
          f"process wall and CPU of runs to t = {LONG_TIMED:g} s minus runs to {SHORT:g} s, medians of {repeats} "
          f"repeats, the scenes rotated; ratios to (a), of time the medians of the per-repeat ratios):")
    header = (f"  {'scene':<62} {'unknowns':>8} {'Newton/step':>11} {'instr/step':>11} {'/Newton':>8} "
              f"{'process':>8} {'ratio':>6} {'wall us':>8} {'CPU us':>7} {'loop us':>8} {'/Newton':>8} "
              f"{'wall ratio':>10} {'CPU ratio':>9}")
    print(header)
    lines = []
    for name, count in counts.items():
        rung = next(rung for rung in RUNGS if rung.name == name)
        run = timed[name]
        wall, cpu, loop, newton_timed = (median(run[key]) for key in ("wall", "cpu", "loop", "newton"))
        wall_ratio, cpu_ratio = median(run["wall_ratio"]), median(run["cpu_ratio"])
        print(f"  {rung.label:<62} {len(columns[name]):>8} {count['newton']:>11.2f} {count['step']:>11,.0f} "
              f"{count['step'] / count['newton']:>8,.0f} {count['process']:>8,.0f} "
              f"{count['step'] / full['step']:>6.3f} {wall:>8.2f} {cpu:>7.2f} {loop:>8.2f} "
              f"{wall / newton_timed:>8.2f} {wall_ratio:>10.3f} {cpu_ratio:>9.3f}")
        lines.append(f"rung={name} unknowns={len(columns[name])} newton_per_step={count['newton']:.3f} "
                     f"step_instructions={count['step']:.0f} process_instructions={count['process']:.0f} "
                     f"instructions_per_newton={count['step'] / count['newton']:.0f} "
                     f"instructions_over_full={count['step'] / full['step']:.3f} "
                     f"process_instructions_over_full={count['process'] / full['process']:.3f} "
                     f"timed_newton_per_step={newton_timed:.3f} wall_us_per_step={wall:.3f} "
                     f"cpu_us_per_step={cpu:.3f} "
                     f"loop_us_per_step={loop:.3f} wall_over_full={wall_ratio:.3f} cpu_over_full={cpu_ratio:.3f}")
    print("  (instr/step: the stepper's advance; process: the whole eme_run per step; Newton/step over the "
          f"instruction counts' {steps} steps; us per Newton iteration at the timed runs' Newton/step)")
    for line in lines:
        print(line)
    ratios = {"planar_thermoelastic_over_full_instructions": counts[PLANAR_THERMOELASTIC]["step"] / full["step"],
              "planar_thermoelastic_over_full_time": median(timed[PLANAR_THERMOELASTIC]["wall_ratio"])}
    for name, value in ratios.items():
        print(target_line(name, value, TARGETS[name]))
    print(f"  in the whole process's instructions {counts[PLANAR_THERMOELASTIC]['process'] / full['process']:.3f}, "
          f"in CPU time {median(timed[PLANAR_THERMOELASTIC]['cpu_ratio']):.3f}")
    return ratios


def measure(bin_dir, repeats):
    """The check, both parts and the report, in a scratch folder of their own."""
    with tempfile.TemporaryDirectory(prefix="bench_rungs_") as scratch:
        folder = Path(scratch)
        columns = check_rungs(bin_dir, folder)
        counts, counted = instructions(bin_dir, folder)
        timed, clocked = times(bin_dir, folder, repeats)
    report(columns, counts, timed, repeats)
    for part, load in (("the instruction counts", counted), ("the timed runs", clocked)):
        print(f"around {part}:")
        load.report("bench_rungs.py")
    return 0


def main(argv=None):
    return bench_main(argv, __doc__, "eme_run", 7, measure)


if __name__ == "__main__":
    sys.exit(main())
