#!/usr/bin/env python3
"""The module graph of the code, drawn from its sources (make docs; docs/architecture.md).

Nodes are the Fortran modules, submodules and programs under src/ and drivers/, and the C files
there that Fortran calls (bind(C, name='...') interfaces matched to the C functions defined in
them). Edges are `use` statements between the project's modules and those calls. A node's folder
is its file's folder relative to src/ (`model`, `model/pendulum`; `drivers` for the programs), and
its layer is the folder's first component. The layers, lowest first, are LAYERS: a module may use
its own layer's modules and lower layers' only, and the graph has no cycle. `python3
module_graph.py --check` says which edges break that and which files lie in no layer (exit
status 1); without --check it draws two pictures into the folder -o names, each as SVG and PNG:
folder_graph (the layers as bands, a folder as a box, an arrow per pair of folders labelled
with its number of edges) and module_graph (every module and edge, one band per layer).
"""
import argparse
import hashlib
import html
import re
import sys
from collections import Counter, defaultdict, namedtuple
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
SUFFIXES = (".f90", ".F90", ".c")
USE = re.compile(r"^\s*use\s*(?:,\s*\w+\s*)?(?:::)?\s*(\w+)", re.IGNORECASE | re.MULTILINE)
UNIT = re.compile(r"^\s*(module|program)\s+(\w+)\s*$", re.IGNORECASE | re.MULTILINE)
# A submodule (the implementation of part of a module, in a file of its own) uses its parent.
SUBMODULE = re.compile(r"^\s*submodule\s*\(\s*(\w+)\s*\)\s*(\w+)\s*$", re.IGNORECASE | re.MULTILINE)
BIND = re.compile(r"bind\s*\(\s*c\s*,\s*name\s*=\s*['\"](\w+)['\"]", re.IGNORECASE)
C_FUNCTION = re.compile(r"^[A-Za-z_][\w \*]*?\b(\w+)\s*\([^;{]*\)\s*\{", re.MULTILINE)
# (layer, path) first, as graph() gave them before folders were told apart.
Node = namedtuple("Node", "layer path folder")


def sources(root=ROOT):
    """[(path, folder)] of every Fortran and C source under src/ and drivers/, subfolders included.

    The folder is relative to src/ (`model/pendulum`), or to the top for the programs (`drivers`)."""
    found = []
    for top, base in ((root / "src", root / "src"), (root / "drivers", root)):
        for path in sorted(top.rglob("*")):
            if path.suffix in SUFFIXES and path.is_file():
                found.append((path, path.parent.relative_to(base).as_posix()))
    return found


def layer_of(folder):
    """A folder's layer: its first component (`model/pendulum` is in `model`)."""
    return folder.split("/")[0]


def graph(root=ROOT):
    """(nodes {name: Node(layer, path, folder)}, edges {(from, to)}) of the code under `root`."""
    nodes, uses, calls, defined = {}, defaultdict(set), defaultdict(set), {}
    for path, folder in sources(root):
        node = Node(layer_of(folder), path, folder)
        text = path.read_text(errors="replace")
        if path.suffix == ".c":
            nodes[path.name] = node
            for name in C_FUNCTION.findall(text):
                defined[name] = path.name
            continue
        match = UNIT.search(text) or SUBMODULE.search(text)
        if not match:
            continue
        name = match.group(2).lower()
        nodes[name] = node
        uses[name] = {used.lower() for used in USE.findall(text)}
        if match.re is SUBMODULE:
            uses[name].add(match.group(1).lower())
        calls[name] = set(BIND.findall(text))
    edges = set()
    for name in uses:
        edges |= {(name, used) for used in uses[name] if used in nodes and used != name}
        edges |= {(name, defined[c]) for c in calls[name] if c in defined}
    return nodes, edges


def unlayered(nodes):
    """Nodes whose folder lies in no layer of LAYERS (src/<other>/...)."""
    return sorted(name for name, node in nodes.items() if node.layer not in LAYERS)


