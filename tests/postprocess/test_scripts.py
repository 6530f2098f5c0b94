"""The plot scripts on short eme_run runs (t_end = 1 s) and on synthetic files that follow the
documented layout: they write PNG and PDF, plot the files' own numbers, name a missing dataset,
and label an incomplete run."""
import re
import shutil
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest
from matplotlib.collections import LineCollection
from PIL import Image

ROOT = Path(__file__).resolve().parents[2]
POSTPROCESS = ROOT / "postprocess"
EME_RUN = ROOT / "build" / "bin" / "eme_run"
sys.path.insert(0, str(POSTPROCESS))

import plot_balance  # noqa: E402
import plot_constrained  # noqa: E402
import plot_snapshots  # noqa: E402
import plot_temperatures  # noqa: E402
import plotting  # noqa: E402
from plotting import DOUBLE_COLUMN, figure_texts as texts_of, plt  # noqa: E402
from file_checksums import seal_texts  # noqa: E402
from synthetic_runs import constraint_attributes, write_run  # noqa: E402
from trajectory import CONSTRAINT_ATTRIBUTES, RunFileError, read_run  # noqa: E402

VARIABLES = ("entropy", "temperature", "internal_energy")
BALANCE = ["energy", "entropy", "lyapunov"]


def run_eme(directory, name, scheme, variable, *options):
    """1 s of the paper scene; returns (exit status, stderr, output path)."""
    output = directory / f"{name}.h5"
    namelist = directory / f"{name}.nml"
    namelist.write_text(f"&integrator scheme='{scheme}' thermo_variable='{variable}' t_end=1.0 /\n"
                        f"&output file='{output}' /\n")
    result = subprocess.run([str(EME_RUN), str(namelist), *options], capture_output=True,
                            text=True, timeout=120)
    return result.returncode, result.stderr, output


@pytest.fixture(scope="module")
def eme_files(tmp_path_factory):
    """{(scheme, variable): path} of complete runs, and 'incomplete': a run that -snes_max_it 1
    stops at its first step (exit status 3; the file holds only the initial state)."""
    if not EME_RUN.exists():
        pytest.skip(f"{EME_RUN} is missing: run `make` in {ROOT} first")
    directory = tmp_path_factory.mktemp("eme_runs")
    files = {}
    for scheme in ("eme", "midpoint"):
        for variable in VARIABLES:
            status, stderr, path = run_eme(directory, f"{scheme}_{variable}", scheme, variable)
            assert status == 0, stderr
            files[scheme, variable] = path
    status, stderr, path = run_eme(directory, "incomplete", "eme", "temperature", "-snes_max_it", "1")
    assert status == 3, f"expected an incomplete run (exit status 3), got {status}: {stderr}"
    files["incomplete"] = path
    return files


def eme(files):
    return [files["eme", v] for v in VARIABLES]


def midpoint(files):
    return [files["midpoint", v] for v in VARIABLES]


def figure_texts(fig):
    """Every text of a figure, with the run descriptions' wrapped lines joined again."""
    return [text.replace("\n    ", " ") for text in texts_of(fig)]


def assert_png_and_pdf(paths, stem):
    assert [Path(p) for p in paths[:2]] == [stem.with_suffix(".png"), stem.with_suffix(".pdf")]
    png, pdf = (Path(p).read_bytes() for p in paths[:2])
    assert png.startswith(b"\x89PNG") and len(png) > 10_000
    assert pdf.startswith(b"%PDF") and len(pdf) > 5_000


def truncated_copy(source, target, steps, status):
    """A copy of a complete run cut after `steps` steps and marked as the simulator marks an
    incomplete run (status, steps_completed); per-state datasets keep N+1 rows, per-step ones N."""
    shutil.copy(source, target)
    with h5py.File(target, "r+") as f:
        states = len(f["time"])
        for name in list(f):
            rows = steps + 1 if len(f[name]) == states else steps
            data, attrs = f[name][:rows], dict(f[name].attrs)
            del f[name]
            f[name] = data
            f[name].attrs.update(attrs)
        f.attrs["status"] = status
        f.attrs["steps_completed"] = steps
        seal_texts(f)
    return target


# ---------------------------------------------------------------- Fig. 4: balance
def test_balance_writes_png_and_pdf(eme_files, tmp_path):
    stem = tmp_path / "figures" / "fig4"
    paths = plot_balance.main([*map(str, eme(eme_files)), "--compare", *map(str, midpoint(eme_files)),
                               "-o", str(stem)])
    assert_png_and_pdf(paths, stem)


