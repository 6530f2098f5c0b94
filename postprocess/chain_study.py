"""Where methods fail on the spring chain (issue 39, item 7; make study-chain; docs/performance.md):
the continuum family's stability map over (N, dt) and a work-precision chart.

Both run eme_ensemble on studies this script writes (zipped sweeps: a fixed number of steps needs
t_end = (STEPS - 1/2) dt case by case, which a product of sweeps cannot give) into the study's
folder, on the base scenes inputs/chain_rod.nml (stability) and inputs/chain_rod_heat.nml cut
into WP_LINKS springs (work precision: the base is written beside the study, heat_base).

  chain_study.py stability --bin build/bin --study-dir results/study -o results/figures
  chain_study.py work-precision --bin build/bin --study-dir results/study -o results/figures

**Stable** (the map's definition, written on the chart): a run of STEPS steps of dt reaches its
end without halving a step, every temperature stays finite and positive, and its energy stays
within STABLE_ENERGY of the start's, max_n |E_n - E_0| <= STABLE_ENERGY |E_0| (the index's
energy_drift; E_0 is about -600 J, the rod's internal energy below theta_ref). Otherwise the case
is classed by OUTCOMES: finished only by halving steps, finished with an energy error above the
bound, left the model's domain (a blow-up: a non-positive temperature or length, or a value not
finite), or its solver failed (no Newton root, no relaxation root).

**The estimate** (docs/formulation.md section 10, Why an explicit step shrinks like 1/N^2): for a
rod of n_s springs of length h = L/n_s, conduction's fastest decay rate is lambda = 4 kA/((1 +
beta_v) c h^2) and the axial waves' fastest frequency omega = (2/h) sqrt((1 + beta_v) EA(theta)/
rho) with EA(theta) = EA - dEA/dtheta (theta - theta_ref) (the spring's instantaneous stiffness
(1 + beta_v) mu/h^2 against its mass rho h). RK4 is stable for dt lambda <= RK4_REAL (on the
negative real axis) and dt omega <= RK4_IMAGINARY (on the imaginary axis): dt <= min(RK4_REAL/
lambda, RK4_IMAGINARY/omega), which falls like 1/N for the waves and like 1/N^2 for conduction.
"""
import argparse
import csv
import math
import re
import resource
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np

import integrators
from plotting import DOUBLE_COLUMN, plt, save
from study_analysis import StudyError, namelist_numbers, namelist_text_value, read_index
from chain_dataset import open_chain
from trajectory import RunFileError

ROOT = Path(__file__).resolve().parent.parent
STEPS = 20                       # steps of every stability case
STABLE_ENERGY = 1e-2             # max_n |E_n - E_0| / |E_0| of a stable case
STABILITY_SCHEMES = ("eme", "midpoint", "relaxed_rk4", "relaxed_rk8", "ts_rk4")
STABILITY_LINKS = (10, 20, 40, 80, 160, 250)
STABILITY_DT = tuple(0.064 / 2.0 ** k for k in range(9))        # 0.064 s down to 0.25 ms
OUTCOMES = ("stable", "halved", "energy", "blow-up", "solver")
OUTCOME_TEXT = {"stable": "stable", "halved": "finished only by halving steps",
                "energy": f"energy error > {STABLE_ENERGY:g}",
                "blow-up": "blow-up: left the domain (theta or length <= 0, not finite)",
                "solver": "solver failed (no Newton or relaxation root)"}
OUTCOME_COLOURS = {"stable": "#009E73", "halved": "#F0E442", "energy": "#E69F00", "blow-up": "#7f7f7f",
                   "solver": "#56B4E9"}
DOMAIN_REASONS = ("domain", "non-positive", "blow-up", "nan", "not finite")
# RK4's stability region meets the negative real axis at the real root of 1 - x + x^2/2 - x^3/6
# + x^4/24 = 1 (R(-x), positive on the axis, rises back through 1 there), and the imaginary axis
# at y = 2 sqrt(2) (|R(iy)|^2 = 1 - y^6/72 + y^8/576).
RK4_REAL = 2.785293563405282
RK4_IMAGINARY = 2.0 * math.sqrt(2.0)

