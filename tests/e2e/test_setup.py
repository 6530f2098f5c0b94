"""The set-up (Makefile section set-up, setup/configure.sh, setup/check_python_lock.py): the
libraries are found by PETSC_DIR without pkg-config, by pkg-config, and HDF5 by its h5pfc
wrapper; without them the script says what to install instead of calling apt-get; the Python
lock pins every package of the environment."""
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import ROOT

CONFIGURE = ROOT / "setup" / "configure.sh"
LOCK_CHECK = ROOT / "setup" / "check_python_lock.py"
DEBIAN_PETSC = Path("/usr/lib/petscdir/petsc3.18/x86_64-linux-gnu-real")


def path_without(tmp_path, *hidden):
    """A PATH of links to every program on PATH but `hidden`."""
    folder = tmp_path / "bin"
    folder.mkdir()
    for directory in os.environ["PATH"].split(os.pathsep):
        if not os.path.isdir(directory):
            continue
        for entry in os.scandir(directory):
            if entry.name in hidden or (folder / entry.name).exists():
                continue
            (folder / entry.name).symlink_to(entry.path)
    return str(folder)


def configure(tmp_path, **environment):
    """Runs setup/configure.sh (never apt-get) and returns (status, stderr, {variable: value})."""
    output = tmp_path / "config.mk"
    env = {key: value for key, value in os.environ.items()
           if key not in ("PETSC_DIR", "PETSC_ARCH", "HDF5_DIR", "SUNDIALS_DIR")}
    env.update(EME_SETUP_APT="no", NATIVE_PACKAGES="gfortran petsc-dev", **environment)
    result = subprocess.run(["sh", str(CONFIGURE), str(output)], capture_output=True, text=True, env=env, timeout=60)
    variables = {}
    if output.exists():
        for line in output.read_text().splitlines():
            if " := " in line:
                name, value = line.split(" := ", 1)
                variables[name] = value.split()
    return result.returncode, result.stderr, variables


def include_dirs(flags):
    return [Path(flag[2:]) for flag in flags if flag.startswith("-I")]


def holds(flags, relative):
    return any((directory / relative).exists() for directory in include_dirs(flags))


def test_system_libraries_are_found_by_pkg_config(tmp_path):
    status, message, found = configure(tmp_path)
    assert status == 0, message
    assert holds(found["PETSC_INCLUDES"], "petsc/finclude/petscsys.h")
    assert holds(found["HDF5_FLAGS"], "hdf5.mod")
    assert "-lhdf5_fortran" in found["HDF5_LIBS"]
    petsc_pkg_config = subprocess.run(["pkg-config", "--libs", "PETSc"], capture_output=True, text=True).stdout.split()
    assert set(petsc_pkg_config) <= set(found["PETSC_LIBS"])


@pytest.mark.skipif(not DEBIAN_PETSC.exists(), reason="Debian's PETSc is not installed")
def test_petsc_dir_without_pkg_config_and_hdf5_from_h5pfc(tmp_path):
    """PETSC_DIR alone (its petscvariables) and HDF5 from `h5pfc -show`, with pkg-config hidden."""
    path = path_without(tmp_path, "pkg-config", "pkgconf", "x86_64-linux-gnu-pkg-config")
    status, message, found = configure(tmp_path, PATH=path, PETSC_DIR=str(DEBIAN_PETSC))
    assert status == 0, message
    assert include_dirs(found["PETSC_INCLUDES"])[0] == DEBIAN_PETSC / "include"
    assert f"-L{DEBIAN_PETSC}/lib" in found["PETSC_LIBS"] and f"-Wl,-rpath,{DEBIAN_PETSC}/lib" in found["PETSC_LIBS"]
    h5pfc = subprocess.run(["h5pfc", "-show"], capture_output=True, text=True).stdout.split()
    assert [f for f in found["HDF5_FLAGS"] if f.startswith("-I")] == [f for f in h5pfc if f.startswith("-I")]
    assert holds(found["HDF5_FLAGS"], "hdf5.mod")
    assert len(found["HDF5_LIBS"]) == len(set(found["HDF5_LIBS"]))


