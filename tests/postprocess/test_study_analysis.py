"""postprocess/study_analysis.py: the error norm, the order fit and the outcome classification on
hand-made inputs, and the whole script on tiny studies run with eme_ensemble."""
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import h5py
import matplotlib
import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "postprocess"))

import stability_sets  # noqa: E402
import study_analysis  # noqa: E402
import study_plots  # noqa: E402
from figure_checks import (drawn_font_sizes, marked_lines, pdf_font_kinds, pdf_width_inches,  # noqa: E402
                           unexplained_markers)
from plotting import plt  # noqa: E402
from study_analysis import (FinalPoint, StudyError, asymptotic_range, classify,  # noqa: E402
                            entropy_violation, final_point, fitted_order, state_error)
from file_checksums import seal_texts  # noqa: E402
from synthetic_runs import STATE_COLUMNS, write_run  # noqa: E402
from trajectory import RunFileError  # noqa: E402

ENSEMBLE = ROOT / "build" / "bin" / "eme_ensemble"
SCRIPT = ROOT / "postprocess" / "study_analysis.py"
BASE = ROOT / "inputs" / "paper_fig4_eme_theta.nml"
GAS_BASE = ROOT / "inputs" / "gas_containers.nml"
# The pendulum's /state columns but its thermodynamic variable's, as final_point keeps them.
PENDULUM_MECHANICAL = tuple(STATE_COLUMNS[:13])


# ---------------------------------------------------------------- error norm
def point(mechanical=None, temperatures=(300.0, 350.0), time=2.0, theta_ref=300.0, name="run.h5",
          columns=PENDULUM_MECHANICAL):
    mechanical = np.zeros(len(columns)) if mechanical is None else np.asarray(mechanical, float)
    return FinalPoint(Path(name), time, mechanical, np.asarray(temperatures, float), theta_ref, tuple(columns))


def test_error_is_the_largest_mechanical_or_scaled_temperature_difference():
    reference = point()
    mechanical = np.zeros(13)
    mechanical[10] = -0.3                                        # p2_y off by 0.3 N s
    assert state_error(point(mechanical, (300.0, 410.0)), reference) == pytest.approx(0.3)   # 60 K / 300 K = 0.2
    assert state_error(point(mechanical, (150.0, 350.0)), reference) == pytest.approx(0.5)   # 150 K / 300 K
    assert state_error(point(), reference) == 0.0


def test_error_reads_q_p_gamma_and_temperatures_by_column_name_not_tau(tmp_path):
    # /state columns written in reverse order, and tau = (theta_1, theta_2) far apart: they must not count.
    steps = 3
    state = np.zeros((steps + 1, 15))
    state[-1, STATE_COLUMNS.index("gamma")] = 0.25
    state[-1, STATE_COLUMNS.index("theta_1")] = 1e6
    temperature = np.full((steps + 1, 2), 300.0)
    temperature[-1] = (300.0, 330.0)                              # 30 K / 300 K = 0.1
    attributes = {"theta_ref": 300.0}
    case, _ = write_run(tmp_path / "case.h5", steps, {"state": state, "temperature": temperature},
                        attributes, columns=STATE_COLUMNS[::-1])
    reference, _ = write_run(tmp_path / "reference.h5", steps, {"state": np.zeros((steps + 1, 15)),
                             "temperature": np.full((steps + 1, 2), 300.0)}, attributes)
    last = final_point(case)
    assert last.mechanical[last.columns.index("gamma")] == 0.25 and last.time == pytest.approx(0.3)
    assert sorted(last.columns) == sorted(PENDULUM_MECHANICAL)
    assert state_error(last, final_point(reference)) == pytest.approx(0.25)
    temperature[-1] = (300.0, 450.0)                              # now the temperature decides: 0.5
    case, _ = write_run(tmp_path / "case2.h5", steps, {"state": state, "temperature": temperature}, attributes)
    assert state_error(final_point(case), final_point(reference)) == pytest.approx(0.5)


def test_error_refuses_states_at_different_times():
    with pytest.raises(StudyError, match=r"case\.h5 ends at t = 1\.9.*reference\.h5 at t = 2 s"):
        state_error(point(time=1.9, name="case.h5"), point(name="reference.h5"))


def test_a_missing_theta_ref_is_named(tmp_path):
    path, _ = write_run(tmp_path / "run.h5")
    with pytest.raises(RunFileError, match=r"run\.h5: root attribute 'theta_ref' is missing"):
        final_point(path)


# ---------------------------------------------------------------- order fit
@pytest.mark.parametrize("order", [1.0, 2.0, 4.0])
def test_fit_recovers_an_exact_slope(order):
    dt = 0.1 / 2.0 ** np.arange(6)
    slope, constant = fitted_order(dt, 3.0 * dt ** order)
    assert slope == pytest.approx(order, abs=1e-12) and constant == pytest.approx(3.0, rel=1e-10)


def test_asymptotic_range_skips_errors_near_the_reference_level_and_large_steps():
    dt = 0.1 / 2.0 ** np.arange(7)                    # 0.1 ... 0.0015625
    error = 5.0 * dt ** 2
    error[0] = 1.0                                     # pre-asymptotic largest step
    level = 1e-9
    error[dt < 0.004] = 50 * level                     # the two finest sit on the reference's level
    chosen = asymptotic_range(dt, error, level)
    np.testing.assert_allclose(np.sort(dt[chosen]), [0.00625, 0.0125, 0.025])
    assert fitted_order(dt[chosen], error[chosen])[0] == pytest.approx(2.0, abs=1e-12)
    # Every point in the fit would give a wrong order: the selection is what makes it 2.
    assert abs(fitted_order(dt, error)[0] - 2.0) > 0.3


def test_asymptotic_range_of_a_scheme_at_the_level_is_empty_and_gives_no_order():
    dt = np.array([0.1, 0.05])
    chosen = asymptotic_range(dt, np.array([1e-10, 1e-10]), 1e-11)
    assert len(chosen) == 0 and np.isnan(fitted_order(dt[chosen], dt[chosen])[0])