# Work precision: the hot-half rod of inputs/chain_rod_heat.nml cut into WP_LINKS springs (4000
# unknowns: the sparse path, one rank a case) to WP_END, each fixed-step scheme over its step
# counts, the adaptive ones over their tolerances. RK4's limit there is 4.2e-5 s (conduction), so
# the explicit schemes start at WP_END/512 (3.9e-5 s) and relaxed_rk8 (twice RK4's limit) at /256.
WP_LINKS = 1000
WP_END = 0.02
WP_FIXED = {"eme": (5, 10, 20, 40, 80), "midpoint": (5, 10, 20, 40, 80), "ts_bdf2": (5, 10, 20, 40, 80),
            "relaxed_gauss6": (10, 20, 40, 80), "relaxed_rk4": (512, 1024, 2048), "relaxed_rk8": (256, 512, 1024),
            "ts_rk4": (512, 1024, 2048)}
WP_ADAPTIVE = {"eme": (1e-1, 1e-2, 1e-3), "relaxed_dp853": (1e-4, 1e-6, 1e-8, 1e-10)}
WP_REFERENCE = ("relaxed_rk8", 4096)        # the reference: relaxed_rk8 at WP_END/4096
WP_CROSS_CHECK = ("relaxed_rk8", 2048)      # and its check: the same at twice the step
WP_REPEATS = 3


def classify(row):
    """The OUTCOMES name of one index row (a dict with status, energy_drift, min_temperature and
    halved_steps), by the module's definition of stable, in OUTCOMES' order of precedence from the
    end: a failed case by its reason, then a state outside the domain, the energy, halving."""
    status = row["status"]
    if status.startswith("failed"):
        return "blow-up" if any(reason in status.lower() for reason in DOMAIN_REASONS) else "solver"
    if status != "complete":
        raise StudyError(f"case {row.get('case', '?')} is neither complete nor failed ({status!r}): "
                         "finish the study first")
    drift, coldest = row["energy_drift"], row["min_temperature"]
    if not (np.isfinite(drift) and np.isfinite(coldest) and coldest > 0):
        return "blow-up"
    if drift > STABLE_ENERGY:
        return "energy"
    if row["halved_steps"] > 0:
        return "halved"
    return "stable"


def rod_data(case_input):
    """The rod's data (SI) from a case's namelist text (the index's case_1_input)."""
    names = ("rod_length", "mass_per_length", "axial_stiffness", "stiffness_slope", "rod_heat_capacity",
             "rod_conductivity", "beta_v", "theta_ref", "theta")
    data = {}
    for name in names:
        text = namelist_text_value(case_input, name)
        if text is None:
            raise StudyError(f"the study's case_1_input has no field {name}: not a rod scene")
        data[name] = namelist_numbers(text)[0]
    return data


def rk4_limits(links, rod):
    """(conduction's, the waves') RK4 step limits [s] of a fixed-free rod of `links` springs."""
    h = rod["rod_length"] / links
    capacity = (1.0 + rod["beta_v"]) * rod["rod_heat_capacity"]
    decay = 4.0 * rod["rod_conductivity"] / (capacity * h * h)
    stiffness = rod["axial_stiffness"] - rod["stiffness_slope"] * (rod["theta"] - rod["theta_ref"])
    frequency = 2.0 / h * math.sqrt((1.0 + rod["beta_v"]) * stiffness / rod["mass_per_length"])
    return RK4_REAL / decay, RK4_IMAGINARY / frequency


def zipped_study(base, output_dir, cases, index_only, repeats=1):
    """The text of an eme_ensemble study (combine = 'zip') of `cases`, each a dict of namelist
    fields (the same fields in every case)."""
    fields = list(cases[0])
    lines = ["! Written by postprocess/chain_study.py: one case per column of the sweeps.", "&study",
             f"  base = '{base}'", f"  output_dir = '{output_dir}'", "  combine = 'zip'",
             f"  index_only = {'.true.' if index_only else '.false.'}", f"  repeats = {repeats}", "/"]
    for field in fields:
        values = [case[field] for case in cases]
        if isinstance(values[0], str):
            lines.append(f"&sweep field = '{field}', texts = " + ", ".join(f"'{v}'" for v in values) + " /")
        else:
            lines.append(f"&sweep field = '{field}', values = " + ", ".join(repr(float(v)) for v in values) + " /")
    return "\n".join(lines) + "\n"


