"""Fig. 3 analogue: snapshots of the double pendulum, or of a spring chain, at chosen times, and an
animation.

Each snapshot shows the origin (support), the masses m1 at q1 and m2 at q1 + q2 (q2 is
relative to m1) and the two springs coloured by their temperatures (a perceptually uniform
map trimmed so that no temperature is drawn near-white, and a dark outline), in two
projections: side view x-z (gravity points to -z) and top view x-y. One row pair per run file;
a planar run (columns q1_x q1_y ..., y vertical) has one row, its plane x-y. Springs without
temperatures (elastic springs, no /temperature) are drawn in one colour, and without any the
figure has no colour bar.

A spring chain's file (docs/output.md, A chain's file; read through chain_dataset.open_chain) is
drawn the same way at its snapshots (a dense run's file: every point): the support at the origin,
the masses at q_i (markers for at most 20 masses: more would hide the springs' colours), the
springs between them coloured by their temperatures (and the second support at x = span of a
fixed-fixed chain), the path of the last mass; a 3D chain in the two views, a 2D one in its
plane, a 1D one along x in a flat panel without a vertical scale. A chosen time is the nearest
snapshot's.

Animation (unless --no-animation): OUT_animation.mp4 with matplotlib's ffmpeg writer when
ffmpeg is available (the imageio-ffmpeg wheel of postprocess/requirements.txt brings one, or
ffmpeg on PATH), otherwise OUT_animation.gif with the Pillow writer (Pillow ships with
matplotlib). Frames are one journal page wide at --dpi, so their 8-pt text stays readable.
The script prints which one it wrote.
"""
import matplotlib
from matplotlib import animation, patheffects
from matplotlib.collections import LineCollection
from matplotlib.colors import ListedColormap
from matplotlib.lines import Line2D
import numpy as np

from chain_dataset import open_chain
from plotting import (DOUBLE_COLUMN, argument_parser, output_stem, parse_arguments, plt, run_script,
                      save)
from trajectory import CHAIN_MODEL, RunFileError, dimension, mass_positions, read_run, run_file, snapshot_steps

TITLE = "Snapshots of the thermoviscoelastic double pendulum"
CHAIN_TITLE = "Snapshots of the thermoviscoelastic spring chain"
PLANES = [((0, 2), "x [m]", "side view\nz [m]"), ((0, 1), "x [m]", "top view\ny [m]")]
# A planar run's one plane (y vertical, gravity along -y).
PLANAR_PLANES = [((0, 1), "x [m]", "plane\ny [m]")]
# A 1D chain's line: its masses move along x only.
LINE_PLANES = [((0, 1), "x [m]", "1D chain\n(along x)")]
PLAIN_SPRING_COLOUR = "0.35"
# plasma without its light-yellow top: every temperature is drawn clearly darker than white.
COLOUR_MAP = ListedColormap(matplotlib.colormaps["plasma"](np.linspace(0.0, 0.82, 256)), name="plasma_trimmed")
SPRING_OUTLINE = [patheffects.Stroke(linewidth=4.2, foreground="0.15"), patheffects.Normal()]
PATH_COLOUR = "0.65"
FRAMES_PER_SECOND = 10
MASS_STYLE = dict(marker="o", color="black", markersize=5, linestyle="none")
CHAIN_MASS_STYLE = dict(markersize=2.5)
# A chain of more masses is drawn without their markers, which would hide the springs' colours.
MOST_MASSES_DRAWN = 20
# A 1D chain's panel height against a plane's: the chain is a line, the vertical axis has no meaning.
LINE_PANEL_HEIGHT = 0.3
ORIGIN_STYLE = dict(marker="^", color="black", markersize=6, linestyle="none")


def ffmpeg_available():
    """True when matplotlib can write MP4: ffmpeg from the imageio-ffmpeg wheel, or on PATH."""
    try:
        import imageio_ffmpeg
        matplotlib.rcParams["animation.ffmpeg_path"] = imageio_ffmpeg.get_ffmpeg_exe()
    except (ImportError, RuntimeError):
        pass  # no wheel, or none with a binary for this platform: an ffmpeg on PATH, if any
    return animation.writers.is_available("ffmpeg")