def test_balance_plots_the_files_values_and_next_minus_current_increments(eme_files):
    runs = [read_run(p, BALANCE) for p in eme(eme_files)]
    compare = [read_run(p, BALANCE) for p in midpoint(eme_files)]
    fig = plot_balance.make_figure(runs, compare)
    axes = fig.axes
    for row, name in enumerate(BALANCE):
        values_ax, increments_ax = axes[2 * row], axes[2 * row + 1]
        assert len(values_ax.get_lines()) == 6 and len(increments_ax.get_lines()) == 6
        for run, values_line, increments_line in zip(runs + compare, values_ax.get_lines(),
                                                     increments_ax.get_lines()):
            with h5py.File(run.path, "r") as f:
                time, values = f["time"][()], f[name][()]
            np.testing.assert_array_equal(values_line.get_xdata(), time)
            np.testing.assert_array_equal(values_line.get_ydata(), values)
            np.testing.assert_array_equal(increments_line.get_xdata(), time[1:])
            np.testing.assert_array_equal(increments_line.get_ydata(), values[1:] - values[:-1])
        styles = [line.get_linestyle() for line in values_ax.get_lines()]
        assert styles == ["-"] * 3 + ["--"] * 3
    texts = "\n".join(figure_texts(fig))
    assert "$E$ [J]" in texts and "$S$ [J/K]" in texts and "[s]" in texts
    plt.close(fig)


def test_provenance_goes_to_the_caption_file_and_metadata_not_onto_the_figure(eme_files, tmp_path):
    stem = tmp_path / "fig4"
    png, pdf, caption = plot_balance.main([*map(str, eme(eme_files)), "--compare", *map(str, midpoint(eme_files)),
                                           "-o", str(stem)])
    text = caption.read_text()
    assert caption == stem.with_suffix(".txt") and text.startswith(plot_balance.TITLE)
    for variable in VARIABLES:
        assert f"thermo_variable={variable}" in text
    assert text.count("status: complete") == 6 and "dt=0.15 s" in text and "code " in text
    assert "input " + str(eme(eme_files)[0].with_suffix(".nml")) in text
    assert "Drawn by: " in text
    assert Image.open(png).text["Description"] == text.rstrip("\n")
    assert b"/Subject" in pdf.read_bytes() and b"thermo_variable=entropy" in pdf.read_bytes()
    runs = [read_run(p, BALANCE) for p in eme(eme_files)]
    texts = "\n".join(figure_texts(plot_balance.make_figure(runs)))
    assert "thermo_variable" not in texts and "input" not in texts
    plt.close("all")


def test_balance_increments_of_1e_minus_12_and_1_joule_are_both_readable(eme_files):
    runs = [read_run(p, BALANCE) for p in eme(eme_files)]
    compare = [read_run(p, BALANCE) for p in midpoint(eme_files)]
    fig = plot_balance.make_figure(runs, compare)
    energy_increments = fig.axes[1]
    fig.canvas.draw()
    assert energy_increments.get_yscale() == "symlog"
    low, high = energy_increments.get_ylim()
    assert low <= -1.0 and high >= 1.0
    to_axes = energy_increments.transAxes.inverted()
    heights = [to_axes.transform(energy_increments.transData.transform((0.5, y)))[1]
               for y in (1e-13, 1e-12, 1.0)]
    # 1e-12 sits a visible distance from both round-off (1e-13) and 1 J on the axis.
    assert heights[1] - heights[0] > 0.02 and heights[2] - heights[1] > 0.15
    # matplotlib's symlog locator and 10^n formatter label the axis, 0 included, up to its top.
    labels = [t.get_text() for t in energy_increments.get_yticklabels()
              if low <= t.get_position()[1] <= high]
    assert r"$\mathdefault{0}$" in labels
    powers = [label for label in labels if label != r"$\mathdefault{0}$"]
    assert powers and all(re.fullmatch(r"\$\\mathdefault\{-?10\^\{-?\d+\}\}\$", label) for label in powers), labels
    assert labels[-1] == rf"$\mathdefault{{10^{{{round(np.log10(high))}}}}}$"
    plt.close(fig)


