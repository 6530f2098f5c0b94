"""The reader and data extraction of postprocess/trajectory.py on hand-made inputs."""
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "postprocess"))

import trajectory  # noqa: E402
from synthetic_runs import STATE_COLUMNS, constraint_attributes, write_run  # noqa: E402
from trajectory import RunFileError, read_run  # noqa: E402


def test_increments_are_next_minus_current():
    np.testing.assert_array_equal(trajectory.increments([1.0, 4.0, 9.0, 16.0]), [3.0, 5.0, 7.0])
    np.testing.assert_array_equal(trajectory.increments([2.0, 1.0]), [-1.0])
    assert trajectory.increments([5.0]).shape == (0,)


def test_jz_drift_is_z_component_minus_its_initial_value(tmp_path):
    momentum = np.array([[7.0, 8.0, -3.0], [1.0, 2.0, -2.5], [0.0, 0.0, -4.0]])
    path, _ = write_run(tmp_path / "run.h5", steps=2, data={"angular_momentum": momentum})
    run = read_run(path, ["angular_momentum"])
    np.testing.assert_array_equal(trajectory.jz_drift(run), [0.0, 0.5, -1.0])


def test_positions_follow_the_columns_attribute_and_q2_is_relative(tmp_path):
    # Columns written in reverse order: guessing positions 0..5 would read theta_2, theta_1, gamma, ...
    path, data = write_run(tmp_path / "run.h5", columns=STATE_COLUMNS[::-1])
    m1, m2 = trajectory.mass_positions(read_run(path, ["state"]))
    q1, q2 = data["state"][:, 0:3], data["state"][:, 3:6]
    np.testing.assert_array_equal(m1, q1)
    np.testing.assert_array_equal(m2, q1 + q2)


def test_a_missing_state_column_is_named(tmp_path):
    path, _ = write_run(tmp_path / "run.h5")
    with h5py.File(path, "r+") as f:
        f["state"].attrs["columns"] = " ".join(c if c != "q2_z" else "q2_w" for c in STATE_COLUMNS)
    with pytest.raises(RunFileError) as error:
        trajectory.mass_positions(read_run(path, ["state"]))
    message = str(error.value)
    assert str(path) in message and "/state" in message and "'q2_z'" in message


def test_a_missing_dataset_is_named_with_the_file(tmp_path):
    path, _ = write_run(tmp_path / "run.h5", drop=["lyapunov"])
    assert read_run(path, ["energy"]).data["energy"].shape == (5,)
    with pytest.raises(RunFileError) as error:
        read_run(path, ["energy", "lyapunov"])
    assert str(error.value) == f"{path}: dataset '/lyapunov' is missing"


@pytest.mark.parametrize("attribute", ["scheme", "thermo_variable"])
def test_a_missing_identity_attribute_is_named_with_the_file(tmp_path, attribute):
    path, _ = write_run(tmp_path / "run.h5", drop=[attribute])
    with pytest.raises(RunFileError) as error:
        read_run(path, ["energy"])
    assert str(error.value) == f"{path}: root attribute '{attribute}' is missing"


def test_missing_descriptive_attributes_are_named_and_mark_the_run_incomplete(tmp_path):
    # What a run killed before its end leaves: no status of its own, no times, no dt.
    path, data = write_run(tmp_path / "killed.h5", steps=3, drop=["status", "dt", "input_file"])
    run = read_run(path, ["energy"])
    np.testing.assert_array_equal(run.data["energy"], data["energy"])
    assert run.incomplete and run.steps == 3
    assert run.label.endswith("(INCOMPLETE after 3 steps)") and "Delta t" not in run.label
    assert "dt=(missing)" in run.description and "input (missing)" in run.description
    assert "root attributes dt, input_file missing" in run.description
    assert "status: incomplete: no status attribute" in run.description


def test_a_constraint_attribute_is_required_only_when_asked_for(tmp_path):
    path, _ = write_run(tmp_path / "run.h5")  # no constraint attributes at all
    read_run(path, ["energy"])
    with pytest.raises(RunFileError, match="root attributes 'constraints', 'fix_length', 'length', "
                                           "'fix_temperature', 'temperature' are missing"):
        read_run(path, ["energy"], trajectory.CONSTRAINT_ATTRIBUTES)