def read_drawn_run(path):
    """A run file to draw: the double pendulum's (/state, /temperature), or a spring chain's of either
    path, its rows read as any run's and its snapshots (times, node positions, temperatures) kept
    in run.chain."""
    with run_file(path) as handle:
        chain = handle.attrs.get("model_name") in (CHAIN_MODEL, CHAIN_MODEL.encode())
    if not chain:
        return read_run(path, ["state"], thermal_datasets=["temperature"])
    run = read_run(path, [])
    with open_chain(path) as snapshots:
        try:
            q = snapshots["q"].values
            theta = snapshots["theta"].values if "theta" in snapshots else None
        except OSError as error:
            raise RunFileError(f"{path}: cannot read the snapshots ({error}); the file may be damaged") from None
        times = snapshots["snapshot_time"].values
    # Nodes: the support at the origin, the masses, and a fixed-fixed chain's second support at x = span.
    count = len(times)
    nodes = [np.zeros((count, 1, 3)), np.pad(q, ((0, 0), (0, 0), (0, 3 - q.shape[2])))]
    if run.attrs.get("ends") == "fixed-fixed":
        nodes.append(np.tile([[[float(run.attrs["span"]), 0.0, 0.0]]], (count, 1, 1)))
    run.chain = {"time": times, "points": np.concatenate(nodes, axis=1), "temperature": theta,
                 "masses": q.shape[1], "dimension": q.shape[2]}
    return run


def is_chain(run):
    """True for a spring chain's run (read_drawn_run keeps its snapshots)."""
    return hasattr(run, "chain")


def times_of(run):
    """The times of a run's drawable states: every point's, or a chain's snapshots'."""
    return run.chain["time"] if is_chain(run) else run.data["time"]


def pendulum_points(run):
    """The nodes per state, (states, nodes, 3): origin, m1 and m2 of the pendulum (a planar run's
    (x, y) with z = 0), or a chain's supports and masses."""
    if is_chain(run):
        return run.chain["points"]
    m1, m2 = mass_positions(run)
    points = np.stack([np.zeros_like(m1), m1, m2], axis=1)
    return np.pad(points, ((0, 0), (0, 0), (0, 3 - points.shape[2])))


def last_mass(run):
    """The node of the mass whose path is drawn: m2, or a chain's last mass."""
    return run.chain["masses"] if is_chain(run) else 2


def planes(run):
    """The projections of a run's panels: side and top view, a planar run's plane, or a 1D chain's line."""
    return {3: PLANES, 2: PLANAR_PLANES, 1: LINE_PLANES}[run.chain["dimension"] if is_chain(run) else dimension(run)]


def masses_drawn(run):
    """Whether a run's masses get markers: the pendulum's two, a chain's up to MOST_MASSES_DRAWN."""
    return not is_chain(run) or run.chain["masses"] <= MOST_MASSES_DRAWN


def temperatures_of(run):
    """The springs' temperatures per state, or None for springs without temperatures."""
    return run.chain["temperature"] if is_chain(run) else run.data.get("temperature")


def view_limits(runs):
    """Limits (low, high) per coordinate over every run, origin included: one common width for
    x, y and z, so every panel is square at equal aspect even when the motion is flat."""
    points = np.concatenate([pendulum_points(run).reshape(-1, 3) for run in runs])
    low, high = points.min(axis=0), points.max(axis=0)
    centre, half_width = 0.5 * (low + high), 0.55 * max(high - low) + 0.1
    return centre - half_width, centre + half_width


def temperature_scale(runs):
    """One colour scale for both springs of every run, so colours compare across panels; None
    when no run has temperatures."""
    found = [temperatures_of(run).ravel() for run in runs if temperatures_of(run) is not None]
    if not found:
        return None
    temperatures = np.concatenate(found)
    return matplotlib.colors.Normalize(temperatures.min(), temperatures.max())


