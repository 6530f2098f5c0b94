#!/usr/bin/env python3
"""What a leaner PETSc would give eme_run's start (docs/performance.md, section
"Issue 34"), estimated by measurement. Not a test, not part of `make test` or `make bench`:

    .venv/bin/python tests/e2e/bench_lean_petsc.py [--repeats 15]

Debian's PETSc links the external packages it was configured with (HYPRE, MUMPS, ScaLAPACK,
SuperLU and SuperLU_dist, Trilinos ML, SuiteSparse, FFTW, PT-Scotch, YAML), and through them about
fifty more shared objects; eme_run uses none of them (SNES, KSPPREONLY, a shell preconditioner,
TS). This script makes, in a scratch folder, a copy of Debian's libpetsc_real whose NEEDED entries
are cut (patchelf) to what a PETSc configured with MPI, BLAS/LAPACK and HDF5 only would need,
plus libX11 (hwloc's GL plugin, which Open MPI loads, binds to it) and the OpenCL loader (the
library's symbol versions require it). The references to the dropped packages' functions
remain in PETSc's code and are bound to a stub library of empty functions, which eme_run never
calls. eme_run then runs against the copy (LD_LIBRARY_PATH) and must write the same /state and
Newton iterations bit for bit; the script then alternates, repeat by repeat:
  - eme_run on the paper scene with Debian's PETSc, with the lean copy, and cvode_baseline:
    process wall and CPU time, medians;
and prints the shared objects each loads, the dynamic loader's own statistics
(LD_DEBUG=statistics) and, with valgrind, the instructions before main of each. An estimate: a
real PETSc built without external packages would also drop the stub, the remaining symbol
lookups, libX11 and OpenCL from the start, and could differ in its own code.
"""
import argparse
import os
import re
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import h5py
import numpy as np

ROOT = Path(__file__).resolve().parents[2]
BIN = ROOT / "build" / "bin"
SCENE = ROOT / "inputs" / "paper_fig4_eme_theta.nml"
# What a PETSc configured with MPI, BLAS/LAPACK and HDF5 only keeps of Debian's NEEDED entries
# (libX11 and libOpenCL: see above); the C and Fortran runtimes stay too.
KEPT = ("liblapack", "libblas", "libhdf5", "libmpi", "libm.", "libstdc++", "libgfortran", "libgcc_s", "libc.",
        "libX11", "libOpenCL")


def tool_output(command, **options):
    """A tool's stdout (it must exit 0)."""
    return subprocess.run(command, capture_output=True, text=True, check=True, **options).stdout


def petsc_library():
    """The libpetsc eme_run loads (ldd), and its NEEDED entries."""
    for line in tool_output(["ldd", str(BIN / "eme_run")]).splitlines():
        if "libpetsc" in line and "=>" in line:
            path = Path(line.split("=>")[1].split()[0])
            needed = re.findall(r"\(NEEDED\).*\[(.*)\]", tool_output(["readelf", "-d", str(path)]))
            return path, needed
    raise SystemExit("eme_run loads no libpetsc")


def defined_symbols(library):
    """The dynamic symbols a shared library defines, without their versions."""
    return {line.split()[-1].split("@")[0] for line in tool_output(["nm", "-D", "--defined-only", str(library)])
            .splitlines() if line.strip()}


def lean_copy(folder):
    """The lean copy of libpetsc and its stub library in `folder`; the dropped NEEDED entries."""
    library, needed = petsc_library()
    dropped = [name for name in needed if not name.startswith(KEPT)]
    paths = {}
    for line in tool_output(["ldd", str(library)]).splitlines():
        if "=>" in line and line.split("=>")[1].split():
            paths[line.split()[0]] = line.split("=>")[1].split()[0]
    undefined = {line.split()[-1].split("@")[0] for line in
                 tool_output(["nm", "-D", "--undefined-only", str(library)]).splitlines() if line.strip()}
    stubs, data = set(), set()
    for name in dropped:
        for line in tool_output(["nm", "-D", "--defined-only", paths[name]]).splitlines():
            kind, symbol = line.split()[-2:]
            symbol = symbol.split("@")[0]
            if symbol in undefined:
                (data if kind in "BDVR" else stubs).add(symbol)
    # Symbols a kept library defines (libX11's, for hwloc) must not be shadowed by a stub.
    kept = set()
    for name in needed:
        if name not in dropped and name in paths:
            kept |= defined_symbols(paths[name])
    stub = folder / "stub.c"
    stub.write_text("".join(f"void {symbol}(void) {{}}\n" for symbol in sorted(stubs - kept))
                    + "".join(f"char {symbol}[64];\n" for symbol in sorted(data - kept)))
    subprocess.run(["cc", "-shared", "-fPIC", "-w", "-o", str(folder / "libpetsc_stub.so"), str(stub)], check=True)
    copy = folder / library.name      # the name eme_run asks for (ldd shows that, not the file's)
    shutil.copyfile(library, copy)
    for name in dropped:
        subprocess.run(["patchelf", "--remove-needed", name, str(copy)], check=True)
    subprocess.run(["patchelf", "--add-needed", "libpetsc_stub.so", str(copy)], check=True)
    subprocess.run(["patchelf", "--set-rpath", str(folder), str(copy)], check=True)
    return dropped


