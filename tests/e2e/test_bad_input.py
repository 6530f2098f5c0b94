"""Bad input: a clear message naming the file, the group, the field and what is allowed,
exit status 2, and nothing written (no output file, no directory, nothing next to the input).

The malformed inputs are tried as an attacker would: misspelt and mistyped fields, files that
are not namelists at all (empty, comments only, random bytes, a directory, /dev/null, a FIFO, a
device), broken group structure, unquoted texts, short arrays, NaN and Inf, bad subscripts,
step counts past the integer range, and the ranges of the paper's eq. (17)."""
import os
import random
import subprocess
from pathlib import Path

import pytest

from conftest import BIN

# Appended to every case, so that a case that is wrongly accepted writes here.
OUTPUT = "&output file = '{output}' /\n"

CASES = {
    # name: (namelist text before &output, words the message must contain)
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
    "too many values": ("&model gravity = 0, 0, -9.81, 1 /\n", ["&model", "gravity", "more than 3 values"]),
    "zero Newton iterations": ("&integrator newton_max_iterations = 0 /\n",
                               ["&integrator", "newton_max_iterations = 0", "an integer >= 1"]),
    "zero spring length": ("&initial q1 = 0, 0, 0 /\n", ["&initial", "q1", "not all zero"]),
    # Group structure.
    "repeated group": ("&integrator t_end = 0.3 /\n&integrator dt = 0.2 /\n",
                       ["&integrator appears 2 times", "each group once"]),
    "repeated group, other case": ("&MODEL beta = 0.1 /\n&model beta = 0.2 /\n", ["&model appears 2 times"]),
    "unterminated group": ("&integrator t_end = 0.3\n", ["&integrator is not closed by '/' before '&output"]),
    "group without its &": ("integrator t_end = 0.3 /\n", ["text outside any namelist group", "'integrator t_end",
                                                           "'&' forgotten"]),
    "text between groups": ("&integrator t_end = 0.3 /\nstray words\n", ["text outside any namelist group",
                                                                        "'stray words"]),
    "& without a name": ("& t_end = 0.3 /\n", ["'&' without a group name"]),
    "unclosed quote": ("&integrator scheme = 'eme /\n", ["line 1", "&integrator", "a text opened by ' is not closed"]),
    "unclosed quote before a comment": ("&integrator\n t_end = 0.3\n scheme = \"eme ! the scheme\n/\n",
                                        ["line 3", "&integrator", 'a text opened by " is not closed']),
    "$end syntax": ("$integrator t_end = 0.3 $end\n", ["text outside any namelist group", "'$integrator"]),
    # Values.
    "unquoted text": ("&integrator scheme = eme /\n", ["&integrator", "'scheme'", "texts need quotes: scheme = 'eme'"]),
    # An unquoted relative path: its '/' closed the group, and the rest was "text outside any group".
    "unquoted path": ("&output file = results/x.h5 /\n",
                      ["&output", "field 'file'", "results/x.h5", "texts need quotes: file = 'results/x.h5'"]),
    "unquoted path before another field": ("&output file = run/x.h5, overwrite = .true. /\n",
                                           ["&output", "field 'file'", "texts need quotes: file = 'run/x.h5'"]),
    "two texts for one": ("&integrator scheme = 'eme' 'midpoint' /\n", ["&integrator", "'scheme'",
                                                                       "cannot take the value"]),
    "too few values": ("&initial theta = 300 /\n", ["&initial", "'theta'", "2 values needed, 1 given",
                                                    "two real numbers > 0"]),
    "too few values, trailing comma": ("&initial theta = 300, /\n", ["&initial", "'theta'", "2 values needed, 1 given"]),
    "value missing between commas": ("&model gravity = 0, , -9.81 /\n", ["&model", "'gravity'",
                                                                          "a value is missing between commas"]),
    "leading empty value": ("&initial theta = , 300 /\n", ["&initial", "'theta'", "a value is missing"]),
    "too few values in a range": ("&initial p2(1:3) = 2*0.5 /\n", ["&initial", "'p2'", "3 values needed, 2 given"]),
    "empty value": ("&integrator dt = , t_end = 1 /\n", ["&integrator", "'dt'", "no value"]),
    "two integers": ("&integrator newton_max_iterations = 5 6 /\n", ["newton_max_iterations", "cannot take"]),
    "integer overflow": ("&integrator newton_max_iterations = 99999999999 /\n", ["newton_max_iterations", "cannot take"]),
    "real for an integer": ("&integrator newton_max_iterations = 2.5 /\n", ["newton_max_iterations", "cannot take"]),
    "logical word": ("&constraints fix_length = yes /\n", ["&constraints", "'fix_length'", ".true. or .false."]),
    # NaN and Inf anywhere.
    "NaN in an array": ("&model gravity = 0, nan, 0 /\n", ["&model", "'gravity'", "NaN and Inf are not allowed"]),
    "Inf scalar": ("&model beta = Inf /\n", ["&model", "'beta'", "NaN and Inf are not allowed"]),
    "-Infinity": ("&initial gamma = -Infinity /\n", ["&initial", "'gamma'", "NaN and Inf"]),
    "NaN dt": ("&integrator dt = NaN /\n", ["&integrator", "'dt'", "NaN and Inf"]),
    "overflow to Inf": ("&model beta = 1e400 /\n", ["&model", "'beta'", "NaN and Inf"]),
    "NaN in a subscript range": ("&initial p1(2:3) = 0, nan /\n", ["&initial", "'p1'", "NaN and Inf"]),
    "NaN repeated": ("&model mass = 2*nan /\n", ["&model", "'mass'", "NaN and Inf"]),
    # Subscripts are subscript errors.
    "subscript past the end": ("&initial theta(3) = 300 /\n", ["&initial: theta(3): subscript (3) is out of range",
                                                              "'theta' has elements 1 to 2"]),
    "subscript zero": ("&initial q1(0) = 1 /\n", ["&initial: q1(0):", "out of range", "'q1' has elements 1 to 3"]),
    "reversed range": ("&initial p2(3:1) = 1 /\n", ["&initial: p2(3:1):", "out of range"]),
    "range past the end": ("&initial theta(1:3) = 3*300 /\n", ["theta(1:3)", "out of range"]),
    "subscript on a scalar": ("&integrator t_end(1) = 0.3 /\n", ["&integrator: t_end(1):", "'t_end' takes no subscript"]),
    "subscript not a number": ("&initial theta(a) = 300 /\n", ["&initial: theta(a):", "is not i or i:j"]),
    # Step counts past the step budget (&integrator max_steps, default 1e8), and past any integer.
    "step count over the budget": ("&integrator t_end = 5000, dt = 1e-6 /\n",
                                   ["&integrator", "t_end = 5000", "needs 5e9 steps, more than max_steps = 100000000",
                                    "allowed: t_end/dt <= max_steps"]),
    "step count overflow, huge t_end": ("&integrator t_end = 1e300 /\n", ["more than max_steps"]),
    "plan over a budget the input sets": ("&integrator max_steps = 100 /\n",
                                          ["&integrator", "needs 133.3", "more than max_steps = 100"]),
    "zero step budget": ("&integrator max_steps = 0 /\n", ["&integrator", "max_steps = 0", "an integer >= 1"]),
    # One rule for dt and t_end: a fixed step longer than the run is refused (it would step past
    # t_end; tiny t_end made runs of 0 steps "complete").
    "fixed step longer than the run": ("&integrator dt = 150, t_end = 20 /\n",
                                       ["&integrator", "dt = 150.0 is longer than t_end = 20.0", "dt <= t_end"]),
    "tiny t_end": ("&integrator t_end = 1e-17 /\n", ["&integrator", "t_end = 1e-17", "dt <= t_end"]),
    "denormal t_end": ("&integrator t_end = 1e-320 /\n", ["&integrator", "dt <= t_end"]),
    "huge dt": ("&integrator dt = 1e308 /\n", ["&integrator", "dt = 1e308", "dt <= t_end"]),
    # Conflicts: one field set twice, or through its old name too; a control byte in the file.
    "field given twice": ("&integrator dt = 0.1, dt = 0.2 /\n", ["&integrator", "dt is given twice"]),
    "subscript given twice": ("&initial theta(2) = 300, theta( 2 ) = 310 /\n",
                              ["&initial", "theta(2) is given twice"]),
    # An element set twice by any two items (issue 41 item 11: the whole array, then one element, was taken).
    "array whole, then an element": ("&initial theta = 300, 300, theta(2) = 310 /\n",
                                     ["&initial", "theta(2) is given twice", "theta = 300, 300", "theta(2) = 310",
                                      "each element once"]),
    "element, then the array whole": ("&initial theta(1) = 300, theta = 300, 310 /\n",
                                      ["&initial", "theta(1) is given twice"]),
    "overlapping range and element": ("&initial p2(1:2) = 2*0.5, p2(2) = 1 /\n", ["&initial", "p2(2) is given twice"]),
    "array whole twice": ("&model mass = 1, 2, mass = 1, 3 /\n", ["&model", "mass is given twice"]),
    "field and its old name": ("&integrator scheme = 'relaxed_dp853', tolerance = 1e-6, ts_tolerance = 1e-7 /\n",
                               ["&integrator", "tolerance and ts_tolerance set the same field", "one of them"]),
    "NUL byte": ("&integrator dt = 0.1\0 /\n", ["line 1", "control character 0", "a text file"]),
    # A tolerance so loose that Newton accepts its predictor.
    "loose newton_tol": ("&integrator newton_tol = 100 /\n", ["&integrator", "newton_tol = 100",
                                                              "a real number > 0 and <= 0.01"]),
    "newton_tol just too loose": ("&integrator newton_tol = 0.011 /\n", ["newton_tol = 0.011", "<= 0.01"]),
    # Eq. (17): mu^eq, mu^neq constants and slopes, eta_cst and eta_theta > 0; heat capacities > 0.
    "mu_eq_const zero": ("&model mu_eq_const = 200, 0 /\n", ["&model", "mu_eq_const", "two real numbers > 0 [J]",
                                                           "eq. (17)"]),
    "mu_eq_slope negative": ("&model mu_eq_slope = -0.5, 0.5 /\n", ["&model", "mu_eq_slope", ">= 0 [J/K]"]),
    "mu_neq_const zero": ("&model mu_neq_const = 0 /\n", ["&model", "mu_neq_const = 0", "> 0"]),
    "mu_neq_slope negative": ("&model mu_neq_slope = -0.1 /\n", ["&model", "mu_neq_slope = -0.1", "> 0"]),
    "viscosity_const zero": ("&model viscosity_const = 0 /\n", ["&model", "viscosity_const = 0", "> 0"]),
    "viscosity_activation negative": ("&model viscosity_activation = -10 /\n",
                                      ["&model", "viscosity_activation = -10", "> 0 [K]"]),
    "heat capacity zero": ("&model heat_capacity = 10, 0 /\n", ["&model", "heat_capacity", "two real numbers > 0"]),
    "negative conductivity": ("&model conductivity = -1 /\n", ["&model", "conductivity = -1", ">= 0"]),
    "theta_ref zero": ("&model theta_ref = 0 /\n", ["&model", "theta_ref = 0", "> 0"]),
    # Spring 2's stiffness mu_eq = 200 - 0.5 (theta - 300) of eq. (17) is -50 J at 800 K.
    "no stiffness at the initial temperature": ("&initial theta = 280, 800 /\n",
                                                ["&initial", "theta = 280.0, 800.0", "is 210.0, -50.0 J",
                                                 "below theta_ref + mu_eq_const/mu_eq_slope"]),
    # The gas containers' initial state outside the model's domain: the message names the file
    # too (issue 41 item 11: it began '&initial:').
    "gas entropy overflowing its energy": ("&model model_name = 'gas_containers' /\n&initial entropy = 1e300, 3 /\n",
                                           ["&initial", "entropy = 1e300, 3.0", "an overflow", "allowed: entropies"]),
    "gas entropy with no temperature": ("&model model_name = 'gas_containers' /\n&initial entropy = 1.5, -1e300 /\n",
                                        ["&initial", "entropy = 1.5, -1e300", "a non-positive temperature",
                                         "allowed: entropies"]),
    # Texts.
    "output not .h5": ("&output_x /\n", ["unknown namelist group &output_x"]),
    "path too long": ("&output file = '" + "x" * 5000 + ".h5' /\n", ["&output", "'file'", "longer than 4096 characters"]),
}