# ---------------------------------------------------------------- temperatures and J_z
def test_temperatures_and_jz_drift(eme_files, tmp_path):
    files = eme(eme_files) + [eme_files["midpoint", "temperature"]]
    stem = tmp_path / "temperatures"
    assert_png_and_pdf(plot_temperatures.main([*map(str, files), "-o", str(stem)]), stem)
    runs = [read_run(p, ["temperature", "angular_momentum"]) for p in files]
    fig = plot_temperatures.make_figure(runs)
    for index, path in enumerate(files):
        with h5py.File(path, "r") as f:
            theta, jz = f["temperature"][()], f["angular_momentum"][:, 2]
        np.testing.assert_array_equal(fig.axes[0].get_lines()[index].get_ydata(), theta[:, 0])
        np.testing.assert_array_equal(fig.axes[1].get_lines()[index].get_ydata(), theta[:, 1])
        np.testing.assert_array_equal(fig.axes[2].get_lines()[index].get_ydata(), jz - jz[0])
    assert "[K]" in fig.axes[0].get_ylabel() and "[J s]" in fig.axes[2].get_ylabel()
    plt.close(fig)


def test_compared_temperatures_get_a_column_of_panels_of_their_own(eme_files):
    """EME in three variables against the midpoint rule in three: the files in the left column,
    the compared runs in the right, three curves each, the rows on the same y axes."""
    needed = ["temperature", "angular_momentum"]
    runs = [read_run(p, needed) for p in eme(eme_files)]
    compare = [read_run(p, needed) for p in midpoint(eme_files)]
    fig = plot_temperatures.make_figure(runs, compare)
    grid = np.array(fig.axes).reshape(3, 2)
    for column, drawn in enumerate((runs, compare)):
        assert "MP" in grid[0, column].get_title() if column else "EME" in grid[0, column].get_title()
        for row, name in enumerate(("theta_1", "theta_2")):
            lines = grid[row, column].get_lines()
            assert len(lines) == 3
            for run, line in zip(drawn, lines):
                np.testing.assert_array_equal(line.get_ydata(), run.column("temperature", name))
                assert line.get_linestyle() == ("--" if column else "-")
        assert grid[0, 0].get_ylim() == grid[0, 1].get_ylim()
    assert len(fig.legends[0].get_texts()) == 6
    plt.close(fig)


# ---------------------------------------------------------------- Fig. 3: snapshots
def test_snapshots_and_animation(eme_files, tmp_path, capsys):
    path = eme_files["eme", "temperature"]
    stem = tmp_path / "fig3"
    written = plot_snapshots.main([str(path), "--times", "0", "0.5", "5", "-o", str(stem)])
    assert_png_and_pdf(written, stem)
    suffix = "mp4" if plot_snapshots.ffmpeg_available() else "gif"
    assert written[3] == tmp_path / f"fig3_animation.{suffix}"
    out = capsys.readouterr().out
    assert f"wrote {written[3]} ({'MP4, ffmpeg' if suffix == 'mp4' else 'GIF, Pillow'}" in out
    assert "times [5.0] s lie past its last step" in out
    with h5py.File(path, "r") as f:
        frames = len(f["time"])
    if suffix == "gif":
        assert Image.open(written[3]).n_frames == frames
    assert f"{frames} frames" in out


def test_animation_is_mp4_when_imageio_ffmpeg_provides_ffmpeg(eme_files, tmp_path):
    pytest.importorskip("imageio_ffmpeg")
    written = plot_snapshots.main([str(eme_files["eme", "temperature"]), "--max-frames", "5", "--dpi", "150",
                                   "-o", str(tmp_path / "fig3")])
    movie = written[3]
    assert movie.suffix == ".mp4"
    header = movie.read_bytes()[:12]
    assert header[4:8] == b"ftyp", header          # an ISO media (MP4) file
    # The frames are the figure's 7 in at 150 dpi: 8-pt text is 17 pixels high.
    import imageio_ffmpeg
    reader = imageio_ffmpeg.read_frames(str(movie))
    width, height = next(reader)["size"]
    reader.close()
    assert width == round(DOUBLE_COLUMN * 150)


def test_snapshot_springs_join_origin_m1_and_m2_coloured_by_temperature(eme_files):
    run = read_run(eme_files["eme", "temperature"], ["state", "temperature"])
    fig = plot_snapshots.make_figure([run], [0.0, 0.45])
    with h5py.File(run.path, "r") as f:
        names = f["state"].attrs["columns"].split()
        state, theta = f["state"][3], f["temperature"][3]
    q1 = np.array([state[names.index(f"q1_{a}")] for a in "xyz"])
    q2 = np.array([state[names.index(f"q2_{a}")] for a in "xyz"])
    side_view = fig.axes[1]  # column 2 (t = 0.45 s = step 3), top row: x-z
    assert "0.45 s" in side_view.get_title()
    springs = [c for c in side_view.collections if isinstance(c, LineCollection)][0]
    m1, m2 = q1[[0, 2]], (q1 + q2)[[0, 2]]
    np.testing.assert_allclose(springs.get_segments(), [[[0, 0], m1], [m1, m2]])
    np.testing.assert_array_equal(springs.get_array(), theta)
    texts = figure_texts(fig)
    assert any("spring temperature" in t and "[K]" in t for t in texts)
    plt.close(fig)


