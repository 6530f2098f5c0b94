#!/usr/bin/env python3
"""make bench: the spring chain's EME step on the sparse path (build/bin/chain_bench) against the
chain's size, on one rank and on two.

The chain is the continuum family of docs/formulation.md section 10 at a fixed physical step: a
1 m thermoviscoelastic rod (EA = 1e4 N, rho A = 1 kg/m, c = 100 J/(K m), k A = 1 W m/K,
eta A = 10 N s, E^neq A = 1e3 N), 1D, fixed at both ends with 1 % pre-stretch, a half-sine of
20 K on 300 K, EME in the temperature, dt = 1e-4 s. For N = 1e3, 1e4 and 1e5 springs, `--steps`
steps each, the sizes alternating within each repeat, it records the time loop's CPU seconds per
step, Newton iterations per step, the CPU time per Newton iteration per unknown and the largest
per-step |dE|/E (medians over `--repeats`), and the fitted exponent of CPU per step against N.
Then the largest N on two ranks against one, the two runs alternating (their order swapped each
repeat): rank 0's CPU per step and the wall time per step, and their ratios to the one-rank run
of the same repeat (medians of the repeats' ratios). Last, the instructions of the time loop
(valgrind's callgrind, --toggle-collect on the loop) of each rank on two ranks against one rank's,
at `--callgrind-springs` for `--callgrind-steps` steps (issue 39 asks at most 0.55 of one rank's per
rank), also without Open MPI's progress polling (opal_progress, inclusive): a waiting rank's
polling grows with the load, the rest does not move with it. The 1-minute load average before and after is printed
and recorded with the table (machine_load.py): on a busy machine the times are inflated.

  bench_chain.py [--bin build/bin] [--repeats 3] [--steps 3] [--sizes 1000 10000 100000]
                 [--callgrind-springs 100000] [--callgrind-steps 2] [--record FILE.json]
"""
import argparse
import json
import math
import re
import shutil
import statistics
import subprocess
import tempfile
from pathlib import Path

from machine_load import measured

ROOT = Path(__file__).resolve().parents[1]


def rod_namelist(n_springs, dt, steps, output):
    h = 1.0 / n_springs
    theta = ",".join(f"{300.0 + 20.0 * math.sin(math.pi * (a + 0.5) / n_springs):.6g}" for a in range(n_springs))
    return f"""&model
  model_name = 'spring_chain'
  links = {n_springs - 1}
  ends = 'fixed-fixed'
  span = 1.01
  dimension = 1
  gravity = 0.0
  spring_law = 'thermoviscoelastic'
  mass = {h!r}
  natural_length = {h!r}
  mu_eq_const = {1.0e4 * h!r}
  mu_eq_slope = 0.0
  beta = {h!r}
  heat_capacity = {100.0 * h!r}
  theta_ref = 300.0
  beta_v = 0.5
  mu_neq_const = {1.0e3 / h!r}
  mu_neq_slope = 0.0
  viscosity_const = {10.0 / h!r}
  viscosity_activation = 10.0
  conductivity = {1.0 / h!r}
/
&initial
  theta = {theta}
/
&integrator
  scheme = 'eme'
  thermo_variable = 'temperature'
  dt = {dt!r}
  t_end = {dt * steps!r}
  newton_tol = 1.0e-9
/
&output
  file = '{output}'
/
"""


def run(binary, namelist, ranks, *options):
    """chain_bench's figures (key=value) on `ranks` ranks."""
    command = [str(binary), str(namelist), *options]
    if ranks > 1:
        command = ["mpirun", "--allow-run-as-root", "--oversubscribe", "-n", str(ranks), *command]
    result = subprocess.run(command, capture_output=True, text=True, check=True)
    line = next(line for line in result.stdout.splitlines() if line.startswith("chain_bench:"))
    return {key: float(value) for key, value in re.findall(r"(\w+)=\s*(\S+)", line)}


LOOP = "__spring_chain_sparse_run_MOD_advance"      # chain_bench's time loop: one step each call


def loop_instructions(binary, namelist, ranks, folder, steps):
    """Each rank's instructions in `steps` steps of the time loop (callgrind, collecting inside LOOP
    only); mpirun even for one rank, which names each rank's profile."""
    prefix = Path(folder) / f"callgrind{ranks}"
    subprocess.run(["mpirun", "--allow-run-as-root", "--oversubscribe", "-n", str(ranks), "valgrind", "--tool=callgrind",
                    f"--toggle-collect={LOOP}", f"--callgrind-out-file={prefix}.%q{{OMPI_COMM_WORLD_RANK}}",
                    str(binary), str(namelist), "-chain_steps", str(steps)], capture_output=True, text=True, check=True)
    counts, polling = [], []
    for rank in range(ranks):
        profile = f"{prefix}.{rank}"
        counts.append(int(re.search(r"^(?:summary|totals):\s*(\d+)", Path(profile).read_text(), re.MULTILINE).group(1)))
        polling.append(progress_polling(profile))
    return counts, polling