def unlimited_stack():
    """The dense path at 1000 unknowns needs more than the usual 8 MB stack (its 8 MB Jacobian)."""
    resource.setrlimit(resource.RLIMIT_STACK, (resource.RLIM_INFINITY, resource.RLIM_INFINITY))


def run_study(bin_dir, path, ranks):
    """Runs eme_ensemble on the study file `path` on `ranks` ranks (an earlier complete run of
    the same study is kept: eme_ensemble reruns nothing complete)."""
    command = ["mpirun", "--allow-run-as-root", "--oversubscribe", "-n", str(ranks),
               str(Path(bin_dir) / "eme_ensemble"), str(path)]
    print("running:", " ".join(command), flush=True)
    subprocess.run(command, check=True, preexec_fn=unlimited_stack)


def stability_cases(schemes=STABILITY_SCHEMES, links=STABILITY_LINKS, steps=STABILITY_DT, count=STEPS):
    """Every (scheme, links, dt) case of the map, each to t_end = (count - 1/2) dt: count steps."""
    return [{"scheme": scheme, "links": n, "dt": dt, "t_end": (count - 0.5) * dt}
            for scheme in schemes for n in links for dt in steps]


def stability_grid(rows):
    """{scheme: {"links", "dt", "outcome" (codes into OUTCOMES, -1: not run), "rows"}}."""
    grids = {}
    for row in rows:
        grid = grids.setdefault(row["scheme"], {"rows": []})
        grid["rows"].append(row)
    for grid in grids.values():
        links = sorted({int(row["links"]) for row in grid["rows"]})
        steps = sorted({row["dt"] for row in grid["rows"]})
        outcome = np.full((len(links), len(steps)), -1, dtype=int)
        for row in grid["rows"]:
            outcome[links.index(int(row["links"])), steps.index(row["dt"])] = OUTCOMES.index(classify(row))
        grid.update(links=np.array(links), dt=np.array(steps), outcome=outcome)
    return dict(sorted(grids.items(), key=lambda item: (integrators.position(item[0]), item[0])))


def stable_limit(dt, outcome):
    """(the largest dt below which every dt of the grid is stable, the smallest dt that is not);
    NaN where there is none."""
    stable = outcome == OUTCOMES.index("stable")
    last, first_unstable = float("nan"), float("nan")
    for value, ok in zip(dt, stable):
        if not ok:
            first_unstable = float(value)
            break
        last = float(value)
    return last, first_unstable


def stability_figure(grids, rod, output, load_text=""):
    """One panel per scheme: outcome over (dt, N), RK4's estimated limit drawn on each."""
    fig, axes = plt.subplots(1, len(grids), figsize=(DOUBLE_COLUMN, 3.1), sharey=True, squeeze=False)
    colours = [plt.matplotlib.colors.to_rgb(OUTCOME_COLOURS[name]) for name in OUTCOMES]
    for ax, (scheme, grid) in zip(axes[0], grids.items()):
        image = np.ones(grid["outcome"].shape + (3,))
        for (i, j), code in np.ndenumerate(grid["outcome"]):
            if code >= 0:
                image[i, j] = colours[code]
        ax.imshow(image, origin="lower", aspect="auto", interpolation="nearest")
        ax.set_xticks(range(len(grid["dt"])), [f"{1e3 * v:g}" for v in grid["dt"]], rotation=90)
        ax.set_yticks(range(len(grid["links"])), [str(v) for v in grid["links"]])
        ax.set_title(integrators.label(scheme))
        ax.set_xlabel("dt [ms]")
        ax.tick_params(length=0)
        # The estimate as a curve through the cells: dt's position on the grid's log axis.
        n = np.geomspace(grid["links"][0], grid["links"][-1], 60)
        limit = np.array([min(rk4_limits(value, rod)) for value in n])
        log_dt = np.log2(grid["dt"])
        x = np.interp(np.log2(limit), log_dt, np.arange(len(log_dt)))
        y = np.interp(np.log(n), np.log(grid["links"]), np.arange(len(grid["links"])))
        ax.plot(x, y, color="black", lw=1.0, ls="--")
    axes[0][0].set_ylabel("springs N")
    handles = [plt.matplotlib.patches.Patch(color=OUTCOME_COLOURS[name], label=OUTCOME_TEXT[name])
               for name in OUTCOMES]
    handles.append(plt.matplotlib.lines.Line2D([], [], color="black", ls="--",
                                               label="RK4's limit estimated from the rod's data"))
    fig.legend(handles=handles, loc="outside lower center", ncols=2)
    title = (f"Stability of the rod family over (N, dt): stable = {STEPS} steps of dt without halving, "
             f"temperatures finite and > 0, max |E - E0| <= {STABLE_ENERGY:g} |E0|")
    fig.suptitle(f"stable: {STEPS} steps, no halving, theta > 0, |E - E0| <= {STABLE_ENERGY:g} |E0|",
                 fontsize=8)
    return save(fig, output, title, lines=[load_text] if load_text else ())