# ---------------------------------------------------------------- Fig. 5: constrained runs
@pytest.fixture()
def constrained_files(tmp_path):
    cases = {"fixed_length": (True, False), "fixed_temperature": (False, True), "both": (True, True)}
    return [write_run(tmp_path / f"fig5_{name}.h5", steps=6,
                      attributes={"dt": 0.15, **constraint_attributes(*flags)})[0]
            for name, flags in cases.items()]


def test_constrained_runs(constrained_files, tmp_path):
    stem = tmp_path / "fig5"
    assert_png_and_pdf(plot_constrained.main([*map(str, constrained_files), "-o", str(stem)]), stem)
    runs = [read_run(p, BALANCE, CONSTRAINT_ATTRIBUTES) for p in constrained_files]
    fig = plot_constrained.make_figure(runs)
    for index, path in enumerate(constrained_files):
        with h5py.File(path, "r") as f:
            values = {name: f[name][()] for name in ("time", *BALANCE)}
        for ax, name in zip(fig.axes[:3], BALANCE):
            np.testing.assert_array_equal(ax.get_lines()[index].get_ydata(), values[name])
        lyapunov_increments = fig.axes[3].get_lines()[index]
        np.testing.assert_array_equal(lyapunov_increments.get_xdata(), values["time"][1:])
        np.testing.assert_array_equal(lyapunov_increments.get_ydata(),
                                      values["lyapunov"][1:] - values["lyapunov"][:-1])
    legend = "\n".join(t.get_text() for t in fig.legends[0].get_texts())
    assert legend.count(r"$l_1$ = 2.5 m") == 2 and legend.count(r"$\theta_1$ = 300 K") == 2
    plt.close(fig)


def test_constrained_run_without_constraint_attributes_is_refused(tmp_path):
    path, _ = write_run(tmp_path / "plain.h5", attributes={"constraints": "length"})
    with pytest.raises(RunFileError, match=f"{path}: root attributes 'fix_length', 'length', "
                                           "'fix_temperature', 'temperature' are missing"):
        plot_constrained.main([str(path), "-o", str(tmp_path / "out")])


# ---------------------------------------------------------------- incomplete runs
def test_incomplete_run_from_eme_run_is_plotted_and_labelled(eme_files, tmp_path):
    path = eme_files["incomplete"]
    with h5py.File(path, "r") as f:
        status = f.attrs["status"]
    assert status.startswith("incomplete")
    plots = [(plot_balance, BALANCE), (plot_temperatures, ["temperature", "angular_momentum"])]
    for module, needed in plots:
        stem = tmp_path / module.__name__
        written = module.main([str(path), "-o", str(stem)])
        assert_png_and_pdf(written, stem)
        assert "status: incomplete: step 1" in written[2].read_text()
        fig = module.make_figure([read_run(path, needed)])
        texts = "\n".join(figure_texts(fig))
        assert "INCOMPLETE after 0 steps" in texts
        plt.close(fig)
    stem = tmp_path / "snapshots"
    written = plot_snapshots.main([str(path), "-o", str(stem)])
    assert_png_and_pdf(written, stem)


def test_truncated_run_is_plotted_up_to_its_last_step(eme_files, tmp_path):
    status = "incomplete: step 4 (t = .6000 s): Newton did not converge"
    path = truncated_copy(eme_files["eme", "entropy"], tmp_path / "stopped.h5", 3, status)
    fig = plot_balance.make_figure([read_run(path, BALANCE)])
    assert len(fig.axes[0].get_lines()[0].get_ydata()) == 4
    assert len(fig.axes[1].get_lines()[0].get_ydata()) == 3
    texts = "\n".join(figure_texts(fig))
    assert "INCOMPLETE after 3 steps" in texts
    plt.close(fig)
    assert status in read_run(path, BALANCE).description
    stem = tmp_path / "snapshots"
    assert_png_and_pdf(plot_snapshots.main([str(path), "--no-animation", "-o", str(stem)]), stem)


# ---------------------------------------------------------------- the command line
SCRIPTS = ["plot_balance.py", "plot_temperatures.py", "plot_snapshots.py", "plot_constrained.py"]