def upward(nodes, edges):
    """Edges from a module to one of a higher layer."""
    order = list(LAYERS)
    return sorted((a, b) for a, b in edges if nodes[a].layer in LAYERS and nodes[b].layer in LAYERS
                  and order.index(nodes[b].layer) > order.index(nodes[a].layer))


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


def folder_graph(nodes, edges):
    """(files {folder: number of nodes}, counts {(from folder, to folder): number of edges}).

    The folders come lowest layer first, and in a layer by their path, so the layer's own folder
    comes before its subfolders."""
    order = list(LAYERS)
    folders = sorted({node.folder for node in nodes.values()}, key=lambda f: (order.index(layer_of(f)), f))
    files = Counter(node.folder for node in nodes.values())
    counts = Counter((nodes[a].folder, nodes[b].folder) for a, b in edges)
    return {folder: files[folder] for folder in folders}, dict(sorted(counts.items()))


def descriptions(nodes, edges):
    """{picture: the text its files carry as their description}: what it was drawn from, so that a
    test can tell a picture that no longer matches the sources."""
    files, counts = folder_graph(nodes, edges)
    listing = [f"{name} {node.folder}" for name, node in sorted(nodes.items())] + [f"{a} {b}" for a, b in sorted(edges)]
    fingerprint = hashlib.sha256("\n".join(listing).encode()).hexdigest()[:16]
    return {
        "folder_graph": "; ".join([f"{folder}: {n} files" for folder, n in files.items()]
                                  + [f"{a} -> {b}: {n}" for (a, b), n in counts.items()]),
        "module_graph": f"{len(nodes)} modules and C files, {len(edges)} edges, fingerprint {fingerprint}",
    }


def described(svg_text):
    """The description an SVG drawn by this script carries ('' when it has none)."""
    match = re.search(r"<dc:description>(.*?)</dc:description>", svg_text, re.DOTALL)
    return html.unescape(match.group(1)) if match else ""


def box_label(folder):
    return folder if layer_of(folder) == "drivers" else f"src/{folder}"


def box_counts(files, inside):
    """The second line of a folder's box: its files and the edges between them."""
    return f"{files} file{'s' * (files != 1)}, {inside} edge{'s' * (inside != 1)} within"


def draw_modules(nodes, edges):
    """One band per layer (lowest at the bottom), modules as labelled boxes, uses as arrows; the
    modules of a subfolder are framed together in their layer's band."""
    import matplotlib.pyplot as plt

    order = list(LAYERS)
    rows = {layer: sorted((n for n, node in nodes.items() if node.layer == layer), key=lambda n: (nodes[n].folder, n))
            for layer in order}
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
        for folder in sorted({nodes[n].folder for n in members} - {layer}):
            xs = [place[n][0] for n in members if nodes[n].folder == folder]
            step = width / len(members)
            ax.add_patch(plt.Rectangle((min(xs) - 0.45 * step, y - 0.36), max(xs) - min(xs) + 0.9 * step, 0.72,
                                       facecolor="none", edgecolor="0.3", linewidth=0.8, zorder=2))
            ax.text(min(xs) - 0.42 * step, y + 0.33, box_label(folder), ha="left", va="top", fontsize=7, zorder=2)
    for a, b in sorted(edges):
        (x0, y0), (x1, y1) = place[a], place[b]
        bad = order.index(nodes[b].layer) > order.index(nodes[a].layer)
        ax.annotate("", xy=(x1, y1 + 0.12 * (1 if y1 < y0 else -1)), xytext=(x0, y0),
                    arrowprops=dict(arrowstyle="-|>", color="red" if bad else "0.55", linewidth=0.35,
                                    alpha=0.9 if bad else 0.35, shrinkA=4, shrinkB=4), zorder=1)
    ax.set_xlim(-1.0, width)
    ax.set_ylim(-0.6, len(order) - 0.4)
    ax.axis("off")
    ax.set_title("Module graph: `use` and C calls, layers lowest at the bottom (an arrow points to what is used)",
                 fontsize=10)
    fig.tight_layout()
    return fig, 150


