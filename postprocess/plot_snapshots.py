"""Fig. 3 analogue: snapshots of the double pendulum at chosen times, and an animation.

Each snapshot shows the origin (support), the masses m1 at q1 and m2 at q1 + q2 (q2 is
relative to m1) and the two springs coloured by their temperatures, in two projections:
side view x-z (gravity points to -z) and top view x-y. One row pair per run file.

Animation (unless --no-animation): written as OUT_animation.mp4 with matplotlib's ffmpeg
writer when ffmpeg is on PATH, otherwise as OUT_animation.gif with the Pillow writer (Pillow
ships with matplotlib). The script prints which one it wrote.
"""
import matplotlib
from matplotlib import animation
from matplotlib.collections import LineCollection
import numpy as np

from plotting import argument_parser, describe, output_stem, plt, run_script, save
from trajectory import mass_positions, read_run, snapshot_steps

PLANES = [((0, 2), "x [m]", "z [m]", "side view x-z"), ((0, 1), "x [m]", "y [m]", "top view x-y")]
COLOUR_MAP = "coolwarm"


def pendulum_points(run):
    """Origin, m1 and m2 positions per step, (N+1, 3, 3)."""
    m1, m2 = mass_positions(run)
    return np.stack([np.zeros_like(m1), m1, m2], axis=1)


def view_limits(runs):
    """Limits (low, high) per coordinate over every run, origin included: one common width for
    x, y and z, so every panel is square at equal aspect even when the motion is flat."""
    points = np.concatenate([pendulum_points(run).reshape(-1, 3) for run in runs])
    low, high = points.min(axis=0), points.max(axis=0)
    centre, half_width = 0.5 * (low + high), 0.55 * max(high - low) + 0.1
    return centre - half_width, centre + half_width


def temperature_scale(runs):
    """One colour scale for both springs of every run, so colours compare across panels."""
    temperatures = np.concatenate([run.data["temperature"].ravel() for run in runs])
    return matplotlib.colors.Normalize(temperatures.min(), temperatures.max())


class PendulumView:
    """The artists of one projection panel: trail of m2, two springs, masses, origin."""

    def __init__(self, ax, plane, limits, norm):
        (i, j), xlabel, ylabel, _ = plane
        self.axes = (i, j)
        self.trail, = ax.plot([], [], color="0.75", linewidth=0.6, zorder=1)
        self.springs = LineCollection([], cmap=COLOUR_MAP, norm=norm, linewidths=3, zorder=2)
        ax.add_collection(self.springs)
        self.masses, = ax.plot([], [], "o", color="black", markersize=7, zorder=3)
        ax.plot([0], [0], marker="^", color="black", markersize=9, linestyle="none", zorder=3)
        ax.set_xlim(limits[0][i], limits[1][i])
        ax.set_ylim(limits[0][j], limits[1][j])
        ax.set_aspect("equal")
        ax.set_xlabel(xlabel)
        ax.set_ylabel(ylabel)

    def show(self, points, temperatures, step):
        """Draws step `step`; the trail is m2's path up to it."""
        i, j = self.axes
        now = points[step][:, [i, j]]
        self.springs.set_segments([now[0:2], now[1:3]])
        self.springs.set_array(np.asarray(temperatures[step]))
        self.masses.set_data(now[1:, 0], now[1:, 1])
        self.trail.set_data(points[: step + 1, 2, i], points[: step + 1, 2, j])


def make_figure(runs, times):
    """Snapshot columns (one per time) and, per run, a side-view and a top-view row."""
    limits, norm = view_limits(runs), temperature_scale(runs)
    selections = [snapshot_steps(run.data["time"], times) for run in runs]
    columns = max(len(steps) for steps, _ in selections)
    if columns == 0:
        raise ValueError(f"no requested time {list(times)} lies within any run")
    fig, axes = plt.subplots(2 * len(runs), columns, figsize=(3.2 * columns + 1.5, 3.4 * 2 * len(runs)),
                             layout="constrained", squeeze=False)
    for r, (run, (steps, dropped)) in enumerate(zip(runs, selections)):
        if dropped:
            print(f"{run.path}: times {dropped} s lie past its last step "
                  f"t = {run.data['time'][-1]:g} s and are left out")
        points, temperatures = pendulum_points(run), run.data["temperature"]
        for c in range(columns):
            for p, plane in enumerate(PLANES):
                ax = axes[2 * r + p, c]
                if c >= len(steps):
                    ax.set_visible(False)
                    continue
                PendulumView(ax, plane, limits, norm).show(points, temperatures, steps[c])
                ax.set_title(f"{run.label}\n{plane[3]}, $t_n$ = {run.data['time'][steps[c]]:.2f} s",
                             fontsize=8)
    colour_bar = fig.colorbar(matplotlib.cm.ScalarMappable(norm, COLOUR_MAP), ax=axes, shrink=0.6)
    colour_bar.set_label(r"spring temperature $\theta_a$ [K]")
    describe(fig, "Snapshots of the thermoviscoelastic double pendulum "
                  "(triangle: origin, dots: m1 and m2, grey: path of m2)", runs)
    return fig