def write_stability_tables(grids, rod, stem):
    """STEM.csv (one line per case) and STEM_limits.csv (per scheme and N: the measured limit
    bracket and RK4's estimate)."""
    with open(f"{stem}.csv", "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["scheme", "links", "dt_s", "outcome", "energy_drift", "min_temperature_K",
                         "halved_steps", "steps_completed", "solve_cpu_time_s", "status"])
        for scheme, grid in grids.items():
            for row in sorted(grid["rows"], key=lambda r: (r["links"], r["dt"])):
                writer.writerow([scheme, int(row["links"]), f"{row['dt']:.6g}", classify(row),
                                 f"{row['energy_drift']:.3g}", f"{row['min_temperature']:.6g}",
                                 row["halved_steps"], row["steps_completed"],
                                 f"{row.get('solve_cpu_time_seconds', float('nan')):.4g}", row["status"]])
    lines = []
    with open(f"{stem}_limits.csv", "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["scheme", "links", "largest_stable_dt_s", "smallest_unstable_dt_s",
                         "rk4_conduction_limit_s", "rk4_wave_limit_s"])
        for scheme, grid in grids.items():
            for i, n in enumerate(grid["links"]):
                last, first = stable_limit(grid["dt"], grid["outcome"][i])
                conduction, waves = rk4_limits(int(n), rod)
                writer.writerow([scheme, int(n), f"{last:.6g}", f"{first:.6g}", f"{conduction:.4g}", f"{waves:.4g}"])
                lines.append(f"chain stability {integrators.label(scheme)} N = {int(n)}: stable up to dt = "
                             f"{last:g} s, first unstable {first:g} s (RK4 estimate: conduction "
                             f"{conduction:.3g} s, waves {waves:.3g} s)")
    return lines


def study_load(index_path):
    """The load averages the index recorded, as a caption line."""
    with h5py.File(index_path, "r") as handle:
        start = handle.attrs.get("load_average_start")
        end = handle.attrs.get("load_average_end")
    if start is None:
        return ""
    return (f"load average at the start {', '.join(f'{v:.2f}' for v in start)}"
            + (f", at the end {', '.join(f'{v:.2f}' for v in end)}" if end is not None else "")
            + " (1, 5, 15 min)")


def stability(args):
    """Runs the map's studies (one per scheme: a sweep takes at most 256 values) and draws it."""
    folder = Path(args.study_dir) / "chain_stability"
    folder.mkdir(parents=True, exist_ok=True)
    rows = []
    for scheme in STABILITY_SCHEMES:
        study = folder / f"{scheme}.nml"
        study.write_text(zipped_study(Path(args.base).resolve(), folder.resolve() / scheme,
                                      stability_cases((scheme,), args.links or STABILITY_LINKS), index_only=True))
        if not args.analyse_only:
            run_study(args.bin, study, args.ranks)
        rows += read_index(folder / scheme)
    rod = rod_data(rows[0]["case_1_input"])
    grids = stability_grid(rows)
    load = "; ".join(f"{scheme}: {study_load(folder / scheme / 'index.h5')}" for scheme in STABILITY_SCHEMES)
    stability_figure(grids, rod, Path(args.output) / "chain_stability_map", load)
    for line in write_stability_tables(grids, rod, Path(args.study_dir) / "chain_stability_map"):
        print(line)


