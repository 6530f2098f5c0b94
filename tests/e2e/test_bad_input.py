"""Bad input: a clear message naming the file, the group, the field and what is allowed,
exit status 2, and no output file."""
import subprocess

import pytest

from conftest import BIN

CASES = {
    # name: (namelist text, words the message must contain)
    "misspelt name": ("&integrator\n  dtt = 0.1\n/\n", ["&integrator", "unknown field 'dtt'", "allowed: scheme"]),
    "wrong type": ("&integrator\n  dt = 'abc'\n/\n", ["&integrator", "'dt'", "'abc'", "a real number > 0"]),
    "non-positive dt": ("&integrator\n  dt = -0.1\n/\n", ["&integrator", "dt = -0.1", "a real number > 0"]),
    "zero dt": ("&integrator dt = 0.0 /\n", ["&integrator", "dt = 0", "a real number > 0"]),
    "non-positive mass": ("&model\n  mass = 1.0, -2.0\n/\n", ["&model", "mass", "two real numbers > 0"]),
    "non-positive temperature": ("&initial theta = 280.0, -5.0 /\n", ["&initial", "theta", "two real numbers > 0"]),
    "unknown scheme": ("&integrator scheme = 'rk4' /\n", ["&integrator", "scheme = 'rk4'", "allowed: 'eme', 'midpoint'"]),
    "unknown thermodynamic variable": ("&integrator thermo_variable = 'enthalpy' /\n",
                                       ["thermo_variable = 'enthalpy'", "'entropy', 'temperature' or 'internal_energy'"]),
    "unknown discrete gradient": ("&integrator discrete_gradient = 'itoh' /\n", ["discrete_gradient", "'gonzalez' or 'partitioned'"]),
    "unknown group": ("&integrater dt = 0.1 /\n", ["unknown namelist group &integrater", "&integrator"]),
    "too many values": ("&model gravity = 0, 0, -9.81, 1 /\n", ["&model", "gravity"]),
    "zero Newton iterations": ("&integrator newton_max_iterations = 0 /\n",
                               ["&integrator", "newton_max_iterations = 0", "an integer >= 1"]),
    "zero spring length": ("&initial q1 = 0, 0, 0 /\n", ["&initial", "q1", "not all zero"]),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_bad_input_is_rejected_clearly(tmp_path, eme_run_binary, case):
    text, words = CASES[case]
    output = tmp_path / "out.h5"
    namelist = tmp_path / "bad.nml"
    namelist.write_text(text + f"&output file = '{output}' /\n")
    result = subprocess.run([str(eme_run_binary), str(namelist)], capture_output=True, text=True)
    assert result.returncode == 2
    message = result.stderr
    assert str(namelist) in message
    for word in words:
        assert word in message, f"{word!r} not in {message!r}"
    assert not output.exists()


def test_unknown_scheme_lists_every_registered_integrator(tmp_path, eme_run_binary):
    """The message names every integrator of the registry (as --integrators prints it), uncut."""
    registry = subprocess.run([str(eme_run_binary), "--integrators"], capture_output=True, text=True, check=True)
    names = [line.split("\t")[0] for line in registry.stdout.splitlines()[1:]]
    assert len(names) >= 10
    namelist = tmp_path / "bad.nml"
    namelist.write_text(f"&integrator scheme = 'rk4' /\n&output file = '{tmp_path / 'out.h5'}' /\n")
    result = subprocess.run([str(eme_run_binary), str(namelist)], capture_output=True, text=True)
    assert result.returncode == 2
    allowed = result.stderr.split("allowed:")[1]
    assert [name for name in names if f"'{name}'" not in allowed] == []
    assert allowed.rstrip().endswith(f"or '{names[-1]}'")


def test_unreadable_file(tmp_path, eme_run_binary):
    missing = tmp_path / "nowhere.nml"
    result = subprocess.run([str(eme_run_binary), str(missing)], capture_output=True, text=True)
    assert result.returncode == 2
    assert str(missing) in result.stderr and "cannot read the input file" in result.stderr


def test_no_arguments_prints_usage(eme_run_binary):
    result = subprocess.run([str(BIN / "eme_run")], capture_output=True, text=True)
    assert result.returncode == 2 and "usage: eme_run FILE.nml" in result.stderr