# ---------------------------------------------------------------- outcome classification
NO_ROOT = ("failed: incomplete: step 16 (t = 12.0000 s): no root from the predictor, from the old state, "
           "or by continuation in dt (last: {})")


@pytest.mark.parametrize("status, drift, dv, positive, expected", [
    ("complete", 1e-15, -1.0, True, ("kept", "")),
    ("complete", 1e-6, 1e-8, True, ("kept", "")),                 # both limits are inclusive
    ("complete", 2e-6, -1.0, True, ("energy", "")),
    ("complete", 2e-6, 5.0, True, ("energy", "V")),               # energy decides, V is flagged
    ("complete", 1e-15, 2e-8, True, ("lyapunov", "")),
    ("complete", 5.0, 5.0, False, ("nonphysical", "")),           # a temperature <= 0 beats the rest
    ("complete", np.nan, -1.0, True, ("nonphysical", "")),
    ("complete", 1e-15, np.nan, True, ("nonphysical", "")),
    (NO_ROOT.format("root rejected: non-positive temperature at the new state (theta_2 = -1.965E-01 K))"),
     1e-15, -1.0, True, ("solver", "T")),
    (NO_ROOT.format("Newton did not converge: DIVERGED_LINE_SEARCH)"), 1e-15, -1.0, True, ("solver", "")),
    ("failed: incomplete: step 6 (t = 3.0000 s): PETSc TS: the Newton solve of an implicit step diverged "
     "(TS_DIVERGED_NONLINEAR_SOLVE)", 1e-15, -1.0, True, ("solver", "")),
    ("failed: incomplete: step 6 (t = 3.0000 s): PETSc TS did not converge, TSConvergedReason -1",
     1e-15, -1.0, True, ("solver", "")),
    ("failed: incomplete: step 4 (t = 3.0000 s): the state left the model's domain (a non-positive "
     "temperature, or a blow-up)", 1e-15, -1.0, True, ("nonphysical", "")),
    ("failed: incomplete: step 1 (t = 0.1500 s): no root from the predictor, from the old state, or by "
     "continuation in dt (last: Newton did not converge: DIVERGED_MAX_IT)", np.nan, np.nan, True, ("solver", "")),
])
def test_outcome_and_precedence(status, drift, dv, positive, expected):
    assert classify(status, drift, dv, positive) == expected


@pytest.mark.parametrize("status", ["pending", "failed: cannot write to x.h5"])
def test_unclassifiable_cases_stop_the_analysis(status):
    with pytest.raises(StudyError, match="pending|unknown failure"):
        classify(status, 0.0, 0.0)


@pytest.mark.parametrize("min_temperature, positive", [(300.0, True), (1e-300, True), (0.0, False),
                                                     (-5.0, False), (np.nan, False), (np.inf, False)])
def test_temperatures_are_positive_when_the_lowest_is_finite_and_positive(min_temperature, positive):
    assert study_analysis.temperatures_positive(min_temperature) is positive


def test_entropy_violation_is_the_largest_decrease_and_zero_for_increases():
    np.testing.assert_array_equal(entropy_violation([-0.5, 0.0, 1e-3, -1e-20]), [0.5, 0.0, 0.0, 1e-20])


# ---------------------------------------------------------------- the script on tiny studies
STUDIES = {
    # 2 schemes x 3 dt on [0, 0.4] s: 6 cases of 10 to 40 steps.
    "convergence": """&sweep field = 't_end', values = 0.4 /
&sweep field = 'scheme', texts = 'eme', 'ts_rk4' /
&sweep field = 'thermo_variable', texts = 'temperature' /
&sweep field = 'dt', values = 0.04, 0.02, 0.01 /""",
    "convergence_reference": """&sweep field = 't_end', values = 0.4, 0.4 /
&sweep field = 'dt', values = 0.01, 0.01 /
&sweep field = 'scheme', texts = 'ts_rk5dp', 'ts_rk5dp' /
&sweep field = 'thermo_variable', texts = 'temperature', 'entropy' /
&sweep field = 'ts_tolerance', values = 1.0e-13, 1.0e-12 /""",
    # One case per outcome we can force: kept (EME), energy error (MP_s), and two failures by
    # allowing one Newton iteration per solve: our solver ("no root") and PETSc TS; and a relaxed
    # scheme at a step it must halve.
    "stability_paper": """&sweep field = 't_end', values = 1.0, 1.0, 1.0, 1.0, 1.0 /
&sweep field = 'scheme', texts = 'eme', 'midpoint', 'eme', 'ts_midpoint', 'relaxed_rk4' /
&sweep field = 'thermo_variable', texts = 'temperature', 'entropy', 'temperature', 'internal_energy',
  'temperature' /
&sweep field = 'dt', values = 0.1, 0.1, 0.2, 0.1, 0.5 /
&sweep field = 'newton_max_iterations', values = 50, 50, 1, 1, 50 /""",
    # Work precision on [0, 0.4] s: two fixed-step schemes over dt, two adaptive ones over the
    # tolerance, and a reference (relaxed_rk8 at a tiny step) with a CVODE cross-check.
    "work_precision": """&sweep field = 't_end', values = 4*0.4 /
&sweep field = 'scheme', texts = 'eme', 'eme', 'relaxed_rk8', 'relaxed_rk8' /
&sweep field = 'thermo_variable', texts = 'temperature', 'temperature', 'temperature', 'temperature' /
&sweep field = 'dt', values = 0.02, 0.01, 0.1, 0.05 /""",
    "work_precision_adaptive": """&sweep field = 't_end', values = 4*0.4 /
&sweep field = 'scheme', texts = 'relaxed_dp853', 'relaxed_dp853', 'cvode_bdf', 'cvode_bdf' /
&sweep field = 'thermo_variable', texts = 'temperature', 'temperature', 'temperature', 'temperature' /
&sweep field = 'dt', values = 4*0.2 /
&sweep field = 'tolerance', values = 1e-5, 1e-8, 1e-5, 1e-8 /""",
    "work_precision_reference": """&sweep field = 't_end', values = 0.4, 0.4 /
&sweep field = 'scheme', texts = 'relaxed_rk8', 'cvode_adams' /
&sweep field = 'thermo_variable', texts = 'temperature', 'temperature' /
&sweep field = 'dt', values = 0.005, 0.2 /
&sweep field = 'tolerance', values = 1e-10, 1e-13 /""",
}
STUDIES["stability_hard"] = STUDIES["stability_paper"]
# EME with step-size control over its tolerance, on the work-precision scene.
STUDIES["work_precision_step_control"] = """&sweep field = 't_end', values = 2*0.4 /
&sweep field = 'scheme', texts = 'eme', 'eme' /
&sweep field = 'thermo_variable', texts = 'temperature', 'temperature' /
&sweep field = 'dt', values = 2*0.2 /
&sweep field = 'tolerance', values = 1e-3, 1e-4 /"""
# The harder scene set, tiny: per scene a fixed-step study over dt and a step-controlled one over
# the tolerance (the scene itself is the base's: the analysis reads only the indexes).
for _scene in stability_sets.SCENES:
    STUDIES[f"stability_{_scene}"] = """&sweep field = 't_end', values = 4*0.6 /
&sweep field = 'scheme', texts = 'eme', 'eme', 'relaxed_rk4', 'ts_rk4' /
&sweep field = 'thermo_variable', texts = 'temperature', 'temperature', 'temperature', 'temperature' /
&sweep field = 'dt', values = 0.1, 0.3, 0.3, 0.3 /"""
    STUDIES[f"stability_{_scene}_tolerance"] = """&sweep field = 't_end', values = 4*0.6 /
&sweep field = 'scheme', texts = 'eme', 'eme', 'relaxed_rk4', 'cvode_bdf' /
&sweep field = 'thermo_variable', texts = 'temperature', 'temperature', 'temperature', 'temperature' /
&sweep field = 'dt', values = 4*0.3 /
&sweep field = 'tolerance', values = 1e-2, 1e-3, 1e-4, 1e-4 /"""
EXPECTED_OUTCOMES = {("EME_theta", 0.1): "kept", ("MP_s", 0.1): "energy", ("EME_theta", 0.2): "solver",
                     ("TS-midpoint_u", 0.1): "solver", ("RRK4_theta", 0.5): "kept"}
