#!/usr/bin/env python3
"""Fault campaign (not a test: it takes minutes): many kills, signals and full disks at random
moments and sizes, and a count of what they left behind. docs/faults.md's figures come from it.

  .venv/bin/python tests/e2e/fault_campaign.py [--runs N] [--study-runs M] [--seed S] [--only NAME ...]

Categories (N or M tries each, random moments or sizes):
  run_kill_long / run_kill_short     SIGKILL to eme_run (20 million steps / the paper scene)
  run_term_long / run_term_short     SIGTERM or SIGINT to eme_run
  run_full_disk                      eme_run on a disk of random size (1 kB to 50 MB)
  run_twice                          a second eme_run of the same file (another scheme), started
                                     0 to 1.5 s after the first
  study_kill / study_term            SIGKILL to every rank / SIGTERM to mpirun, then a restart
  study_full_disk                    a study on a small disk, then a restart with room
What counts as bad: a file under its final name that is neither complete (read back) nor marked
incomplete with a reason; a crash (a signal other than the one sent); a full disk not reported
with the OS's reason, file and input file; a study that does not finish on restart, or reruns a
case it had recorded complete with a good file; two runs of one file that both write it (both
exit 0, or the file is not the one run that completed). A FILE.part that cannot be read after SIGKILL
is counted apart (docs/faults.md states this risk)."""
import argparse
import collections
import os
import random
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import h5py

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))
from conftest import BIN, ROOT, namelist_text  # noqa: E402
from faults import check_run_file, mpirun_env_options, small_disk, wait_for  # noqa: E402

MPIRUN = ["mpirun", "--allow-run-as-root", "--oversubscribe"]
SHORT = {}                                           # the paper scene, 134 steps
LONG = {"dt": 0.05, "t_end": 1.0e6}


def write_run(folder, integrator, overwrite=False):
    output = folder / "run.h5"
    namelist = folder / "run.nml"
    namelist.write_text(namelist_text({"integrator": integrator, "output": {"file": str(output),
                                                                             "overwrite": overwrite}}))
    return namelist, output


def judge_final(output, expected_interrupt=None):
    """'' if the file under its final name (if any) tells the truth, else why not."""
    if not output.exists():
        return ""
    try:
        status, steps = check_run_file(output)
        with h5py.File(output, "r") as f:
            kind = f.attrs["failure_kind"]
    except Exception as error:           # noqa: BLE001 - any failure to read is a finding
        return f"final file unreadable: {error!r}"[:200]
    if status == "complete":
        return "" if kind == "none" else f"complete with failure_kind {kind}"
    if not status.startswith("incomplete: ") or status == "incomplete: running" or kind == "none":
        return f"final file says {status!r} ({kind})"
    if expected_interrupt and status != f"incomplete: interrupted by {expected_interrupt}":
        return f"final file says {status!r}"
    return ""


def judge_part(part):
    """('ok' | 'absent' | 'unreadable', detail)."""
    if not part.exists():
        return "absent", ""
    try:
        status, _ = check_run_file(part)
    except Exception as error:           # noqa: BLE001
        return "unreadable", repr(error)[:200]
    return ("ok", "") if status == "incomplete: running" else ("wrong", status)


def run_signal(folder, integrator, number, rng, window):
    namelist, output = write_run(folder, integrator)
    process = subprocess.Popen([str(BIN / "eme_run"), str(namelist)], stdout=subprocess.DEVNULL,
                               stderr=subprocess.PIPE, text=True)
    time.sleep(rng.uniform(*window))
    process.send_signal(number)
    _, err = process.communicate()
    return process.returncode, err, output


def category_run_signal(folder, rng, long_run, kill):
    integrator = LONG if long_run else SHORT
    window = (0.0, 3.0) if long_run else (0.0, 0.8)
    name = "SIGKILL" if kill else rng.choice(["SIGTERM", "SIGINT"])
    number = getattr(signal, name)
    code, err, output = run_signal(folder, integrator, number, rng, window)
    bad = judge_final(output, None if kill else name)
    if code not in (0, -number, 128 + number):
        bad = bad or f"exit status {code}: {err[-200:]}"
    part_state, detail = judge_part(output.with_name("run.h5.part"))
    if part_state == "wrong" or (part_state != "absent" and not kill):
        bad = bad or f"FILE.part {part_state} {detail}"
    outcome = "final" if output.exists() else "no final"
    return bad, f"{outcome}, FILE.part {part_state}", part_state == "unreadable"


