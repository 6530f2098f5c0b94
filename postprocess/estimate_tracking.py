#!/usr/bin/env python3
"""Does EME's local error estimate track the true local error? (make study; docs/studies.md)

For each scene and step dt, a fixed-step EME_theta run records its per-step estimate
(`-eme_error_estimate`, dataset error_estimate: the weighted RMS norm of
src/integrator/local_error_estimate). At sampled steps n the true local error is measured: a
tight reference (CVODE-BDF at tolerance 1e-13) integrates the same model from the run's state z_n
over the same step, and the error is the difference to z_{n+1}, in the same weighted norm.
A Milne-type estimate that costs nothing (the step against the quadratic extrapolation of the last
three states, times 1/23, the ratio of the midpoint rule's and the extrapolation's error constants)
is measured beside it.

Writes results/study/estimate_tracking.h5 (one row per sampled step) and the chart
results/figures/estimate_tracking.png/.pdf with a caption; prints the ratio estimate/true per
scene and dt (median, min, max). Needs build/bin/eme_run.
"""
import argparse
import concurrent.futures
import subprocess
import sys
import tempfile
from pathlib import Path

import h5py
import numpy as np

import plotting

ROOT = Path(__file__).resolve().parent.parent
STEPS = (0.001, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5)
# The scenes: &model overrides of the paper's data.
SCENES = {"paper": "", "low_viscosity": "viscosity_const = 1"}
SAMPLES = 6            # sampled steps per scene and dt, spread over the first SPAN seconds
SPAN = 2.0
REFERENCE_TOLERANCE = 1e-13


def weighted_norm(error, z_old, z_new):
    """The estimate's norm (local_error_estimate.f90, weighted_rms_norm)."""
    return float(np.sqrt(np.mean((error / (1.0 + np.maximum(np.abs(z_old), np.abs(z_new)))) ** 2)))


def eme_run(binary, text, folder, name, options=()):
    """Runs one namelist text; returns the output file (or None if the run did not complete)."""
    nml = Path(folder) / f"{name}.nml"
    out = Path(folder) / f"{name}.h5"
    nml.write_text(text + f"&output file = '{out}', overwrite = .true. /\n")
    result = subprocess.run([str(binary), str(nml), *options], capture_output=True, text=True)
    return out if out.exists() and result.returncode in (0, 3) else None


def initial_group(z):
    """&initial from a state in temperature variables (q1, q2, p1, p2, gamma, theta1, theta2)."""
    def reals(values):
        return ", ".join(repr(float(v)) for v in values)
    return (f"&initial q1 = {reals(z[0:3])}, q2 = {reals(z[3:6])}, p1 = {reals(z[6:9])}, "
            f"p2 = {reals(z[9:12])}, gamma = {float(z[12])!r}, theta = {reals(z[13:15])} /\n")