@pytest.mark.parametrize("script", SCRIPTS)
def test_help(script):
    result = subprocess.run([sys.executable, str(POSTPROCESS / script), "--help"],
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    text = " ".join(result.stdout.split())
    assert "OUT.png and OUT.pdf" in text and "FILE.h5" in text and "OUT.txt" in text
    assert "--style" in text and "column widths (3.5 and 7 in)" in text
    if script == "plot_snapshots.py":
        for word in ("OUT_animation.mp4", "imageio-ffmpeg", "OUT_animation.gif", "Pillow"):
            assert word in text
    if script == "plot_balance.py":
        assert "--compare" in result.stdout


def test_command_line_on_eme_run_output(eme_files, tmp_path):
    # One script through `python postprocess/SCRIPT.py`; the others run the same main() above.
    stem = tmp_path / "out"
    result = subprocess.run([sys.executable, str(POSTPROCESS / "plot_temperatures.py"),
                             *map(str, eme(eme_files)), "-o", str(stem)],
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == ["wrote", str(stem) + ".png", "wrote", str(stem) + ".pdf",
                                     "wrote", str(stem) + ".txt"]
    assert_png_and_pdf([stem.with_suffix(".png"), stem.with_suffix(".pdf")], stem)


def test_command_line_names_a_missing_dataset(eme_files, tmp_path):
    path = tmp_path / "no_lyapunov.h5"
    shutil.copy(eme_files["eme", "entropy"], path)
    with h5py.File(path, "r+") as f:
        del f["lyapunov"]
        seal_texts(f)                        # a file without it, not a damaged one
    result = subprocess.run([sys.executable, str(POSTPROCESS / "plot_balance.py"), str(path),
                             "-o", str(tmp_path / "out")], capture_output=True, text=True, timeout=60)
    assert result.returncode == 2
    assert result.stderr.strip() == f"plot_balance.py: error: {path}: dataset '/lyapunov' is missing"
    assert not (tmp_path / "out.png").exists()


def test_a_long_run_draws_the_extremes_of_each_stretch_not_a_marker_per_step(tmp_path):
    """40,000 steps: at most MAX_POINT_MARKERS increments per series, among them the largest and
    the smallest (a single negative entropy increment planted in the middle stays drawn)."""
    steps = 40_000
    n = np.arange(steps + 1, dtype=float)
    entropy = 1.7 + 1e-4 * n + 1e-9 * np.sin(n)
    entropy[20_001:] -= 5e-4                  # step 20,000 -> 20,001 lowers S
    path, _ = write_run(tmp_path / "long.h5", steps=steps, data={"entropy": entropy,
                                                                 "lyapunov": 600.0 - 300.0 * entropy})
    fig = plot_balance.make_figure([read_run(path, BALANCE)])
    increments_ax = fig.axes[3]                                 # entropy row, increments
    (line,) = increments_ax.get_lines()
    drawn = np.asarray(line.get_ydata())
    assert len(drawn) <= plotting.MAX_POINT_MARKERS < steps
    expected = np.diff(entropy)
    assert drawn.min() == expected.min() < 0 and drawn.max() == expected.max()
    assert set(drawn) <= set(expected)                          # the file's increments, none made up
    plt.close(fig)


def test_a_strided_run_s_increments_are_labelled_between_written_points(tmp_path):
    """A file of eme_run with &output every = 5: the axis and the caption say the increments are
    between written points; the same run written every step says per step."""
    labels = {}
    for every in (1, 5):
        output = tmp_path / f"every{every}.h5"
        namelist = tmp_path / f"every{every}.nml"
        namelist.write_text(f"&integrator t_end = 1.5 /\n&output file = '{output}', every = {every} /\n")
        result = subprocess.run([str(EME_RUN), str(namelist)], capture_output=True, text=True, timeout=120)
        assert result.returncode == 0, result.stderr
        png, _, caption = plot_balance.main([str(output), "-o", str(tmp_path / f"fig{every}")])
        labels[every] = (texts_of_saved(output), caption.read_text())
    assert "increment of step" in labels[1][0] and "between written points" not in labels[1][1]
    assert "between written points" in labels[5][0]
    assert "2 rows for 10 steps" in labels[5][1] and "increments are between written points" in labels[5][1]


def texts_of_saved(path):
    fig = plot_balance.make_figure([read_run(path, BALANCE)])
    text = "\n".join(texts_of(fig))
    plt.close(fig)
    return text
