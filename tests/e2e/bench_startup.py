#!/usr/bin/env python3
"""Start-up benchmark (docs/performance.md, "Start-up"): a run is mostly start-up, so this times
whole processes, this build against another (a baseline build of an earlier commit), alternating
the two repeat by repeat (the order flips every repeat) and reporting medians and the median of
the per-repeat ratios:
  - a 1-step eme_run (the paper scene with t_end = dt), the process's wall time;
  - a 300-case index-only study of the paper scene on one rank without mpirun (eme_ensemble as
    a singleton), the whole command;
then, for this build, where the rest of the start goes: the dynamic loader, timed with trivial C
programs (main returns 0) linked like the drivers: with nothing, with MPI, with everything but
PETSc (MPI, HDF5, SUNDIALS, LAPACK: about what a PETSc built without external packages would
add), and with everything (Debian's PETSc brings its ~100 shared libraries); `eme_run --version`
(the drivers' libraries loaded and their constructors run, no MPI); and LD_DEBUG=statistics of
a 1-step run. Not a test, not part of `make test` or `make bench`:

    .venv/bin/python tests/e2e/bench_startup.py --base /tmp/base19/build/bin [--repeats 15]
"""
import argparse
import os
import platform
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SCENE = ROOT / "inputs" / "paper_fig4_eme_theta.nml"


def machine():
    model = "unknown CPU"
    for line in Path("/proc/cpuinfo").read_text().splitlines():
        if line.startswith("model name"):
            model = line.split(":", 1)[1].strip()
            break
    return f"{model}, {os.cpu_count()} cores, {platform.system()} {platform.release()}"


def wall(command, cwd=None, env=None):
    """Wall time of one process, in seconds; it must exit 0."""
    start = time.perf_counter()
    result = subprocess.run(command, cwd=cwd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    elapsed = time.perf_counter() - start
    if result.returncode != 0:
        raise RuntimeError(f"{command} exited {result.returncode}: {result.stderr[-500:]}")
    return elapsed


def study_text(output):
    first = ", ".join(f"{270 + 0.5 * i:.1f}" for i in range(15))
    second = ", ".join(f"{340 + 0.2 * i:.1f}" for i in range(20))
    return f"&study base = '{SCENE}', output_dir = '{output}', index_only = .true., combine = 'product' /\n" \
           f"&sweep field = 'theta(1)', values = {first} /\n&sweep field = 'theta(2)', values = {second} /\n"


def config_flags():
    """The link flags of build/config.mk (PETSC_LIBS, HDF5_LIBS, SUNDIALS_LDFLAGS, SUNDIALS_LIBS)."""
    flags = {}
    for line in (ROOT / "build" / "config.mk").read_text().splitlines():
        match = re.match(r"(\w+)\s*:?=\s*(.*)", line)
        if match:
            flags[match.group(1)] = match.group(2).split()
    return flags


def trivial_programs(folder):
    """Trivial programs linked with nothing, MPI, everything but PETSc, and everything."""
    source = folder / "trivial.c"
    source.write_text("int main(void) { return 0; }\n")
    flags = config_flags()
    sundials = flags.get("SUNDIALS_LDFLAGS", []) + ["-lsundials_cvode", "-lsundials_nvecserial"]
    others = flags.get("HDF5_LIBS", []) + sundials + ["-llapack", "-lblas"]
    links = {"nothing": ("cc", []), "MPI": ("mpicc", []), "all but PETSc": ("mpicc", others),
             "all (as eme_run)": ("mpicc", flags.get("PETSC_LIBS", []) + others)}
    programs = {}
    for name, (compiler, libraries) in links.items():
        program = folder / f"trivial_{len(programs)}"
        subprocess.run([compiler, "-O2", "-o", str(program), str(source), "-Wl,--no-as-needed", *libraries],
                       check=True)
        count = sum(1 for line in subprocess.run(["ldd", str(program)], capture_output=True, text=True).stdout
                    .splitlines() if "=>" in line or "ld-linux" in line)
        programs[name] = (program, count)
    return programs


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--base", type=Path, required=True, help="bin folder of the baseline build")
    parser.add_argument("--new", type=Path, default=ROOT / "build" / "bin", help="bin folder of this build")
    parser.add_argument("--repeats", type=int, default=15)
    options = parser.parse_args()
    folder = Path(tempfile.mkdtemp(prefix="eme_bench_startup_"))
    builds = {"new": options.new.resolve(), "base": options.base.resolve()}
    one_step = folder / "one_step.nml"
    one_step.write_text(f"&integrator dt = 0.15, t_end = 0.15 /\n&output file = '{folder / 'one_step.h5'}' /\n")
    studies = {}
    for name in builds:
        studies[name] = folder / f"study_{name}.nml"
        studies[name].write_text(study_text(folder / f"study_{name}"))
    times = {(kind, name): [] for kind in ("run", "study") for name in builds}
    loads = []
    for repeat in range(options.repeats):
        order = list(builds) if repeat % 2 == 0 else list(builds)[::-1]
        for name in order:
            times["run", name].append(wall([str(builds[name] / "eme_run"), str(one_step), "-eme_overwrite"]))
        for name in order:
            shutil.rmtree(folder / f"study_{name}", ignore_errors=True)
            times["study", name].append(wall([str(builds[name] / "eme_ensemble"), str(studies[name])]))
        loads.append(os.getloadavg()[0])
    print(f"machine: {machine()}; load average {min(loads):.1f} to {max(loads):.1f} during the "
          f"{options.repeats} repeats")
    for kind, label in (("run", "1-step eme_run"), ("study", "300-case index-only study, 1 rank")):
        new, base = times[kind, "new"], times[kind, "base"]
        ratios = [n / b for n, b in zip(new, base)]
        print(f"{label}: {statistics.median(new) * 1e3:.0f} ms against {statistics.median(base) * 1e3:.0f} ms "
              f"(medians of {options.repeats}); ratio {statistics.median(new) / statistics.median(base):.2f}, "
              f"median of per-repeat ratios {statistics.median(ratios):.2f}")

    programs = trivial_programs(folder)
    version = [str(builds["new"] / "eme_run"), "--version"]
    samples = {name: [] for name in [*programs, "eme_run --version"]}
    for _ in range(max(15, options.repeats)):
        for name, (program, _) in programs.items():
            samples[name].append(wall([str(program)]))
        samples["eme_run --version"].append(wall(version))
    for name, values in samples.items():
        libraries = f", {programs[name][1]} shared objects" if name in programs else ""
        print(f"start of a trivial program linked with {name}{libraries}: {statistics.median(values) * 1e3:.1f} ms"
              if name in programs else f"{name} (the drivers' libraries and constructors, no MPI): "
              f"{statistics.median(values) * 1e3:.1f} ms")
    statistics_text = subprocess.run([str(builds["new"] / "eme_run"), str(one_step), "-eme_overwrite"],
                                     env=dict(os.environ, LD_DEBUG="statistics"), capture_output=True,
                                     text=True).stderr
    for line in statistics_text.splitlines():
        if "total startup time" in line or "final number of relocations:" in line or "time needed for relocation" \
                in line:
            print("LD_DEBUG=statistics:", line.split(":", 1)[1].strip())
    shutil.rmtree(folder, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
