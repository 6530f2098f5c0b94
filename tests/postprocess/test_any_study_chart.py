"""study_analysis.py INDEX.h5 --reference REF.h5: the work-precision chart of any study (issue 40
item 3), here a small one run on 2 ranks, against a run file or a case of a study index, with
its error norm named on the chart and in its caption, on the CPU time of the cases by default
and on their wall time when asked; and bad input named with exit status 2 and nothing written."""
import os
import shutil
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest
from PIL import Image

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "postprocess"))

import study_analysis  # noqa: E402
import study_plots  # noqa: E402
from plotting import plt  # noqa: E402

BIN = Path(os.environ.get("EME_BIN_DIR", ROOT / "build" / "bin"))
SCRIPT = ROOT / "postprocess" / "study_analysis.py"
BASE = ROOT / "inputs" / "paper_fig4_eme_theta.nml"
MPIRUN = ["mpirun", "--allow-run-as-root", "--oversubscribe"]
# A study no make target names: EME and RRK4 over dt on [0, 0.4] s, in the temperature variable.
STUDY = """&study base = '{base}', output_dir = '{output}', combine = 'zip' /
&sweep field = 't_end', values = 5*0.4 /
&sweep field = 'scheme', texts = 'eme', 'eme', 'eme', 'relaxed_rk4', 'relaxed_rk4' /
&sweep field = 'thermo_variable', texts = 'temperature', 'temperature', 'temperature', 'temperature', 'temperature' /
&sweep field = 'dt', values = 0.04, 0.02, 0.01, 0.1, 0.05 /
"""
# A reference study of one case: RRK8 at a small step.
REFERENCE_STUDY = """&study base = '{base}', output_dir = '{output}' /
&sweep field = 't_end', values = 0.4 /
&sweep field = 'scheme', texts = 'relaxed_rk8' /
&sweep field = 'thermo_variable', texts = 'temperature' /
&sweep field = 'dt', values = 0.005 /
"""
# Run by eme_run alone: the same reference as a run file, and a cross-check coarse enough (one
# of the study's own cases, RRK4 at dt = 0.05 s) that its level leaves some points out.
RUN_FILES = {"ref": "scheme = 'relaxed_rk8', dt = 0.005", "cross": "scheme = 'relaxed_rk4', dt = 0.05"}
# The norm typed from its definition (docs/figures.md): the pendulum's 13 mechanical entries and
# its two temperatures over theta_ref = 300 K.
METRIC = ("max over the 13 mechanical entries (q, p, gamma) of |z - z_ref| and over the temperatures of "
          "|theta_a - theta_a,ref| / theta_ref (theta_ref = 300 K)")
METRIC_LABEL = r"max(|$\Delta q$|, |$\Delta p$|, |$\Delta\gamma$|, |$\Delta\theta_a$|/$\theta_{ref}$)"


def run(command, **options):
    return subprocess.run([str(part) for part in command], capture_output=True, text=True, timeout=300, cwd=ROOT,
                          **options)


@pytest.fixture(scope="module")
def studies(tmp_path_factory):
    """The study and the reference study on 2 ranks, and the run files of RUN_FILES."""
    folder = tmp_path_factory.mktemp("any_study")
    for name, text in (("study", STUDY), ("reference", REFERENCE_STUDY)):
        (folder / f"{name}.nml").write_text(text.format(base=BASE, output=folder / name))
        result = run([*MPIRUN, "-n", 2, BIN / "eme_ensemble", folder / f"{name}.nml"])
        assert result.returncode == 0, result.stderr
    for name, settings in RUN_FILES.items():
        (folder / f"{name}.nml").write_text(f"&integrator {settings}, thermo_variable = 'temperature', t_end = 0.4 /\n"
                                            f"&output file = '{folder / name}.h5' /\n")
        result = run([BIN / "eme_run", folder / f"{name}.nml"])
        assert result.returncode == 0, result.stderr
    return folder


