"""How eme_run starts MPI (docs/running.md, docs/faults.md "On a busy machine"). Started without
mpirun it is an MPI singleton: it gives Open MPI a session directory of its own (Open MPI 4.1
names every isolated singleton's alike), removed at exit, or by the next start if the process was
killed; and only the transport to itself (pml ob1, btl self). The user's own settings win, and
under mpirun nothing is set.

The runs are stopped by the LD_PRELOAD shim kill_at_write.c (SIGSTOP at their third file
operation in their output folder, after MPI has started), so two of them hold their session at
once without any timing. Each test has a TMPDIR of its own."""
import os
import signal
import socket
import subprocess
from pathlib import Path

import pytest

from conftest import BIN
from faults import shim_library

LONG = "&integrator dt=0.001, t_end=60 /\n&output file='{file}' /\n"
SHORT = "&integrator dt=0.01, t_end=0.01 /\n&output file='{file}' /\n"
MPIRUN = ["mpirun", "--allow-run-as-root", "--oversubscribe"]


def prepared(tmp_path, name, text=LONG):
    folder = tmp_path / name
    folder.mkdir()
    namelist = folder / "run.nml"
    namelist.write_text(text.format(file=folder / "run.h5"))
    return folder, namelist


def environment(tmp_path, **extra):
    temporary = tmp_path / "tmp"
    temporary.mkdir(exist_ok=True)
    env = {k: v for k, v in os.environ.items() if not k.startswith("OMPI_MCA_")}
    env.update(TMPDIR=str(temporary), HOME=str(tmp_path / "home"), **extra)
    return env


def stopped_run(namelist, env):
    """eme_run on `namelist`, stopped (SIGSTOP) at its third file operation in its folder."""
    env = dict(env, LD_PRELOAD=str(shim_library("kill_at_write")), EME_KILL_DIR=str(namelist.parent),
               EME_KILL_AT="3", EME_KILL_SIGNAL=str(int(signal.SIGSTOP)))
    process = subprocess.Popen([str(BIN / "eme_run"), str(namelist)], env=env, stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True)
    _, status = os.waitpid(process.pid, os.WUNTRACED)
    assert os.WIFSTOPPED(status), status
    return process


def session_directories(temporary):
    """The Open MPI session directories (.../ompi.HOST.UID/jf.N/JOB/RANK) under `temporary`."""
    return sorted(str(p.relative_to(temporary)) for p in temporary.glob("**/ompi.*/jf.*/*/*") if p.is_dir())


def test_two_singletons_at_once_have_session_directories_of_their_own_removed_at_exit(tmp_path):
    env = environment(tmp_path)
    temporary = Path(env["TMPDIR"])
    runs = [stopped_run(prepared(tmp_path, name)[1], env) for name in ("a", "b")]
    try:
        directories = session_directories(temporary)
        bases = sorted(p.name for p in temporary.iterdir())
    finally:
        for run in runs:
            run.send_signal(signal.SIGCONT)
    for run in runs:
        _, err = run.communicate(timeout=600)
        assert run.returncode == 0, err
    assert len(directories) == 2, directories               # before: both ompi.HOST.UID/jf.0/1/0
    host = socket.gethostname()
    assert sorted(b.rsplit(".", 1)[0] for b in bases) == sorted(f"eme-mpi.{host}.{run.pid}" for run in runs)
    assert list(temporary.iterdir()) == []                   # removed at exit


def test_a_killed_singletons_session_directory_is_removed_by_the_next_start(tmp_path):
    env = environment(tmp_path)
    temporary = Path(env["TMPDIR"])
    killed = stopped_run(prepared(tmp_path, "killed")[1], env)
    killed.kill()
    killed.communicate()
    assert len(session_directories(temporary)) == 1          # left behind by the SIGKILL
    result = subprocess.run([str(BIN / "eme_run"), str(prepared(tmp_path, "next", SHORT)[1])], env=env,
                            capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr
    assert list(temporary.iterdir()) == []


def environment_settings(result):
    """The Open MPI parameters a process took from its environment (mpi_show_mca_params)."""
    settings = {}
    for line in result.stderr.splitlines():
        if line.endswith(" (environment)") and "=" in line:
            name, value = line.split("] ", 1)[1].rsplit(" (", 1)[0].split("=", 1)
            settings[name] = value
    return settings


def shown_run(tmp_path, name, env, launcher=()):
    _, namelist = prepared(tmp_path, name, SHORT)
    result = subprocess.run([*launcher, str(BIN / "eme_run"), str(namelist)], capture_output=True, text=True,
                            timeout=600, env=dict(env, OMPI_MCA_mpi_show_mca_params="enviro"))
    assert result.returncode == 0, result.stderr
    return environment_settings(result)


def test_a_singleton_takes_only_the_transport_to_itself(tmp_path):
    env = environment(tmp_path)
    settings = shown_run(tmp_path, "alone", env)
    assert settings["pml"] == "ob1" and settings["btl"] == "self", settings
    assert settings["ess_singleton_isolated"] == "true"
    assert settings["orte_tmpdir_base"].startswith(f"{env['TMPDIR']}/eme-mpi.")


def test_the_users_own_settings_win(tmp_path):
    mine = tmp_path / "mine"
    mine.mkdir()
    home = tmp_path / "home" / ".openmpi"
    home.mkdir(parents=True)
    (home / "mca-params.conf").write_text("# the user's file\n  pml = ob1\n")
    env = environment(tmp_path, OMPI_MCA_btl="self,vader", OMPI_MCA_orte_tmpdir_base=str(mine))
    settings = shown_run(tmp_path, "user", env)
    assert settings["btl"] == "self,vader" and settings["orte_tmpdir_base"] == str(mine), settings
    assert "pml" not in settings                             # from the user's file, not the environment
    assert list(Path(env["TMPDIR"]).iterdir()) == []         # no session base of ours


@pytest.mark.skipif(subprocess.run(["which", "mpirun"], capture_output=True).returncode != 0, reason="no mpirun")
def test_under_mpirun_nothing_is_set(tmp_path):
    env = environment(tmp_path)
    settings = shown_run(tmp_path, "launched", env, launcher=[*MPIRUN, "-n", "1"])
    assert "pml" not in settings and "btl" not in settings and "ess_singleton_isolated" not in settings, settings
    assert "eme-mpi." not in settings.get("orte_tmpdir_base", "")
