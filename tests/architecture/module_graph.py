#!/usr/bin/env python3
"""The module graph of the code, drawn from its sources (make docs; docs/architecture.md).

Nodes are the Fortran modules, submodules and programs of src/<folder>/ and drivers/, and the C files of
src/<folder>/ that Fortran calls (bind(C, name='...') interfaces matched to the C functions
defined in them). Edges are `use` statements between the project's modules and those calls. The
folders are the layers, lowest first (LAYERS): a module may use its own folder's modules and
lower folders' only, and the graph has no cycle. `python3 module_graph.py --check` says which
edges break that (exit status 1); without --check it draws the graph as SVG (and PNG) with one
band per layer.
"""
import argparse
import re
import sys
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
# The layers, lowest first, and what each folder owns (docs/architecture.md says the same).
LAYERS = {
    "util": "numbers as text, medians, solver descriptions, the namelist language (lexer, typed fields)",
    "solver": "nonlinear solving for any problem: the problem's interface, PETSc SNES, LU, retry strategies",
    "structure": "the GENERIC contract: the model interface, potentials in invariants, constraints, L and K",
    "scheme": "discrete gradients, the generic step residual and Jacobian, the interface of a fused step",
    "model": "the model registry and scenes; each model in a folder of its own (pendulum/: free energies, "
             "thermodynamic variables, the mechanics, its scene and its fused step)",
    "integrator": "time steppers (EME, midpoint, relaxed Runge-Kutta, TS, CVODE), the registry, step control",
    "io": "run and study input, help texts, versions, provenance, HDF5 files and file-system helpers",
    "run": "the time loop, the run file's schema, signals, the MPI ensemble and its index",
    "drivers": "the programs: eme_run, eme_ensemble, eme_structure and the benchmarks",
}
USE = re.compile(r"^\s*use\s*(?:,\s*\w+\s*)?(?:::)?\s*(\w+)", re.IGNORECASE | re.MULTILINE)
UNIT = re.compile(r"^\s*(module|program)\s+(\w+)\s*$", re.IGNORECASE | re.MULTILINE)
# A submodule (the implementation of part of a module, in a file of its own) uses its parent.
SUBMODULE = re.compile(r"^\s*submodule\s*\(\s*(\w+)\s*\)\s*(\w+)\s*$", re.IGNORECASE | re.MULTILINE)
BIND = re.compile(r"bind\s*\(\s*c\s*,\s*name\s*=\s*['\"](\w+)['\"]", re.IGNORECASE)
C_FUNCTION = re.compile(r"^[A-Za-z_][\w \*]*?\b(\w+)\s*\([^;{]*\)\s*\{", re.MULTILINE)


def sources(root=ROOT):
    """[(path, layer)] of every Fortran and C source of the code."""
    found = []
    for layer in LAYERS:
        folder = root / "drivers" if layer == "drivers" else root / "src" / layer
        for path in sorted(folder.rglob("*")):
            if path.suffix in (".f90", ".F90", ".c"):
                found.append((path, layer))
    return found


def graph(root=ROOT):
    """(nodes {name: (layer, path)}, edges {(from, to)}) of the code under `root`."""
    nodes, uses, calls, defined = {}, defaultdict(set), defaultdict(set), {}
    for path, layer in sources(root):
        text = path.read_text(errors="replace")
        if path.suffix == ".c":
            nodes[path.name] = (layer, path)
            for name in C_FUNCTION.findall(text):
                defined[name] = path.name
            continue
        match = UNIT.search(text) or SUBMODULE.search(text)
        if not match:
            continue
        name = match.group(2).lower()
        nodes[name] = (layer, path)
        uses[name] = {used.lower() for used in USE.findall(text)}
        if match.re is SUBMODULE:
            uses[name].add(match.group(1).lower())
        calls[name] = set(BIND.findall(text))
    edges = set()
    for name in uses:
        edges |= {(name, used) for used in uses[name] if used in nodes and used != name}
        edges |= {(name, defined[c]) for c in calls[name] if c in defined}
    return nodes, edges


def upward(nodes, edges):
    """Edges from a module to one of a higher layer."""
    order = list(LAYERS)
    return sorted((a, b) for a, b in edges if order.index(nodes[b][0]) > order.index(nodes[a][0]))


