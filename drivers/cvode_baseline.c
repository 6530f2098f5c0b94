/* cvode_baseline [--tolerance TOL] [--t-end T] [--difference-quotients] [--check-jacobian]:
 * the paper scene with SUNDIALS CVODE alone, the whole-run baseline of `make bench`
 * (docs/performance.md, section "Issue 34").
 * cvode_baseline --arkode-dp5 [--tolerance TOL] [--t-end T]: the same scene with ARKODE's explicit
 * Dormand-Prince 5(4) (ERKStep, its own error control at rtol = atol = TOL) instead, the outside
 * program of make bench's work-precision line for relaxed_dp853 (postprocess/bench_arkode.py,
 * issue 42 item 5); it prints steps=N rhs_evaluations=N error_test_failures=N.
 * cvode_baseline --field-evaluations K: only evaluates this file's field (without its Jacobian)
 * K times at the initial state and prints field_evaluations=K and a checksum, the C side of
 * make bench's instructions per field evaluation (postprocess/bench_field.py, issue 42 item 5).
 *
 * A minimal C program of the same model as eme_run's paper scene: the thermoviscoelastic double
 * pendulum with Table 1's data and the initial state of docs/formulation.md section 1, in the
 * temperature variable (tau_a = theta_a, as inputs/paper_fig4_eme_theta.nml), its right-hand
 * side f = L grad E + K grad S written out as in docs/formulation.md section 4 with the springs'
 * closed forms of section 3. CVODE's variable-order BDF with Newton's method on the dense
 * SUNMatrix and SUNLinearSolver and this file's analytic Jacobian (--difference-quotients: CVODE's
 * own difference-quotient Jacobian instead), rtol = atol = 1e-10, from t = 0 to t = 20 s in one
 * call (a stop time there). No MPI, PETSc or HDF5: SUNDIALS and the C library only.
 *
 * It prints what it ran, the final time and state (z = (q1, q2, p1, p2, gamma, theta_1,
 * theta_2), eme_run's /state columns in the temperature variable) and CVODE's counts, each on a
 * machine-readable line:
 *   t_final=20
 *   state=<15 numbers, %.17g>
 *   steps=N rhs_evaluations=N jacobian_evaluations=N linear_setups=N nonlinear_iterations=N
 *   error_test_failures=N nonlinear_failures=N
 * --check-jacobian also compares the analytic Jacobian at the final state with central
 * differences of the right-hand side (jacobian_deviation=<largest deviation, relative to the
 * largest entry of its row>). Exit status 0, 1 when CVODE fails, 2 on bad usage; --help, -h,
 * -help and --version print and exit with status 0.
 */
#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <arkode/arkode_erkstep.h>
#include <cvode/cvode.h>
#include <nvector/nvector_serial.h>
#include <sundials/sundials_version.h>
#include <sunlinsol/sunlinsol_dense.h>
#include <sunmatrix/sunmatrix_dense.h>

/* The code's version, from the Makefile ("0.9.0 (git cb77f99)"), as the other programs print it. */
#ifndef EME_VERSION
#define EME_VERSION "unknown"
#endif

#define N_STATE 15
/* z's columns (docs/formulation.md section 2): q_a at Q(a), p_a at P(a), a = 0, 1 for springs 1, 2. */
#define Q(a) (3 * (a))
#define P(a) (6 + 3 * (a))
#define GAMMA 12
#define THETA(a) (13 + (a))

/* Table 1 of the paper as plain SI numbers (docs/formulation.md section 1, item 6). */
typedef struct {
  double mass[2], natural_length[2], mu_eq_const[2], mu_eq_slope[2], mu_neq_const, mu_neq_slope;
  double heat_capacity[2], viscosity_const, viscosity_activation, conductivity, theta_ref, beta, beta_v;
  double gravity[3];
} parameters;

static const parameters table1 = {
    .mass = {1.0, 1.0}, .natural_length = {1.5, 2.0}, .mu_eq_const = {200.0, 200.0}, .mu_eq_slope = {0.5, 0.5},
    .mu_neq_const = 5.0, .mu_neq_slope = 0.1, .heat_capacity = {10.0, 10.0}, .viscosity_const = 100.0,
    .viscosity_activation = 10.0, .conductivity = 1.0, .theta_ref = 300.0, .beta = 0.02, .beta_v = 0.5,
    .gravity = {0.0, 0.0, -9.81}};