def progress_polling(profile):
    """The instructions a rank spent in Open MPI's progress loop (opal_progress with what it calls:
    the shared-memory transport's and the non-blocking collectives' polling) while it waited for
    the other rank: they grow with the machine's load, not with the work."""
    listing = subprocess.run(["callgrind_annotate", "--inclusive=yes", "--threshold=100", profile],
                             capture_output=True, text=True, check=True).stdout
    match = re.search(r"^\s*([\d,]+) \(.*\)\s+\S*:opal_progress ", listing, re.MULTILINE)
    return int(match.group(1).replace(",", "")) if match else 0


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--bin", default=str(ROOT / "build" / "bin"))
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--steps", type=int, default=3)
    parser.add_argument("--sizes", type=int, nargs="+", default=[1000, 10000, 100000])
    parser.add_argument("--callgrind-springs", type=int, default=100000)
    parser.add_argument("--callgrind-steps", type=int, default=2)
    parser.add_argument("--record", default=str(ROOT / "results" / "bench" / "chain.json"))
    args = parser.parse_args()
    binary = Path(args.bin) / "chain_bench"
    largest = max(args.sizes)
    rows = {n: [] for n in args.sizes}
    two = []
    with tempfile.TemporaryDirectory() as folder, measured(own=2) as load:
        namelists = {}
        for n in sorted(set(args.sizes) | {args.callgrind_springs}):
            namelists[n] = Path(folder) / f"rod{n}.nml"
            namelists[n].write_text(rod_namelist(n, 1.0e-4, args.steps, Path(folder) / f"rod{n}.h5"))
        for repeat in range(args.repeats):
            for n in args.sizes:
                if n != largest:
                    rows[n].append(run(binary, namelists[n], 1))
            # One rank against two at the largest size, the order swapped each repeat.
            if repeat % 2:
                two.append(run(binary, namelists[largest], 2))
                rows[largest].append(run(binary, namelists[largest], 1))
            else:
                rows[largest].append(run(binary, namelists[largest], 1))
                two.append(run(binary, namelists[largest], 2))
        one_instructions = two_instructions = None
        if shutil.which("valgrind"):
            (one_instructions, _), (two_instructions, two_polling) = (
                loop_instructions(binary, namelists[args.callgrind_springs], ranks, folder, args.callgrind_steps)
                for ranks in (1, 2))
    table = []
    print(f"{'springs':>8} {'unknowns':>9} {'CPU s/step':>11} {'Newton/step':>11} {'us/(Newton unknown)':>20} "
          f"{'max |dE|/E':>11}")
    for n in args.sizes:
        cpu = statistics.median(r["cpu_per_step"] for r in rows[n])
        newton = statistics.median(r["newton"] / r["steps"] for r in rows[n])
        per_unknown = statistics.median(r["cpu_per_newton_unknown"] for r in rows[n]) * 1e6
        energy = max(r["max_energy_error"] for r in rows[n])
        unknowns = int(rows[n][0]["unknowns"])
        table.append(dict(springs=n, unknowns=unknowns, cpu_per_step=cpu, newton_per_step=newton,
                          us_per_newton_unknown=per_unknown, max_energy_error=energy))
        print(f"{n:>8} {unknowns:>9} {cpu:>11.4g} {newton:>11.2f} {per_unknown:>20.3g} {energy:>11.2e}")
    logs = [(math.log(t["springs"]), math.log(t["cpu_per_step"])) for t in table]
    mean_x = sum(x for x, _ in logs) / len(logs)
    mean_y = sum(y for _, y in logs) / len(logs)
    exponent = (sum((x - mean_x) * (y - mean_y) for x, y in logs) / sum((x - mean_x) ** 2 for x, _ in logs)
                if len(logs) > 1 else float("nan"))
    two_cpu = statistics.median(r["cpu_per_step"] for r in two)
    two_wall = statistics.median(r["wall_per_step"] for r in two)
    one_wall = statistics.median(r["wall_per_step"] for r in rows[largest])
    cpu_ratio = statistics.median(b["cpu_per_step"] / a["cpu_per_step"] for a, b in zip(rows[largest], two))
    speed_up = statistics.median(a["wall_per_step"] / b["wall_per_step"] for a, b in zip(rows[largest], two))
    print(f"CPU per step grows like N^{exponent:.3f} (least squares over N = {args.sizes})")
    print(f"N = {largest} on 2 ranks: rank 0's CPU per step {two_cpu:.4g} s, {cpu_ratio:.2f} of one rank's; wall "
          f"{two_wall:.4g} s against {one_wall:.4g} s, speed-up {speed_up:.2f} (medians of {args.repeats} alternating "
          "repeats' ratios)")
    instructions = None
    if one_instructions and two_instructions:
        fractions = [count / one_instructions[0] for count in two_instructions]
        without_polling = [(count - polled) / one_instructions[0] for count, polled in zip(two_instructions, two_polling)]
        instructions = dict(springs=args.callgrind_springs, steps=args.callgrind_steps, one_rank=one_instructions[0],
                            two_ranks=two_instructions, fractions=fractions, polling=two_polling,
                            fractions_without_polling=without_polling)
        print(f"time loop's instructions, N = {args.callgrind_springs}, {args.callgrind_steps} steps: one rank "
              f"{one_instructions[0]:.4g}; two ranks " + ", ".join(
                  f"rank {rank} {count:.4g} ({fraction:.3f} of one rank's, {bare:.3f} without MPI's progress polling)"
                  for rank, (count, fraction, bare) in enumerate(zip(two_instructions, fractions, without_polling))))
    else:
        print("time loop's instructions: not counted (valgrind is not installed)")
    load.report("bench_chain.py")
    record = Path(args.record)
    record.parent.mkdir(parents=True, exist_ok=True)
    record.write_text(json.dumps(dict(table=table, exponent=exponent, two_ranks=dict(
        cpu_per_step=two_cpu, wall_per_step=two_wall, one_rank_wall_per_step=one_wall, cpu_ratio=cpu_ratio,
        wall_speed_up=speed_up), instructions=instructions, repeats=args.repeats, steps=args.steps,
        load=load.attributes()), indent=1) + "\n")


if __name__ == "__main__":
    main()
