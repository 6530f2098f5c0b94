"""PETSc's own output never lands on the run's or the study's files (issue 41, item 4): every
option that has PETSc write a file (-log_view, the viewers of -*_view and -*_monitor with
:FILE, ascii:, binary: or hdf5:, -options_view, -history, -info and -log_trace, which PETSc opens
as it starts) is refused with exit status 2 and one line naming the option and the file when
that file is the run's input, its output, FILE.part, FILE.part.spare or FILE.lock, or any file of
a study's folder, whether named directly, through '..' or through a symbolic link; nothing is run
or written, and the target is left byte for byte. Before, `-log_view :o.h5` wrote PETSc's log
over the complete o.h5 the run had just reported, and `-history o.nml` appended to the input of a
run that was refused. Options whose files are the user's own still work. The same holds for an
option read from PETSC_OPTIONS, an options file or .petscrc.

PETSc 3.18 writes `-info FILE` and `-log_trace FILE` to FILE.RANK (FILE.0 here): those two reach a
protected file through a symbolic link FILE.0 that points at it."""
import os
import shutil
import subprocess

import h5py
import pytest

from conftest import BIN, namelist_text

RUN = {"integrator": {"scheme": "eme", "dt": 0.15, "t_end": 0.3}, "output": {"file": "o.h5"}}

# Each form puts the target T where PETSc takes a file name.
FORMS = {
    "-log_view :T": ["-log_view", ":{T}"],
    "-log_view ascii:T:ascii_info_detail": ["-log_view", "ascii:{T}:ascii_info_detail"],
    "-snes_view binary:T": ["-snes_view", "binary:{T}"],
    "-ksp_view hdf5:T": ["-ksp_view", "hdf5:{T}"],
    "-snes_monitor ascii:T": ["-snes_monitor", "ascii:{T}"],
    "-options_view :T": ["-options_view", ":{T}"],
    "-history T": ["-history", "{T}"],
    "-info L (L.0 -> T)": ["-info", "{L}:sys"],
    "-log_trace L (L.0 -> T)": ["-log_trace", "{L}"],
}

# The run's files (made before the run with bytes of their own), and two other ways to name one.
RUN_TARGETS = ["run.nml", "o.h5", "o.h5.part", "o.h5.part.spare", "o.h5.lock", "sub/../o.h5", "alias.h5",
               "study_out/notes.txt"]


def snapshot(folder):
    """Every file under `folder` (links as links) with its bytes."""
    return {str(p.relative_to(folder)): (p.readlink() if p.is_symlink() else p.read_bytes() if p.is_file() else None)
            for p in sorted(folder.rglob("*"))}


def arguments(form, target, folder):
    """The option's arguments for `target` and the name of the file PETSc would open; for -info
    and -log_trace, a link L.0 -> target is made first."""
    link = "petsc_link"
    if "{L}" in " ".join(FORMS[form]):
        (folder / f"{link}.0").symlink_to(target)
        return [word.format(L=link) for word in FORMS[form]], f"{link}.0"
    return [word.format(T=target) for word in FORMS[form]], target


def assert_refused(result, program, options, written):
    """Exit 2 and one line naming the option and the file PETSc would write. (A value ending in
    .nml is a second input file on the command line: refused as such, naming it.)"""
    assert result.returncode == 2, (result.returncode, result.stderr)
    lines = result.stderr.splitlines()
    assert len(lines) == 1, result.stderr
    if options[1].endswith(".nml"):
        assert lines[0].startswith(f"{program}: ") and options[1] in lines[0], result.stderr
    else:
        assert lines[0].startswith(f"{program}: option {options[0]} {options[1]}"), result.stderr
        assert f"write '{written}'" in lines[0], result.stderr
    assert result.stdout == ""


@pytest.fixture(scope="module")
def run_template(tmp_path_factory):
    """A folder with the run's input, a complete output, the companions a killed run leaves,
    a sub-folder, a link to the output and a study's folder (its index.journal)."""
    folder = tmp_path_factory.mktemp("run")
    (folder / "run.nml").write_text(namelist_text(RUN))
    made = subprocess.run([str(BIN / "eme_run"), "run.nml"], cwd=folder, capture_output=True, text=True, timeout=120)
    assert made.returncode == 0, made.stderr
    for name in ("o.h5.part", "o.h5.part.spare", "o.h5.lock"):
        (folder / name).write_bytes(f"left by a killed run: {name}\n".encode())
    (folder / "sub").mkdir()
    (folder / "alias.h5").symlink_to("o.h5")
    (folder / "study_out").mkdir()
    (folder / "study_out" / "index.journal").write_text("# a study's journal\n")
    (folder / "study_out" / "notes.txt").write_text("the study's\n")
    return folder