def refused(tmp_path, arguments, words, namelist=None):
    """Runs eme_run, checks exit status 2, the words in the message and that nothing was written."""
    before = sorted(tmp_path.rglob("*"))
    result = subprocess.run([str(BIN / "eme_run"), *arguments], capture_output=True, text=True, timeout=30)
    assert result.returncode == 2, result.stderr
    assert result.stdout == ""
    message = result.stderr
    assert message.startswith("eme_run: ") and message.count("\n") == 1, message
    if namelist is not None:
        assert message.startswith(f"eme_run: {namelist}: "), message
    for word in words:
        assert word in message, f"{word!r} not in {message!r}"
    assert sorted(tmp_path.rglob("*")) == before
    return message


@pytest.mark.parametrize("case", sorted(CASES))
def test_bad_input_is_rejected_clearly(tmp_path, eme_run_binary, case):
    text, words = CASES[case]
    output = tmp_path / "out" / "out.h5"
    namelist = tmp_path / "bad.nml"
    # The output group comes last, so that a group that swallows the rest still names a file here.
    namelist.write_text(text if "&output" in text else text + OUTPUT.format(output=output))
    refused(tmp_path, [str(namelist)], words, namelist)


@pytest.mark.parametrize("case", ["empty", "comments only", "blank lines", "random bytes", "random text",
                                  "binary zeros"])
