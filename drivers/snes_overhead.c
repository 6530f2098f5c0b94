/* snes_overhead [SOLVES] [PETSc options]: what PETSc SNES costs by itself on a system of the
 * step's size, with callbacks that do next to nothing (make bench; docs/performance.md, "Issue
 * 22's four ratios").
 *
 * The SNES is configured as src/solver/snes_solver.F90 configures the step's solver on its lean
 * way: NEWTONLS with the Jacobian never recomputed by SNES (lag -1), KSPPREONLY, a shell
 * preconditioner, a shell line search that takes the full step and sets the norms, a convergence
 * test of our own, and the option viewers switched off around SNESSolve. The callbacks reach
 * the vectors' entries as the step solver's do (PETSc lends the arrays) and do their own
 * arithmetic, but the residual is F(x) = x and the preconditioner the identity (9 numbers
 * copied), and the convergence test stops after exactly K iterations, so that what is timed is
 * PETSc's machinery around the callbacks: SNESSolve, SNESSolve_NEWTONLS, KSPSolve, PCApply, the
 * line search's bookkeeping. For K = 1..6 the program
 * times SOLVES solves (default 20000) per round, alternating the K's, over 7 rounds, and prints
 * the median us per solve and the least-squares line a + b K through them. In the same rounds it
 * times SNESSolve of an SNESSHELL whose solve does nothing: what SNESSolve costs around a Newton
 * loop that is not PETSc's (docs/performance.md, "Issue 22's four ratios").
 *
 * --help, -h, PETSc's -help and --version print and exit with status 0, timing nothing.
 */
#define _POSIX_C_SOURCE 199309L /* clock_gettime under -std=c11 */
#include <ctype.h>
#include <errno.h>
#include <petscsnes.h>
#include <string.h>
#include <time.h>

/* The code's version, from the Makefile ("0.9.0 (git cb77f99)"), as the Fortran programs print it. */
#ifndef EME_VERSION
#define EME_VERSION "unknown"
#endif

#define MAX_ITERATIONS 6
#define ROUNDS 7
#define UNKNOWNS 9

static PetscInt iterations_wanted = 1;

/* The 2-norm of n numbers (the step solver's are src/solver/euclidean_norm's, in Fortran). */
static PetscReal two_norm(const PetscScalar *values, PetscInt n)
{
  PetscReal sum = 0.0;
  for (PetscInt i = 0; i < n; i++) sum += values[i] * values[i];
  return PetscSqrtReal(sum);
}

/* out := in, entry by entry through the arrays PETSc lends, as the step solver's callbacks reach
 * their vectors (src/solver/vector_access.c): the stand-in for a residual evaluation and for the
 * LU's solve, which cost nothing here. */
static PetscErrorCode copy_entries(Vec in, Vec out)
{
  const PetscScalar *from;
  PetscScalar *to;

  PetscFunctionBeginUser;
  PetscCall(VecGetArrayRead(in, &from));
  PetscCall(VecGetArray(out, &to));
  for (PetscInt i = 0; i < UNKNOWNS; i++) to[i] = from[i];
  PetscCall(VecRestoreArray(out, &to));
  PetscCall(VecRestoreArrayRead(in, &from));
  PetscFunctionReturn(0);
}

static PetscErrorCode copy_residual(SNES snes, Vec x, Vec f, void *context)
{
  (void)snes;
  (void)context;
  return copy_entries(x, f);
}

static PetscErrorCode keep_jacobian(SNES snes, Vec x, Mat jacobian, Mat preconditioner, void *context)
{
  (void)snes;
  (void)x;
  (void)jacobian;
  (void)preconditioner;
  (void)context;
  return 0;
}

static PetscErrorCode copy_preconditioner(PC pc, Vec x, Vec y)
{
  (void)pc;
  return copy_entries(x, y);
}

/* The full step x - y, the residual there and the three norms, as snes_shell's full_step: the
 * arithmetic on the lent arrays, the residual evaluated directly (not through
 * SNESComputeFunction). */
static PetscErrorCode full_step(SNESLineSearch line_search, void *context)
{
  Vec x, f, y, w, g;
  const PetscScalar *update;
  PetscScalar *iterate, *residual;
  PetscReal x_norm, f_norm, y_norm;

  (void)context;
  PetscFunctionBeginUser;
  PetscCall(SNESLineSearchGetVecs(line_search, &x, &f, &y, &w, &g));
  PetscCall(VecGetArrayRead(y, &update));
  PetscCall(VecGetArray(x, &iterate));
  for (PetscInt i = 0; i < UNKNOWNS; i++) iterate[i] -= update[i];
  y_norm = two_norm(update, UNKNOWNS);
  x_norm = two_norm(iterate, UNKNOWNS);
  PetscCall(VecGetArray(f, &residual));
  for (PetscInt i = 0; i < UNKNOWNS; i++) residual[i] = iterate[i];
  f_norm = two_norm(residual, UNKNOWNS);
  PetscCall(VecRestoreArray(f, &residual));
  PetscCall(VecRestoreArray(x, &iterate));
  PetscCall(VecRestoreArrayRead(y, &update));
  PetscCall(SNESLineSearchSetNorms(line_search, x_norm, f_norm, y_norm));
  PetscFunctionReturn(0);
}