# The gas containers (base inputs/gas_containers.nml), tiny: a stability study on [0, 2] with one
# case per outcome the scene gives (EME and RRK4 keep everything, MP_s drifts in energy, RK4 leaves
# the domain in its first step of 1, BDF2 loses its Newton root in its second), and the pendulum's
# work-precision sweeps on [0, 0.4] with their reference (relaxed_rk8 at dt = 0.005, cross-checked by
# CVODE-Adams).
GAS_STUDIES = {
    "gas_stability": """&sweep field = 't_end', values = 5*2.0 /
&sweep field = 'scheme', texts = 'eme', 'midpoint', 'ts_rk4', 'ts_bdf2', 'relaxed_rk4' /
&sweep field = 'thermo_variable', texts = 'temperature', 'entropy', 'temperature', 'temperature', 'temperature' /
&sweep field = 'dt', values = 0.1, 0.1, 1.0, 1.0, 0.5 /""",
    **{f"gas_{name}": STUDIES[name] for name in ("work_precision", "work_precision_adaptive",
                                                 "work_precision_step_control", "work_precision_reference")},
}
STUDIES.update(GAS_STUDIES)
EXPECTED_GAS_OUTCOMES = {("EME_theta", 0.1): "kept", ("MP_s", 0.1): "energy", ("RK4_theta", 1.0): "nonphysical",
                         ("BDF2_theta", 1.0): "solver", ("RRK4_theta", 0.5): "kept"}


def run_script(study_dir, output, summary):
    return subprocess.run([sys.executable, str(SCRIPT), "--study-dir", str(study_dir), "-o", str(output),
                           "--summary", str(summary)], capture_output=True, text=True, timeout=300, cwd=ROOT)


@pytest.fixture(scope="module")
def studies(tmp_path_factory):
    """STUDY_DIR with the tiny studies, run with eme_ensemble on one rank; the stability studies
    keep only their index, as make study's do."""
    assert ENSEMBLE.exists(), f"{ENSEMBLE} is missing: run `make` in {ROOT} first"
    directory = tmp_path_factory.mktemp("studies")
    for name, sweeps in STUDIES.items():
        combine = "product" if name == "convergence" else "zip"
        index_only = ".true." if "stability" in name else ".false."     # as make study's
        base = GAS_BASE if name in GAS_STUDIES else BASE
        namelist = directory / f"{name}.nml"
        namelist.write_text(f"&study\n  base = '{base}'\n  output_dir = '{directory / 'study' / name}'\n"
                            f"  combine = '{combine}'\n  index_only = {index_only}\n/\n{sweeps}\n")
        # As make study runs them: the machine's load recorded around each (machine_load.py).
        result = subprocess.run([sys.executable, str(ROOT / "postprocess" / "machine_load.py"), "--record",
                                 str(directory / "study" / f"{name}.load.json"), "--", str(ENSEMBLE), str(namelist)],
                                capture_output=True, text=True, timeout=300, cwd=ROOT)
        assert result.returncode == 0, result.stderr
    return directory / "study"


@pytest.fixture(scope="module")
def analysed(studies, tmp_path_factory):
    output = tmp_path_factory.mktemp("analysis")
    result = run_script(studies, output / "figures", output / "summary.h5")
    assert result.returncode == 0, result.stderr
    return output, result.stdout


@pytest.mark.parametrize("name", ["study_convergence", "study_work_precision", "study_structure_cost",
                                  "study_stability_map", "study_stability_set"])
def test_script_writes_png_and_pdf(analysed, name):
    output, _ = analysed
    png = (output / "figures" / f"{name}.png").read_bytes()
    pdf = (output / "figures" / f"{name}.pdf").read_bytes()
    assert png.startswith(b"\x89PNG") and len(png) > 10_000
    assert pdf.startswith(b"%PDF") and len(pdf) > 5_000


def text(values):
    return [v.decode() if isinstance(v, bytes) else str(v) for v in np.ravel(values)]