/* One of the springs' two closed forms (docs/formulation.md section 3),
 *   h(C, gamma) = (1 + bv)(k/2 L^2 + b L) + m gamma^2 - bv gamma (k L + b)/l,
 * L = ln(l/l0), l = sqrt(C): e_a with (k, b, m) = (a_a, beta theta_ref, A), sigma_a with
 * (mu_{a,theta}, beta, mu^neq_theta); spring 1 has bv = m = 0. */
typedef struct {
  double k, b, m;
} shape;

/* A shape's value's derivatives in C and gamma, first and second. */
typedef struct {
  double c, g, cc, cg, gg;
} derivatives;

static derivatives shape_derivatives(shape s, double bv, double log_stretch, double inverse_length, double c,
                                     double gamma) {
  const double dlog = 0.5 / c, d2log = -0.5 / (c * c);                          /* L_C, L_CC */
  const double dinv = -0.5 * inverse_length / c, d2inv = 0.75 * inverse_length / (c * c); /* (1/l)_C, (1/l)_CC */
  const double slope = s.k * log_stretch + s.b;                                  /* k L + b */
  const double h = slope * inverse_length, dh = s.k * dlog * inverse_length + slope * dinv;
  const double d2h = s.k * d2log * inverse_length + 2.0 * s.k * dlog * dinv + slope * d2inv;
  derivatives d;

  d.c = (1.0 + bv) * slope * dlog - bv * gamma * dh;
  d.g = 2.0 * s.m * gamma - bv * h;
  d.cc = (1.0 + bv) * (s.k * dlog * dlog + slope * d2log) - bv * gamma * d2h;
  d.cg = -bv * dh;
  d.gg = 2.0 * s.m;
  return d;
}

/* Spring a's mechanical parts e_a (energy) and sigma_a (entropy) at z, and its heat capacity. */
typedef struct {
  derivatives e, sigma;
  double capacity;
} spring;

static spring spring_at(const parameters *p, int a, const double *z) {
  const double *q = z + Q(a);
  const double c = q[0] * q[0] + q[1] * q[1] + q[2] * q[2];
  const double gamma = a == 1 ? z[GAMMA] : 0.0;
  const double bv = a == 1 ? p->beta_v : 0.0;
  const double log_stretch = 0.5 * log(c / (p->natural_length[a] * p->natural_length[a]));
  const double inverse_length = 1.0 / sqrt(c);
  shape energy = {p->mu_eq_const[a] + p->mu_eq_slope[a] * p->theta_ref, p->beta * p->theta_ref, 0.0};
  shape entropy = {p->mu_eq_slope[a], p->beta, 0.0};
  spring s;

  if (a == 1) {
    energy.m = p->mu_neq_const + p->mu_neq_slope * p->theta_ref;
    entropy.m = p->mu_neq_slope;
  }
  s.e = shape_derivatives(energy, bv, log_stretch, inverse_length, c, gamma);
  s.sigma = shape_derivatives(entropy, bv, log_stretch, inverse_length, c, gamma);
  s.capacity = (1.0 + bv) * p->heat_capacity[a];
  return s;
}

/* v_a = (m^-1 p)_a: m^-1 = [[I/m1, -I/m1], [-I/m1, (m1 + m2)/(m1 m2) I]] (section 2); the
 * 2 x 2 factor in inverse_mass. */
static void inverse_mass(const parameters *p, double inverse[2][2]) {
  const double m1 = p->mass[0], m2 = p->mass[1];
  inverse[0][0] = 1.0 / m1;
  inverse[0][1] = inverse[1][0] = -1.0 / m1;
  inverse[1][1] = (m1 + m2) / (m1 * m2);
}

/* The viscosity eta(theta) = eta_cst exp(eta_theta (1/theta - 1/theta_ref)), eq. (17). */
static double viscosity(const parameters *p, double theta) {
  return p->viscosity_const * exp(p->viscosity_activation * (1.0 / theta - 1.0 / p->theta_ref));
}