# The folder graph is laid out in inches: a column of folder boxes, one slot each, and every arrow
# an arc on their right whose reach grows with the number of slots it spans, so that no arrow
# crosses a box and every count stands at its own arc's apex.
SLOT, BOX_WIDTH, BOX_HEIGHT, LABEL_WIDTH, REACH, INDENT = 0.72, 2.1, 0.5, 1.15, 0.42, 0.18
CHARACTER_WIDTH = 0.075     # inches, of the 9-point monospaced folder names
# A colour per folder that uses others (red is kept for an arrow to a higher layer).
ARC_COLOURS = ("tab:blue", "tab:orange", "tab:green", "tab:purple", "tab:brown", "tab:pink", "tab:olive",
               "tab:cyan", "0.35", "black", "#8c6d31", "#393b79")


def draw_folders(nodes, edges):
    """The layers as bands (lowest at the bottom), a folder as a box (a subfolder is a box of its
    own, indented, in its layer's band), an arrow from each folder to each folder it uses, labelled
    with the number of edges; the edges inside a folder are counted in its box."""
    import matplotlib.pyplot as plt
    from matplotlib.patches import FancyArrowPatch, Rectangle
    from matplotlib.path import Path as CurvePath

    order = list(LAYERS)
    files, counts = folder_graph(nodes, edges)
    slot = {folder: i for i, folder in enumerate(files)}
    arcs = [(a, b, n) for (a, b), n in counts.items() if a != b]
    # An arc's reach in slots; of two arcs between the same folders, the upward one reaches further.
    reach = {(a, b): abs(slot[a] - slot[b]) + (0.5 if (b, a) in counts and slot[a] < slot[b] else 0.0)
             for a, b, _ in arcs}
    box_width = max([BOX_WIDTH] + [INDENT * f.count("/") + CHARACTER_WIDTH * len(box_label(f)) + 0.3 for f in files])
    users = sorted({a for a, _, _ in arcs}, key=slot.get)
    width = LABEL_WIDTH + box_width + (max(reach.values(), default=0) + 0.8) * REACH + 0.2
    top = 0.62
    height = len(files) * SLOT + top + 0.08
    fig = plt.figure(figsize=(width, height))
    ax = fig.add_axes([0, 0, 1, 1])
    ax.set_xlim(0, width)
    ax.set_ylim(0, height)
    ax.axis("off")

    def y_of(folder):
        return 0.08 + (slot[folder] + 0.5) * SLOT

    right = LABEL_WIDTH + box_width
    for number, layer in enumerate(order, start=1):
        members = [f for f in files if layer_of(f) == layer]
        if not members:
            continue
        low, high = y_of(members[0]) - SLOT / 2 + 0.03, y_of(members[-1]) + SLOT / 2 - 0.03
        ax.add_patch(Rectangle((0.05, low), width - 0.1, high - low, facecolor="0.93" if number % 2 else "0.86",
                               edgecolor="none", zorder=0))
        ax.text(0.15, (low + high) / 2, f"{number}  {layer}", ha="left", va="center", fontsize=9.5,
                fontweight="bold")
    for folder, n in files.items():
        indent = INDENT * folder.count("/")
        ax.add_patch(Rectangle((LABEL_WIDTH + indent, y_of(folder) - BOX_HEIGHT / 2), box_width - indent, BOX_HEIGHT,
                               facecolor="white", edgecolor="0.25", linewidth=0.8, zorder=2))
        inside = counts.get((folder, folder), 0)
        ax.text(LABEL_WIDTH + indent + 0.1, y_of(folder) + 0.07, box_label(folder), ha="left", va="center",
                fontsize=9, family="monospace", zorder=3)
        ax.text(LABEL_WIDTH + indent + 0.1, y_of(folder) - 0.12, box_counts(n, inside), ha="left",
                va="center", fontsize=7, color="0.3", zorder=3)
    # Each arc ends at a port of its own on the box's right side. Top to bottom: the arcs to folders
    # above, nearest first, then those to folders below, farthest first; so arcs that share a box
    # nest instead of crossing there.
    ports = defaultdict(list)
    for a, b, _ in arcs:
        for here, there in ((a, b), (b, a)):
            outer = reach[(a, b)] - abs(slot[a] - slot[b])
            ports[here].append(((slot[there] < slot[here], slot[there] - slot[here],
                                 -outer if slot[there] < slot[here] else outer), (a, b)))
    port = {}
    for folder, ends in ports.items():
        ends.sort()
        for k, (_, arc) in enumerate(ends):
            port[(folder, arc)] = y_of(folder) + 0.4 * BOX_HEIGHT * (1 - 2 * (k + 0.5) / len(ends))
    heaviest = max((n for _, _, n in arcs), default=1)
    for a, b, n in arcs:
        bad = order.index(layer_of(b)) > order.index(layer_of(a))
        colour = "red" if bad else ARC_COLOURS[users.index(a) % len(ARC_COLOURS)]
        start, end = port[(a, (a, b))], port[(b, (a, b))]
        apex = reach[(a, b)] * REACH + 0.12
        control = apex / 0.75       # a cubic Bezier with both controls at `control` peaks at 3/4 of it
        curve = CurvePath([(right, start), (right + control, start), (right + control, end), (right, end)],
                          [CurvePath.MOVETO, CurvePath.CURVE4, CurvePath.CURVE4, CurvePath.CURVE4])
        ax.add_patch(FancyArrowPatch(path=curve, arrowstyle="-|>,head_length=5,head_width=2.2", color=colour,
                                     linewidth=0.6 + 1.4 * n / heaviest, linestyle="--" if bad else "-", zorder=1))
        ax.text(right + apex, (start + end) / 2, str(n), ha="center", va="center", fontsize=7.5, color=colour,
                fontweight="bold", zorder=4, bbox=dict(boxstyle="round,pad=0.12", facecolor="white", edgecolor="none"))
    ax.text(0.1, height - 0.2, "Folders in their layers (lowest at the bottom)", ha="left", va="center", fontsize=10,
            fontweight="bold")
    ax.text(0.1, height - 0.43, "An arrow points from a folder to one it uses, in the user's colour; its number counts "
            "the use statements and C calls between their files.", ha="left", va="center", fontsize=7.5)
    return fig, 200


