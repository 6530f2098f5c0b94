"""The publication style of every run figure, checked on what the files and figures hold:
TrueType fonts in the PDFs (no Type 3), a journal column width, no text under 8 pt, a legend
entry for every marker, coincident curves told apart, Fig. 5's two reference temperatures
said, and Fig. 3's colours visible on white. Runs are synthetic files of the documented layout
(tests/postprocess/synthetic_runs.py), so these checks need no build."""
import sys
from pathlib import Path

import matplotlib
import numpy as np
import pytest
from PIL import Image

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "postprocess"))

import plot_balance  # noqa: E402
import plot_constrained  # noqa: E402
import plot_snapshots  # noqa: E402
import plot_temperatures  # noqa: E402
import plotting  # noqa: E402
from figure_checks import (drawn_font_sizes, marked_lines, pdf_font_kinds, pdf_width_inches,  # noqa: E402
                           unexplained_markers)
from synthetic_runs import constraint_attributes, run_data, write_run  # noqa: E402
from trajectory import CONSTRAINT_ATTRIBUTES, read_run  # noqa: E402

VARIABLES = ("entropy", "temperature", "internal_energy")
BALANCE = ["energy", "entropy", "lyapunov"]
TRUETYPE = {b"TrueType", b"CIDFontType2", b"Type0"}   # Type0 wraps a CIDFontType2 (TrueType) font
# Journal column widths [in] (one column, the text width) and the smallest printed text [pt].
SINGLE_COLUMN, DOUBLE_COLUMN = 3.5, 7.0
SMALLEST_TEXT = 8


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """Three EME and three midpoint runs (identical numbers within a scheme: coincident curves),
    and three constrained runs with theta_R 300, 280 and 280 K."""
    directory = tmp_path_factory.mktemp("runs")
    made = {}
    for scheme in ("eme", "midpoint"):
        for variable in VARIABLES:
            made[scheme, variable] = write_run(directory / f"{scheme}_{variable}.h5", steps=40, attributes={
                "scheme": scheme, "scheme_label": scheme.upper()[:3] if scheme == "eme" else "MP",
                "thermo_variable": variable, "dt": 0.15})[0]
    for name, flags, theta_r in (("length", (True, False), 300.0), ("temperature", (False, True), 280.0),
                                 ("both", (True, True), 280.0)):
        made[name] = write_run(directory / f"fig5_{name}.h5", steps=40,
                               attributes={"dt": 0.15, "theta_r": theta_r, **constraint_attributes(*flags)})[0]
    return made


def balance_files(files):
    return [files["eme", v] for v in VARIABLES], [files["midpoint", v] for v in VARIABLES]


def written_figures(files, directory):
    """{name: (paths, expected width [in])} of every run figure, through each script's main()."""
    eme, midpoint = balance_files(files)
    return {
        "balance": (plot_balance.main([*map(str, eme), "--compare", *map(str, midpoint), "-o", str(directory / "b")]),
                    DOUBLE_COLUMN),
        "constrained": (plot_constrained.main([str(files[n]) for n in ("length", "temperature", "both")]
                                              + ["-o", str(directory / "c")]), DOUBLE_COLUMN),
        "temperatures": (plot_temperatures.main([*map(str, eme), "--compare", *map(str, midpoint),
                                                 "-o", str(directory / "t")]), DOUBLE_COLUMN),
        "temperatures alone": (plot_temperatures.main([*map(str, eme), "-o", str(directory / "t1")]), SINGLE_COLUMN),
        "snapshots": (plot_snapshots.main([str(eme[1]), "--no-animation", "--times", "0", "2", "4", "6",
                                           "-o", str(directory / "s")]), DOUBLE_COLUMN),
    }


def figures(files):
    """{name: Figure} of every run figure, made in this process."""
    eme, midpoint = balance_files(files)
    read = lambda paths, names, *more: [read_run(p, names, *more) for p in paths]  # noqa: E731
    return {
        "balance": plot_balance.make_figure(read(eme, BALANCE), read(midpoint, BALANCE)),
        "constrained": plot_constrained.make_figure(read([files[n] for n in ("length", "temperature", "both")],
                                                         BALANCE, CONSTRAINT_ATTRIBUTES)),
        "temperatures": plot_temperatures.make_figure(read(eme, ["temperature", "angular_momentum"]),
                                                      read(midpoint, ["temperature", "angular_momentum"])),
        "snapshots": plot_snapshots.make_figure(read(eme[1:2], ["state", "temperature"]), [0.0, 2.0, 4.0, 6.0]),
    }


