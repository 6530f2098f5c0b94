"""Figure helpers shared by the plot scripts: the publication style, command line, run styles,
axes, and saving with provenance.

The paper style (the default) sizes figures to journal columns (SINGLE_COLUMN, DOUBLE_COLUMN)
and sets every text to at least MIN_FONT_POINTS at that, the printed, size; PDFs embed TrueType
fonts (pdf.fonttype 42, not Type 3); ticks and their 10^n labels come from matplotlib's own
locators and formatters. Provenance (command line, and per run file its scheme, thermodynamic
variable, dt, input file, code version and status) goes into the files' metadata (PNG text
chunks, PDF document information) and a caption file OUT.txt, not onto the figure.
"""
import argparse
import shlex
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # scripts write files only; no display needed
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.ticker import SymmetricalLogLocator  # noqa: E402

import integrators  # noqa: E402
from trajectory import RunFileError  # noqa: E402

# Journal column widths [in]: one column and the full text width.
SINGLE_COLUMN, DOUBLE_COLUMN = 3.5, 7.0
MIN_FONT_POINTS = 8
PAPER_STYLE = {
    "font.size": MIN_FONT_POINTS, "axes.titlesize": MIN_FONT_POINTS, "axes.labelsize": MIN_FONT_POINTS,
    "xtick.labelsize": MIN_FONT_POINTS, "ytick.labelsize": MIN_FONT_POINTS,
    "legend.fontsize": MIN_FONT_POINTS, "legend.title_fontsize": MIN_FONT_POINTS,
    "figure.titlesize": 9, "figure.labelsize": MIN_FONT_POINTS,
    "pdf.fonttype": 42, "ps.fonttype": 42,            # TrueType, not Type 3
    "axes.formatter.use_mathtext": True,              # 10^n, not 1e-12, in scalar labels too
    "axes.formatter.limits": (-3, 4),
    "axes.linewidth": 0.6, "grid.linewidth": 0.3, "grid.color": "0.85",
    "xtick.major.width": 0.6, "ytick.major.width": 0.6, "xtick.minor.width": 0.4, "ytick.minor.width": 0.4,
    "lines.linewidth": 1.0, "lines.markersize": 3.5, "lines.markeredgewidth": 0.7,
    "legend.frameon": False, "legend.handlelength": 2.2, "legend.columnspacing": 1.2,
    "figure.constrained_layout.use": True, "figure.dpi": 100, "savefig.dpi": 300,
}
matplotlib.style.use(PAPER_STYLE)

# Colour per thermodynamic variable, so EME and midpoint runs of one variable match.
VARIABLE_COLOURS = {"entropy": "tab:blue", "temperature": "tab:red", "internal_energy": "tab:green"}
VARIABLE_ORDER = ("entropy", "temperature", "internal_energy")
# Nested markers (large, middle, small; drawn large first): points of up to three curves that
# coincide stay visible as a circle around a triangle around a square. A second set of shapes
# tells apart curves of two schemes that coincide (a circle and a diamond both show).
NESTED_MARKERS = ((("o", 5.0), ("^", 3.5), ("s", 2.0)), (("D", 4.5), ("v", 3.5), ("p", 2.5)))
# Increments below this size [J or J/K] are drawn on the linear part of the symlog axis.
INCREMENT_LINEAR_THRESHOLD = 1e-16
# Markers on a curve: about this many, so that a curve under another still shows.
MARKERS_PER_CURVE = 12