/* f(z) of docs/formulation.md section 4 with tau_a = theta_a (then d_tau U_a = Cap_a,
 * d_tau S_a = Cap_a/theta_a, Theta_a = theta_a):
 *   dq_a/dt     = v_a = (m^-1 p)_a
 *   dp_a/dt     = -grad_qa V_g - 2 q_a (e_a,C - theta_a sigma_a,C),  -grad_q1 V_g = (m1 + m2) g, -grad_q2 V_g = m2 g
 *   dgamma/dt   = R = (theta_2 sigma_2,gamma - e_2,gamma)/eta(theta_2)
 *   dtheta_a/dt = (-2 theta_a sigma_a,C q_a.v_a + kappa (theta_b - theta_a) - [a = 2] e_2,gamma R)/Cap_a
 * and, when jacobian is not NULL, df/dz column-major (jacobian[i + 15 j] = df_i/dz_j).
 * Returns 0, or 1 (CVODE: recoverable) outside the model's domain. */
static int field(const parameters *p, const double *z, double *f, double *jacobian) {
  double inverse[2][2], v[2][3], work[2];
  spring s[2];

  if (z[THETA(0)] <= 0.0 || z[THETA(1)] <= 0.0) return 1;
  inverse_mass(p, inverse);
  for (int a = 0; a < 2; ++a) {
    const double *q = z + Q(a);
    if (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] <= 0.0) return 1;
    s[a] = spring_at(p, a, z);
    for (int i = 0; i < 3; ++i) v[a][i] = inverse[a][0] * z[P(0) + i] + inverse[a][1] * z[P(1) + i];
    work[a] = q[0] * v[a][0] + q[1] * v[a][1] + q[2] * v[a][2];
  }
  const double theta2 = z[THETA(1)];
  const double inverse_eta = 1.0 / viscosity(p, theta2);
  const double rate = (theta2 * s[1].sigma.g - s[1].e.g) * inverse_eta;

  for (int a = 0; a < 2; ++a) {
    const double theta = z[THETA(a)], mass = a == 0 ? p->mass[0] + p->mass[1] : p->mass[1];
    const double thermal_force = s[a].e.c - theta * s[a].sigma.c;
    for (int i = 0; i < 3; ++i) {
      f[Q(a) + i] = v[a][i];
      f[P(a) + i] = mass * p->gravity[i] - 2.0 * thermal_force * z[Q(a) + i];
    }
    f[THETA(a)] = (-2.0 * theta * s[a].sigma.c * work[a] + p->conductivity * (z[THETA(1 - a)] - theta)) /
                  s[a].capacity;
  }
  f[GAMMA] = rate;
  f[THETA(1)] -= s[1].e.g * rate / s[1].capacity;
  if (jacobian == NULL) return 0;