def animation_writer():
    """('mp4', ffmpeg writer) when ffmpeg is available, otherwise ('gif', Pillow writer)."""
    if animation.writers.is_available("ffmpeg"):
        return "mp4", animation.FFMpegWriter(fps=10)
    return "gif", animation.PillowWriter(fps=10)


def write_animation(runs, output, max_frames):
    """Animation of every run side by side (one row per run); frames are common times."""
    limits, norm = view_limits(runs), temperature_scale(runs)
    last = max(run.data["time"][-1] for run in runs)
    smallest_dt = min(run.attrs["dt"] for run in runs)
    frame_times = np.linspace(0.0, last, int(min(max_frames, round(last / smallest_dt) + 1)))
    fig, axes = plt.subplots(len(runs), 2, figsize=(10, 4.2 * len(runs)), layout="constrained",
                             squeeze=False)
    panels = []
    for run, row in zip(runs, axes):
        views = [PendulumView(ax, plane, limits, norm) for ax, plane in zip(row, PLANES)]
        panels.append((run, pendulum_points(run), views, row[0].set_title("", fontsize=8)))
    fig.colorbar(matplotlib.cm.ScalarMappable(norm, COLOUR_MAP), ax=axes,
                 shrink=0.7).set_label(r"spring temperature $\theta_a$ [K]")
    describe(fig, "Double pendulum (triangle: origin, dots: m1 and m2, grey: path of m2)", runs)

    def draw(t):
        for run, points, views, title in panels:
            # The last completed step at or before t: an incomplete run stops at its last step.
            step = int(np.searchsorted(run.data["time"], t + 1e-9 * smallest_dt, side="right")) - 1
            for view in views:
                view.show(points, run.data["temperature"], step)
            title.set_text(f"{run.label}: $t_n$ = {run.data['time'][step]:.2f} s")

    suffix, writer = animation_writer()
    stem = output_stem(output)
    path = stem.with_name(f"{stem.name}_animation.{suffix}")
    draw(frame_times[0])
    fig.canvas.draw()
    fig.set_layout_engine("none")  # the layout is fixed now; re-solving it per frame is slow
    with writer.saving(fig, path, dpi=80):
        for t in frame_times:
            draw(t)
            writer.grab_frame()
    plt.close(fig)
    print(f"wrote {path} ({'MP4, ffmpeg' if suffix == 'mp4' else 'GIF, Pillow: ffmpeg not found'})")
    return path


def main(argv=None):
    parser = argument_parser(__doc__)
    parser.add_argument("--times", nargs="+", type=float, metavar="T",
                        help="snapshot times [s]; the nearest step is shown "
                             "(default: 4 times spread evenly from 0 to the last step)")
    parser.add_argument("--no-animation", action="store_true", help="write only the snapshots")
    parser.add_argument("--max-frames", type=int, default=200,
                        help="at most this many animation frames (default 200)")
    args = parser.parse_args(argv)
    runs = [read_run(path, ["state", "temperature"]) for path in args.files]
    last = max(run.data["time"][-1] for run in runs)
    times = args.times if args.times else list(np.linspace(0.0, last, 4))
    if not any(snapshot_steps(run.data["time"], times)[0] for run in runs):
        parser.error(f"no time of --times {times} lies within a run (the last step is at {last:g} s)")
    written = save(make_figure(runs, times), args.output)
    if not args.no_animation:
        written.append(write_animation(runs, args.output, args.max_frames))
    return written


if __name__ == "__main__":
    run_script(main)