def test_pdfs_embed_truetype_fonts_and_pages_are_a_journal_column_wide(files, tmp_path):
    for name, (paths, width) in written_figures(files, tmp_path).items():
        png, pdf = paths[0].read_bytes(), paths[1].read_bytes()
        kinds = pdf_font_kinds(pdf)
        assert kinds and kinds <= TRUETYPE and b"/FontFile2" in pdf, (name, kinds)
        assert b"/Type3" not in pdf, name
        assert pdf_width_inches(pdf) == pytest.approx(width, abs=0.01), name
        dpi = matplotlib.rcParams["savefig.dpi"]
        assert Image.open(paths[0]).size[0] == pytest.approx(width * dpi, abs=1), name
        assert png.startswith(b"\x89PNG")


def test_no_text_is_smaller_than_8_pt_at_print_size(files):
    for name, fig in figures(files).items():
        sizes = drawn_font_sizes(fig)
        assert len(sizes) > 10 and min(sizes) >= SMALLEST_TEXT, (name, min(sizes))
        assert fig.get_size_inches()[0] in (SINGLE_COLUMN, DOUBLE_COLUMN), name
    matplotlib.pyplot.close("all")


def test_every_marker_drawn_has_a_legend_entry(files):
    for name, fig in figures(files).items():
        assert marked_lines(fig), name
        assert unexplained_markers(fig) == [], name
    matplotlib.pyplot.close("all")


def test_coincident_curves_keep_distinct_markers(files):
    # The three EME runs hold the same numbers: their curves coincide, their markers must not.
    fig = figures(files)["balance"]
    energy = fig.axes[0].get_lines()[:3]
    assert all(np.array_equal(line.get_ydata(), energy[0].get_ydata()) for line in energy)
    markers = {(line.get_marker(), line.get_markersize()) for line in energy}
    assert len(markers) == 3
    # Drawn largest first, so the smaller ones sit on top and stay visible.
    sizes = [line.get_markersize() for line in sorted(energy, key=lambda line: line.get_zorder())]
    assert sizes == sorted(sizes, reverse=True)
    matplotlib.pyplot.close("all")


def test_fig5_says_when_v_has_two_reference_temperatures(files):
    fig = figures(files)["constrained"]
    lyapunov = fig.axes[2]
    title = lyapunov.get_title(loc="left")
    assert r"own $\theta_R$" in title and "300 K" in title and "280 K" in title
    styles = [line.get_linestyle() for line in lyapunov.get_lines()]
    assert styles[0] != styles[1] and styles[1] == styles[2]      # 300 K against 280 K, 280 K
    runs = [read_run(files[n], BALANCE, CONSTRAINT_ATTRIBUTES) for n in ("temperature", "both")]
    same = plot_constrained.make_figure(runs)
    assert same.axes[2].get_title(loc="left") == ""
    matplotlib.pyplot.close("all")


def relative_luminance(rgba):
    """WCAG relative luminance of sRGB colours (1 = white)."""
    rgb = np.asarray(rgba)[..., :3]
    linear = np.where(rgb <= 0.04045, rgb / 12.92, ((rgb + 0.055) / 1.055) ** 2.4)
    return linear @ [0.2126, 0.7152, 0.0722]


def contrast_with_white(rgba):
    return 1.05 / (relative_luminance(rgba) + 0.05)


def test_fig3_shows_mid_temperatures_on_white():
    colours = plot_snapshots.COLOUR_MAP
    # The middle half of the scale meets WCAG's 3:1 for graphics on white; no colour is paler than 1.5:1...
    assert np.all(contrast_with_white(colours(np.linspace(0.25, 0.75, 128))) >= 3.0)
    assert np.all(contrast_with_white(colours(np.linspace(0.0, 1.0, 256))) >= 1.5)
    # ...which the diverging map it replaces misses in the middle, where it is near-white.
    assert contrast_with_white(matplotlib.colormaps["coolwarm"](0.5)) < 1.5
    # The springs also carry a dark outline.
    stroke = plot_snapshots.SPRING_OUTLINE[0]
    assert contrast_with_white(matplotlib.colors.to_rgba(stroke._gc["foreground"])) > 10


