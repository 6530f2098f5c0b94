"""The drivers' command line: --help and -h, --version with the libraries' own versions,
options before or after exactly one input file, unknown options refused, and a warning for PETSc
options that nothing used."""
import re
import shutil
import subprocess
from pathlib import Path

import h5py
import numpy as np
import pytest

from conftest import BIN, ROOT, namelist_text

MPIRUN = ["mpirun", "--allow-run-as-root", "--oversubscribe"]
PROGRAMS = ["eme_run", "eme_ensemble"]


def run(program, *arguments, cwd=ROOT):
    return subprocess.run([str(BIN / program), *map(str, arguments)], capture_output=True, text=True, timeout=120,
                          cwd=cwd)


@pytest.mark.parametrize("program", PROGRAMS)
@pytest.mark.parametrize("flag", ["--help", "-h"])
def test_help_lists_usage_groups_exit_codes_and_own_options(program, flag, eme_run_binary):
    result = run(program, flag)
    assert result.returncode == 0 and result.stderr == ""
    text = result.stdout
    assert text.startswith(f"usage: ") and program in text.splitlines()[0]
    groups = ["&model", "&initial", "&constraints", "&integrator", "&output"] if program == "eme_run" \
        else ["&study", "&sweep"]
    for word in groups + ["Exit status: 0", "2 bad", "--version", "-eme_chord_predictor", "before or after the input file"]:
        assert word in text, word
    # Help comes before anything else: with an input file, a second one or PETSc options too.
    assert run(program, "a.nml", "b.nml", "-snes_monitor", flag).stdout == text


def library_versions_from_elsewhere():
    """The versions as other tools report them: pkg-config for PETSc and HDF5, SUNDIALS' header,
    Open MPI's mpirun."""
    def pkg_config(name):
        return subprocess.run(["pkg-config", "--modversion", name], capture_output=True, text=True,
                              check=True).stdout.strip()
    sundials = re.search(r'#define SUNDIALS_VERSION "([^"]+)"',
                         Path("/usr/include/sundials/sundials_config.h").read_text()).group(1)
    mpi = re.search(r"\(Open MPI\) (\S+)", subprocess.run(["mpirun", "--version"], capture_output=True,
                                                           text=True).stdout).group(1)
    return {"PETSc": pkg_config("PETSc"), "HDF5": pkg_config("hdf5-openmpi"), "SUNDIALS": sundials,
            "MPI": f"Open MPI v{mpi}"}


@pytest.mark.parametrize("program", PROGRAMS)
def test_version_names_the_code_and_every_library(program, eme_run_binary):
    result = run(program, "--version")
    assert result.returncode == 0 and result.stderr == ""
    lines = result.stdout.splitlines()
    git = subprocess.run(["git", "describe", "--always", "--dirty"], capture_output=True, text=True, cwd=ROOT)
    # "eme_run (eme) 0.9.0 (git cb77f99)": the release of the file VERSION and the git description.
    release = (ROOT / "VERSION").read_text().strip()
    assert re.fullmatch(r"\d+\.\d+\.\d+", release)
    match = re.fullmatch(rf"{program} \(eme\) {re.escape(release)} \(git ([0-9a-z.-]+)\)", lines[0])
    assert match, lines[0]
    if git.returncode == 0:
        # The build's version is the commit it was built from (the tree may have changed since).
        assert match.group(1).split("-dirty")[0] == git.stdout.strip().split("-dirty")[0]
    found = dict(line.split(": ", 1) for line in lines[1:])
    assert set(found) >= {"PETSc", "HDF5", "MPI", "SUNDIALS", "LAPACK", "compiler"}
    for library, version in library_versions_from_elsewhere().items():
        assert found[library].startswith(version), (library, found[library], version)
    assert re.fullmatch(r"\d+\.\d+\.\d+", found["LAPACK"])


def test_a_source_tarball_knows_its_release(tmp_path):
    """A tree without .git (a source tarball, git archive) records the release number of VERSION,
    not 'unknown' as before."""
    tree = tmp_path / "tarball"
    tree.mkdir()
    for name in ("Makefile", "VERSION"):
        shutil.copy(ROOT / name, tree / name)
    result = subprocess.run(["make", "-s", "version"], capture_output=True, text=True, cwd=tree, timeout=60)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == (ROOT / "VERSION").read_text().strip()