# --- work precision ---------------------------------------------------------------------------

def final_chain_state(path):
    """(time, mechanical state, temperatures [K], theta_ref) of a chain run file's last snapshot,
    whichever path wrote it (chain_dataset.open_chain)."""
    chain = open_chain(path).isel(snapshot_time=-1)
    mechanical = np.concatenate([chain.q.values.ravel(), chain.p.values.ravel(), chain.gamma.values.ravel()])
    theta_ref = float(np.atleast_1d(chain.attrs["theta_ref"])[0])
    return float(chain.snapshot_time), mechanical, chain.theta.values, theta_ref


def heat_base(source, links, target):
    """inputs/chain_rod_heat.nml cut into `links` springs into `target`: its hot and cold halves
    kept (theta's two runs scaled to the new count), the state written at the start and the end
    only (snapshot_every = 0)."""
    text = Path(source).read_text()
    hot, cold = re.search(r"theta = (\d+)\*([0-9.]+), (\d+)\*([0-9.]+)", text).group(2, 4)
    text = re.sub(r"links = \d+", f"links = {links}", text)
    text = re.sub(r"theta = \d+\*[0-9.]+, \d+\*[0-9.]+", f"theta = {links // 2}*{hot}, {links - links // 2}*{cold}", text)
    text = re.sub(r"snapshot_every = \d+", "snapshot_every = 0", text)
    Path(target).write_text(text)


def chain_error(point, reference):
    """max(|x, p, gamma - reference|, |theta - reference| / theta_ref) at the common end time."""
    time, mechanical, temperatures, theta_ref = point
    if abs(time - reference[0]) > 1e-9 * max(1.0, reference[0]):
        raise StudyError(f"a case ends at t = {time:.10g} s, the reference at {reference[0]:.10g} s")
    return float(max(np.max(np.abs(mechanical - reference[1])),
                     np.max(np.abs(temperatures - reference[2])) / theta_ref))


def work_precision_cases():
    """(fixed-step cases, adaptive cases, reference cases) of the chart."""
    fixed = [{"scheme": scheme, "dt": WP_END / n, "t_end": WP_END} for scheme, counts in WP_FIXED.items()
             for n in counts]
    adaptive = [{"scheme": scheme, "tolerance": tolerance, "dt": WP_END / 20, "t_end": WP_END}
                for scheme, tolerances in WP_ADAPTIVE.items() for tolerance in tolerances]
    reference = [{"scheme": scheme, "dt": WP_END / n, "t_end": WP_END} for scheme, n in (WP_REFERENCE, WP_CROSS_CHECK)]
    return fixed, adaptive, reference


