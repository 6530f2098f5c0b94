"""Stress of eme_run's MPI start-up on one host (docs/faults.md, "On a busy machine"): many short
runs started at once, some of them SIGKILLed while they start, and a count of the runs that
failed at MPI start-up. Not part of `make test` (about a minute on two cores).

    .venv/bin/python tests/e2e/stress_startup.py [--runs 200] [--parallel 20] [--kill-every 4]
                                                 [--bin build/bin] [--seed 1]

Every run writes its own file in a fresh folder; every `--kill-every`-th run gets a SIGKILL after a
random 0 to 0.4 s (mostly inside MPI start-up or the 1-step run). A run counts as a start-up
failure if it was not killed by the script and exited other than 0 with Open MPI's or PETSc's
start-up words in its stderr (ORTE, orte_init, session directory, MPI_Init, PetscInitialize); any
other failure is counted apart. The last line reads "start-up failures: N" (0 expected). Also
counted: the session bases (TMPDIR/eme-mpi.HOST.PID.*) of the script's runs left at the end
(those of killed runs are removed by a later start; a few may remain after the last kills)."""
import argparse
import os
import random
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
START_UP_WORDS = ("ORTE", "orte_init", "session directory", "MPI_Init", "PetscInitialize", "ompi_mpi_init")


def one_run(binary, folder, number, kill_after):
    run_folder = folder / f"run{number:04d}"
    run_folder.mkdir()
    namelist = run_folder / "run.nml"
    namelist.write_text(f"&integrator dt=0.01, t_end=0.01 /\n&output file='{run_folder / 'run.h5'}' /\n")
    process = subprocess.Popen([str(binary), str(namelist)], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                               text=True)
    timer = None
    if kill_after is not None:
        timer = threading.Timer(kill_after, lambda: process.poll() is None and process.send_signal(signal.SIGKILL))
        timer.start()
    _, err = process.communicate()
    if timer is not None:
        timer.cancel()
    return number, process.pid, process.returncode, kill_after is not None, err


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=200)
    parser.add_argument("--parallel", type=int, default=20)
    parser.add_argument("--kill-every", type=int, default=4)
    parser.add_argument("--bin", type=Path, default=ROOT / "build" / "bin")
    parser.add_argument("--seed", type=int, default=1)
    options = parser.parse_args()
    generator = random.Random(options.seed)
    binary = options.bin.resolve() / "eme_run"
    folder = Path(tempfile.mkdtemp(prefix="eme_stress_startup_"))
    kills = [generator.uniform(0.0, 0.4) if (k + 1) % options.kill_every == 0 else None
             for k in range(options.runs)]
    started = time.monotonic()
    with ThreadPoolExecutor(max_workers=options.parallel) as pool:
        outcomes = list(pool.map(lambda k: one_run(binary, folder, k, kills[k]), range(options.runs)))
    elapsed = time.monotonic() - started
    killed = completed = start_up = other = 0
    for number, pid, code, kill_sent, err in outcomes:
        if code == 0:
            completed += 1
        elif kill_sent and code == -signal.SIGKILL:
            killed += 1
        elif any(word in err for word in START_UP_WORDS):
            start_up += 1
            print(f"run {number} (pid {pid}) failed at start-up, exit {code}: {err.strip()[:400]}")
        else:
            other += 1
            print(f"run {number} (pid {pid}) failed, exit {code}: {err.strip()[:400]}")
    temporary = Path(os.environ.get("TMPDIR") or "/tmp")
    ours = {f"eme-mpi.{socket.gethostname()}.{pid}." for _, pid, _, _, _ in outcomes}
    left = [p for p in temporary.glob("eme-mpi.*") if p.name.rsplit(".", 1)[0] + "." in ours]
    shutil.rmtree(folder, ignore_errors=True)
    print(f"{options.runs} runs ({options.parallel} at a time, {elapsed:.1f} s, load average "
          f"{os.getloadavg()[0]:.1f}) with {binary}: {completed} complete, {killed} killed, {other} other failures, "
          f"{len(left)} session bases left")
    print(f"start-up failures: {start_up}")
    return 1 if start_up or other else 0


if __name__ == "__main__":
    sys.exit(main())
