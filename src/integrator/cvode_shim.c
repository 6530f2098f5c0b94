/* SUNDIALS CVODE for the CVODE baselines (src/integrator/cvode_stepper.f90): a serial vector,
 * BDF with Newton's method on CVODE's dense direct solver and the caller's analytic Jacobian, or
 * Adams-Moulton with fixed-point iteration (the nonstiff pairing SUNDIALS recommends). The
 * caller's right-hand side and Jacobian are plain C functions on arrays (column-major Jacobian),
 * so the Fortran side never sees a SUNDIALS type. Every function returns 0 or a CVODE flag. */
#include <stdio.h>
#include <stdlib.h>

#include <cvode/cvode.h>
#include <nvector/nvector_serial.h>
#include <sunlinsol/sunlinsol_dense.h>
#include <sunmatrix/sunmatrix_dense.h>
#include <sunnonlinsol/sunnonlinsol_fixedpoint.h>

/* f = y'(t, y); 0 ok, > 0 a recoverable failure (outside the domain: CVODE retries smaller). */
typedef int (*eme_cvode_rhs)(double t, const double *y, double *f, void *context);
/* jacobian(n, n), column-major, = df/dy at y; 0 ok, > 0 recoverable. */
typedef int (*eme_cvode_jacobian)(double t, const double *y, double *jacobian, void *context);

typedef struct {
  SUNContext sundials;
  void *cvode;
  N_Vector y;
  SUNMatrix matrix;
  SUNLinearSolver linear;
  SUNNonlinearSolver nonlinear;
  eme_cvode_rhs rhs;
  eme_cvode_jacobian jacobian;
  void *context;
} eme_cvode;

static int rhs_adapter(realtype t, N_Vector y, N_Vector f, void *data) {
  eme_cvode *run = (eme_cvode *)data;
  return run->rhs(t, N_VGetArrayPointer(y), N_VGetArrayPointer(f), run->context);
}

static int jacobian_adapter(realtype t, N_Vector y, N_Vector f, SUNMatrix jacobian, void *data,
                            N_Vector work1, N_Vector work2, N_Vector work3) {
  (void)f;
  (void)work1;
  (void)work2;
  (void)work3;
  eme_cvode *run = (eme_cvode *)data;
  return run->jacobian(t, N_VGetArrayPointer(y), SM_DATA_D(jacobian), run->context);
}

void eme_cvode_free(void **handle);

/* A CVODE run of n unknowns from y0 at t0: bdf != 0 for BDF with Newton and the dense solver,
 * else Adams with fixed-point iteration; scalar relative and absolute tolerances. */
int eme_cvode_create(int n, int bdf, double t0, const double *y0, double relative, double absolute,
                     eme_cvode_rhs rhs, eme_cvode_jacobian jacobian, void *context, void **handle) {
  eme_cvode *run = calloc(1, sizeof(eme_cvode));
  int flag;

  *handle = run;
  if (run == NULL) return CV_MEM_FAIL;
  run->rhs = rhs;
  run->jacobian = jacobian;
  run->context = context;
  if (SUNContext_Create(NULL, &run->sundials) != 0) return CV_MEM_FAIL;
  run->y = N_VNew_Serial(n, run->sundials);
  run->cvode = CVodeCreate(bdf ? CV_BDF : CV_ADAMS, run->sundials);
  if (run->y == NULL || run->cvode == NULL) return CV_MEM_FAIL;
  for (int i = 0; i < n; ++i) NV_Ith_S(run->y, i) = y0[i];
  if ((flag = CVodeInit(run->cvode, rhs_adapter, t0, run->y)) != CV_SUCCESS) return flag;
  if ((flag = CVodeSetUserData(run->cvode, run)) != CV_SUCCESS) return flag;
  if ((flag = CVodeSStolerances(run->cvode, relative, absolute)) != CV_SUCCESS) return flag;
  if ((flag = CVodeSetMaxNumSteps(run->cvode, 1000000)) != CV_SUCCESS) return flag;
  if (bdf) {
    run->matrix = SUNDenseMatrix(n, n, run->sundials);
    run->linear = SUNLinSol_Dense(run->y, run->matrix, run->sundials);
    if (run->matrix == NULL || run->linear == NULL) return CV_MEM_FAIL;
    if ((flag = CVodeSetLinearSolver(run->cvode, run->linear, run->matrix)) != CV_SUCCESS) return flag;
    if ((flag = CVodeSetJacFn(run->cvode, jacobian_adapter)) != CV_SUCCESS) return flag;
  } else {
    run->nonlinear = SUNNonlinSol_FixedPoint(run->y, 0, run->sundials);
    if (run->nonlinear == NULL) return CV_MEM_FAIL;
    if ((flag = CVodeSetNonlinearSolver(run->cvode, run->nonlinear)) != CV_SUCCESS) return flag;
  }
  return CV_SUCCESS;
}