#define J(i, j) jacobian[(i) + N_STATE * (j)]
  memset(jacobian, 0, sizeof(double) * N_STATE * N_STATE);
  /* R's derivatives: in C_2 (times dC/dq_2 = 2 q_2), gamma and theta_2 (d(1/eta)/dtheta =
   * (1/eta) eta_theta/theta^2). */
  const double rate_c = (theta2 * s[1].sigma.cg - s[1].e.cg) * inverse_eta;
  const double rate_g = (theta2 * s[1].sigma.gg - s[1].e.gg) * inverse_eta;
  const double rate_theta = s[1].sigma.g * inverse_eta + rate * p->viscosity_activation / (theta2 * theta2);
  for (int a = 0; a < 2; ++a) {
    const double *q = z + Q(a);
    const double theta = z[THETA(a)], capacity = s[a].capacity;
    const double thermal_force = s[a].e.c - theta * s[a].sigma.c;
    const double force_c = s[a].e.cc - theta * s[a].sigma.cc, force_g = s[a].e.cg - theta * s[a].sigma.cg;
    for (int i = 0; i < 3; ++i) {
      for (int b = 0; b < 2; ++b) {
        J(Q(a) + i, P(b) + i) = inverse[a][b];
        J(THETA(a), P(b) + i) = -2.0 * theta * s[a].sigma.c * inverse[a][b] * q[i] / capacity;
      }
      /* dp_a/dq_a = -2 thermal_force I - 4 force_c q q^T; dp_a/dgamma, dp_a/dtheta_a */
      for (int j = 0; j < 3; ++j) J(P(a) + i, Q(a) + j) = -4.0 * force_c * q[i] * q[j];
      J(P(a) + i, Q(a) + i) -= 2.0 * thermal_force;
      J(P(a) + i, GAMMA) = -2.0 * force_g * q[i];
      J(P(a) + i, THETA(a)) = 2.0 * s[a].sigma.c * q[i];
      /* dtheta_a/dq_a: -2 theta (2 sigma_CC q (q.v) + sigma_C v)/Cap */
      J(THETA(a), Q(a) + i) = -2.0 * theta * (2.0 * s[a].sigma.cc * q[i] * work[a] + s[a].sigma.c * v[a][i]) / capacity;
    }
    J(THETA(a), GAMMA) = -2.0 * theta * s[a].sigma.cg * work[a] / capacity;
    J(THETA(a), THETA(a)) = (-2.0 * s[a].sigma.c * work[a] - p->conductivity) / capacity;
    J(THETA(a), THETA(1 - a)) = p->conductivity / capacity;
  }
  /* gamma's row, and the viscous heating -(e_2,gamma R)/Cap_2 in theta_2's row */
  const double *q2 = z + Q(1);
  const double capacity = s[1].capacity;
  for (int i = 0; i < 3; ++i) {
    J(GAMMA, Q(1) + i) = 2.0 * rate_c * q2[i];
    J(THETA(1), Q(1) + i) -= 2.0 * (s[1].e.cg * rate + s[1].e.g * rate_c) * q2[i] / capacity;
  }
  J(GAMMA, GAMMA) = rate_g;
  J(GAMMA, THETA(1)) = rate_theta;
  J(THETA(1), GAMMA) -= (s[1].e.gg * rate + s[1].e.g * rate_g) / capacity;
  J(THETA(1), THETA(1)) -= s[1].e.g * rate_theta / capacity;
#undef J
  return 0;
}

static int rhs(realtype t, N_Vector y, N_Vector ydot, void *data) {
  (void)t;
  return field(data, N_VGetArrayPointer(y), N_VGetArrayPointer(ydot), NULL);
}

static int analytic_jacobian(realtype t, N_Vector y, N_Vector fy, SUNMatrix jacobian, void *data, N_Vector work1,
                             N_Vector work2, N_Vector work3) {
  double f[N_STATE];
  (void)t;
  (void)fy;
  (void)work1;
  (void)work2;
  (void)work3;
  return field(data, N_VGetArrayPointer(y), f, SM_DATA_D(jacobian));
}

/* The largest deviation of the analytic Jacobian at z from central differences of f, each
 * relative to the largest entry of its row (the differences err by about 1e-7 of that). */
static double jacobian_deviation(const parameters *p, const double *z) {
  double jacobian[N_STATE * N_STATE], f[N_STATE], plus[N_STATE], minus[N_STATE], shifted[N_STATE];
  double row_size[N_STATE] = {0.0}, deviation = 0.0;

  if (field(p, z, f, jacobian) != 0) return INFINITY;
  for (int i = 0; i < N_STATE; ++i)
    for (int j = 0; j < N_STATE; ++j) row_size[i] = fmax(row_size[i], fabs(jacobian[i + N_STATE * j]));
  for (int j = 0; j < N_STATE; ++j) {
    const double h = 1e-6 * fmax(1.0, fabs(z[j]));
    memcpy(shifted, z, sizeof shifted);
    shifted[j] = z[j] + h;
    field(p, shifted, plus, NULL);
    shifted[j] = z[j] - h;
    field(p, shifted, minus, NULL);
    for (int i = 0; i < N_STATE; ++i) {
      const double difference = (plus[i] - minus[i]) / (2.0 * h);
      deviation = fmax(deviation, fabs(jacobian[i + N_STATE * j] - difference) / fmax(row_size[i], 1e-300));
    }
  }
  return deviation;
}

