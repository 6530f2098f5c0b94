!> What PETSc SNES calls back while snes_solver's Newton iterations run, and the context they
!> share (PETSc holds its address): the residual and the analytic Jacobian of the problem, the
!> convergence test of the retry strategies, the shell preconditioner that factors the Jacobian
!> with dense_lu's LU (on the lean way: when the modified Newton's record says the factors it has
!> no longer contract, src/solver/modified_newton; without it, every iteration but the final chord
!> step), and the shell line search that takes the full Newton step (docs/integrators.md).
module snes_shell
#include <petsc/finclude/petscsnes.h>
  use petscsnes
  use, intrinsic :: iso_fortran_env, only: real64
  use, intrinsic :: iso_c_binding, only: c_int, c_double
  use nonlinear_problem, only: nonlinear_system
  use retry_strategies, only: final_chord_step
  use modified_newton, only: factor_record
  use dense_lu, only: lu_factors
  use euclidean_norm, only: two_norm
  use dense_assembly, only: assemble_jacobian
  use vector_arrays, only: borrow, give_back, borrow_read, give_back_read
  implicit none
  private
  public :: solver_context, PCSetApplicationContext, converged_on_update, form_residual, form_jacobian, factor_operator, &
            apply_lu, full_step

  ! SNES_LINESEARCH_FAILED_DOMAIN of petscsnes.h (PETSc 3.18 has no Fortran name for it).
  PetscEnum, parameter :: line_search_failed_domain = 2

  !> What the callbacks see (PETSc holds this context's address): the problem, the LU factors
  !> with their record and, within a solve, what the lean preconditioner needs to choose between
  !> a new Jacobian and the factors it has.
  type :: solver_context
    class(nonlinear_system), pointer :: problem => null()
    type(lu_factors) :: lu
    type(factor_record) :: reuse                    !! the modified Newton's (reuse%enabled: in use)
    real(real64) :: step_length = 0.0_real64        !! the problem's (nonlinear_system's step_length)
    SNES :: snes
    logical :: lean = .false.
    logical :: final_chord = .true.
    real(real64) :: tolerance = 0.0_real64          !! the convergence test's absolute tolerance, min(newton_tol, -snes_atol)
    real(real64) :: update_tolerance = 0.0_real64   !! SNES's relative update tolerance (-snes_stol)
    integer :: accepted_at = -1                     !! the iteration our convergence test accepted (-1: none)
    real(real64) :: residual_norm = huge(1.0_real64)  !! at SNES's current iterate
    real(real64) :: update_norm = huge(1.0_real64)    !! of the update that led there
    real(real64) :: previous_residual = huge(1.0_real64)  !! the residual the convergence test saw before
    real(real64) :: state_scale = 0.0_real64          !! the problem's rounding scales (newton_converged)
    real(real64) :: residual_scale = 0.0_real64
    logical :: chord_taken = .false.                !! the last iteration reused the factors
    integer :: factorizations = 0                   !! LU factorizations since the solver was made
  end type solver_context

  ! PETSc needs these interfaces to pass a Fortran derived type as the preconditioner's context.
  ! The PC's application context, not PCShellSetContext's: PCShellGetContext compares the PC's
  ! type name at every call (about 90 instructions), PCGetApplicationContext reads a field (15),
  ! and apply_lu asks for it at every Newton iteration.
  interface
    subroutine PCSetApplicationContext(pc, context, ierr)
      import :: tPC, solver_context
      PC, intent(in) :: pc
      type(solver_context), intent(in) :: context
      PetscErrorCode, intent(out) :: ierr
    end subroutine PCSetApplicationContext
    subroutine PCGetApplicationContext(pc, context, ierr)
      import :: tPC, solver_context
      PC, intent(in) :: pc
      type(solver_context), pointer, intent(out) :: context
      PetscErrorCode, intent(out) :: ierr
    end subroutine PCGetApplicationContext
    !> The dense matrix's values without changing its state (dense_read.c).
    function eme_dense_read(matrix, values) bind(C, name='eme_dense_read') result(ierr)
      import :: c_int, c_double
      type(*), intent(in) :: matrix
      real(c_double), intent(out) :: values(*)
      integer(c_int) :: ierr
    end function eme_dense_read
  end interface

