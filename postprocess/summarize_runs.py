#!/usr/bin/env python3
"""Prints the summary table of one or more eme_run result files.

For each run: status, steps, the relative energy balance error max_n |E_n - E_0 - Q_n| / |E_0|
(Q_n is the heat supplied through constraint g2, zero without it, so this is the energy drift),
the smallest entropy increment, the largest Lyapunov increment, the J_z drift
max_n |J_z,n - J_z,0|, the largest constraint residual, the mean Newton iterations per step and
the wall time. Everything is read from the HDF5 files.

usage: summarize_runs.py FILE.h5 [FILE.h5 ...] [--markdown]
"""
import argparse
import sys
from pathlib import Path

import h5py
import numpy as np

from trajectory import RunFileError


def summarize(path):
    """The table row of one run file, as a dict of numbers and strings."""
    with h5py.File(path, "r") as f:
        for name in ("energy", "entropy", "lyapunov", "angular_momentum", "newton_iterations"):
            if name not in f:
                raise RunFileError(f"{path}: dataset /{name} is missing; is this an eme_run file?")
        energy, entropy, lyapunov = f["energy"][:], f["entropy"][:], f["lyapunov"][:]
        heat = f["boundary_heat"][:] if "boundary_heat" in f else np.zeros_like(energy)
        constraint = float(np.abs(f["constraint_residual"][:]).max()) if "constraint_residual" in f else None
        jz = f["angular_momentum"][:, 2]
        newton = f["newton_iterations"][:]
        attrs = f.attrs
        steps = len(newton)
        return {
            "file": Path(path).stem,
            "run": f"{attrs['scheme']}/{attrs['thermo_variable']}"
                   + (f"/{attrs['discrete_gradient']}" if attrs["discrete_gradient"] != "none" else "")
                   + (f" + {attrs['constraints']}" if attrs.get("constraints", "none") != "none" else ""),
            "status": attrs["status"],
            "steps": steps,
            "energy_drift": float(np.max(np.abs(energy - energy[0] - heat)) / abs(energy[0])),
            "min_dS": float(np.diff(entropy).min()) if steps else float("nan"),
            "max_dV": float(np.diff(lyapunov).max()) if steps else float("nan"),
            "jz_drift": float(np.max(np.abs(jz - jz[0]))),
            "constraint": "-" if constraint is None else f"{constraint:.1e}",
            "newton_per_step": float(newton.mean()) if steps else float("nan"),
            "wall_s": float(attrs["wall_time_seconds"]),
        }


COLUMNS = [("file", "file", "{}"), ("run", "scheme", "{}"), ("steps", "steps", "{}"), ("energy_drift", "energy balance", "{:.2e}"),
           ("min_dS", "min dS [J/K]", "{:.2e}"), ("max_dV", "max dV [J]", "{:.2e}"),
           ("jz_drift", "Jz drift [J s]", "{:.2e}"), ("constraint", "max |g|", "{}"),
           ("newton_per_step", "Newton/step", "{:.2f}"),
           ("wall_s", "wall [s]", "{:.3f}"), ("status", "status", "{}")]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("files", nargs="+", help="eme_run HDF5 files")
    parser.add_argument("--markdown", action="store_true", help="print a Markdown table")
    args = parser.parse_args(argv)
    rows = [[fmt.format(summarize(path)[key]) for key, _, fmt in COLUMNS] for path in args.files]
    headers = [title for _, title, _ in COLUMNS]
    if args.markdown:
        print("| " + " | ".join(headers) + " |")
        print("|" + "---|" * len(headers))
        for row in rows:
            print("| " + " | ".join(row) + " |")
        return 0
    widths = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(headers)]
    print("  ".join(h.ljust(w) for h, w in zip(headers, widths)))
    for row in rows:
        print("  ".join(c.ljust(w) for c, w in zip(row, widths)))
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main())
    except (RunFileError, OSError) as error:      # a bad or unreadable file: exit status 2
        print(f"summarize_runs.py: error: {error}", file=sys.stderr)
        sys.exit(2)