def test_a_file_without_groups_is_refused(tmp_path, eme_run_binary, case):
    """Each of these ran the paper scene with exit status 0 before."""
    namelist = tmp_path / "scene.nml"
    generator = random.Random(13)
    content = {
        "empty": b"",
        "comments only": b"! a comment\n   ! another\n",
        "blank lines": b"\n\n   \n\t\n",
        "random bytes": bytes(generator.randrange(256) for _ in range(4000)).replace(b"&", b"").replace(b"!", b""),
        "random text": " ".join(generator.choice(["dt", "=", "0.1", "scheme", "'eme'", ","]) for _ in range(50)).encode(),
        "binary zeros": b"\0" * 100,
    }[case]
    namelist.write_bytes(content)
    words = ["no namelist group found", "allowed groups: &model, &initial, &constraints, &integrator, &output"]
    if case == "random text":
        words = ["text outside any namelist group"]
    elif case in ("random bytes", "binary zeros"):
        words = ["is the control character", "allowed: a text file"]
    with_results = tmp_path / "run"
    with_results.mkdir()
    # The default output file is results/<input name>.h5 relative to the working directory.
    before = sorted(tmp_path.rglob("*"))
    result = subprocess.run([str(BIN / "eme_run"), str(namelist)], capture_output=True, text=True, timeout=30,
                            cwd=with_results)
    assert result.returncode == 2, result.stderr
    for word in words + [str(namelist)]:
        assert word in result.stderr, result.stderr
    assert sorted(tmp_path.rglob("*")) == before