@pytest.fixture
def run_folder(run_template, tmp_path):
    folder = tmp_path / "run"
    shutil.copytree(run_template, folder, symlinks=True)
    return folder


@pytest.mark.parametrize("target", RUN_TARGETS)
@pytest.mark.parametrize("form", list(FORMS))
def test_an_option_writing_a_run_file_is_refused(run_folder, form, target):
    options, written = arguments(form, target, run_folder)
    before = snapshot(run_folder)
    result = subprocess.run([str(BIN / "eme_run"), "run.nml", *options], cwd=run_folder, capture_output=True,
                            text=True, timeout=120)
    assert_refused(result, "eme_run", options, written)
    assert snapshot(run_folder) == before                 # the target and everything else untouched


@pytest.mark.parametrize("option", [["-history", "run.nml"], ["-log_view", ":o.h5"]])
@pytest.mark.parametrize("route", ["PETSC_OPTIONS", "-options_file", ".petscrc"])
def test_an_option_given_outside_the_command_line_is_refused_too(run_folder, route, option):
    """The same refusal for an option PETSc reads from PETSC_OPTIONS, an options file or the
    folder's .petscrc, which PETSc reads as it starts (-history's file it opens then)."""
    environment = dict(os.environ)
    command = [str(BIN / "eme_run"), "run.nml"]
    if route == "PETSC_OPTIONS":
        environment["PETSC_OPTIONS"] = " ".join(option)
    else:
        name = "opts.txt" if route == "-options_file" else ".petscrc"
        (run_folder / name).write_text(" ".join(option) + "\n")
        command += ["-options_file", name] if route == "-options_file" else []
    before = snapshot(run_folder)
    result = subprocess.run(command, cwd=run_folder, capture_output=True, text=True, timeout=120, env=environment)
    assert_refused(result, "eme_run", option, option[1].lstrip(":"))
    assert snapshot(run_folder) == before


STUDY_TARGETS = ["study.nml", "base.nml", "out/index.h5", "out/case_00001.h5", "out/index.journal", "out/study.lock",
                 "out/../out/new.txt"]
STUDY_FORMS = ["-log_view :T", "-snes_view binary:T", "-history T", "-info L (L.0 -> T)"]


@pytest.fixture(scope="module")
def finished_study(tmp_path_factory):
    folder = tmp_path_factory.mktemp("study")
    (folder / "base.nml").write_text(namelist_text({"integrator": {"scheme": "eme", "dt": 0.15, "t_end": 0.3}}))
    (folder / "study.nml").write_text("&study base = 'base.nml', output_dir = 'out' /\n"
                                      "&sweep field = 'dt', values = 0.15, 0.1 /\n")
    made = subprocess.run([str(BIN / "eme_ensemble"), "study.nml"], cwd=folder, capture_output=True, text=True,
                          timeout=120)
    assert made.returncode == 0, made.stderr
    (folder / "out" / "index.journal").write_text("# a journal a killed study left\n")
    (folder / "out" / "study.lock").write_text("process 1 on host elsewhere\n")
    return folder


@pytest.mark.parametrize("target", STUDY_TARGETS)
@pytest.mark.parametrize("form", STUDY_FORMS)
def test_an_option_writing_a_study_file_is_refused(finished_study, tmp_path, form, target):
    folder = tmp_path / "study"
    shutil.copytree(finished_study, folder, symlinks=True)
    options, written = arguments(form, target, folder)
    before = snapshot(folder)
    result = subprocess.run([str(BIN / "eme_ensemble"), "study.nml", *options], cwd=folder, capture_output=True,
                            text=True, timeout=120)
    assert_refused(result, "eme_ensemble", options, written)
    assert snapshot(folder) == before


@pytest.mark.parametrize("form", [form for form in FORMS if not form.startswith("-options_view")])
def test_an_option_writing_a_file_of_its_own_still_works(tmp_path, form):
    """The same forms with a file that is the user's: the run completes and PETSc writes it.
    (PETSc 3.18's -options_view takes no file: it prints to standard output.)"""
    (tmp_path / "run.nml").write_text(namelist_text(RUN))
    options, _ = arguments(form, "mine.out", tmp_path)
    result = subprocess.run([str(BIN / "eme_run"), "run.nml", *options], cwd=tmp_path, capture_output=True,
                            text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    with h5py.File(tmp_path / "o.h5", "r") as f:
        assert f.attrs["status"] == "complete"
    assert (tmp_path / "mine.out").exists() and (tmp_path / "mine.out").stat().st_size > 0