def category_run_full_disk(folder, rng):
    size = int(10 ** rng.uniform(3.0, 7.7))
    long_run = rng.random() < 0.7
    with small_disk(folder / "disk", size) as disk:
        method = disk.method
        output = disk.folder / "run.h5"
        namelist = folder / "run.nml"
        namelist.write_text(namelist_text({"integrator": {"dt": 0.01, "t_end": 600.0} if long_run else {},
                                           "output": {"file": str(output)}}))
        result = subprocess.run([str(BIN / "eme_run"), str(namelist)], capture_output=True, text=True, env=disk.env)
        bad = judge_final(output)
        if result.returncode == 1:
            for word in ("No space left on device", f"{output}.part", str(namelist)):
                if word not in result.stderr:
                    bad = bad or f"message lacks {word!r}: {result.stderr[-200:]}"
            part_state, detail = judge_part(output.with_name("run.h5.part"))
            if part_state == "ok":
                part_state = "wrong"        # a stopped file must say why
            if part_state in ("wrong", "unreadable"):
                try:
                    status, _ = check_run_file(f"{output}.part")
                    part_state = "marked" if status.startswith("incomplete: cannot write") else "wrong"
                except Exception as error:   # noqa: BLE001
                    part_state, detail = "unreadable", repr(error)[:200]
            if part_state in ("wrong", "unreadable"):
                bad = bad or f"FILE.part {part_state} {detail}"
            outcome = f"exit 1, FILE.part {part_state}"
        elif result.returncode == 0:
            outcome = "complete"
            if judge_final(output) or not output.exists():
                bad = bad or "exit 0 without a complete file"
        else:
            outcome = f"exit {result.returncode}"
            bad = bad or f"exit status {result.returncode}: {result.stderr[-300:]}"
    return bad, f"{method}: {outcome}", False


def category_run_twice(folder, rng):
    """The reporter's two writers: 60,000 EME steps, then the midpoint rule into the same file.
    One of them writes it (the other is refused: exit 2, nothing written; or, started after the
    first finished, refused for the complete file it finds), and the file is that run's."""
    output = folder / "same.h5"
    runs = {}
    for scheme in ("eme", "midpoint"):
        runs[scheme] = folder / f"{scheme}.nml"
        runs[scheme].write_text(namelist_text({"integrator": {"dt": 0.001, "t_end": 60.0, "scheme": scheme},
                                               "output": {"file": str(output)}}))
    first = subprocess.Popen([str(BIN / "eme_run"), str(runs["eme"])], stdout=subprocess.DEVNULL,
                             stderr=subprocess.PIPE, text=True)
    time.sleep(rng.uniform(0.0, 1.5))
    second = subprocess.run([str(BIN / "eme_run"), str(runs["midpoint"])], capture_output=True, text=True)
    _, first_err = first.communicate()
    codes = (first.returncode, second.returncode)
    bad = judge_final(output)
    writers = [scheme for scheme, code in zip(runs, codes) if code == 0]
    if len(writers) != 1 or any(code not in (0, 2) for code in codes):
        bad = bad or f"exit statuses {codes}: {(first_err + second.stderr)[-300:]}"
    elif not bad:
        with h5py.File(output, "r") as f:
            if f.attrs["scheme"] != writers[0] or check_run_file(output) != ("complete", 60000):
                bad = f"the file is not the {writers[0]} run's: {f.attrs['scheme']}"
    refused = second.stderr if codes[1] == 2 else first_err
    why = "in use" if "is being written by" in refused else "complete" if "holds a complete run" in refused else "?"
    leftovers = sorted(p.name for p in folder.iterdir() if p.name.startswith("same.h5."))
    if leftovers:
        bad = bad or f"left behind: {leftovers}"
    return bad, f"{writers[0] if len(writers) == 1 else writers} wrote, the other refused ({why})", False


STUDY = """&study base = '{base}', output_dir = '{output}', index_only = {index_only} /
&sweep field = 'theta(1)', values = {values1} /
&sweep field = 'theta(2)', values = {values2} /
"""


