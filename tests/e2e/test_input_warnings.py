"""Plausible mistakes that still run get one warning: a temperature level given in degrees
Celsius (theta = 7, 77 ran to completion without a word). Temperatures in kelvin below 150 K
are named, field by field, once per run and once per study; differences in kelvin (the viscosity's
activation temperature, 10 K by default) and the defaults are not."""
import subprocess

import pytest

from conftest import BIN, namelist_text

SHORT = {"integrator": {"t_end": 0.3}}


@pytest.mark.parametrize("group, field, value", [("initial", "theta", [7.0, 77.0]), ("model", "theta_ref", 27.0),
                                                 ("output", "theta_r", 20.0)])
def test_a_temperature_that_looks_like_celsius_is_named(tmp_path, eme_run_binary, group, field, value):
    groups = {**SHORT, group: {field: value}}
    if field == "theta_ref":      # theta must stay below theta_ref + mu_eq_const/mu_eq_slope
        groups["initial"] = {"theta": [20.0, 30.0]}
    groups.setdefault("output", {})["file"] = str(tmp_path / "run.h5")
    (tmp_path / "run.nml").write_text(namelist_text(groups))
    result = subprocess.run([str(BIN / "eme_run"), "run.nml"], capture_output=True, text=True, cwd=tmp_path)
    warnings = [line for line in result.stderr.splitlines() if "looks like degrees Celsius" in line]
    assert any(f"&{group}: {field} = " in line for line in warnings), result.stderr
    assert all(line.startswith("eme_run: warning: run.nml: ") for line in warnings)


def test_the_constraint_temperature_is_named_too(tmp_path, eme_run_binary):
    groups = {**SHORT, "initial": {"theta": [20.0, 350.0]},
              "constraints": {"fix_temperature": True, "temperature": 20.0}, "output": {"file": str(tmp_path / "r.h5")}}
    (tmp_path / "run.nml").write_text(namelist_text(groups))
    result = subprocess.run([str(BIN / "eme_run"), "run.nml"], capture_output=True, text=True, cwd=tmp_path)
    assert "&constraints: temperature = 20.0 K looks like degrees Celsius" in result.stderr
    assert "&initial: theta = 20.0, 350.0 K looks like degrees Celsius" in result.stderr


def test_kelvin_and_the_defaults_give_no_warning(tmp_path, eme_run_binary):
    groups = {**SHORT, "initial": {"theta": [150.0, 350.0]}, "output": {"file": str(tmp_path / "r.h5")}}
    (tmp_path / "run.nml").write_text(namelist_text(groups))
    result = subprocess.run([str(BIN / "eme_run"), "run.nml"], capture_output=True, text=True, cwd=tmp_path)
    assert result.returncode == 0 and "warning" not in result.stderr, result.stderr


def test_a_study_warns_once(tmp_path, eme_run_binary):
    (tmp_path / "base.nml").write_text(namelist_text({**SHORT, "initial": {"theta": [7.0, 77.0]}}))
    (tmp_path / "study.nml").write_text("&study base = 'base.nml', output_dir = 'out' /\n"
                                        "&sweep field = 'dt', values = 0.1, 0.15, 0.3 /\n")
    result = subprocess.run([str(BIN / "eme_ensemble"), "study.nml"], capture_output=True, text=True, cwd=tmp_path,
                            timeout=120)
    assert result.returncode == 0, result.stderr
    lines = [line for line in (result.stdout + result.stderr).splitlines() if "looks like degrees Celsius" in line]
    assert lines == ["eme_ensemble: warning: base.nml: &initial: theta = 7.0, 77.0 K looks like degrees Celsius "
                     "(below 150.0 K); temperatures are absolute, in kelvin (3 cases)"], lines
