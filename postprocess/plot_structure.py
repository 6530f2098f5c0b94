"""The paper's Fig. 2: which entries of the Poisson matrix L and the friction matrix K are
occupied for each thermodynamic variable tau = s, theta, u, drawn from the matrices the code
computes (build/bin/eme_structure FILE.nml OUT.h5; src/run/structure_file.f90).

One row per variable, L left and K right. Entries are grouped by block of the state (q, p, gamma,
tau, as in the run files) and coloured by value on a symmetric-log scale; structural zeros (exact
zeros) are white, so that a small entry and a zero are told apart.

Example: plot_structure.py results/structure.h5 -o results/figures/fig2_structure
"""
import argparse

import h5py
import numpy as np
from matplotlib.colors import SymLogNorm

from plotting import DOUBLE_COLUMN, plt, run_script, save
from trajectory import RunFileError

TITLE = "Fig. 2: occupation of L and K for tau = s, theta, u"
VARIABLES = (("entropy", r"$\tau = s$"), ("temperature", r"$\tau = \theta$"), ("internal_energy", r"$\tau = u$"))
# Values below this fraction of a matrix's largest entry are drawn in the linear band of the scale.
LINEAR_FRACTION = 1e-8


def read_structure(path):
    """{variable: {"L", "K", "columns"}} of a structure file; RunFileError if it lacks a part."""
    try:
        handle = h5py.File(path, "r")
    except OSError as error:
        raise RunFileError(f"{path}: cannot open as an HDF5 file ({error})") from None
    with handle:
        matrices = {}
        for variable, _ in VARIABLES:
            if variable not in handle or not {"L", "K"} <= set(handle[variable]):
                raise RunFileError(f"{path}: /{variable}/L or /{variable}/K is missing; is this an eme_structure file?")
            group = handle[variable]
            columns = group["L"].attrs["columns"]
            columns = (columns.decode() if isinstance(columns, bytes) else str(columns)).split()
            matrices[variable] = {"L": group["L"][()], "K": group["K"][()], "columns": columns}
        title = handle.attrs.get("input_file", b"")
    return matrices, title.decode() if isinstance(title, bytes) else str(title)


def blocks(columns):
    """(label, first, last) of the state's blocks: q, p, gamma, tau (in the columns' order)."""
    def kind(name):
        if name.startswith("q"):
            return "q"
        if name.startswith("p"):
            return "p"
        if name.startswith("gamma"):
            return r"$\gamma$"
        return r"$\tau$"
    found = []
    for index, name in enumerate(columns):
        if found and found[-1][0] == kind(name):
            found[-1][2] = index
        else:
            found.append([kind(name), index, index])
    return [tuple(block) for block in found]


def draw_matrix(ax, matrix, columns, title):
    """Nonzero entries on a symmetric-log colour scale, zeros white, block lines and labels."""
    largest = np.max(np.abs(matrix)) if np.any(matrix) else 1.0
    norm = SymLogNorm(linthresh=LINEAR_FRACTION * largest, vmin=-largest, vmax=largest, base=10)
    shown = np.ma.masked_where(matrix == 0.0, matrix)
    image = ax.imshow(shown, cmap="RdBu_r", norm=norm, interpolation="nearest")
    for _, first, last in blocks(columns)[1:]:
        ax.axhline(first - 0.5, color="0.3", linewidth=0.6)
        ax.axvline(first - 0.5, color="0.3", linewidth=0.6)
    centres = [((first + last) / 2, label) for label, first, last in blocks(columns)]
    ax.set_xticks([c for c, _ in centres], [label for _, label in centres])
    ax.set_yticks([c for c, _ in centres], [label for _, label in centres])
    ax.tick_params(length=0)
    ax.set_title(title)
    return image


def make_figure(matrices):
    fig, axes = plt.subplots(len(VARIABLES), 2, figsize=(DOUBLE_COLUMN, 9.0))
    for row, (variable, symbol) in enumerate(VARIABLES):
        data = matrices[variable]
        for column, name in enumerate(("L", "K")):
            image = draw_matrix(axes[row, column], data[name], data["columns"],
                                f"${name}$, {symbol}: {np.count_nonzero(data[name])} nonzero entries")
            bar = fig.colorbar(image, ax=axes[row, column], shrink=0.85)
            top = 10.0 ** np.floor(np.log10(np.max(np.abs(data[name]))))
            bar.set_ticks([-top, -top * 1e-4, 0.0, top * 1e-4, top])
            bar.set_label(f"entry of ${name}$ (white: exactly 0)")
    return fig


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("file", metavar="STRUCTURE.h5", help="a file written by eme_structure")
    parser.add_argument("-o", "--output", required=True, metavar="OUT", help="output path without suffix")
    args = parser.parse_args(argv)
    matrices, input_file = read_structure(args.file)
    lines = [f"L and K of eq. (8) at the initial state of {input_file}, computed by eme_structure "
             f"({args.file}). Colour: the entry on a symmetric-log scale (linear below {LINEAR_FRACTION:g} of the "
             "largest entry); white: structural zeros. Blocks: positions q = (q1, q2), momenta p = (p1, p2), the "
             "viscous strain gamma, the thermodynamic variables tau = (tau1, tau2)."]
    for variable, _ in VARIABLES:
        counts = ", ".join(f"{name} {np.count_nonzero(matrices[variable][name])}" for name in ("L", "K"))
        lines.append(f"{variable}: nonzero entries {counts}")
    return save(make_figure(matrices), args.output, TITLE, lines=lines)


if __name__ == "__main__":
    run_script(main)