def track(binary, scene, dt, folder):
    """Rows (dt, time, estimate, Milne estimate, true error) of the sampled steps of one run."""
    model = f"&model {SCENES[scene]} /\n"
    steps = max(3, int(round(SPAN / dt)))
    run = eme_run(binary, model + f"&integrator scheme = 'eme', thermo_variable = 'temperature', dt = {dt!r}, "
                  f"t_end = {steps * dt!r} /\n", folder, f"{scene}_{dt}", ("-eme_error_estimate",))
    with h5py.File(run, "r") as f:
        z = f["state"][()]
        estimate = f["error_estimate"][()]
    completed = len(estimate)
    picks = sorted(set(np.linspace(0, completed - 1, min(SAMPLES, completed)).astype(int)))
    rows = []
    for n in picks:
        reference = eme_run(binary, model + initial_group(z[n]) + "&integrator scheme = 'cvode_bdf', "
                            f"dt = {dt!r}, t_end = {dt!r}, tolerance = {REFERENCE_TOLERANCE!r} /\n",
                            folder, f"{scene}_{dt}_ref{n}")
        if reference is None:
            continue
        with h5py.File(reference, "r") as f:
            exact = f["state"][-1]
        true = weighted_norm(z[n + 1] - exact, z[n], z[n + 1])
        milne = np.nan
        if n >= 2:
            extrapolated = 3 * z[n] - 3 * z[n - 1] + z[n - 2]
            milne = weighted_norm((z[n + 1] - extrapolated) / 23.0, z[n], z[n + 1])
        rows.append((dt, n * dt, float(estimate[n]), milne, true))
    return scene, rows


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--bin", default=str(ROOT / "build" / "bin"), help="folder of eme_run")
    parser.add_argument("-o", "--output", default=str(ROOT / "results" / "figures" / "estimate_tracking"),
                        help="chart path without extension")
    parser.add_argument("--data", default=str(ROOT / "results" / "study" / "estimate_tracking.h5"))
    parser.add_argument("--steps", type=float, nargs="*", default=STEPS)
    parser.add_argument("--jobs", type=int, default=2)
    args = parser.parse_args()
    binary = Path(args.bin) / "eme_run"
    results = {scene: [] for scene in SCENES}
    with tempfile.TemporaryDirectory() as folder, concurrent.futures.ThreadPoolExecutor(args.jobs) as pool:
        for scene, rows in pool.map(lambda job: track(binary, *job, folder),
                                    [(s, dt) for s in SCENES for dt in args.steps]):
            results[scene].extend(rows)
    Path(args.data).parent.mkdir(parents=True, exist_ok=True)
    with h5py.File(args.data, "w") as f:
        f.attrs["description"] = ("EME_theta's local error estimate against the true local error (CVODE-BDF at "
                                  f"tolerance {REFERENCE_TOLERANCE:g} from the same state), weighted RMS norm")
        for scene, rows in results.items():
            data = np.array(rows, dtype=float).reshape(-1, 5)
            for k, (name, unit) in enumerate((("dt", "s"), ("time", "s"), ("estimate", "1"),
                                              ("milne_estimate", "1"), ("true_error", "1"))):
                dataset = f.create_dataset(f"{scene}/{name}", data=data[:, k])
                dataset.attrs["units"] = unit
    print("scene          dt [s]   estimate/true: median  min    max    | Milne/true median")
    for scene, rows in results.items():
        data = np.array(rows).reshape(-1, 5)
        for dt in args.steps:
            chosen = data[data[:, 0] == dt]
            if len(chosen) == 0:
                print(f"{scene:14s} {dt:<8g} no sample")
                continue
            ratio = chosen[:, 2] / chosen[:, 4]
            milne = chosen[:, 3] / chosen[:, 4]
            milne = milne[np.isfinite(milne)]
            print(f"{scene:14s} {dt:<8g} {np.median(ratio):22.3f} {ratio.min():6.3f} {ratio.max():6.3f} | "
                  + (f"{np.median(milne):.3f}" if len(milne) else "-"))
    draw(results, args.output)


def draw(results, output):
    """Estimate against true error, both scenes, log-log, with the band of a factor 2."""
    figure, axes = plotting.plt.subplots(1, len(results), figsize=(plotting.DOUBLE_COLUMN, 3.2), sharey=True)
    for ax, (scene, rows) in zip(np.atleast_1d(axes), results.items()):
        data = np.array(rows).reshape(-1, 5)
        true = data[:, 4]
        span = np.array([true.min() / 3, true.max() * 3])
        ax.fill_between(span, span / 2, span * 2, color="0.9")
        ax.plot(span, span, color="0.5", lw=0.8)
        points = ax.scatter(true, data[:, 2], c=np.log10(data[:, 0]), cmap="viridis", s=14, marker="o")
        ax.scatter(true, data[:, 3], c=np.log10(data[:, 0]), cmap="viridis", s=14, marker="x")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("true local error (weighted RMS)")
        ax.set_title(scene.replace("_", " ") + " scene")
    np.atleast_1d(axes)[0].set_ylabel("estimate")
    handles = [plotting.plt.matplotlib.patches.Patch(color="0.9", label="factor 2"),
               plotting.plt.matplotlib.lines.Line2D([], [], color="0.3", marker="o", linestyle="none",
                                                    label="Hermite defect (used)"),
               plotting.plt.matplotlib.lines.Line2D([], [], color="0.3", marker="x", linestyle="none",
                                                    label="Milne, quadratic predictor")]
    np.atleast_1d(axes)[0].legend(handles=handles, loc="upper left")
    colorbar = figure.colorbar(points, ax=axes, shrink=0.9)
    colorbar.set_label("log10 dt [s]")
    caption = ("EME_theta's local error estimate against its true local error (CVODE-BDF at tolerance "
               f"{REFERENCE_TOLERANCE:g} from the same state) over dt = {min(STEPS):g} to {max(STEPS):g} s, "
               f"{SAMPLES} steps per dt in the first {SPAN:g} s; the grey band is a factor 2 either way.")
    plotting.save(figure, output, caption)


if __name__ == "__main__":
    sys.exit(main())