def test_summary_holds_every_figure_s_numbers_with_units(studies, analysed):
    output, _ = analysed
    with h5py.File(output / "summary.h5", "r") as f:
        names = []
        f.visititems(lambda name, obj: names.append(name) if isinstance(obj, h5py.Dataset) else None)
        for name in names:
            assert {"units", "description"} <= set(f[name].attrs), name
        for scene in ("paper", "hard", "gas"):
            for dataset in ("scheme", "dt", "outcome", "outcome_names", "flags", "case", "kept_count"):
                assert f"stability/{scene}/{dataset}" in names
        for dataset in ("scheme", "dt", "error", "solve_time_seconds", "cross_check_level", "fit_scheme",
                        "fitted_order"):
            assert f"convergence/{dataset}" in names
        for dataset in ("solve_time_seconds", "energy_drift", "entropy_violation"):
            assert f"structure_cost/{dataset}" in names
        assert len(f["convergence/error"]) == 6
        grid = f["stability/paper/outcome"][()]
        schemes, steps = text(f["stability/paper/scheme"][()]), list(f["stability/paper/dt"][()])
        assert (grid >= 0).sum() == 5
        codes = {(schemes[i], steps[j]): study_analysis.OUTCOMES[grid[i, j]] for i, j in zip(*np.nonzero(grid >= 0))}
        assert codes == EXPECTED_OUTCOMES
        # The stability studies kept no case files: the map came from their indexes.
        assert not list((studies / "stability_paper").glob("case_*.h5"))
        # The relaxed case at dt = 0.5 s halves steps, and only it.
        halved = f["stability/paper/halved_steps"][()]
        assert halved[schemes.index("RRK4_theta"), steps.index(0.5)] > 0 and halved.sum() == halved.max()
        for group in ("work_precision", "gas_work_precision"):
            for dataset in ("scheme", "study", "dt", "tolerance", "error", "shown", "solve_time_seconds",
                            "energy_drift", "cross_check_level"):
                assert f"{group}/{dataset}" in names
            assert len(f[f"{group}/error"]) == 10     # 4 fixed-step, 4 adaptive, 2 step-controlled
        # The gas containers are nondimensional: their V and dt have the unit 1, the pendulum's J and s.
        assert f["stability/gas/max_lyapunov_increment"].attrs["units"] == "1"
        assert f["stability/gas/dt"].attrs["units"] == "1"
        assert f["stability/paper/max_lyapunov_increment"].attrs["units"] == "J"
        orders = dict(zip(text(f["convergence/fit_scheme"][()]), f["convergence/fitted_order"][()]))
        assert orders["EME_theta"] == pytest.approx(2.0, abs=0.3)
        assert orders["RK4_theta"] == pytest.approx(4.0, abs=0.5)


def test_summary_numbers_are_the_files_numbers(studies, analysed):
    """Errors recomputed here with plain h5py, and the index's metrics, equal the summary's."""
    output, _ = analysed

    def last(path):
        with h5py.File(path, "r") as f:
            return f["state"][-1, :13], f["temperature"][-1], f.attrs["theta_ref"]

    q_ref, theta_ref_values, theta_ref = last(studies / "convergence_reference" / "case_00001.h5")
    with h5py.File(output / "summary.h5", "r") as f, \
            h5py.File(studies / "convergence" / "index.h5", "r") as index:
        rows = {row["case"]: row for row in index["cases"][()]}
        for case, error, time in zip(f["convergence/case"][()], f["convergence/error"][()],
                                     f["convergence/solve_time_seconds"][()]):
            q, theta, _ = last(studies / "convergence" / rows[case]["file"].decode())
            expected = max(np.abs(q - q_ref).max(), np.abs(theta - theta_ref_values).max() / theta_ref)
            assert error == pytest.approx(expected, rel=1e-12, abs=0)
            assert time == rows[case]["solve_time_seconds"]
        q_check, theta_check, _ = last(studies / "convergence_reference" / "case_00002.h5")
        level = max(np.abs(q_check - q_ref).max(), np.abs(theta_check - theta_ref_values).max() / theta_ref)
        assert f["convergence/cross_check_level"][()] == pytest.approx(level, rel=1e-12)
    # The gas containers' q, p are /state's first two columns; their temperatures are compared
    # unscaled (units 1, no theta_ref).
    for group, reference, mechanical, scaled in (("work_precision", "work_precision_reference", 13, True),
                                                 ("gas_work_precision", "gas_work_precision_reference", 2, False)):
        def last_point(path):
            with h5py.File(path, "r") as f:
                return (f["state"][-1, :mechanical], f["temperature"][-1],
                        f.attrs["theta_ref"] if scaled else 1.0)

        q_ref, theta_ref_values, theta_ref = last_point(studies / reference / "case_00001.h5")
        with h5py.File(output / "summary.h5", "r") as f:
            assert len(f[f"{group}/error"]) > 0
            for study, case, error, time in zip(text(f[f"{group}/study"][()]), f[f"{group}/case"][()],
                                                f[f"{group}/error"][()], f[f"{group}/solve_time_seconds"][()]):
                with h5py.File(studies / study / "index.h5", "r") as index:
                    row = {row["case"]: row for row in index["cases"][()]}[case]
                q, theta, _ = last_point(studies / study / row["file"].decode())
                expected = max(np.abs(q - q_ref).max(), np.abs(theta - theta_ref_values).max() / theta_ref)
                assert error == pytest.approx(expected, rel=1e-12, abs=0)
                assert time == row["solve_time_seconds"]
    with h5py.File(output / "summary.h5", "r") as f, \
            h5py.File(studies / "stability_paper" / "index.h5", "r") as index:
        rows = {row["case"]: row for row in index["cases"][()]}
        for case, drift, violation in zip(f["structure_cost/case"][()], f["structure_cost/energy_drift"][()],
                                          f["structure_cost/entropy_violation"][()]):
            assert rows[case]["status"] == b"complete"
            assert drift == rows[case]["energy_drift"]
            assert violation == max(0.0, -rows[case]["min_entropy_increment"])