def last_point(path):
    """The final mechanical entries, temperatures and theta_ref of a run file, read with h5py."""
    with h5py.File(path, "r") as f:
        return f["state"][-1, :13], f["temperature"][-1], float(f.attrs["theta_ref"])


def expected_error(path, reference):
    q, theta, _ = last_point(path)
    q_ref, theta_ref_values, theta_ref = last_point(reference)
    return max(np.abs(q - q_ref).max(), np.abs(theta - theta_ref_values).max() / theta_ref)


def index_rows(folder):
    with h5py.File(folder / "index.h5", "r") as f:
        return {int(row["case"]): row for row in f["cases"][()]}


@pytest.mark.drawing
def test_a_study_is_charted_against_a_run_file_on_cpu_time(studies, tmp_path):
    result = run([sys.executable, SCRIPT, studies / "study" / "index.h5", "--reference", studies / "ref.h5",
                  "-o", tmp_path / "figures"])
    assert result.returncode == 0, result.stderr
    stem = tmp_path / "figures" / "work_precision_study"
    assert (stem.with_suffix(".pdf")).read_bytes().startswith(b"%PDF")
    caption = stem.with_suffix(".txt").read_text()
    # The norm, the time and the load are named in the caption and in the PNG's own text.
    for text in (caption, Image.open(stem.with_suffix(".png")).info["Description"]):
        assert METRIC in text
        assert "error against solve CPU time" in text and "solve_cpu_time_seconds" in text
        assert f"Studies {studies / 'study'}: machine load: 1-minute load average" in text
    rows = index_rows(studies / "study")
    with h5py.File(stem.with_suffix(".h5"), "r") as f:
        group = f["work_precision"]
        assert group.attrs["chart_time"].startswith("cpu: ")
        assert group.attrs["load_recorded"] == 1 and group.attrs["own_processes"] == 2
        assert sorted(group["case"][()]) == sorted(rows)
        for case, error, cpu, wall in zip(group["case"][()], group["error"][()], group["solve_cpu_time_seconds"][()],
                                          group["solve_time_seconds"][()]):
            assert error == pytest.approx(expected_error(studies / "study" / rows[case]["file"].decode(),
                                                         studies / "ref.h5"), rel=1e-12, abs=0)
            assert (cpu, wall) == (rows[case]["solve_cpu_time_seconds"], rows[case]["solve_time_seconds"])
        assert "cross_check_level" not in group
    assert "work precision: reference" in result.stdout and "no cross-check; times: solve CPU time" in result.stdout


@pytest.mark.drawing
@pytest.mark.parametrize("kind, column, words", [("cpu", "solve_cpu_time_seconds", "solve CPU time"),
                                                 ("wall", "solve_time_seconds", "solve wall time")])
def test_the_chart_s_points_are_the_times_asked_for(studies, kind, column, words):
    """Every point drawn sits at its case's error and at the index's time of the kind asked for,
    and the axis says which time it is."""
    rows, left_out = study_analysis.split_complete([study_analysis.read_index(studies / "study" / "index.h5")])
    reference = study_analysis.solution_point(studies / "ref.h5", 1)
    norm, label = study_analysis.error_metric(reference)
    assert (norm, label) == (METRIC, METRIC_LABEL)
    wp = study_analysis.work_precision_result(rows, left_out, reference, None, None, kind, title="study",
                                              norm=norm, norm_label=label, end="t = 0.4 s")
    fig, title, lines = study_plots.work_precision_figure({"study": wp}, 10.0)
    drawn = set()
    for ax in fig.axes:
        for line in ax.get_lines():
            if line.get_marker() not in (None, "", "None", "none"):
                drawn |= set(zip(line.get_xdata(), line.get_ydata()))
    expected = {(row[column], error) for row, error in zip(rows, wp["errors"])}
    assert drawn == expected and len(drawn) == 5
    assert fig.axes[-1].get_xlabel() == f"{words}, one rank [s]"
    assert words in title and label in fig.axes[0].get_title()
    plt.close("all")