def test_datasets_of_different_lengths_are_cut_to_the_steps_they_all_hold(tmp_path):
    # A point dataset one row short: the run is read up to step 2 of 4, and says so.
    path, data = write_run(tmp_path / "run.h5", steps=4, data={"entropy": 1.7 + 0.01 * np.arange(3)})
    run = read_run(path, ["energy", "entropy", "newton_iterations"])
    assert run.steps == 2 and run.incomplete and not str(run.status).startswith("incomplete")
    np.testing.assert_array_equal(run.data["time"], data["time"][:3])
    np.testing.assert_array_equal(run.data["energy"], data["energy"][:3])
    np.testing.assert_array_equal(run.data["newton_iterations"], data["newton_iterations"][:2])
    assert "/entropy 3 rows" in run.description and "read up to step 2" in run.description
    # Step datasets longer than the points allow (a kill between the two flushes) are cut too.
    path, data = write_run(tmp_path / "steps.h5", steps=4, data={"newton_iterations": np.full(7, 4)})
    run = read_run(path, ["newton_iterations"])
    assert run.steps == 4 and len(run.data["newton_iterations"]) == 4 and run.incomplete


def test_a_file_without_any_state_is_refused(tmp_path):
    path, _ = write_run(tmp_path / "empty.h5", steps=0, data={"time": np.zeros(0)})
    with pytest.raises(RunFileError, match=f"{path}: no state written"):
        read_run(path, ["energy"])


def test_a_file_that_is_not_hdf5_is_named(tmp_path):
    path = tmp_path / "notes.h5"
    path.write_text("not HDF5")
    with pytest.raises(RunFileError, match=f"{path}: cannot open"):
        read_run(path, ["energy"])


def test_incomplete_status_is_detected_and_labelled(tmp_path):
    status = "incomplete: step 3 (t = .3000 s): Newton did not converge"
    path, _ = write_run(tmp_path / "stopped.h5", steps=2, attributes={"status": status})
    run = read_run(path, ["energy"])
    assert run.incomplete and run.steps == 2
    assert "INCOMPLETE after 2 steps" in run.label
    assert status in run.description
    complete = read_run(write_run(tmp_path / "done.h5")[0], ["energy"])
    assert not complete.incomplete and "INCOMPLETE" not in complete.label


def test_description_states_scheme_variable_dt_and_input(tmp_path):
    path, _ = write_run(tmp_path / "run.h5", attributes={"thermo_variable": "internal_energy",
                                                          "dt": 0.05, "input_file": "inputs/x.nml"})
    run = read_run(path, ["energy"])
    assert run.name == "EME_u"
    for text in ("eme", "thermo_variable=internal_energy", "dt=0.05 s", "input inputs/x.nml", str(path)):
        assert text in run.description


def test_snapshot_steps_pick_the_nearest_step_and_drop_times_past_the_end():
    time = 0.5 * np.arange(5)  # 0, 0.5, ..., 2.0
    steps, dropped = trajectory.snapshot_steps(time, [0.0, 0.74, 0.76, 2.2, 3.0])
    assert steps == [0, 1, 2, 4]
    assert dropped == [3.0]
    # Two times nearest to one step show it once.
    assert trajectory.snapshot_steps(time, [1.4, 0.6, 0.5])[0] == [3, 1]


def test_constraint_summary_reads_the_constraint_attributes(tmp_path):
    def summary(name, fix_length, fix_temperature):
        attributes = constraint_attributes(fix_length, fix_temperature)
        path, _ = write_run(tmp_path / name, attributes=attributes)
        return trajectory.constraint_summary(read_run(path, [], trajectory.CONSTRAINT_ATTRIBUTES))

    assert summary("both.h5", True, True) == r"$g_1$: $l_1$ = 2.5 m, $g_2$: $\theta_1$ = 300 K"
    assert summary("length.h5", True, False) == r"$g_1$: $l_1$ = 2.5 m"
    assert summary("temperature.h5", False, True) == r"$g_2$: $\theta_1$ = 300 K"