def test_petsc_dir_with_its_pkg_config_file(tmp_path):
    """PETSC_DIR/PETSC_ARCH/lib/pkgconfig/PETSc.pc, as a PETSc build tree has it, wins over the
    system's: a copy whose include folder is elsewhere shows which one was read."""
    arch = tmp_path / "petsc" / "arch-test"
    (arch / "lib" / "pkgconfig").mkdir(parents=True)
    system_pc = Path(subprocess.run(["pkg-config", "--variable=pcfiledir", "PETSc"], capture_output=True,
                                    text=True).stdout.strip()) / "PETSc.pc"
    prefix = Path(subprocess.run(["pkg-config", "--variable=prefix", "PETSc"], capture_output=True,
                                 text=True).stdout.strip())
    mirror = tmp_path / "mirror"
    mirror.symlink_to(prefix)
    text = re.sub(r"(?m)^prefix=.*$", f"prefix={mirror}", system_pc.read_text())
    (arch / "lib" / "pkgconfig" / "PETSc.pc").write_text(text)
    status, message, found = configure(tmp_path, PETSC_DIR=str(tmp_path / "petsc"), PETSC_ARCH="arch-test")
    assert status == 0, message
    assert include_dirs(found["PETSC_INCLUDES"]) == [mirror / "include"]


def test_missing_libraries_say_what_to_install(tmp_path):
    """No compilers, no pkg-config, no wrappers: the script stops with the Debian, Spack and
    conda-forge lines, calls no apt-get, and writes no configuration."""
    path = path_without(tmp_path, "pkg-config", "pkgconf", "x86_64-linux-gnu-pkg-config", "mpif90", "mpicc",
                        "h5pfc", "h5fc", "apt-get")
    status, message, found = configure(tmp_path, PATH=path)
    assert status == 1 and found == {}
    for words in ["The build needs: MPI-Fortran-compiler(mpif90) MPI-C-compiler(mpicc) PETSc(with-Fortran)",
                  "HDF5(with-Fortran-and-high-level)", "apt-get install gfortran petsc-dev", "spack install", "petsc+mpi+fortran",
                  "hdf5+fortran+hl+mpi", "conda install -c conda-forge", "make PETSC_DIR=... [PETSC_ARCH=...] HDF5_DIR=..."]:
        assert words in message, message
    assert "Permission denied" not in message


def test_a_petsc_dir_without_petsc_is_refused(tmp_path):
    status, message, _ = configure(tmp_path, PETSC_DIR=str(tmp_path))
    assert status == 1 and "PETSc(with-Fortran)" in message


def test_the_lock_pins_every_package_of_the_environment():
    """What .venv holds is what the lock pins; a package not in the lock, or at another
    version, is found."""
    lock = ROOT / "postprocess" / "requirements.lock"
    requirements = ROOT / "postprocess" / "requirements.txt"
    assert subprocess.run([sys.executable, str(LOCK_CHECK), "--installed", str(lock)]).returncode == 0
    assert subprocess.run([sys.executable, str(LOCK_CHECK), str(requirements), str(lock)]).returncode == 0
    frozen = subprocess.run([sys.executable, "-m", "pip", "freeze"], capture_output=True, text=True).stdout
    assert all(re.fullmatch(r"[A-Za-z0-9._-]+==\S+", line) for line in frozen.splitlines())


@pytest.mark.parametrize("requirement,words", [
    ("tabulate==0.9.0", ["tabulate is not pinned"]),
    ("h5py==0.0.1", ["h5py: ", "pins 0.0.1, the lock "]),
])
def test_a_requirement_the_lock_lacks_is_found(tmp_path, requirement, words):
    requirements = tmp_path / "requirements.txt"
    requirements.write_text((ROOT / "postprocess" / "requirements.txt").read_text() + requirement + "\n")
    result = subprocess.run([sys.executable, str(LOCK_CHECK), str(requirements),
                             str(ROOT / "postprocess" / "requirements.lock")], capture_output=True, text=True)
    assert result.returncode == 1
    for word in words + ["run 'make python-lock'"]:
        assert word in result.stderr