/* The initial state of docs/formulation.md section 1: q1 = (1, 0, 0) m, q2 = (3, 0, 0) m (m2
 * relative to m1), p1 = 0, p2 = (-1, -1, 0) N s, gamma = 0, theta = (280, 350) K. */
static void initial_state(double *z) {
  static const double z0[N_STATE] = {1.0, 0.0, 0.0, 3.0, 0.0, 0.0, 0.0, 0.0, 0.0, -1.0, -1.0, 0.0, 0.0, 280.0, 350.0};
  memcpy(z, z0, sizeof z0);
}

static int usage(FILE *stream, int status) {
  fprintf(stream, "usage: cvode_baseline [--tolerance TOL] [--t-end T] [--difference-quotients] [--check-jacobian]\n"
                  "       cvode_baseline --arkode-dp5 [--tolerance TOL] [--t-end T]\n"
                  "       cvode_baseline --field-evaluations K\n"
                  "The paper scene (Table 1, theta variable) with SUNDIALS CVODE BDF alone: Newton, dense solver,\n"
                  "analytic Jacobian (--difference-quotients: CVODE's), rtol = atol = TOL (1e-10) to t = T (20 s).\n"
                  "Prints the final state and CVODE's counts; --check-jacobian also the analytic Jacobian's\n"
                  "deviation from central differences at the final state. --arkode-dp5: ARKODE's explicit\n"
                  "Dormand-Prince 5(4) (ERKStep) at rtol = atol = TOL instead. --field-evaluations K: evaluate the\n"
                  "right-hand side alone K times at the initial state, print field_evaluations=K and a checksum.\n\n"
                  "--help, -h, -help: this text; --version: the code's and the libraries' versions. Each prints\n"
                  "and exits with status 0.\n");
  return status;
}

/* The program's, SUNDIALS' (as the library reports it) and the compiler's versions, in the other
 * programs' format. */
static int print_versions(void) {
  char sundials[64] = "unknown";
  SUNDIALSGetVersion(sundials, (int)sizeof sundials);
  printf("cvode_baseline (eme) %s\nSUNDIALS: %s\ncompiler: GCC version %s\n", EME_VERSION, sundials, __VERSION__);
  return 0;
}

/* The field K times at the initial state, each state moved in its last digit by the sign of the
 * previous field (so no evaluation repeats the one before); the instructions of one evaluation
 * are the difference of two counts' over the difference of the counts (bench_field.py). */
static int evaluate_field(const parameters *p, long evaluations) {
  double z0[N_STATE], z[N_STATE], f[N_STATE] = {0.0}, checksum = 0.0;
  initial_state(z0);
  memcpy(z, z0, sizeof z);
  for (long e = 0; e < evaluations; ++e) {
    z[0] = z0[0] + DBL_EPSILON * fabs(z0[0]) * copysign(1.0, f[0]);
    if (field(p, z, f, NULL) != 0) {
      fprintf(stderr, "cvode_baseline: the field failed at the initial state\n");
      return 1;
    }
  }
  for (int i = 0; i < N_STATE; ++i) checksum += fabs(f[i]);
  printf("field_evaluations=%ld sum_abs_f=%.17g\n", evaluations, checksum);
  return 0;
}

/* The final time, state and counts of a run, on the lines the header describes; `counts` is the
 * method's own line. */
static void print_run(const char *method, double tolerance, double t_end, double t_reached, const double *z,
                      const char *counts) {
  printf("cvode_baseline: the paper scene in the temperature variable, SUNDIALS %s %s, rtol = atol = %g, to t = %g s\n",
         SUNDIALS_VERSION, method, tolerance, t_end);
  printf("t_final=%.17g\nstate=", t_reached);
  for (int i = 0; i < N_STATE; ++i) printf(i ? " %.17g" : "%.17g", z[i]);
  printf("\n%s\n", counts);
}

/* The scene with ARKODE's ERKStep and the Dormand-Prince 5(4) table to t_end (a stop time
 * there); 0, or 1 when ARKODE fails (said on stderr). */