def test_findings_are_printed(analysed):
    _, stdout = analysed
    assert "convergence: reference" in stdout and "|reference - cross-check| = " in stdout
    assert "convergence EME_theta: fitted order " in stdout
    assert "stability EME_theta: finished with everything kept at 1 of 2 dt (paper scene), 1 of 2 dt (harder " \
        "scene), 1 of 1 dt (gas containers)" in stdout
    assert "stability MP_s: finished with everything kept at 0 of 1 dt (paper scene)" in stdout
    assert "work precision: reference" in stdout
    assert "work precision RRK8_theta: error <= 1e-04 at dt " in stdout and "x CVODE-BDF_theta's time" in stdout
    # The gas containers: their own lines, times without s (nondimensional).
    assert "work precision (gas containers): reference" in stdout
    assert "work precision (gas containers) RRK8_theta: error <= 1e-04 at dt " in stdout
    assert "stability gas containers: RK4_theta at dt = 1 failed in the step ending at t = 1: nonphysical" in stdout


def test_a_missing_columns_attribute_names_the_file(studies, tmp_path):
    broken = tmp_path / "study"
    shutil.copytree(studies, broken)
    case = broken / "convergence" / "case_00002.h5"
    with h5py.File(case, "r+") as f:
        del f["state"].attrs["columns"]
        seal_texts(f)                        # a file without it, not a damaged one
    result = run_script(broken, tmp_path / "figures", tmp_path / "summary.h5")
    assert result.returncode == 2
    assert str(case) in result.stderr and "/state has no column" in result.stderr


def test_a_missing_study_names_its_index(studies, tmp_path):
    broken = tmp_path / "study"
    shutil.copytree(studies, broken)
    shutil.rmtree(broken / "stability_hard")
    result = run_script(broken, tmp_path / "figures", tmp_path / "summary.h5")
    assert result.returncode == 2
    assert str(broken / "stability_hard" / "index.h5") in result.stderr and "cannot open" in result.stderr
    assert not (tmp_path / "figures").exists() and not (tmp_path / "summary.h5").exists()


# ---------------------------------------------------------------- publication style of the charts
@pytest.mark.parametrize("name", ["study_convergence", "study_work_precision", "study_structure_cost",
                                  "study_stability_map"])
def test_charts_are_a_page_wide_with_truetype_fonts_and_a_caption(analysed, name):
    output, _ = analysed
    pdf = (output / "figures" / f"{name}.pdf").read_bytes()
    kinds = pdf_font_kinds(pdf)
    assert kinds and kinds <= {b"TrueType", b"CIDFontType2", b"Type0"} and b"/Type3" not in pdf
    assert pdf_width_inches(pdf) == pytest.approx(7.0, abs=0.01)
    caption = (output / "figures" / f"{name}.txt").read_text()
    assert "Drawn by: study_analysis.py" in caption


def test_charts_text_is_at_least_8_pt_and_legends_explain_every_marker(studies):
    conv, wps, structure, maps, _ = study_analysis.analyse(studies, list(study_analysis.MODELS))
    made = {"convergence": study_plots.convergence_figure(conv, wps["pendulum"], (3, 100.0)),
            "work_precision": study_plots.work_precision_figure(wps, 10.0),
            "structure": study_plots.structure_figure(structure, studies / "stability_paper"),
            "stability": study_plots.stability_figure(maps)}
    for name, (fig, title, lines) in made.items():
        assert min(drawn_font_sizes(fig)) >= 8, name
        assert unexplained_markers(fig) == [], name
        assert title and lines, name
        if name != "stability":
            assert marked_lines(fig), name
    plt.close("all")


# ---------------------------------------------------------------- unusable files: a message, no traceback
def test_an_unreadable_case_file_is_named_without_a_traceback(studies, tmp_path):
    broken = tmp_path / "study"
    shutil.copytree(studies, broken)
    case = broken / "work_precision" / "case_00001.h5"
    case.write_bytes(case.read_bytes()[:96])           # what a kill before the first flush left
    result = run_script(broken, tmp_path / "figures", tmp_path / "summary.h5")
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert f"{case}: cannot open as an HDF5 run file" in result.stderr


def test_an_unreadable_index_is_named_without_a_traceback(studies, tmp_path):
    broken = tmp_path / "study"
    shutil.copytree(studies, broken)
    index = broken / "convergence" / "index.h5"
    index.write_text("not an index")
    result = run_script(broken, tmp_path / "figures", tmp_path / "summary.h5")
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert f"{index}: cannot open as a study index" in result.stderr


# ---------------------------------------------------------------- the harder scene set
@pytest.mark.parametrize("status, reason", [
    # Statuses as eme_run writes them (copied from runs of the harder scene set).
    ("failed: incomplete: step 34 (t = 14.2517 s): a step halved 12 times still failed (last: no relaxation root "
     "gamma in [0.2, 2])", "gamma"),
    ("failed: incomplete: step 3 (t = 0.7 s): a step halved 12 times still failed (last: gamma = 0.412345 outside "
     "the band |gamma - 1| <= 2.5E-03 of the tolerance)", "gamma"),
    ("failed: incomplete: step 2 (t = 0.5 s): step-size underflow: the trial step fell below 3.0E-13 s (last "
     "rejection: no root from the predictor or from the old state (last: Newton did not converge: DIVERGED_MAX_IT))",
     "step budget"),
    ("failed: incomplete: t_end not reached in 1000000 steps", "step budget"),
    ("failed: incomplete: step 4 (t = 0.8000 s): no root from the predictor or from the old state (last: Newton "
     "did not converge: DIVERGED_LOCAL_MIN) (also in steps of dt/64)", "no root"),
    ("failed: incomplete: step 29 (t = 8.7000 s): PETSc TS: the Newton solve of an implicit step diverged "
     "(TS_DIVERGED_NONLINEAR_SOLVE)", "no root"),
    ("failed: incomplete: step 1 (t = 0.2000 s): the state left the model's domain (a non-positive temperature, "
     "or a blow-up)", "domain"),
    ("failed: incomplete: step 2 (t = 1.0000 s): PETSc TS: a stage left the model's domain, a non-positive "
     "temperature or spring length (TS_DIVERGED_STEP_REJECTED)", "domain"),
    ("failed: incomplete: step 9 (t = 3.0 s): SUNDIALS CVODE failed (CV_TOO_MUCH_WORK)", "solver"),
])
def test_a_failure_is_classified_by_its_reason(status, reason):
    assert stability_sets.failure_reason(status) == reason