class PendulumView:
    """The artists of one projection panel: the path of m2 (a chain's last mass), the springs, the
    masses, the origin."""

    def __init__(self, ax, plane, limits, norm, run):
        (i, j), xlabel, ylabel = plane
        self.axes = (i, j)
        self.path, = ax.plot([], [], color=PATH_COLOUR, linewidth=0.6, zorder=1)
        coloured = dict(cmap=COLOUR_MAP, norm=norm) if norm is not None else dict(colors=PLAIN_SPRING_COLOUR)
        self.springs = LineCollection([], **coloured, linewidths=2.8, zorder=2, path_effects=SPRING_OUTLINE)
        ax.add_collection(self.springs)
        self.last_mass = last_mass(run)
        self.masses, = ax.plot([], [], **{**MASS_STYLE, **(CHAIN_MASS_STYLE if is_chain(run) else {})}, zorder=3)
        self.masses.set_visible(masses_drawn(run))
        ax.plot([0], [0], **ORIGIN_STYLE, zorder=3)
        self.far_supports, = ax.plot([], [], **ORIGIN_STYLE, zorder=3)     # a fixed-fixed chain's second
        ax.set_xlim(limits[0][i], limits[1][i])
        ax.set_xlabel(xlabel)
        ax.set_ylabel(ylabel)
        if plane is LINE_PLANES[0]:     # a line: a flat panel, no vertical scale
            ax.set_ylim(-1.0, 1.0)
            ax.set_yticks([])
        else:
            ax.set_ylim(limits[0][j], limits[1][j])
            ax.set_aspect("equal")

    def show(self, points, temperatures, step):
        """Draws state `step`: a spring between each two neighbouring nodes; the path is that of
        m2 (a chain's last mass) up to it."""
        i, j = self.axes
        now = points[step][:, [i, j]]
        self.springs.set_segments(np.stack([now[:-1], now[1:]], axis=1))
        if temperatures is not None:
            self.springs.set_array(np.asarray(temperatures[step]))
        else:
            self.springs.set_color(PLAIN_SPRING_COLOUR)
        self.masses.set_data(now[1:self.last_mass + 1, 0], now[1:self.last_mass + 1, 1])
        self.far_supports.set_data(now[self.last_mass + 1:, 0], now[self.last_mass + 1:, 1])
        self.path.set_data(points[: step + 1, self.last_mass, i], points[: step + 1, self.last_mass, j])


def legend_handles(coloured=True, chain=False, all_masses=True):
    """What the markers and lines of a panel are (the springs' colours have the colour bar); a
    chain's masses are named as not drawn where some chain has more than MOST_MASSES_DRAWN."""
    masses = ("masses $m_i$ at $q_i$" if all_masses else
              f"masses $m_i$ at $q_i$ (not drawn for more than {MOST_MASSES_DRAWN})")
    return [Line2D([], [], **ORIGIN_STYLE, label="supports: the origin (and x = span, fixed-fixed)" if chain
                   else "origin (support)"),
            Line2D([], [], **MASS_STYLE, label=masses if chain else "masses $m_1$ at $q_1$, $m_2$ at $q_1 + q_2$"),
            Line2D([], [], color=PATH_COLOUR, linewidth=0.6,
                   label="path of the last mass so far" if chain else "path of $m_2$ so far"),
            Line2D([], [], color=COLOUR_MAP(0.5) if coloured else PLAIN_SPRING_COLOUR, linewidth=2.8,
                   path_effects=SPRING_OUTLINE,
                   label="springs, coloured by temperature" if coloured else "springs (no temperatures)")]


def finish_figure(fig, axes, norm, chain=False, all_masses=True):
    """Colour bar (when some run has temperatures) and the legend of markers and lines (of a
    chain's when `chain`; `all_masses` whether every chain's masses are drawn)."""
    if norm is not None:
        flat = fig.get_figheight() < 3.0      # 1D chains only: a bar as high as the panels, a short label
        colour_bar = fig.colorbar(matplotlib.cm.ScalarMappable(norm, COLOUR_MAP), ax=axes, shrink=1.0 if flat else 0.8,
                                  aspect=8 if flat else 25)
        colour_bar.set_label(r"$\theta_a$ [K]" if flat else r"spring temperature $\theta_a$ [K]")
    fig.legend(handles=legend_handles(norm is not None, chain, all_masses), loc="outside lower center", ncols=2)


def make_figure(runs, times):
    """Snapshot columns (one per time) and, per run, a side-view and a top-view row (a planar
    run: one row, its plane)."""
    limits, norm = view_limits(runs), temperature_scale(runs)
    selections = [snapshot_steps(times_of(run), times) for run in runs]
    columns = max(len(steps) for steps, _ in selections)
    if columns == 0:
        raise ValueError(f"no requested time {list(times)} lies within any run")
    panel = (DOUBLE_COLUMN - 0.9) / max(columns, 3)
    first_rows = np.cumsum([0] + [len(planes(run)) for run in runs])
    heights = [LINE_PANEL_HEIGHT if plane is LINE_PLANES[0] else 1.0 for run in runs for plane in planes(run)]
    fig, axes = plt.subplots(first_rows[-1], columns, figsize=(DOUBLE_COLUMN, sum(heights) * panel + 1.1),
                             squeeze=False, sharex="col", sharey="row", gridspec_kw={"height_ratios": heights})
    for r, (run, (steps, dropped)) in enumerate(zip(runs, selections)):
        if dropped:
            print(f"{run.path}: times {dropped} s lie past its last step "
                  f"t = {times_of(run)[-1]:g} s and are left out")
        points, temperatures = pendulum_points(run), temperatures_of(run)
        for c in range(columns):
            for p, plane in enumerate(planes(run)):
                ax = axes[first_rows[r] + p, c]
                view = PendulumView(ax, plane, limits, norm, run)
                ax.label_outer()  # the panels share their scales: labels on the outer ones
                if c >= len(steps):
                    ax.set_visible(False)
                    continue
                view.show(points, temperatures, steps[c])
                if p == 0:
                    ax.set_title(f"$t_n$ = {times_of(run)[steps[c]]:.2f} s")
    fig.suptitle("; ".join(run.label for run in runs))
    finish_figure(fig, axes, norm, any(is_chain(run) for run in runs), all(masses_drawn(run) for run in runs))
    return fig