static int integrate_dp5(parameters *model, double tolerance, double t_end, SUNContext context) {
  N_Vector y = N_VNew_Serial(N_STATE, context);
  if (y == NULL) return 1;
  initial_state(N_VGetArrayPointer(y));
  void *arkode = ERKStepCreate(rhs, 0.0, y, context);
  double t_reached = 0.0;
  int flag = arkode == NULL ? ARK_MEM_NULL : ARK_SUCCESS;
  if (flag == ARK_SUCCESS) flag = ERKStepSetTableNum(arkode, ARKODE_DORMAND_PRINCE_7_4_5);
  if (flag == ARK_SUCCESS) flag = ERKStepSetUserData(arkode, model);
  if (flag == ARK_SUCCESS) flag = ERKStepSStolerances(arkode, tolerance, tolerance);
  if (flag == ARK_SUCCESS) flag = ERKStepSetMaxNumSteps(arkode, 10000000);
  if (flag == ARK_SUCCESS) flag = ERKStepSetStopTime(arkode, t_end);
  if (flag == ARK_SUCCESS) flag = ERKStepEvolve(arkode, t_end, y, &t_reached, ARK_NORMAL);
  if (flag == ARK_TSTOP_RETURN) flag = ARK_SUCCESS;
  long steps = 0, rhs_evaluations = 0, error_fails = 0;
  char counts[160];
  if (arkode != NULL) {
    ERKStepGetNumSteps(arkode, &steps);
    ERKStepGetNumRhsEvals(arkode, &rhs_evaluations);
    ERKStepGetNumErrTestFails(arkode, &error_fails);
  }
  snprintf(counts, sizeof counts, "steps=%ld rhs_evaluations=%ld error_test_failures=%ld", steps, rhs_evaluations,
           error_fails);
  print_run("ARKODE ERKStep Dormand-Prince 5(4)", tolerance, t_end, t_reached, N_VGetArrayPointer(y), counts);
  if (flag != ARK_SUCCESS) {
    char *name = ERKStepGetReturnFlagName(flag); /* allocated by ARKODE */
    fprintf(stderr, "cvode_baseline: ARKODE failed at t = %g s: %s\n", t_reached, name != NULL ? name : "?");
    free(name);
  }
  ERKStepFree(&arkode);
  N_VDestroy(y);
  return flag == ARK_SUCCESS ? 0 : 1;
}

/* A positive number from text, or 0 where the text is not one. */
static double positive_number(const char *text) {
  char *end;
  double value = strtod(text, &end);
  return (*text != '\0' && *end == '\0' && value > 0.0 && isfinite(value)) ? value : 0.0;
}