def test_the_set_map_and_the_step_controlled_curves(analysed):
    """Every scene's two maps are in the summary with their outcomes; EME run with a tolerance is
    a curve of its own (EME-tol) beside fixed-step EME in the work-precision findings."""
    output, stdout = analysed
    with h5py.File(output / "summary.h5", "r") as f:
        for scene in stability_sets.SCENES:
            fixed, controlled = f[f"stability_set/{scene}/fixed"], f[f"stability_set/{scene}/tolerance"]
            assert [s.decode() for s in fixed["scheme"][()]] == ["EME", "RK4", "RRK4"]
            assert [s.decode() for s in controlled["scheme"][()]] == ["CVODE-BDF", "EME-tol", "RRK4-tol"]
            np.testing.assert_array_equal(controlled["tolerance"][()], [1e-2, 1e-3, 1e-4])
            assert (fixed["outcome"][()][0] >= 0).sum() == 2 and (controlled["outcome"][()] >= 0).sum() == 4
    assert "work precision EME-tol_theta" in stdout and "stability low viscosity (tolerance) EME-tol" in stdout


def test_every_scheme_s_legend_and_map_fit_the_page(studies):
    """With every registered integrator in every variable (36 curves, 33 map rows per scene), the
    structure-against-cost legend lies inside the figure and the stability map fits a page.
    Before: 12 legend columns in 7 in (EME and MP cut off), and a map 7 x 16 in."""
    study_analysis.read_index(studies / "stability_paper")        # registers the integrators
    with h5py.File(studies / "stability_paper" / "index.h5", "r") as f:
        names = [row["name"].decode() for row in f["integrators"][()]]
    variables = ("entropy", "temperature", "internal_energy")
    rows = [{"scheme": n, "thermo_variable": v, "dt": dt, "index": studies / "x"} for n in names
            for v in variables for dt in (0.1, 0.2)]
    structure = {"rows": rows, "solve_time": np.geomspace(1e-3, 1, len(rows)),
                 "energy": np.geomspace(1e-15, 1e-1, len(rows)), "violation": np.zeros(len(rows)),
                 "time_kind": "cpu"}
    fig, _, _ = study_plots.structure_figure(structure, "synthetic")
    fig.canvas.draw()
    legends = [ax.get_legend() for ax in fig.axes if ax.get_legend()] + list(fig.legends)
    page = fig.bbox
    for legend in legends:
        box = legend.get_window_extent()
        assert page.x0 <= box.x0 and box.x1 <= page.x1 and page.y0 <= box.y0 and box.y1 <= page.y1
    # One legend per family row, together naming every scheme in every variable once.
    entries = [text.get_text() for legend in legends[:-1] for text in legend.get_texts()]
    assert len(entries) == len(set(entries)) == len(names) * 3
    assert fig.get_size_inches()[1] <= 10.0 and min(drawn_font_sizes(fig)) >= 8
    keys = [(n, v) for n in names for v in variables if not n.startswith("ts_") or n == "ts_rk4"]
    steps = np.array([0.01, 0.02, 0.05, 0.1, 0.15, 0.2, 0.3, 0.5, 0.75, 1.0])
    grid = {"keys": keys, "dt": steps, "outcome": np.zeros((len(keys), 10), dtype=int),
            "flags": np.full((len(keys), 10), "", dtype=object), "failed_at": np.full((len(keys), 10), np.nan),
            "halved": np.zeros((len(keys), 10), dtype=int), "scene": "synthetic", "source": "synthetic"}
    fig, _, _ = study_plots.stability_figure({"paper": grid, "hard": grid, "gas": grid})
    width, height = fig.get_size_inches()
    assert width <= 7.0 and height <= 10.0, (width, height)
    assert min(drawn_font_sizes(fig)) >= 8
    plt.close("all")


# ---------------------------------------------------------------- the machine's load
# The work-precision chart's load is the highest of every model's timed work-precision studies.
WORK_PRECISION_STUDIES = ("work_precision", "work_precision_adaptive", "work_precision_step_control",
                          "gas_work_precision", "gas_work_precision_adaptive", "gas_work_precision_step_control")
TIMED = {"study_work_precision": ("work_precision", WORK_PRECISION_STUDIES),
         "study_structure_cost": ("structure_cost", ("stability_paper",))}


@pytest.mark.parametrize("chart", TIMED)
def test_timing_charts_record_the_load_and_cores_in_caption_and_summary(analysed, studies, chart):
    output, _ = analysed
    group, names = TIMED[chart]
    records = [json.loads((studies / f"{name}.load.json").read_text()) for name in names]
    caption = (output / "figures" / f"{chart}.txt").read_text()
    with h5py.File(output / "summary.h5", "r") as f:
        attrs = dict(f[group].attrs)
    # The highest of the studies' loads, as each study's record holds it.
    assert attrs["load_recorded"] == 1
    assert attrs["load_average_before"] == max(r["load_average_before"] for r in records)
    assert attrs["load_average_after"] == max(r["load_average_after"] for r in records)
    assert attrs["cores"] == len(os.sched_getaffinity(0))
    assert f"{attrs['load_average_before']:.2f} before" in caption and f"{attrs['cores']} cores" in caption
    assert ("BUSY" in caption) == bool(attrs["busy"])