@pytest.mark.parametrize("kind", ["directory", "/dev/null", "/dev/zero", "FIFO", "missing"])
def test_a_file_that_is_not_a_regular_file_is_refused_without_waiting(tmp_path, eme_run_binary, kind):
    """A FIFO with no writer would block Fortran's open, /dev/zero would never end: both are
    refused at once (the 30 s timeout would fail the test) with the OS's words."""
    if kind == "directory":
        path, words = tmp_path / "dir.nml", ["it is a directory, not a regular file"]
        path.mkdir()
    elif kind == "FIFO":
        path, words = tmp_path / "pipe.nml", ["it is a FIFO (pipe), not a regular file"]
        os.mkfifo(path)
    elif kind == "missing":
        path, words = tmp_path / "nowhere.nml", ["No such file or directory"]
    else:
        path, words = Path(kind), ["it is a character device, not a regular file"]
    refused(tmp_path, [str(path)], [f"{path}: cannot read the input file: "] + words)


@pytest.mark.parametrize("kind", ["not a directory", "symbolic link loop"])
def test_an_unreadable_file_names_the_os_reason(tmp_path, eme_run_binary, kind):
    """Errors that root gets too (a permission error would not show when the tests run as root)."""
    if kind == "not a directory":
        (tmp_path / "plain").write_text("")
        path, reason = tmp_path / "plain" / "scene.nml", "Not a directory"
    else:
        path, reason = tmp_path / "loop.nml", "Too many levels of symbolic links"
        path.symlink_to(path)
    refused(tmp_path, [str(path)], [f"{path}: cannot read the input file: {reason}"])