def draw(nodes, edges, folder):
    """Both pictures into `folder`, as SVG and PNG, each described by what it was drawn from."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    # The same sources give the same bytes, so that make docs leaves a clean tree: no date in the
    # SVG's metadata, and its clip-path ids from a fixed salt instead of a random one.
    plt.rcParams["svg.hashsalt"] = "module_graph"
    text = descriptions(nodes, edges)
    for name, picture in (("folder_graph", draw_folders), ("module_graph", draw_modules)):
        fig, dpi = picture(nodes, edges)
        for suffix, metadata in ((".svg", {"Date": None, "Description": text[name]}),
                                 (".png", {"Description": text[name]})):
            path = (folder / name).with_suffix(suffix)
            fig.savefig(path, dpi=dpi, metadata=metadata)
            print(f"wrote {path}")
        plt.close(fig)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--check", action="store_true", help="check the layers and cycles instead of drawing")
    parser.add_argument("-o", "--output", default=str(ROOT / "docs" / "architecture"),
                        help="the folder to draw folder_graph and module_graph (SVG and PNG) into")
    parser.add_argument("--root", default=str(ROOT), help="the project's top folder")
    args = parser.parse_args(argv)
    root = Path(args.root)
    nodes, edges = graph(root)
    problems = [f"{nodes[name].path.relative_to(root)} is in src/{nodes[name].folder}, which is in no layer "
                f"({', '.join(LAYERS)})" for name in unlayered(nodes)]
    if args.check:
        problems += [f"{a} ({nodes[a].layer}) uses {b} ({nodes[b].layer}), a higher layer"
                     for a, b in upward(nodes, edges)]
        cycle = cycles(nodes, edges)
        if cycle:
            problems.append("cycle: " + " -> ".join(cycle))
        for problem in problems:
            print(problem)
        print(f"{len(nodes)} modules and C files, {len(edges)} edges, {len(problems)} problems")
        return 1 if problems else 0
    if problems:
        print(*problems, sep="\n", file=sys.stderr)
        return 1
    draw(nodes, edges, args.output)
    return 0


if __name__ == "__main__":
    sys.exit(main())