def test_a_busy_or_unrecorded_load_is_said(studies, tmp_path):
    """A study run while others loaded the machine (a planted record: load 3.0 on the cores before
    it) makes a warning, a BUSY caption and a mark on the chart; a study without a record (neither
    beside it nor in its index) says the conditions are unknown."""
    copy = tmp_path / "study"
    shutil.copytree(studies, copy)
    record = json.loads((copy / "work_precision.load.json").read_text())
    record.update(load_average_before=3.0 * record["cores"], load_average_after=0.0)
    (copy / "work_precision.load.json").write_text(json.dumps(record))
    (copy / "stability_paper.load.json").unlink()
    with h5py.File(copy / "stability_paper" / "index.h5", "r+") as index:
        del index.attrs["load_average_end"]             # as a study that did not end leaves it
    result = run_script(copy, tmp_path / "figures", tmp_path / "summary.h5")
    assert result.returncode == 0, result.stderr
    assert "study_work_precision: warning: the machine was busy" in result.stderr
    assert "BUSY" in (tmp_path / "figures" / "study_work_precision.txt").read_text()
    assert "Machine load: not recorded" in (tmp_path / "figures" / "study_structure_cost.txt").read_text()
    with h5py.File(tmp_path / "summary.h5", "r") as f:
        assert f["work_precision"].attrs["busy"] == 1 and f["structure_cost"].attrs["load_recorded"] == 0


# ---------------------------------------------------------------- schemes told apart
def every_scheme_rows(studies):
    study_analysis.read_index(studies / "stability_paper")        # registers the integrators
    with h5py.File(studies / "stability_paper" / "index.h5", "r") as f:
        names = [row["name"].decode() for row in f["integrators"][()]]
    return names, [{"scheme": n, "thermo_variable": v, "dt": dt, "index": studies / "x"} for n in names
                   for v in ("entropy", "temperature", "internal_energy") for dt in (0.1, 0.2)]


def coloured_lines(ax):
    return [line for line in ax.get_lines() if line.get_marker() not in (None, "", "None", "none")]


def test_structure_chart_gives_each_family_a_row_a_colour_and_each_scheme_a_marker(studies):
    """36 curves: one row of panels per family, its curves in the family's colour, a marker per
    scheme within the row, the other families grey behind; every curve drawn in colour once."""
    names, rows = every_scheme_rows(studies)
    structure = {"rows": rows, "solve_time": np.geomspace(1e-3, 1, len(rows)),
                 "energy": np.geomspace(1e-15, 1e-1, len(rows)), "violation": np.zeros(len(rows)),
                 "time_kind": "cpu"}
    fig, _, _ = study_plots.structure_figure(structure, "synthetic")
    grid = np.array(fig.axes).reshape(-1, 2)
    families = list(dict.fromkeys(study_analysis.integrators.family(name) for name in names))
    assert len(grid) == len(families) == 4
    drawn = []
    for row_axes, family in zip(grid, families):
        schemes = [name for name in names if study_analysis.integrators.family(name) == family]
        for ax in row_axes:
            lines = coloured_lines(ax)
            assert len(lines) == 3 * len(schemes)
            assert {matplotlib.colors.to_hex(line.get_color()) for line in lines} == \
                {matplotlib.colors.to_hex(study_analysis.integrators.FAMILY_COLOURS[family])}
            # A marker per scheme; the three variables of a scheme share it, told apart by line style.
            markers = {}
            for line in lines:
                markers.setdefault(line.get_marker(), set()).add(line.get_linestyle())
            assert len(markers) == len(schemes) and all(len(styles) == 3 for styles in markers.values())
            grey = [line for line in ax.get_lines() if line not in lines
                    and matplotlib.colors.to_hex(line.get_color()) == matplotlib.colors.to_hex(study_plots.BACKGROUND)]
            assert len(grey) == 3 * (len(names) - len(schemes))
        drawn += [line.get_label() for line in coloured_lines(row_axes[0])]
    assert len(drawn) == len(set(drawn)) == 3 * len(names)
    plt.close("all")


def test_work_precision_chart_gives_each_model_a_column_and_each_family_a_row(studies):
    """A column per model (the pendulum's, the gas containers'), a row per family named by its
    legend; each panel draws its model's curves of its family in colour, a marker per scheme,
    through that model's errors and solve times."""
    wps = {model: study_analysis.work_precision(studies, model) for model in ("pendulum", "gas")}
    fig, _, lines = study_plots.work_precision_figure(wps, 10.0)
    integrators = study_analysis.integrators
    keys = sorted({key for wp in wps.values() for key in study_plots.curve_keys(wp["rows"])},
                  key=study_plots.key_rank)
    families = list(dict.fromkeys(integrators.family(scheme) for scheme, _ in keys))
    grid = np.array(fig.axes).reshape(len(families), 2)
    assert len(families) >= 3
    assert [ax.get_title().splitlines()[0] for ax in grid[0]] == ["double pendulum, t = 0.4 s", "gas containers, t = 0.4"]
    for row_axes, family in zip(grid, families):
        assert row_axes[-1].get_legend().get_title().get_text() == integrators.family_title(family)
        for ax, wp in zip(row_axes, wps.values()):
            mine = [key for key in study_plots.curve_keys(wp["rows"]) if integrators.family(key[0]) == family]
            drawn = coloured_lines(ax)
            assert len(drawn) == len(mine)
            assert {line.get_marker() for line in drawn} == {integrators.marker(scheme) for scheme, _ in mine}
            shown = set(wp["errors"][wp["shown"]])
            assert all(set(line.get_ydata()) <= shown for line in drawn)
    # The gas column has the gas curves: its EME curve runs through the gas errors, not the pendulum's.
    gas_eme = [i for i in study_plots.members(wps["gas"]["rows"], ("eme", "temperature")) if wps["gas"]["shown"][i]]
    eme_lines = [line for line in coloured_lines(grid[0, 1]) if line.get_marker() == integrators.marker("eme")]
    assert len(gas_eme) == 2 and sorted(eme_lines[0].get_ydata()) == sorted(wps["gas"]["errors"][gas_eme])
    assert any("A column per model, a row per scheme family" in line for line in lines)
    assert any(line.startswith("gas containers: error at t = 0.4") for line in lines)
    plt.close("all")