def test_fig3_reaches_24_s_when_the_run_does(tmp_path):
    steps = 160                                        # dt = 0.15 s: 24 s
    path, _ = write_run(tmp_path / "fig3.h5", steps=steps, data={"time": 0.15 * np.arange(steps + 1)},
                        attributes={"dt": 0.15})
    fig = plot_snapshots.make_figure([read_run(path, ["state", "temperature"])], [0.0, 8.0, 16.0, 24.0])
    titles = [ax.get_title() for ax in fig.axes if ax.get_title()]
    assert titles[-1] == "$t_n$ = 24.00 s" and len(titles) == 4
    matplotlib.pyplot.close("all")


def test_a_style_sheet_can_be_applied_and_a_bad_one_is_a_usage_error(files, tmp_path, capsys):
    style = tmp_path / "journal.mplstyle"
    style.write_text("font.size: 9\naxes.labelsize: 9\n")
    eme, _ = balance_files(files)
    try:
        plot_balance.main([str(eme[0]), "--style", str(style), "-o", str(tmp_path / "styled")])
        assert matplotlib.rcParams["axes.labelsize"] == 9.0
        with pytest.raises(SystemExit) as stop:
            plot_balance.main([str(eme[0]), "--style", "no-such-style", "-o", str(tmp_path / "x")])
        assert stop.value.code == 2 and "--style no-such-style" in capsys.readouterr().err
    finally:
        matplotlib.style.use(plotting.PAPER_STYLE)


def test_run_data_are_what_the_files_hold(files):
    """The synthetic runs these checks draw are the documented layout's (a guard on the fixture)."""
    run = read_run(files["eme", "entropy"], BALANCE)
    np.testing.assert_array_equal(run.data["energy"], run_data(40, 0.15)["energy"])
    assert not run.incomplete


# ---------------------------------------------------------------- runs told apart (issue 24)
@pytest.mark.parametrize("script", [plot_balance, plot_temperatures])
def test_runs_of_one_variable_and_several_schemes_are_told_apart(tmp_path, script):
    """EME_s, RRK8_s and CVODE-BDF_s (one variable, three schemes): three colours and three
    markers. Before, all three were blue circles."""
    paths = [write_run(tmp_path / f"{scheme}.h5", steps=20, attributes={
        "scheme": scheme, "scheme_label": label, "thermo_variable": "entropy", "dt": 0.15})[0]
        for scheme, label in (("eme", "EME"), ("relaxed_rk8", "RRK8"), ("cvode_bdf", "CVODE-BDF"))]
    runs = [read_run(path, BALANCE + ["temperature", "angular_momentum"]) for path in paths]
    fig = script.make_figure(runs)
    lines = [line for line in fig.axes[0].get_lines() if line.get_label() and not line.get_label().startswith("_")]
    assert len(lines) == 3
    assert len({matplotlib.colors.to_hex(line.get_color()) for line in lines}) == 3
    assert len({line.get_marker() for line in lines}) == 3
    plotting.plt.close(fig)


def test_labels_name_the_runs_and_same_labels_get_the_file(tmp_path):
    paths = [write_run(tmp_path / f"run_{k}.h5", steps=10, attributes={
        "scheme": "eme", "scheme_label": "EME", "thermo_variable": "temperature", "dt": 0.15})[0] for k in (1, 2)]
    output = tmp_path / "figure"
    plot_balance.main([*map(str, paths), "--labels", "coarse", "fine", "-o", str(output)])
    caption = (tmp_path / "figure.txt").read_text()
    assert output.with_suffix(".png").exists() and "run_1.h5" in caption
    runs = [read_run(path, BALANCE) for path in paths]
    plotting.apply_labels(None, None, runs)       # without --labels: two equal labels get their files
    assert [run.label for run in runs] == [r"EME$_{\theta}$, $\Delta t$ = 0.15 s (run_1)",
                                           r"EME$_{\theta}$, $\Delta t$ = 0.15 s (run_2)"]
    fig = plot_balance.make_figure([read_run(path, BALANCE) for path in paths])
    for run, label in zip(runs, ("coarse", "fine")):
        run.custom_label = label
    fig = plot_balance.make_figure(runs)
    assert [t.get_text() for t in fig.legends[0].get_texts()] == ["coarse", "fine"]
    plotting.plt.close("all")
    with pytest.raises(SystemExit):
        plot_balance.main([*map(str, paths), "--labels", "only one", "-o", str(output)])