static PetscErrorCode after_wanted_iterations(SNES snes, PetscInt iteration, PetscReal x_norm, PetscReal update_norm,
                                              PetscReal residual_norm, SNESConvergedReason *reason, void *context)
{
  (void)snes;
  (void)x_norm;
  (void)update_norm;
  (void)residual_norm;
  (void)context;
  *reason = iteration >= iterations_wanted ? SNES_CONVERGED_FNORM_ABS : SNES_CONVERGED_ITERATING;
  return 0;
}

static double seconds(void)
{
  struct timespec now;
  clock_gettime(CLOCK_MONOTONIC, &now);
  return (double)now.tv_sec + 1e-9 * (double)now.tv_nsec;
}

static PetscErrorCode solve_nothing(SNES snes, Vec x)
{
  (void)x;
  return SNESSetConvergedReason(snes, SNES_CONVERGED_FNORM_ABS);
}

/* us per solve of `solves` SNESSolves of `snes` from x = 1, option viewers off as in the step solver. */
static PetscErrorCode time_solves(SNES snes, Vec x, long solves, double *us)
{
  double start = seconds();

  PetscFunctionBeginUser;
  for (long i = 0; i < solves; i++) {
    PetscCall(VecSet(x, 1.0));
    PetscCall(PetscOptionsPushGetViewerOff(PETSC_TRUE));
    PetscCall(SNESSolve(snes, NULL, x));
    PetscCall(PetscOptionsPopGetViewerOff());
  }
  *us = 1e6 * (seconds() - start) / (double)solves;
  PetscFunctionReturn(0);
}

static int by_value(const void *a, const void *b)
{
  double x = *(const double *)a, y = *(const double *)b;
  return (x > y) - (x < y);
}

static void print_usage(void)
{
  printf("usage: snes_overhead [SOLVES] [PETSc options]\n\n"
         "Times PETSc SNES by itself on a system of the step's size (%d unknowns), configured as the step solver's\n"
         "lean way, with callbacks that only copy a vector: for 1 to %d Newton iterations per solve, SOLVES solves\n"
         "(default 20000) per round over %d rounds, alternating; prints the median us per solve, the line a + b K\n"
         "through them and an SNESSHELL's empty solve. A benchmark, not a test; the last line is machine-readable:\n"
         "snes_fixed_us=... snes_per_iteration_us=... snes_shell_us=...\n\n"
         "--help, -h: this text; --version: the code's and the libraries' versions; -help: PETSc's help and this\n"
         "text. Each prints and exits with status 0.\n",
         UNKNOWNS, MAX_ITERATIONS, ROUNDS);
}

/* The program's, PETSc's, MPI's and the compiler's versions, in the Fortran programs' format. */
static void print_versions(void)
{
  int major = 0, minor = 0, subminor = 0, release = 0, length = 0;
  char mpi[MPI_MAX_LIBRARY_VERSION_STRING] = "";

  (void)PetscGetVersionNumber(&major, &minor, &subminor, &release);
  (void)MPI_Get_library_version(mpi, &length);
  mpi[strcspn(mpi, "\n")] = '\0';
  printf("snes_overhead (eme) %s\nPETSc: %d.%d.%d\nMPI: %s\n", EME_VERSION, major, minor, subminor, mpi);
#ifdef __VERSION__
  printf("compiler: GCC version %s\n", __VERSION__);
#endif
}

/* Whether one of the command line's arguments is `flag`. */
static int has_argument(int argc, char **argv, const char *flag)
{
  for (int i = 1; i < argc; i++)
    if (strcmp(argv[i], flag) == 0) return 1;
  return 0;
}