def study_files(folder, output, cases=600, index_only=False):
    """A study of `cases` paper-scene cases (20 values of theta(2) per value of theta(1))."""
    study = folder / "study.nml"
    study.write_text(STUDY.format(base=ROOT / "inputs" / "paper_fig4_eme_theta.nml", output=output,
                                  index_only=".true." if index_only else ".false.",
                                  values1=", ".join(f"{270 + i:.1f}" for i in range(cases // 20)),
                                  values2=", ".join(f"{340 + i:.1f}" for i in range(20))))
    return study


def recorded_complete(output):
    """Cases the index and journal record complete."""
    done = set()
    try:
        with h5py.File(output / "index.h5", "r") as f:
            for row in f["cases"][:]:
                if row["status"] == b"complete":
                    done.add(int(row["case"]))
    except (OSError, KeyError):
        pass
    journal = output / "index.journal"
    if journal.exists():
        for line in journal.read_text().splitlines()[1:]:
            fields = line.split("\t")
            if len(fields) > 3:
                (done.add if fields[-2] == "complete" else done.discard)(int(fields[0]))
    return done


def finish_and_judge(study, output, env=None, before=frozenset()):
    """Runs the study again (2 ranks) and checks it ends complete, rerunning no case recorded
    complete whose file was good."""
    good = {c for c in before if not (output / f"case_{c:05d}.h5").exists() or judge_final(
        output / f"case_{c:05d}.h5") == ""}
    result = subprocess.run([*MPIRUN, *(mpirun_env_options(env) if env else []), "-n", "2",
                             str(BIN / "eme_ensemble"), str(study)], capture_output=True, text=True, cwd=ROOT, env=env)
    if result.returncode != 0:
        return f"restart exit {result.returncode}: {(result.stdout + result.stderr)[-300:]}"
    with h5py.File(output / "index.h5", "r") as f:
        cases = f["cases"][:]
    if not all(status == b"complete" for status in cases["status"]):
        return "restart left cases not complete"
    rerun = [int(row["case"]) for row in cases if int(row["case"]) in good and row["run_count"] > 1]
    if rerun:
        return f"cases recorded complete were run again: {rerun[:5]}"
    return ""


def kill_ranks(text):
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                if text.encode() in (entry / "cmdline").read_bytes():
                    os.kill(int(entry.name), signal.SIGKILL)
            except (OSError, ProcessLookupError):
                pass


def category_study_signal(folder, rng, kill):
    output = folder / "out"
    index_only = rng.random() < 0.5
    study = study_files(folder, output, index_only=index_only)
    process = subprocess.Popen([*MPIRUN, "-n", "2", str(BIN / "eme_ensemble"), str(study)], cwd=ROOT,
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    wait_for(lambda: (output / "index.h5").exists() or process.poll() is not None)
    time.sleep(rng.uniform(0.0, 1.5))
    if kill:
        kill_ranks(str(study))
    else:
        process.send_signal(signal.SIGTERM)
    process.wait()
    if not (output / "index.h5").exists():
        raise RuntimeError(f"the study did not start: {study}")
    before = recorded_complete(output)
    bad = ""
    if not index_only:
        for path in output.glob("case_*.h5"):
            bad = bad or judge_final(path)
    bad = bad or finish_and_judge(study, output, before=before)
    mode = "index-only" if index_only else "files"
    stage = "none" if not before else "all" if len(before) == 600 else "some"
    return bad, f"{mode}, {stage} recorded complete before the restart", False


def category_study_full_disk(folder, rng):
    size = int(10 ** rng.uniform(4.0, 6.5))
    with small_disk(folder / "disk", size) as disk:
        method = disk.method
        output = disk.folder / "out"
        study = study_files(folder, output, cases=40)
        result = subprocess.run([*MPIRUN, *mpirun_env_options(disk.env), "-n", "2", str(BIN / "eme_ensemble"),
                                 str(study)], capture_output=True, text=True, cwd=ROOT, env=disk.env)
        bad = ""
        if result.returncode not in (0, 1):
            bad = f"exit {result.returncode}: {(result.stdout + result.stderr)[-300:]}"
        elif result.returncode == 1 and "No space left on device" not in result.stdout + result.stderr:
            bad = f"not reported: {(result.stdout + result.stderr)[-300:]}"
        for path in output.glob("case_*.h5"):
            bad = bad or judge_final(path)
        before = recorded_complete(output) if (output / "index.h5").exists() else set()
        disk.resize(100_000_000)
        bad = bad or finish_and_judge(study, output, env=disk.env, before=before)
    return bad, f"{method}: first run exit {result.returncode}", False


CATEGORIES = {
    "run_kill_long": lambda folder, rng: category_run_signal(folder, rng, True, True),
    "run_kill_short": lambda folder, rng: category_run_signal(folder, rng, False, True),
    "run_term_long": lambda folder, rng: category_run_signal(folder, rng, True, False),
    "run_term_short": lambda folder, rng: category_run_signal(folder, rng, False, False),
    "run_full_disk": category_run_full_disk,
    "run_twice": category_run_twice,
    "study_kill": lambda folder, rng: category_study_signal(folder, rng, True),
    "study_term": lambda folder, rng: category_study_signal(folder, rng, False),
    "study_full_disk": category_study_full_disk,
}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=20, help="tries per eme_run category (default 20)")
    parser.add_argument("--study-runs", type=int, default=10, help="tries per study category (default 10)")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--only", nargs="*", choices=sorted(CATEGORIES), help="categories to run (default all)")
    args = parser.parse_args(argv)
    rng = random.Random(args.seed)
    totals = collections.Counter()
    for name in args.only or CATEGORIES:
        outcomes, bad, unreadable = collections.Counter(), [], 0
        tries = args.study_runs if name.startswith("study") else args.runs
        for _ in range(tries):
            folder = Path(tempfile.mkdtemp(prefix=f"eme_{name}_"))
            try:
                problem, outcome, part_unreadable = CATEGORIES[name](folder, rng)
            finally:
                shutil.rmtree(folder, ignore_errors=True)
            outcomes[outcome] += 1
            unreadable += part_unreadable
            if problem:
                bad.append(problem)
        totals["tries"] += tries
        totals["bad"] += len(bad)
        totals["unreadable FILE.part"] += unreadable
        print(f"{name}: {tries} tries, {len(bad)} bad, {unreadable} unreadable FILE.part; "
              + "; ".join(f"{k}: {v}" for k, v in sorted(outcomes.items())), flush=True)
        for problem in bad:
            print(f"  BAD {problem}", flush=True)
    print(f"total: {totals['tries']} tries, {totals['bad']} bad, {totals['unreadable FILE.part']} unreadable FILE.part")
    return 1 if totals["bad"] else 0


if __name__ == "__main__":
    sys.exit(main())