@pytest.fixture
def scene(tmp_path):
    def make(name="scene", t_end=0.3):
        output = tmp_path / f"{name}.h5"
        path = tmp_path / f"{name}.nml"
        path.write_text(namelist_text({"integrator": {"t_end": t_end}, "output": {"file": str(output)}}))
        return path, output
    return make


@pytest.mark.parametrize("order", ["after", "before", "flag before", "value before", "both sides"])
def test_options_before_or_after_the_input_file(scene, order, eme_run_binary):
    """-snes_converged_reason prints a line per solve wherever it stands; an option's value
    (-snes_linesearch_type basic) before the file is not taken for the file; the same states
    result either way."""
    path, output = scene()
    arguments = {
        "after": [path, "-snes_converged_reason"],
        "before": ["-snes_converged_reason", path],
        "flag before": ["-snes_converged_reason", path, "-snes_linesearch_type", "basic"],
        "value before": ["-snes_linesearch_type", "basic", path, "-snes_converged_reason"],
        "both sides": ["-snes_max_it", "50", "-snes_converged_reason", path, "-snes_linesearch_type", "basic"],
    }[order]
    result = run("eme_run", *arguments)
    assert result.returncode == 0, result.stderr
    assert result.stdout.count("Nonlinear solve converged") >= 2
    assert "warning" not in result.stderr, result.stderr
    with h5py.File(output, "r") as f:
        state = f["state"][()]
    plain_path, plain_output = scene("plain")
    assert run("eme_run", plain_path).returncode == 0
    with h5py.File(plain_output, "r") as f:
        # -snes_linesearch_type selects PETSc's standard SNES path (docs/integrators.md), which reaches
        # the same roots to rounding, not bit for bit.
        np.testing.assert_allclose(f["state"][()], state, rtol=0, atol=1e-12)


@pytest.mark.parametrize("arguments,words", [
    (["{a}", "{b}"], ["2 input files: '{a}' '{b}'", "allowed: exactly one input file"]),
    (["-snes_monitor", "{a}", "{b}"], ["2 input files"]),
    (["{a}", "-pc_type", "lu", "{b}"], ["2 input files"]),
    (["-snes_monitor"], ["no input file", "usage:"]),
    (["--bogus", "{a}"], ["unknown option '--bogus'", "allowed: --help, -h, --version"]),
])
def test_usage_errors_write_nothing(tmp_path, scene, arguments, words, eme_run_binary):
    a, output_a = scene("a")
    b, output_b = scene("b")
    for program in PROGRAMS:
        result = run(program, *[x.format(a=a, b=b) for x in arguments])
        assert result.returncode == 2, (program, result.stderr)
        for word in words:
            assert word.format(a=a, b=b) in result.stderr, result.stderr
        assert not output_a.exists() and not output_b.exists()
        assert sorted(p.name for p in tmp_path.iterdir()) == ["a.nml", "b.nml"]


def test_unused_petsc_options_are_warned(scene, eme_run_binary):
    path, output = scene()
    result = run("eme_run", path, "-snes_atoll", "1e-3", "-snes_converged_reason", "-ts_type", "bdf")
    assert result.returncode == 0, result.stderr
    warnings = [line for line in result.stderr.splitlines() if "warning" in line]
    assert warnings == ["eme_run: warning: PETSc options that nothing used: -snes_atoll -ts_type"]
    # An EME run uses no TS; a TS run uses -ts_* and so is not warned about them.
    path.write_text(namelist_text({"integrator": {"t_end": 0.3, "scheme": "ts_bdf2"}, "output": {"file": str(output)}}))
    output.unlink()
    result = run("eme_run", path, "-ts_max_snes_failures", "3", "-snes_atoll", "1")
    assert result.returncode == 0, result.stderr
    assert "PETSc options that nothing used: -snes_atoll\n" in result.stderr