def measured(command, env=None):
    """Wall and CPU time of one process, s; it must exit 0."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    subprocess.run([str(part) for part in command], env=env, stdout=subprocess.DEVNULL, check=True)
    elapsed = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return elapsed, after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime


def before_main(command, env, folder):
    """Instructions before main (callgrind: the total less __libc_start_main's inclusive count)."""
    profile = folder / "profile.callgrind"
    subprocess.run(["valgrind", "--tool=callgrind", f"--callgrind-out-file={profile}", *map(str, command)],
                   env=dict(env, EME_WRITE_EVERY_ROWS="1000000000"), capture_output=True, check=True)
    text = tool_output(["callgrind_annotate", "--inclusive=yes", "--threshold=100", str(profile)])
    total = int(re.search(r"([0-9,]+)\s.*PROGRAM TOTALS", text).group(1).replace(",", ""))
    start = int(re.search(r"^\s*([0-9,]+)\s.*:__libc_start_main", text, re.MULTILINE).group(1).replace(",", ""))
    return total - start, total


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=15)
    options = parser.parse_args()
    if shutil.which("patchelf") is None:
        raise SystemExit("bench_lean_petsc.py needs patchelf (Debian: apt-get install patchelf)")
    folder = Path(tempfile.mkdtemp(prefix="eme_lean_petsc_"))
    dropped = lean_copy(folder)
    full_env = dict(os.environ)
    lean_env = dict(os.environ, LD_LIBRARY_PATH=str(folder))
    namelist = folder / "paper.nml"
    namelist.write_text(re.sub(r"file\s*=\s*'[^']*'", f"file = '{folder / 'paper.h5'}', overwrite = .true.",
                               SCENE.read_text()))
    runs = {}
    for name, env in (("full", full_env), ("lean", lean_env)):
        subprocess.run([str(BIN / "eme_run"), str(namelist)], env=env, stdout=subprocess.DEVNULL, check=True)
        with h5py.File(folder / "paper.h5", "r") as f:
            runs[name] = (f["state"][()], f["newton_iterations"][()])
    same = all(np.array_equal(a, b) for a, b in zip(runs["full"], runs["lean"]))
    print(f"lean copy of libpetsc: {len(dropped)} NEEDED entries dropped ({', '.join(dropped)}); eme_run's /state "
          f"and Newton iterations with it: {'bit for bit the same' if same else 'DIFFERENT'}")
    if not same:
        return 1
    commands = {"eme_run, Debian's PETSc": ([BIN / "eme_run", namelist], full_env),
                "eme_run, lean PETSc": ([BIN / "eme_run", namelist], lean_env),
                "cvode_baseline": ([BIN / "cvode_baseline"], full_env)}
    times = {name: [] for name in commands}
    loads = []
    for repeat in range(options.repeats):
        order = list(commands) if repeat % 2 == 0 else list(commands)[::-1]
        for name in order:
            times[name].append(measured(*commands[name]))
        loads.append(os.getloadavg()[0])
    print(f"load average {min(loads):.2f} to {max(loads):.2f} during the {options.repeats} repeats")
    for name, (command, env) in commands.items():
        objects = sum(1 for line in tool_output(["ldd", str(command[0])], env=env).splitlines() if "=>" in line
                      or "ld-linux" in line)
        wall = statistics.median(t[0] for t in times[name])
        cpu = statistics.median(t[1] for t in times[name])
        loader = subprocess.run([str(part) for part in command], env=dict(env, LD_DEBUG="statistics"),
                                stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, check=True).stdout
        cycles = re.search(r"total startup time in dynamic loader:\s*(\d+)", loader)
        line = (f"{name}: {objects} shared objects, wall {1e3 * wall:.1f} ms, CPU {1e3 * cpu:.1f} ms (medians of "
                f"{options.repeats}); the loader's own count {int(cycles.group(1)) / 1e6:.1f} M cycles")
        if shutil.which("valgrind"):
            instructions, total = before_main(command, env, folder)
            line += f"; before main {instructions / 1e6:.1f} M of {total / 1e6:.1f} M instructions"
        print(line)
    full, lean, c = (statistics.median(t[0] for t in times[name]) for name in commands)
    print(f"whole run over cvode_baseline: {full / c:.2f} with Debian's PETSc, {lean / c:.2f} with the lean copy "
          f"(ratios of the medians)")
    shutil.rmtree(folder, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