# ---------------------------------------------------------------- the gas containers beside the pendulum
def test_the_stability_map_has_a_gas_panel_with_the_gas_outcomes(analysed, studies):
    """The summary's stability/gas grid holds each gas case's outcome, and the map draws it as a
    third panel, its rows those of every scene (a scheme the gas study did not run is white)."""
    output, _ = analysed
    with h5py.File(output / "summary.h5", "r") as f:
        grid = f["stability/gas/outcome"][()]
        schemes, steps = text(f["stability/gas/scheme"][()]), list(f["stability/gas/dt"][()])
        codes = {(schemes[i], steps[j]): study_analysis.OUTCOMES[grid[i, j]] for i, j in zip(*np.nonzero(grid >= 0))}
        failed_at = f["stability/gas/failed_at"][()]
        assert failed_at[schemes.index("RK4_theta"), steps.index(1.0)] == 1.0
        assert failed_at[schemes.index("BDF2_theta"), steps.index(1.0)] == 2.0
    assert codes == EXPECTED_GAS_OUTCOMES
    _, _, _, maps, _ = study_analysis.analyse(studies, list(study_analysis.MODELS))
    fig, _, lines = study_plots.stability_figure(maps)
    assert [ax.get_title() for ax in fig.axes] == ["paper scene", "harder scene", "gas containers"]
    assert fig.axes[2].get_xlabel() == r"time step $\Delta t$" and fig.axes[0].get_xlabel().endswith("[s]")
    rows = [label.get_text() for label in fig.axes[0].get_yticklabels()]
    keys = sorted({key for grid in maps.values() for key in grid["keys"]}, key=study_plots.key_rank)
    assert rows == [study_plots.label(*key) for key in keys]
    cells = fig.axes[2].collections[0].get_array().reshape(len(keys), -1) - 1      # drawn as outcome + 1
    for (name, dt), outcome in EXPECTED_GAS_OUTCOMES.items():
        row = [study_plots.plain_name(*key) for key in keys].index(name)
        assert cells[row, list(maps["gas"]["dt"]).index(dt)] == study_analysis.OUTCOMES.index(outcome)
    # TS-midpoint_u ran only on the pendulum's scenes: white (not run) in the gas panel.
    assert np.all(cells[[study_plots.plain_name(*key) for key in keys].index("TS-midpoint_u")] == -1)
    assert any("gas containers: [0, 2], model_name = 'gas_containers', friction = 8.0, q = 1.0" in line
               for line in lines)
    plt.close("all")


def test_no_angular_momentum_drift_is_no_trouble(studies, analysed, tmp_path):
    """The gas containers have no momenta: their indexes have no angular_momentum_drift column.
    With the column taken out of every index (the pendulum's too) the analysis still runs and
    finds the same."""
    for name in GAS_STUDIES:
        with h5py.File(studies / name / "index.h5", "r") as index:
            assert "angular_momentum_drift" not in index["cases"].dtype.names
    copy = tmp_path / "study"
    shutil.copytree(studies, copy)
    for index_path in copy.glob("*/index.h5"):
        with h5py.File(index_path, "r+") as index:
            cases = index["cases"][()]
            if "angular_momentum_drift" not in cases.dtype.names:
                continue
            kept = [name for name in cases.dtype.names if name != "angular_momentum_drift"]
            attributes = dict(index["cases"].attrs)
            del index["cases"]
            index["cases"] = cases[kept]
            for key, value in attributes.items():
                if key == "column_units":
                    value = [unit for name, unit in zip(cases.dtype.names, value) if name != "angular_momentum_drift"]
                index["cases"].attrs[key] = value
            seal_texts(index)                # an index without the column, not a damaged one
    result = run_script(copy, tmp_path / "figures", tmp_path / "summary.h5")
    assert result.returncode == 0, result.stderr
    output, _ = analysed
    with h5py.File(tmp_path / "summary.h5", "r") as planted, h5py.File(output / "summary.h5", "r") as original:
        for scene in ("paper", "hard", "gas"):
            np.testing.assert_array_equal(planted[f"stability/{scene}/outcome"][()],
                                          original[f"stability/{scene}/outcome"][()])
        np.testing.assert_array_equal(planted["gas_work_precision/error"][()], original["gas_work_precision/error"][()])


def test_the_gas_studies_alone_with_models_gas(studies, tmp_path):
    """--models gas analyses the gas containers' studies without the pendulum's: the work-precision
    chart and the stability map, each with the gas alone; without --models the missing pendulum
    studies are named (exit 2)."""
    only = tmp_path / "study"
    only.mkdir()
    for name in GAS_STUDIES:
        shutil.copytree(studies / name, only / name)
        shutil.copy(studies / f"{name}.load.json", only)
    figures = tmp_path / "figures"
    result = subprocess.run([sys.executable, str(SCRIPT), "--study-dir", str(only), "-o", str(figures),
                             "--summary", str(tmp_path / "summary.h5"), "--models", "gas"],
                            capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert result.returncode == 0, result.stderr
    assert sorted(path.name for path in figures.glob("*.png")) == ["study_stability_map.png",
                                                                  "study_work_precision.png"]
    with h5py.File(tmp_path / "summary.h5", "r") as f:
        assert sorted(f) == ["gas_work_precision", "stability"] and sorted(f["stability"]) == ["gas"]
    assert "gas_work_precision_step_control" in (figures / "study_work_precision.txt").read_text()
    assert "work precision (gas containers) EME_theta" in result.stdout and "convergence" not in result.stdout
    result = run_script(only, tmp_path / "all", tmp_path / "all.h5")
    assert result.returncode == 2 and "cannot open" in result.stderr and "Traceback" not in result.stderr


def test_a_gas_case_is_not_compared_with_a_pendulum_reference():
    """The error norm matches /state's mechanical entries by name: a gas point (q, p) against a
    pendulum reference (q1_x ... gamma) is refused, not compared entry by entry."""
    gas = point([1.0, 2.0], (1.8, 4.9), theta_ref=1.0, name="gas.h5", columns=("q", "p"))
    with pytest.raises(StudyError, match=r"gas\.h5: /state columns q p, the reference .* not the same model"):
        state_error(gas, point(theta_ref=1.0))
    # Unscaled temperatures (theta_ref 1): 0.25 in theta_2 is an error of 0.25.
    assert state_error(point([1.0, 2.0], (1.8, 5.15), theta_ref=1.0, columns=("p", "q")[::-1]), gas) == \
        pytest.approx(0.25)