contains

  ! SNES convergence test: the modified Newton's record's (retry_strategies' newton_converged after
  ! a Newton update) with the input's newton_tol, or SNES's absolute tolerance where -snes_atol
  ! makes it smaller, and SNES's relative update tolerance (-snes_stol > 0 adds a condition), as
  ! the solver keeps them (they change only where it sets them). Options make the test stricter,
  ! never looser.
  subroutine converged_on_update(snes, iteration, x_norm, update_norm, residual_norm, reason, context, ierr)
    SNES, intent(in) :: snes
    PetscInt, intent(in) :: iteration
    PetscReal, intent(in) :: x_norm, update_norm, residual_norm
    SNESConvergedReason, intent(out) :: reason
    type(solver_context), intent(inout) :: context
    PetscErrorCode, intent(out) :: ierr

    ierr = 0
    if (.not. (residual_norm <= huge(residual_norm))) then
      reason = SNES_DIVERGED_FNORM_NAN
    else if (context%reuse%converged(int(iteration), residual_norm, update_norm, x_norm, context%tolerance, &
                                     context%update_tolerance, context%state_scale, context%residual_scale, &
                                     context%step_length, context%previous_residual)) then
      reason = SNES_CONVERGED_FNORM_ABS
      context%accepted_at = int(iteration)
    else
      reason = SNES_CONVERGED_ITERATING
    end if
    context%previous_residual = residual_norm
  end subroutine converged_on_update

  ! SNES callback: the residual; a point outside the problem's domain is a domain error, which
  ! makes the line search shorten the step. Its norm is the current iterate's for the lean
  ! preconditioner (SNESSolve evaluates the initial residual here).
  subroutine form_residual(snes, x, f, context, ierr)
    SNES, intent(in) :: snes
    Vec, intent(in) :: x
    Vec, intent(in) :: f
    type(solver_context), intent(inout) :: context
    PetscErrorCode, intent(out) :: ierr
    PetscScalar, pointer :: x_values(:), f_values(:)
    integer :: n
    integer :: stat

    n = context%problem%unknowns()
    PetscCall(borrow_read(x, n, x_values, ierr))
    PetscCall(borrow(f, n, f_values, ierr))
    call context%problem%evaluate_residual(x_values, f_values, stat)
    if (stat /= 0) f_values = huge(1.0_real64)
    context%residual_norm = two_norm(f_values)
    PetscCall(give_back(f, f_values, ierr))
    PetscCall(give_back_read(x, x_values, ierr))
    if (stat /= 0) then
      PetscCall(SNESSetFunctionDomainError(snes, ierr))
    end if
  end subroutine form_residual

  ! SNES callback (standard way): the analytic Jacobian, written straight into the dense matrix.
  subroutine form_jacobian(snes, x, jacobian, preconditioner, context, ierr)
    SNES, intent(in) :: snes
    Vec, intent(in) :: x
    Mat, intent(in) :: jacobian
    Mat, intent(in) :: preconditioner
    type(solver_context), intent(in) :: context
    PetscErrorCode, intent(out) :: ierr
    PetscScalar, pointer :: x_values(:), entries(:, :)
    integer :: n
    real(real64) :: residual(context%problem%unknowns())
    integer :: stat

    n = context%problem%unknowns()
    PetscCall(borrow_read(x, n, x_values, ierr))
    PetscCall(MatDenseGetArrayF90(preconditioner, entries, ierr))
    call context%problem%evaluate(x_values, residual, entries, stat)
    PetscCall(MatDenseRestoreArrayF90(preconditioner, entries, ierr))
    PetscCall(give_back_read(x, x_values, ierr))
    PetscCall(assemble_jacobian(jacobian, preconditioner, ierr))
    if (stat /= 0) then
      PetscCall(SNESSetJacobianDomainError(snes, ierr))
    end if
  end subroutine form_jacobian

  ! Shell preconditioner set-up (standard way): factor the new matrix, read without changing its
  ! state. PETSc keeps a failure reason until told otherwise, so a good factorization clears it.
  ! The lean way factors when the preconditioner is applied.
  subroutine factor_operator(pc, ierr)
    PC, intent(in) :: pc
    PetscErrorCode, intent(out) :: ierr
    type(solver_context), pointer :: context
    Mat :: operator, preconditioner
    integer :: info

    PetscCall(PCGetApplicationContext(pc, context, ierr))
    if (context%lean) return
    PetscCall(PCGetOperators(pc, operator, preconditioner, ierr))
    ierr = eme_dense_read(preconditioner, context%lu%factors)
    if (ierr /= 0) return
    call context%lu%factor_in_place(info)
    context%factorizations = context%factorizations + 1
    if (info /= 0) then
      PetscCall(PCSetFailedReason(pc, PC_FACTOR_NUMERIC_ZEROPIVOT, ierr))
    else
      PetscCall(PCSetFailedReason(pc, PC_NOERROR, ierr))
    end if
  end subroutine factor_operator

  ! Shell application: y = J^-1 x from the factors. The lean way first evaluates the Jacobian at
  ! SNES's iterate and factors it, unless the modified Newton keeps the factors it has or (without
  ! it) the final chord step confirms the root with them (module header).
  subroutine apply_lu(pc, x, y, ierr)
    PC, intent(in) :: pc
    Vec, intent(in) :: x
    Vec, intent(in) :: y
    PetscErrorCode, intent(out) :: ierr
    type(solver_context), pointer :: context
    PetscScalar, pointer :: x_values(:), y_values(:)
    Vec :: iterate
    integer :: n
    integer :: info
    logical :: refactor

    PetscCall(PCGetApplicationContext(pc, context, ierr))
    n = context%problem%unknowns()
    if (context%lean) then
      if (context%reuse%enabled) then
        refactor = context%reuse%must_factor(context%lu%ready, context%residual_norm, context%state_scale, &
                                             context%step_length)
      else
        context%chord_taken = final_chord_step(context%final_chord, context%lu%ready, context%chord_taken, &
                                               context%residual_norm, context%tolerance, context%update_norm)
        refactor = .not. context%chord_taken
      end if
      if (refactor) then
        PetscCall(SNESGetSolution(context%snes, iterate, ierr))
        PetscCall(borrow_read(iterate, n, x_values, ierr))
        call factor_jacobian(context, x_values, info)
        PetscCall(give_back_read(iterate, x_values, ierr))
        if (info /= 0) then
          PetscCall(PCSetFailedReason(pc, PC_FACTOR_NUMERIC_ZEROPIVOT, ierr))
          return
        end if
        PetscCall(PCSetFailedReason(pc, PC_NOERROR, ierr))
      else
        call context%reuse%kept()
      end if
    end if
    PetscCall(borrow_read(x, n, x_values, ierr))
    PetscCall(borrow(y, n, y_values, ierr))
    y_values = x_values
    call context%lu%solve(y_values, info)
    PetscCall(give_back(y, y_values, ierr))
    PetscCall(give_back_read(x, x_values, ierr))
    if (info /= 0) then
      PetscCall(PCSetFailedReason(pc, PC_SUBPC_ERROR, ierr))
    end if
  end subroutine apply_lu

  ! The lean way's Jacobian at SNES's current iterate (whose residual the problem may have kept),
  ! written into the LU's own array and factored there, and noted in the factors' record; info /= 0
  ! for a point outside the domain or a zero pivot.
  subroutine factor_jacobian(context, iterate, info)
    type(solver_context), intent(inout) :: context
    real(real64), intent(in) :: iterate(:)
    integer, intent(out) :: info
    integer :: stat

    call context%problem%evaluate_jacobian(iterate, context%lu%factors, stat)
    info = stat
    context%lu%ready = .false.
    if (stat /= 0) return
    call context%lu%factor_in_place(info)
    context%factorizations = context%factorizations + 1
    if (info == 0) call context%reuse%factored()
  end subroutine factor_jacobian

  ! Shell line search (the lean way's 'basic'): the full Newton step X - Y, its residual, and the
  ! norms SNES would otherwise compute again. A step outside the domain fails the line search and
  ! leaves X where it was, as 'basic' does; but a modified Newton's chord step outside the domain
  ! is taken again as a Newton step from X (as src/solver/hand_newton does).
  subroutine full_step(line_search, context, ierr)
    SNESLineSearch, intent(in) :: line_search
    type(solver_context), intent(inout) :: context
    PetscErrorCode, intent(out) :: ierr
    Vec :: x, f, y, w, g
    PetscScalar, pointer :: x_values(:), f_values(:), y_values(:)
    integer :: n
    real(real64) :: trial(context%problem%unknowns()), residual(size(trial)), update(size(trial))
    real(real64) :: x_norm, residual_norm, update_norm
    integer :: stat, info

    PetscCall(SNESLineSearchGetVecs(line_search, x, f, y, w, g, ierr))
    n = context%problem%unknowns()
    PetscCall(borrow_read(y, n, y_values, ierr))
    PetscCall(borrow(x, n, x_values, ierr))
    trial = x_values - y_values
    update_norm = two_norm(y_values)
    call context%problem%evaluate_residual(trial, residual, stat)
    if (stat /= 0 .and. context%reuse%enabled .and. context%reuse%chord) then
      call factor_jacobian(context, x_values, info)
      if (info == 0) then
        PetscCall(borrow_read(f, n, f_values, ierr))
        update = f_values
        PetscCall(give_back_read(f, f_values, ierr))
        call context%lu%solve(update, info)
        trial = x_values - update
        update_norm = two_norm(update)
        call context%problem%evaluate_residual(trial, residual, stat)
      end if
    end if
    if (stat == 0) then
      x_values = trial
      x_norm = two_norm(trial)
      residual_norm = two_norm(residual)
    end if
    PetscCall(give_back(x, x_values, ierr))
    PetscCall(give_back_read(y, y_values, ierr))
    if (stat /= 0) then
      PetscCall(SNESLineSearchSetReason(line_search, line_search_failed_domain, ierr))
      return
    end if
    PetscCall(borrow(f, n, f_values, ierr))
    f_values = residual
    PetscCall(give_back(f, f_values, ierr))
    PetscCall(SNESLineSearchSetNorms(line_search, x_norm, residual_norm, update_norm, ierr))
    call context%reuse%updated(update_norm, context%residual_norm)
    context%residual_norm = residual_norm
    context%update_norm = update_norm
  end subroutine full_step

end module snes_shell