int main(int argc, char **argv)
{
  SNES snes, shell;
  KSP ksp;
  PC pc;
  SNESLineSearch line_search;
  Vec x, r;
  Mat jacobian;
  long solves = 20000;
  double times[MAX_ITERATIONS][ROUNDS], median[MAX_ITERATIONS], shell_times[ROUNDS];

  /* --help, -h and --version answer at once, wherever they stand, before SOLVES is read. */
  if (has_argument(argc, argv, "--help") || has_argument(argc, argv, "-h")) {
    print_usage();
    return 0;
  }
  if (has_argument(argc, argv, "--version")) {
    print_versions();
    return 0;
  }
  /* SOLVES, if given, comes first; PETSc options (which start with a letter after the '-') follow. */
  if (argc > 1 && (argv[1][0] != '-' || isdigit((unsigned char)argv[1][1]))) {
    char *end;
    errno = 0;
    solves = strtol(argv[1], &end, 10);
    if (*end != '\0' || end == argv[1] || errno != 0 || solves < 1 || solves > 100000000) {
      fprintf(stderr, "snes_overhead: SOLVES must be a whole number from 1 to 100000000, not '%s'\n", argv[1]);
      return 1;
    }
  }
  PetscCall(PetscInitialize(&argc, &argv, NULL, NULL));
  {
    PetscBool help = PETSC_FALSE;

    /* PETSc's -help (PETSc has printed its own options): the usage, and nothing timed. */
    PetscCall(PetscOptionsHasHelp(NULL, &help));
    if (help) {
      print_usage();
      PetscCall(PetscFinalize());
      return 0;
    }
  }
  PetscCall(VecCreateSeq(PETSC_COMM_SELF, UNKNOWNS, &x));
  PetscCall(VecDuplicate(x, &r));
  PetscCall(MatCreateSeqDense(PETSC_COMM_SELF, UNKNOWNS, UNKNOWNS, NULL, &jacobian));
  PetscCall(MatAssemblyBegin(jacobian, MAT_FINAL_ASSEMBLY));
  PetscCall(MatAssemblyEnd(jacobian, MAT_FINAL_ASSEMBLY));
  PetscCall(SNESCreate(PETSC_COMM_SELF, &snes));
  PetscCall(SNESSetType(snes, SNESNEWTONLS));
  PetscCall(SNESSetFunction(snes, r, copy_residual, NULL));
  PetscCall(SNESSetJacobian(snes, jacobian, jacobian, keep_jacobian, NULL));
  PetscCall(SNESGetKSP(snes, &ksp));
  PetscCall(KSPSetType(ksp, KSPPREONLY));
  PetscCall(KSPGetPC(ksp, &pc));
  PetscCall(PCSetType(pc, PCSHELL));
  PetscCall(PCShellSetApply(pc, copy_preconditioner));
  PetscCall(SNESSetTolerances(snes, 1e-8, 0.0, 0.0, 50, 10000));
  PetscCall(SNESSetConvergenceTest(snes, after_wanted_iterations, NULL, NULL));
  PetscCall(SNESSetFromOptions(snes));
  PetscCall(SNESSetLagJacobian(snes, -1));
  PetscCall(SNESGetLineSearch(snes, &line_search));
  PetscCall(SNESLineSearchSetType(line_search, SNESLINESEARCHSHELL));
  PetscCall(SNESLineSearchShellSetUserFunc(line_search, full_step, NULL));
  PetscCall(SNESCreate(PETSC_COMM_SELF, &shell));
  PetscCall(SNESSetType(shell, SNESSHELL));
  PetscCall(SNESShellSetSolve(shell, solve_nothing));
  PetscCall(SNESSetFunction(shell, r, copy_residual, NULL));
  PetscCall(SNESSetFromOptions(shell));

  for (int round = -1; round < ROUNDS; round++) { /* round -1: the warm-up */
    double us;

    for (int k = 1; k <= MAX_ITERATIONS; k++) {
      PetscInt taken;

      iterations_wanted = k;
      PetscCall(time_solves(snes, x, solves, &us));
      if (round >= 0) times[k - 1][round] = us;
      PetscCall(SNESGetIterationNumber(snes, &taken));
      PetscCheck(taken == k, PETSC_COMM_SELF, PETSC_ERR_PLIB, "SNES took %d iterations, not %d", (int)taken, k);
    }
    PetscCall(time_solves(shell, x, solves, &us));
    if (round >= 0) shell_times[round] = us;
  }

  {
    double sum_k = 0, sum_t = 0, sum_kk = 0, sum_kt = 0, slope, intercept;
    const int n = MAX_ITERATIONS;

    PetscCall(PetscPrintf(PETSC_COMM_SELF,
                          "PETSc SNES by itself on %d unknowns, the step solver's lean configuration, callbacks that copy "
                          "a vector; medians of %d rounds of %ld solves:\n",
                          UNKNOWNS, ROUNDS, solves));
    for (int k = 1; k <= n; k++) {
      qsort(times[k - 1], ROUNDS, sizeof(double), by_value);
      median[k - 1] = times[k - 1][ROUNDS / 2];
      PetscCall(PetscPrintf(PETSC_COMM_SELF, "  %d Newton iteration%s per solve: %.3f us per solve\n", k,
                            k == 1 ? "" : "s", median[k - 1]));
      sum_k += k;
      sum_t += median[k - 1];
      sum_kk += (double)k * k;
      sum_kt += k * median[k - 1];
    }
    slope = (n * sum_kt - sum_k * sum_t) / (n * sum_kk - sum_k * sum_k);
    intercept = (sum_t - slope * sum_k) / n;
    qsort(shell_times, ROUNDS, sizeof(double), by_value);
    PetscCall(PetscPrintf(PETSC_COMM_SELF, "  SNESSHELL whose solve does nothing: %.3f us per solve\n",
                          shell_times[ROUNDS / 2]));
    PetscCall(PetscPrintf(PETSC_COMM_SELF, "snes_fixed_us=%.3f snes_per_iteration_us=%.3f snes_shell_us=%.3f\n",
                          intercept, slope, shell_times[ROUNDS / 2]));
  }
  PetscCall(SNESDestroy(&shell));
  PetscCall(SNESDestroy(&snes));
  PetscCall(MatDestroy(&jacobian));
  PetscCall(VecDestroy(&r));
  PetscCall(VecDestroy(&x));
  PetscCall(PetscFinalize());
  return 0;
}