def cycles(nodes, edges):
    """A cycle of the graph as a list of nodes, or [] if it has none (depth-first search)."""
    following = defaultdict(list)
    for a, b in edges:
        following[a].append(b)
    state, stack = {}, []

    def visit(node):
        state[node] = "open"
        stack.append(node)
        for nxt in sorted(following[node]):
            if state.get(nxt) == "open":
                return stack[stack.index(nxt):] + [nxt]
            if nxt not in state:
                found = visit(nxt)
                if found:
                    return found
        state[node] = "done"
        stack.pop()
        return []

    for node in sorted(nodes):
        if node not in state:
            found = visit(node)
            if found:
                return found
    return []


def draw(nodes, edges, output):
    """One band per layer (lowest at the bottom), modules as labelled boxes, uses as arrows."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    order = list(LAYERS)
    rows = {layer: sorted(n for n, (l, _) in nodes.items() if l == layer) for layer in order}
    width = max(len(r) for r in rows.values())
    fig, ax = plt.subplots(figsize=(max(12, 1.35 * width), 1.3 * len(order)))
    place = {}
    for y, layer in enumerate(order):
        members = rows[layer]
        ax.axhspan(y - 0.45, y + 0.45, color="0.94" if y % 2 else "0.88", zorder=0)
        ax.text(-0.9, y, f"{layer}", ha="right", va="center", fontsize=10, fontweight="bold")
        for x, name in enumerate(members):
            xpos = (x + 0.5) * width / max(1, len(members)) - 0.5
            place[name] = (xpos, y)
            ax.text(xpos, y, name, ha="center", va="center", fontsize=6.5, zorder=3,
                    bbox=dict(boxstyle="round,pad=0.25", facecolor="white", edgecolor="0.4", linewidth=0.5))
    for a, b in sorted(edges):
        (x0, y0), (x1, y1) = place[a], place[b]
        bad = order.index(nodes[b][0]) > order.index(nodes[a][0])
        ax.annotate("", xy=(x1, y1 + 0.12 * (1 if y1 < y0 else -1)), xytext=(x0, y0),
                    arrowprops=dict(arrowstyle="-|>", color="red" if bad else "0.55", linewidth=0.35,
                                    alpha=0.9 if bad else 0.35, shrinkA=4, shrinkB=4), zorder=1)
    ax.set_xlim(-1.0, width)
    ax.set_ylim(-0.6, len(order) - 0.4)
    ax.axis("off")
    ax.set_title("Module graph: `use` and C calls, layers lowest at the bottom (an arrow points to what is used)",
                 fontsize=10)
    fig.tight_layout()
    output = Path(output)
    output.parent.mkdir(parents=True, exist_ok=True)
    # The same sources give the same bytes, so that make docs leaves a clean tree: no date in the
    # SVG's metadata, and its clip-path ids from a fixed salt instead of a random one.
    plt.rcParams["svg.hashsalt"] = "module_graph"
    for suffix in (".svg", ".png"):
        fig.savefig(output.with_suffix(suffix), dpi=150, metadata={"Date": None} if suffix == ".svg" else None)
        print(f"wrote {output.with_suffix(suffix)}")
    plt.close(fig)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--check", action="store_true", help="check the layers and cycles instead of drawing")
    parser.add_argument("-o", "--output", default=str(ROOT / "docs" / "architecture" / "module_graph"),
                        help="output path without suffix (SVG and PNG)")
    parser.add_argument("--root", default=str(ROOT), help="the project's top folder")
    args = parser.parse_args(argv)
    nodes, edges = graph(Path(args.root))
    if args.check:
        problems = [f"{a} ({nodes[a][0]}) uses {b} ({nodes[b][0]}), a higher layer" for a, b in upward(nodes, edges)]
        cycle = cycles(nodes, edges)
        if cycle:
            problems.append("cycle: " + " -> ".join(cycle))
        for problem in problems:
            print(problem)
        print(f"{len(nodes)} modules and C files, {len(edges)} edges, {len(problems)} problems")
        return 1 if problems else 0
    draw(nodes, edges, args.output)
    return 0


if __name__ == "__main__":
    sys.exit(main())