def work_precision(args):
    folder = Path(args.study_dir) / "chain_work_precision"
    folder.mkdir(parents=True, exist_ok=True)
    base = (folder / "base.nml").resolve()
    heat_base(args.base_heat, args.wp_links, base)
    studies = dict(zip(("fixed", "adaptive", "reference"), work_precision_cases()))
    for name, cases in studies.items():
        study = folder / f"{name}.nml"
        study.write_text(zipped_study(base, folder.resolve() / name, cases, index_only=False,
                                      repeats=1 if name == "reference" else WP_REPEATS))
        if not args.analyse_only:
            run_study(args.bin, study, args.ranks)
    reference_rows = read_index(folder / "reference")
    reference, cross_check = (final_chain_state(row["path"]) for row in reference_rows)
    level = chain_error(cross_check, reference)
    curves = {}
    for name in ("fixed", "adaptive"):
        for row in read_index(folder / name):
            if row["status"] != "complete":
                continue
            error = chain_error(final_chain_state(row["path"]), reference)
            key = integrators.label(row["scheme"])
            curves.setdefault(key, []).append((row["solve_cpu_time_seconds"], error,
                                               row.get("tolerance", row["dt"]), row["scheme"]))
    failed = [(integrators.label(row["scheme"]), row.get("tolerance", row["dt"]), row["status"])
              for name in ("fixed", "adaptive") for row in read_index(folder / name) if row["status"] != "complete"]
    stem = Path(args.output) / "chain_work_precision"
    links = namelist_text_value(reference_rows[0]["case_1_input"], "links")
    load = study_load(folder / "fixed" / "index.h5")
    fig, ax = plt.subplots(figsize=(DOUBLE_COLUMN, 3.4), layout="constrained")
    for key, points in curves.items():
        points.sort(key=lambda point: -point[2])          # along the curve: from the largest dt or tolerance
        ax.loglog([p[0] for p in points], [p[1] for p in points], marker="o",
                  color=integrators.colour(points[0][3]), label=key)
    ax.axhline(level, color="0.5", lw=0.6, ls=":")
    ax.set_xlabel(f"CPU time of the time loop [s] (median of {WP_REPEATS} runs)")
    ax.set_ylabel("error at T")
    ax.set_title(f"rod of N = {links} springs, hot half, T = {WP_END:g} s. Error: max(|x, p, gamma - ref|, "
                 f"|theta - ref|/theta_ref);\nreference {integrators.label(WP_REFERENCE[0])} at dt = T/"
                 f"{WP_REFERENCE[1]}, dotted: its distance to dt = T/{WP_CROSS_CHECK[1]}", fontsize=8)
    fig.legend(loc="outside right upper")
    title = (f"Work precision on the chain's rod family (N = {links}, inputs/chain_rod_heat.nml cut into {links} springs, T = {WP_END:g} s): "
             f"error against {WP_REFERENCE[0]} at dt = T/{WP_REFERENCE[1]} (cross-check at T/{WP_CROSS_CHECK[1]}: "
             f"{level:.2g}, dotted)")
    save(fig, stem, title, lines=[load] if load else ())
    with open(Path(args.study_dir) / "chain_work_precision.csv", "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["scheme", "dt_or_tolerance", "solve_cpu_time_s", "error"])
        for key, points in curves.items():
            for cpu, error, setting, _ in points:
                writer.writerow([key, f"{setting:.6g}", f"{cpu:.4g}", f"{error:.3g}"])
    print(f"chain work precision: reference level {level:.3g}")
    for key, points in curves.items():
        print(f"chain work precision {key}: " + "; ".join(f"{setting:.3g}: {error:.2g} in {cpu:.3g} s"
                                                          for cpu, error, setting, _ in points))
    for key, setting, status in failed:
        print(f"chain work precision {key} at {setting:g}: {status}")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("what", choices=("stability", "work-precision"))
    parser.add_argument("--bin", default=str(ROOT / "build" / "bin"), help="the folder of eme_ensemble")
    parser.add_argument("--study-dir", default="results/study", help="the studies' folder")
    parser.add_argument("-o", "--output", default="results/figures", help="the figures' folder")
    parser.add_argument("--ranks", type=int, default=2, help="eme_ensemble's ranks")
    parser.add_argument("--base", default=str(ROOT / "inputs" / "chain_rod.nml"), help="the stability map's scene")
    parser.add_argument("--base-heat", default=str(ROOT / "inputs" / "chain_rod_heat.nml"),
                        help="the work-precision chart's scene")
    parser.add_argument("--links", type=int, nargs="+", help="the map's N (default: %(default)s)")
    parser.add_argument("--wp-links", type=int, default=WP_LINKS, help="the chart's N (default: %(default)s)")
    parser.add_argument("--analyse-only", action="store_true", help="draw from the studies already run")
    args = parser.parse_args(argv)
    try:
        (stability if args.what == "stability" else work_precision)(args)
    except (StudyError, RunFileError) as error:
        print(f"chain_study.py: error: {error}", file=sys.stderr)
        sys.exit(2)
    except subprocess.CalledProcessError as error:
        print(f"chain_study.py: error: {error}", file=sys.stderr)
        sys.exit(1)


if __name__ == "__main__":
    main()