/* Integrates to t_out exactly (a stop time there, so no step passes it); y gets the state. */
int eme_cvode_advance(void *handle, double t_out, double *y, double *t_reached) {
  eme_cvode *run = (eme_cvode *)handle;
  int flag = CVodeSetStopTime(run->cvode, t_out);

  if (flag != CV_SUCCESS) return flag;
  flag = CVode(run->cvode, t_out, run->y, t_reached, CV_NORMAL);
  sunindextype n = N_VGetLength(run->y);
  for (sunindextype i = 0; i < n; ++i) y[i] = NV_Ith_S(run->y, i);
  return (flag == CV_SUCCESS || flag == CV_TSTOP_RETURN) ? CV_SUCCESS : flag;
}

/* Cumulative counts (steps, right-hand sides, Jacobians, nonlinear iterations, error-test and
 * nonlinear-solver failures) and the order and size of the last internal step. */
int eme_cvode_statistics(void *handle, long counts[6], int *last_order, double *last_step) {
  eme_cvode *run = (eme_cvode *)handle;
  int flag = CVodeGetNumSteps(run->cvode, &counts[0]);

  if (flag == CV_SUCCESS) flag = CVodeGetNumRhsEvals(run->cvode, &counts[1]);
  counts[2] = 0;
  if (flag == CV_SUCCESS && run->linear != NULL) flag = CVodeGetNumJacEvals(run->cvode, &counts[2]);
  if (flag == CV_SUCCESS) flag = CVodeGetNumNonlinSolvIters(run->cvode, &counts[3]);
  if (flag == CV_SUCCESS) flag = CVodeGetNumErrTestFails(run->cvode, &counts[4]);
  if (flag == CV_SUCCESS) flag = CVodeGetNumNonlinSolvConvFails(run->cvode, &counts[5]);
  if (flag == CV_SUCCESS) flag = CVodeGetLastOrder(run->cvode, last_order);
  if (flag == CV_SUCCESS) flag = CVodeGetLastStep(run->cvode, last_step);
  return flag;
}

/* CVODE's name of a return flag, e.g. CV_CONV_FAILURE, into text (length bytes, NUL-ended). */
void eme_cvode_flag_name(int flag, char *text, int length) {
  char *name = CVodeGetReturnFlagName(flag); /* allocated by CVODE */

  snprintf(text, (size_t)length, "%s", name != NULL ? name : "unknown flag");
  free(name);
}

/* Frees everything the run holds; *handle becomes NULL. */
void eme_cvode_free(void **handle) {
  eme_cvode *run = (eme_cvode *)*handle;

  if (run == NULL) return;
  if (run->cvode != NULL) CVodeFree(&run->cvode);
  if (run->nonlinear != NULL) SUNNonlinSolFree(run->nonlinear);
  if (run->linear != NULL) SUNLinSolFree(run->linear);
  if (run->matrix != NULL) SUNMatDestroy(run->matrix);
  if (run->y != NULL) N_VDestroy(run->y);
  if (run->sundials != NULL) SUNContext_Free(&run->sundials);
  free(run);
  *handle = NULL;
}