@pytest.mark.drawing
def test_an_index_case_is_the_reference_with_a_cross_check(studies, tmp_path):
    """The reference as a case of a study index (the study given by its folder); a cross-check
    draws its distance from the reference as a level and leaves out the points within 10 times
    it."""
    result = run([sys.executable, SCRIPT, studies / "study", "--reference", studies / "reference" / "index.h5",
                  "--cross-check", studies / "cross.h5", "-o", tmp_path / "figures", "--name", "crossed",
                  "--time", "wall", "--summary", tmp_path / "crossed.h5"])
    assert result.returncode == 0, result.stderr
    reference = studies / "reference" / index_rows(studies / "reference")[1]["file"].decode()
    level = expected_error(studies / "cross.h5", reference)
    rows = index_rows(studies / "study")
    with h5py.File(tmp_path / "crossed.h5", "r") as f:
        group = f["work_precision"]
        assert group["cross_check_level"][()] == pytest.approx(level, rel=1e-12)
        assert group.attrs["chart_time"].startswith("wall: ")
        for case, error, shown in zip(group["case"][()], group["error"][()], group["shown"][()]):
            path = studies / "study" / rows[case]["file"].decode()
            assert error == pytest.approx(expected_error(path, reference), rel=1e-12, abs=0)
            assert shown == (error >= 10 * level)
        assert 0 < group["shown"][()].sum() < len(group["shown"])
    caption = (tmp_path / "figures" / "crossed.txt").read_text()
    assert METRIC in caption and "error against solve wall time" in caption
    assert f"|reference - cross-check| = {level:.1e}" in caption


def without_cpu_columns(studies, tmp_path):
    """A copy of the study whose index lacks the CPU columns, as an older eme_ensemble wrote it."""
    copy = tmp_path / "old"
    shutil.copytree(studies / "study", copy)
    with h5py.File(copy / "index.h5", "r+") as f:
        del f.attrs["text_checksum"]         # an index of that age has none (and the edit would fail it)
        cases = f["cases"][()]
        del f["cases"]
        f["cases"] = cases[[name for name in cases.dtype.names if "cpu" not in name]]
    return copy


@pytest.mark.parametrize("case", ["no reference", "missing reference", "index only", "other end time",
                                  "no cpu times"])
def test_bad_input_is_named_with_exit_status_2_and_nothing_written(studies, tmp_path, case):
    index, reference, options = studies / "study" / "index.h5", studies / "ref.h5", []
    if case == "no reference":
        reference = None
        expected = "INDEX.h5 and --reference go together"
    elif case == "missing reference":
        reference = tmp_path / "absent.h5"
        expected = f"{reference}: cannot open as an HDF5 file"
    elif case == "index only":
        index = tmp_path / "lean" / "index.h5"
        (tmp_path / "lean.nml").write_text(STUDY.format(base=BASE, output=index.parent).replace(
            "combine = 'zip'", "combine = 'zip', index_only = .true."))
        assert run([BIN / "eme_ensemble", tmp_path / "lean.nml"]).returncode == 0
        expected = f"{index}: an index-only study keeps no case files"
    elif case == "other end time":
        (tmp_path / "short.nml").write_text(f"&integrator scheme = 'relaxed_rk8', dt = 0.005, t_end = 0.2 /\n"
                                            f"&output file = '{tmp_path / 'short.h5'}' /\n")
        assert run([BIN / "eme_run", tmp_path / "short.nml"]).returncode == 0
        reference = tmp_path / "short.h5"
        expected = "ends at t = 0.4 s but the reference"
    else:
        index = without_cpu_columns(studies, tmp_path) / "index.h5"
        expected = f"{index}: /cases has no field solve_cpu_time_seconds"
    command = [sys.executable, SCRIPT, index, "-o", tmp_path / "figures"]
    if reference is not None:
        command += ["--reference", reference]
    result = run(command + options)
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert expected in result.stderr
    assert not (tmp_path / "figures").exists()
    if case == "no cpu times":
        assert "--time wall" in result.stderr
        assert run(command + ["--time", "wall"]).returncode == 0