def argument_parser(description):
    """Parser with the arguments every script takes: FILE.h5 ..., -o OUT and --style."""
    parser = argparse.ArgumentParser(description=description,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("files", nargs="+", metavar="FILE.h5", help="run files written by eme_run")
    parser.add_argument("-o", "--output", required=True, metavar="OUT",
                        help="output path without suffix: writes OUT.png and OUT.pdf, and the caption "
                             "with every file's provenance to OUT.txt")
    parser.add_argument("--style", default="paper", metavar="STYLE",
                        help="'paper' (default): journal column widths (3.5 and 7 in), text >= 8 pt, "
                             "TrueType fonts; any other matplotlib style name or .mplstyle file is "
                             "applied on top of it")
    return parser


def parse_arguments(parser, argv):
    """Parses the command line and applies --style (a bad style is a usage error)."""
    args = parser.parse_args(argv)
    if args.style != "paper":
        try:
            matplotlib.style.use(args.style)
        except (OSError, ValueError) as error:
            parser.error(f"--style {args.style}: {error}")
    return args


def output_stem(output):
    """OUT without a .png/.pdf suffix; its folder is created."""
    path = Path(output)
    if path.suffix.lower() in (".png", ".pdf"):
        path = path.with_suffix("")
    path.parent.mkdir(parents=True, exist_ok=True)
    return path


def provenance(title, runs=(), lines=()):
    """The caption text: title, the command that drew the figure, one line per run file, and
    any further lines."""
    script = Path(sys.argv[0]).name
    command = shlex.join([script, *sys.argv[1:]])
    text = [title, f"Drawn by: {command} (matplotlib {matplotlib.__version__})"]
    text += [f"{run.name}: {run.description}" for run in runs]
    return "\n".join(text + list(lines))


def save(fig, output, title, runs=(), lines=()):
    """Writes OUT.png and OUT.pdf at the figure's size with the provenance in their metadata,
    and OUT.txt with the same text; closes the figure and returns the three paths."""
    for run in runs:
        if run.incomplete:
            print(f"{Path(sys.argv[0]).name}: {run.path}: {run.incomplete_mark}, drawn as far as it goes "
                  f"(status: {run.status}" + "".join(f"; {problem}" for problem in run.problems) + ")",
                  file=sys.stderr)
    stem = output_stem(output)
    caption = provenance(title, runs, lines)
    creator = f"{Path(sys.argv[0]).name} (matplotlib {matplotlib.__version__})"
    metadata = {".png": {"Title": title, "Description": caption, "Software": creator},
                ".pdf": {"Title": title, "Subject": caption, "Creator": creator}}
    paths = []
    for suffix in (".png", ".pdf"):
        path = stem.with_name(stem.name + suffix)
        fig.savefig(path, metadata=metadata[suffix])
        paths.append(path)
        print(f"wrote {path}")
    text_path = stem.with_name(stem.name + ".txt")
    text_path.write_text(caption + "\n")
    paths.append(text_path)
    print(f"wrote {text_path}")
    plt.close(fig)
    return paths


def variable_position(variable):
    """Place of a thermodynamic variable in VARIABLE_ORDER (unknown ones after)."""
    return VARIABLE_ORDER.index(variable) if variable in VARIABLE_ORDER else len(VARIABLE_ORDER)


def curve_style(colour, position, filled=True, linestyle="-", shapes=0):
    """Line and nested marker of curve `position` from the marker set `shapes`; `filled` False
    draws open markers."""
    nested = NESTED_MARKERS[shapes % len(NESTED_MARKERS)]
    marker, size = nested[position % len(nested)]
    return dict(color=colour, marker=marker, markersize=size, linestyle=linestyle,
                markerfacecolor=colour if filled else "none", zorder=2 + 0.1 * position)


# Markers of runs that their variables do not tell apart, large to small so that coinciding points
# of several runs stay visible.
DISTINCT_MARKERS = (("o", 5.5), ("s", 4.6), ("D", 3.9), ("^", 3.6), ("v", 3.3), ("p", 3.0), ("X", 2.8),
                    ("*", 2.6), ("P", 2.4), ("h", 2.2))
# Colours of runs that neither their variable nor their scheme tells apart (Okabe-Ito, then tab10).
RUN_COLOURS = ("#0072B2", "#D55E00", "#009E73", "#CC79A7", "#E69F00", "#56B4E9", "#000000", "#F0E442",
               "tab:brown", "tab:gray", "tab:olive", "tab:purple")


def run_styles(runs, compare=False):
    """One style per run, no two alike in colour or in marker: colour and nested marker by
    thermodynamic variable while the variables tell the runs apart (the paper's Fig. 4); else a
    marker of its own per run, in the scheme's colour (the registry's) while the schemes tell the
    runs apart, otherwise in a colour of its own. Compared runs are dashed with open markers."""
    keys = [(run.attrs["scheme"], run.attrs["thermo_variable"]) for run in runs]
    variables = [variable for _, variable in keys]
    styles = []
    for index, (scheme, variable) in enumerate(keys):
        if len(set(variables)) == len(runs):
            style = curve_style(VARIABLE_COLOURS.get(variable, "black"), variable_position(variable))
        else:
            colour = (integrators.colour(scheme) if len(set(keys)) == len(runs) and
                      len({s for s, _ in keys}) == len(runs) else RUN_COLOURS[index % len(RUN_COLOURS)])
            marker, size = DISTINCT_MARKERS[index % len(DISTINCT_MARKERS)]
            style = dict(color=colour, marker=marker, markersize=size, linestyle="-", markerfacecolor=colour,
                         zorder=2 + 0.1 * index)
        if compare:
            style.update(linestyle="--", markerfacecolor="none")
        styles.append(style)
    return styles


def styled_runs(runs, compare=()):
    """(run, style) pairs: the runs, then the compared runs (dashed, open markers), each set
    told apart by run_styles."""
    return list(zip(runs, run_styles(runs))) + list(zip(compare, run_styles(compare, compare=True)))


def add_compare_argument(parser):
    parser.add_argument("--compare", nargs="+", default=[], metavar="FILE.h5",
                        help="midpoint-rule (or any other) runs to overlay, dashed with open markers")
    parser.add_argument("--labels", nargs="+", default=None, metavar="LABEL",
                        help="legend labels, one per file (FILE.h5 ... then the --compare files), instead of "
                             "the scheme, variable and dt; matplotlib math text such as '$\\Delta t$' works")


def apply_labels(parser, labels, runs):
    """Gives each run its --labels entry (a usage error unless there is one per run); without
    --labels, runs whose labels coincide get their file names added."""
    if labels is not None:
        if len(labels) != len(runs):
            parser.error(f"--labels: {len(labels)} labels for {len(runs)} files; allowed: one per file")
        for run, label in zip(runs, labels):
            run.custom_label = label
        return
    names = [run.label for run in runs]
    for run in runs:
        if names.count(run.label) > 1:
            run.custom_label = f"{run.label} ({run.path.stem})"


def plot_marked(ax, x, y, style, **more):
    """A curve with MARKERS_PER_CURVE markers on it (its legend entry shows line and marker)."""
    return ax.plot(x, y, markevery=max(1, len(x) // MARKERS_PER_CURVE), **style, **more)


# Markers of a point series at most: a 40,000-step run drew one per step, solid bands that took
# 19 s; above it, each of MAX_POINT_MARKERS / 2 equal stretches shows its smallest and largest value.
MAX_POINT_MARKERS = 600


def thinned(x, y, limit=MAX_POINT_MARKERS):
    """At most `limit` points of a series: all of them, or the smallest and the largest of each of
    limit/2 equal stretches (in order), so that every extreme, and every sign, stays drawn."""
    x, y = np.asarray(x), np.asarray(y)
    if len(x) <= limit:
        return x, y
    edges = np.linspace(0, len(x), limit // 2 + 1).astype(int)
    keep = set()
    for start, end in zip(edges[:-1], edges[1:]):
        stretch = y[start:end]
        if np.all(np.isnan(stretch)):
            keep.add(start)
            continue
        keep.update((start + int(np.nanargmin(stretch)), start + int(np.nanargmax(stretch))))
    keep = sorted(keep)
    return x[keep], y[keep]


def plot_points(ax, x, y, style):
    """Only the markers of a curve style (no line: a line joining increments of opposite sign
    would cross every decade of a symlog axis): one per point, or of a long series the extremes of
    each stretch (thinned)."""
    return ax.plot(*thinned(x, y), **{**style, "linestyle": "none"})


def flat_aware_limits(ax, values):
    """Keeps a conserved quantity drawn as a flat line instead of magnifying round-off.

    Matplotlib would stretch a series that varies by 1e-13 J over the whole axis; the
    increment panels already show that variation, so here the range is at least 1e-3 of the
    value. Only the view changes, never the plotted numbers."""
    values = np.concatenate([np.ravel(v) for v in values])
    low, high = values.min(), values.max()
    centre, half = 0.5 * (low + high), 0.5 * (high - low)
    minimum = 1e-3 * max(abs(centre), 1e-30)
    if half < minimum:
        ax.set_ylim(centre - 1.05 * minimum, centre + 1.05 * minimum)
    ax.ticklabel_format(axis="y", useOffset=False)


def increment_axis(ax, values, labels=7):
    """Symmetric-log y axis for per-step increments, with at most `labels` labelled ticks.

    Why symlog: an EME energy increment is round-off (1e-13 J) while a midpoint one is of
    order 1 J, and the sign matters (dS >= 0, dV <= 0). Symlog is logarithmic on both sides
    of zero, so 1e-12 and 1 are both read off decades and the sign is the side of the axis;
    exact zeros, which a log of |increment| cannot show, sit on the linear band |x| < 1e-16,
    below the round-off of any quantity of this model (E ~ 600 J, S ~ 2 J/K). The axis ends at the decade
    above the largest increment that matplotlib's symlog locator labels (10^n formatter)."""
    ax.set_yscale("symlog", linthresh=INCREMENT_LINEAR_THRESHOLD, linscale=3.5)
    locator = ax.yaxis.get_major_locator()
    locator.set_params(numticks=labels)
    largest = max((np.max(np.abs(v)) for v in values if len(v)), default=0.0)
    exponent = int(np.ceil(np.log10(largest))) if largest > INCREMENT_LINEAR_THRESHOLD else -12
    for top in 10.0 ** np.arange(exponent, exponent + labels):
        if np.any(np.isclose(locator.tick_values(-top, top), top, rtol=1e-9)):
            break
    ax.set_ylim(-top, top)
    every_decade = SymmetricalLogLocator(linthresh=INCREMENT_LINEAR_THRESHOLD, base=10)
    every_decade.set_params(numticks=1000)
    ax.yaxis.set_minor_locator(every_decade)
    ax.grid(True, axis="y", which="major")


def figure_texts(fig):
    """Every text shown in a figure (titles, labels, legends), for checks."""
    return [t.get_text() for t in fig.findobj(matplotlib.text.Text) if t.get_text()]


def run_script(main):
    """Runs a script's main(); a bad run file ends it with the message and exit status 2."""
    try:
        main()
    except RunFileError as error:
        print(f"{Path(sys.argv[0]).name}: error: {error}", file=sys.stderr)
        sys.exit(2)