int main(int argc, char **argv) {
  double tolerance = 1e-10, t_end = 20.0, t_reached = 0.0;
  int difference_quotients = 0, check_jacobian = 0, dormand_prince = 0, flag;
  long field_evaluations = 0;
  parameters model = table1;

  /* --help, -h, -help and --version answer at once, wherever they stand. */
  for (int i = 1; i < argc; ++i) {
    if (!strcmp(argv[i], "--help") || !strcmp(argv[i], "-h") || !strcmp(argv[i], "-help")) return usage(stdout, 0);
    if (!strcmp(argv[i], "--version")) return print_versions();
  }
  for (int i = 1; i < argc; ++i) {
    if (!strcmp(argv[i], "--difference-quotients")) difference_quotients = 1;
    else if (!strcmp(argv[i], "--check-jacobian")) check_jacobian = 1;
    else if (!strcmp(argv[i], "--arkode-dp5")) dormand_prince = 1;
    else if (!strcmp(argv[i], "--tolerance") && i + 1 < argc && (tolerance = positive_number(argv[++i])) > 0.0)
      continue;
    else if (!strcmp(argv[i], "--t-end") && i + 1 < argc && (t_end = positive_number(argv[++i])) > 0.0)
      continue;
    else if (!strcmp(argv[i], "--field-evaluations") && i + 1 < argc &&
             (field_evaluations = (long)positive_number(argv[++i])) > 0)
      continue;
    else {
      fprintf(stderr, "cvode_baseline: bad argument '%s' (TOL and T: numbers > 0; K: a whole number >= 1)\n", argv[i]);
      return usage(stderr, 2);
    }
  }
  if (field_evaluations > 0) return evaluate_field(&model, field_evaluations);

  SUNContext context;
  if (SUNContext_Create(NULL, &context) != 0) return 1;
  if (dormand_prince) {
    flag = integrate_dp5(&model, tolerance, t_end, context);
    SUNContext_Free(&context);
    return flag;
  }
  N_Vector y = N_VNew_Serial(N_STATE, context);
  void *cvode = CVodeCreate(CV_BDF, context);
  SUNMatrix matrix = SUNDenseMatrix(N_STATE, N_STATE, context);
  SUNLinearSolver linear = SUNLinSol_Dense(y, matrix, context);
  if (y == NULL || cvode == NULL || matrix == NULL || linear == NULL) {
    fprintf(stderr, "cvode_baseline: out of memory\n");
    return 1;
  }
  initial_state(N_VGetArrayPointer(y));
  flag = CVodeInit(cvode, rhs, 0.0, y);
  if (flag == CV_SUCCESS) flag = CVodeSetUserData(cvode, &model);
  if (flag == CV_SUCCESS) flag = CVodeSStolerances(cvode, tolerance, tolerance);
  if (flag == CV_SUCCESS) flag = CVodeSetMaxNumSteps(cvode, 1000000);
  if (flag == CV_SUCCESS) flag = CVodeSetStopTime(cvode, t_end);
  if (flag == CV_SUCCESS) flag = CVodeSetLinearSolver(cvode, linear, matrix);
  if (flag == CV_SUCCESS && !difference_quotients) flag = CVodeSetJacFn(cvode, analytic_jacobian);
  if (flag == CV_SUCCESS) flag = CVode(cvode, t_end, y, &t_reached, CV_NORMAL);
  if (flag == CV_TSTOP_RETURN) flag = CV_SUCCESS;

  long steps = 0, rhs_evaluations = 0, jacobians = 0, setups = 0, iterations = 0, error_fails = 0,
       nonlinear_fails = 0, difference_rhs = 0;
  CVodeGetNumSteps(cvode, &steps);
  CVodeGetNumRhsEvals(cvode, &rhs_evaluations);
  CVodeGetNumLinRhsEvals(cvode, &difference_rhs);
  CVodeGetNumJacEvals(cvode, &jacobians);
  CVodeGetNumLinSolvSetups(cvode, &setups);
  CVodeGetNumNonlinSolvIters(cvode, &iterations);
  CVodeGetNumErrTestFails(cvode, &error_fails);
  CVodeGetNumNonlinSolvConvFails(cvode, &nonlinear_fails);

  char counts[240];
  snprintf(counts, sizeof counts, "steps=%ld rhs_evaluations=%ld jacobian_evaluations=%ld linear_setups=%ld "
           "nonlinear_iterations=%ld error_test_failures=%ld nonlinear_failures=%ld",
           steps, rhs_evaluations + difference_rhs, jacobians, setups, iterations, error_fails, nonlinear_fails);
  const double *z = N_VGetArrayPointer(y);
  print_run(difference_quotients ? "CVODE BDF, Newton, dense, difference-quotient Jacobian"
                                  : "CVODE BDF, Newton, dense, analytic Jacobian",
            tolerance, t_end, t_reached, z, counts);
  if (check_jacobian) printf("jacobian_deviation=%.3g\n", jacobian_deviation(&model, z));
  if (flag != CV_SUCCESS) {
    char *name = CVodeGetReturnFlagName(flag); /* allocated by CVODE */
    fprintf(stderr, "cvode_baseline: CVODE failed at t = %g s: %s\n", t_reached, name != NULL ? name : "?");
    free(name);
  }

  SUNLinSolFree(linear);
  SUNMatDestroy(matrix);
  CVodeFree(&cvode);
  N_VDestroy(y);
  SUNContext_Free(&context);
  return flag == CV_SUCCESS ? 0 : 1;
}