def test_a_huge_file_is_refused_unread(tmp_path, eme_run_binary):
    namelist = tmp_path / "huge.nml"
    with open(namelist, "wb") as f:
        f.truncate(2_000_000)
    refused(tmp_path, [str(namelist)], ["cannot read the input file: it has more than 1048576 bytes"])


def test_an_unquoted_path_is_refused_not_dropped(tmp_path, eme_run_binary):
    """file = /tmp/x.h5 ends the group at its first '/': the rest was silently dropped before."""
    namelist = tmp_path / "scene.nml"
    namelist.write_text(f"&integrator t_end = 0.3 /\n&output file = {tmp_path}/x.h5 /\n")
    refused(tmp_path, [str(namelist)], ["&output: field 'file' has the unquoted value", "closes the group",
                                        f"texts need quotes: file = '{tmp_path}/x.h5'"], namelist)


def test_long_paths_are_not_cut(tmp_path, eme_run_binary):
    """Paths of more than 256 characters: a missing input file keeps its OS reason, and a
    run writes to a long output path."""
    deep = tmp_path / ("d" * 120) / ("e" * 120) / ("f" * 60)
    deep.mkdir(parents=True)
    missing = deep / "missing.nml"
    message = refused(tmp_path, [str(missing)], [f"{missing}: cannot read the input file: No such file or directory"])
    assert len(str(missing)) > 300 and message.rstrip().endswith("No such file or directory")
    output = deep / ("g" * 100) / "run.h5"
    namelist = deep / "scene.nml"
    namelist.write_text(f"&integrator t_end = 0.3 /\n&output file = '{output}' /\n")
    result = subprocess.run([str(BIN / "eme_run"), str(namelist)], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    assert len(str(output)) > 400 and output.exists()


def test_paper_data_above_350_K_is_not_refused(tmp_path, eme_run_binary):
    """mu2^neq(theta) = 5 - 0.1 (theta - 300) is 0 at 350 K and negative above (docs/formulation.md
    section 1): that is the paper's data, not an input error."""
    output = tmp_path / "hot.h5"
    namelist = tmp_path / "hot.nml"
    namelist.write_text(f"&initial theta = 280, 360 /\n&integrator t_end = 0.3 /\n&output file = '{output}' /\n")
    result = subprocess.run([str(BIN / "eme_run"), str(namelist)], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    assert output.exists()


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


def test_no_arguments_prints_usage(tmp_path, eme_run_binary):
    refused(tmp_path, [], ["no input file", "usage: eme_run [options] FILE.nml [PETSc options]", "--help"])