def animation_writer():
    """('mp4', ffmpeg writer) when ffmpeg is available, otherwise ('gif', Pillow writer)."""
    if ffmpeg_available():
        return "mp4", animation.FFMpegWriter(fps=FRAMES_PER_SECOND)
    return "gif", animation.PillowWriter(fps=FRAMES_PER_SECOND)


def write_animation(runs, output, max_frames, dpi):
    """Animation of every run (one row per run, side and top view); frames are common times."""
    limits, norm = view_limits(runs), temperature_scale(runs)
    last = max(times_of(run)[-1] for run in runs)
    steps = [float(np.min(np.diff(times_of(run)))) for run in runs if len(times_of(run)) > 1]
    smallest_dt = min(steps, default=1.0)
    frame_times = np.linspace(0.0, last, int(min(max_frames, round(last / smallest_dt) + 1)) if steps else 1)
    fig, axes = plt.subplots(len(runs), 2, figsize=(DOUBLE_COLUMN, 3.1 * len(runs) + 0.9), squeeze=False,
                             sharex=True)
    panels = []
    for run, row in zip(runs, axes):
        views = [PendulumView(ax, plane, limits, norm, run) for ax, plane in zip(row, planes(run))]
        for ax in row[len(views):]:
            ax.set_visible(False)        # a planar run has one plane
        panels.append((run, pendulum_points(run), views, row[0].set_title("", loc="left")))
    finish_figure(fig, axes, norm, any(is_chain(run) for run in runs), all(masses_drawn(run) for run in runs))

    def draw(t):
        for run, points, views, title in panels:
            # The last completed step at or before t: an incomplete run stops at its last step.
            step = int(np.searchsorted(times_of(run), t + 1e-9 * smallest_dt, side="right")) - 1
            for view in views:
                view.show(points, temperatures_of(run), step)
            title.set_text(f"{run.label}: $t_n$ = {times_of(run)[step]:.2f} s")

    suffix, writer = animation_writer()
    stem = output_stem(output)
    path = stem.with_name(f"{stem.name}_animation.{suffix}")
    draw(frame_times[0])
    fig.canvas.draw()
    fig.set_layout_engine("none")  # the layout is fixed now; re-solving it per frame is slow
    with writer.saving(fig, path, dpi=dpi):
        for t in frame_times:
            draw(t)
            writer.grab_frame()
    plt.close(fig)
    print(f"wrote {path} ({'MP4, ffmpeg' if suffix == 'mp4' else 'GIF, Pillow: ffmpeg not found'}, "
          f"{len(frame_times)} frames)")
    return path


def main(argv=None):
    parser = argument_parser(__doc__)
    parser.add_argument("--times", nargs="+", type=float, metavar="T",
                        help="snapshot times [s]; the nearest step is shown "
                             "(default: 4 times spread evenly from 0 to the last step)")
    parser.add_argument("--no-animation", action="store_true", help="write only the snapshots")
    parser.add_argument("--max-frames", type=int, default=200,
                        help="at most this many animation frames (default 200)")
    parser.add_argument("--dpi", type=int, default=150,
                        help="animation resolution in pixels per inch of its 7-in width (default 150)")
    args = parse_arguments(parser, argv)
    runs = [read_drawn_run(path) for path in args.files]
    last = max(times_of(run)[-1] for run in runs)
    times = args.times if args.times else list(np.linspace(0.0, last, 4))
    if not any(snapshot_steps(times_of(run), times)[0] for run in runs):
        parser.error(f"no time of --times {times} lies within a run (the last step is at {last:g} s)")
    title = CHAIN_TITLE if all(is_chain(run) for run in runs) else TITLE
    written = save(make_figure(runs, times), args.output, title, runs)
    if not args.no_animation:
        written.append(write_animation(runs, args.output, args.max_frames, args.dpi))
    return written


if __name__ == "__main__":
    run_script(main)