def test_ensemble_warns_only_about_options_no_rank_used(tmp_path, eme_run_binary):
    """A TS option is read by the TS case's solver: no warning for it, whichever rank ran that case
    (every rank also sets up each of the study's integrators once before the first case, to refuse
    bad options before anything runs); a misspelt option is named once, by rank 0. Which rank runs
    which case depends on timing and is not asserted."""
    base = tmp_path / "base.nml"
    base.write_text("&integrator t_end = 0.6 /\n")
    output = tmp_path / "out"
    study = tmp_path / "study.nml"
    study.write_text(f"&study base = '{base}', output_dir = '{output}' /\n"
                     "&sweep field = 'scheme', texts = 'eme', 'ts_bdf2', 'midpoint', 'eme' /\n")
    result = subprocess.run([*MPIRUN, "-n", "2", str(BIN / "eme_ensemble"), "-ts_max_snes_failures", "3", str(study),
                             "-bogus_option"], capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert result.returncode == 0, result.stderr
    assert result.stderr.count("warning") == 1
    assert "eme_ensemble: warning: PETSc options that nothing used: -bogus_option\n" in result.stderr
    with h5py.File(output / "index.h5", "r") as f:
        assert len(f["cases"]) == 4


# ---------------------------------------------------------------- edges a new user hits (issue 24)
def files_in(folder):
    return sorted(p.name for p in Path(folder).iterdir())


@pytest.mark.parametrize("arguments", [["-help", "{a}"], ["{a}", "-help"], ["-help"]])
def test_petsc_help_prints_the_help_and_writes_nothing(tmp_path, scene, arguments, eme_run_binary):
    """PETSc's -help before or after the input file (or without one) prints the usage and, with a
    file, every option the run's solver reads, then exits 0 without integrating: nothing is written.
    Before: `-help FILE.nml` made PETSc take FILE.nml for -help's value and abort (exit 62)."""
    a, output = scene("a")
    result = run("eme_run", *[x.format(a=a) for x in arguments])
    assert result.returncode == 0, result.stderr
    assert "usage: eme_run" in result.stdout
    if "{a}" in arguments:
        assert "-eme_max_halvings" in result.stdout and "-snes_atol" in result.stdout
    assert files_in(tmp_path) == ["a.nml"]


def test_an_nml_argument_is_never_an_option_value(tmp_path, scene, eme_run_binary):
    """-info FILE.nml: -info is a flag (PETSc's info goes to stdout), FILE.nml the input; before,
    PETSc took FILE.nml as -info's log file name and wrote FILE.nml.0."""
    a, output = scene("a")
    result = run("eme_run", "-info", a)
    assert result.returncode == 0, result.stderr
    assert "PetscInitialize" in result.stdout
    assert files_in(tmp_path) == ["a.h5", "a.nml"]


@pytest.mark.parametrize("option, value, allowed", [
    ("-eme_max_halvings", "40", "an integer from 0 to 30"), ("-eme_max_halvings", "two", "an integer from 0 to 30"),
    ("-eme_fused_kernel", "maybe", "true or false"), ("-eme_error_scale", "-1", "a number > 0"),
    ("-eme_progress", "2", "true or false"), ("-eme_chord_iterations", "0", "an integer from 1 to 10")])
def test_a_bad_option_value_is_bad_input_and_writes_nothing(tmp_path, scene, option, value, allowed,
                                                            eme_run_binary):
    """Before: -eme_max_halvings 40 was a PETSc error in the solver's set-up: exit 1 and a stray
    FILE.part."""
    a, _ = scene("a")
    for program in PROGRAMS:
        result = run(program, a, option, value)
        assert result.returncode == 2, (program, result.stderr)
        assert f"{program}: {option} {value}: allowed: {allowed}" in result.stderr
        assert "PETSC ERROR" not in result.stderr
        assert files_in(tmp_path) == ["a.nml"]


def test_eme_run_refuses_more_than_one_rank(tmp_path, scene, eme_run_binary):
    """Before: both ranks wrote the same file (and one of five tries failed)."""
    a, _ = scene("a")
    result = subprocess.run([*MPIRUN, "-n", "2", str(BIN / "eme_run"), str(a)], capture_output=True, text=True,
                            timeout=120)
    assert result.returncode == 2
    assert "eme_run: runs one case on one process, not on 2 ranks" in result.stderr
    assert "mpirun -n N eme_ensemble STUDY.nml" in result.stderr
    assert files_in(tmp_path) == ["a.nml"]
