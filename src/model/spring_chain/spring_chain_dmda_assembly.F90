!> The chain's residual and Jacobian on the DMDA (docs/formulation.md section 10, "Sparse and
!> distributed"): each rank assembles its own rows of R = (z - z_old)/h - f and of dR/dz from the
!> blocks that touch them (chain_step_problem's field_rows, over the ghosted local vector of
!> stencil width 2), in slices of slice_points points so that the springs' partials and the band
!> stay in cache; the residual computes no derivative. Holds the SNES callbacks (residual,
!> Jacobian, convergence test) and the field f and df/dz they share with PETSc TS (field_into,
!> jacobian_into). Apart from spring_chain_dmda because these run every Newton iteration on a
!> chain_context alone, while the distributed chain makes and owns the PETSc objects.
!> Every procedure keeps PETSc's ierr (the callbacks' argument lists are PETSc's).
module spring_chain_dmda_assembly
#include <petsc/finclude/petscsnes.h>
#include <petsc/finclude/petscdmda.h>
  use petscsnes
  use petscdmda
  use, intrinsic :: iso_fortran_env, only: real64
  use failures, only: failure_none
  use vector_arrays, only: borrow, give_back, borrow_read, give_back_read
  use retry_strategies, only: newton_converged
  use spring_chain_partials, only: partials_exact
  use spring_chain_dmda_context, only: chain_context
  use spring_chain_dmda_pattern, only: pattern_columns
  implicit none
  private
  public :: field_into, jacobian_into, chain_residual, chain_jacobian, converged_or_rounding, newton_verdict

contains

  ! The rank's rows of f at the iterate x into rows(:), slice by slice, without derivatives: the
  ! step's f(z_old, x) (z_old in old_local), or for the field (partials_exact) f(x) alone.
  subroutine field_into(context, x, rows, stat, ierr)
    type(chain_context), intent(inout) :: context
    Vec, intent(in) :: x
    real(real64), intent(out) :: rows(:)
    integer, intent(out) :: stat
    PetscErrorCode, intent(out) :: ierr
    real(real64), pointer :: old(:), new(:)
    integer :: slice_first, slice_last

    PetscCall(DMGlobalToLocalBegin(context%da, x, INSERT_VALUES, context%new_local, ierr))
    PetscCall(DMGlobalToLocalEnd(context%da, x, INSERT_VALUES, context%new_local, ierr))
    PetscCall(borrow_read(context%new_local, context%local_size, new, ierr))
    old => new
    if (context%problem%rule /= partials_exact) then
      PetscCall(borrow_read(context%old_local, context%local_size, old, ierr))
    end if
    stat = failure_none
    do slice_first = context%first_row, context%last_row, size(context%rows)
      slice_last = min(context%last_row, slice_first + size(context%rows) - 1)
      call context%problem%field_rows(old, new, context%base, slice_first, slice_last, &
                                      rows(slice_first - context%first_row + 1:slice_last - context%first_row + 1), stat=stat)
      if (stat /= failure_none) exit
    end do
    if (context%problem%rule /= partials_exact) then
      PetscCall(give_back_read(context%old_local, old, ierr))
    end if
    PetscCall(give_back_read(context%new_local, new, ierr))
    PetscCall(agree_on_domain(context, stat, ierr))
  end subroutine field_into

  ! SNES callback: the rank's rows of R(x) = (x - z_old)/h - f(z_old, x) (field_into); a state
  ! outside a spring's domain is a domain error (SNES stops).
  subroutine chain_residual(snes, x, r, context, ierr)
    SNES, intent(in) :: snes
    Vec, intent(in) :: x
    Vec, intent(in) :: r
    type(chain_context), intent(inout) :: context
    PetscErrorCode, intent(out) :: ierr
    real(real64), pointer :: old(:), rows(:), state(:)
    integer :: stat, owned, first
    real(real64) :: h

    owned = context%last_row - context%first_row + 1
    first = context%first_row - context%base
    h = context%problem%fraction*context%problem%dt
    PetscCall(borrow(r, owned, rows, ierr))
    PetscCall(field_into(context, x, rows, stat, ierr))
    PetscCall(borrow_read(context%old_local, context%local_size, old, ierr))
    PetscCall(borrow_read(x, owned, state, ierr))
    rows = (state - old(first:first + owned - 1))/h - rows
    PetscCall(give_back_read(x, state, ierr))
    PetscCall(give_back_read(context%old_local, old, ierr))
    PetscCall(give_back(r, rows, ierr))
    if (stat /= failure_none) then
      PetscCall(SNESSetFunctionDomainError(snes, ierr))
    end if
  end subroutine chain_residual

  ! SNES callback: the rank's rows of dR/dx = I/h - df/dx (jacobian_into).
  subroutine chain_jacobian(snes, x, jacobian, preconditioner, context, ierr)
    SNES, intent(in) :: snes
    Vec, intent(in) :: x
    Mat, intent(in) :: jacobian, preconditioner
    type(chain_context), intent(inout) :: context
    PetscErrorCode, intent(out) :: ierr
    integer :: stat

    PetscCall(jacobian_into(context, x, preconditioner, -1.0_real64, 1.0_real64/(context%problem%fraction*context%problem%dt), stat, ierr))
    if (jacobian /= preconditioner) then
      PetscCall(MatAssemblyBegin(jacobian, MAT_FINAL_ASSEMBLY, ierr))
      PetscCall(MatAssemblyEnd(jacobian, MAT_FINAL_ASSEMBLY, ierr))
    end if
    if (stat /= failure_none) then
      PetscCall(SNESSetJacobianDomainError(snes, ierr))
    end if
  end subroutine chain_jacobian

  ! The rank's rows of sign df/dx + diagonal I at x into `matrix`, assembled: slice by slice,
  ! each row's structural nonzeros (coupling_pattern) taken from the slice's band and written over
  ! the row's stored values (MatSetValuesRow: the matrix holds exactly these columns, in this
  ! ascending order, since create_jacobian_matrix; no column search). With -chain_check_pattern
  ! a derivative outside the pattern is an error.
  subroutine jacobian_into(context, x, matrix, sign, diagonal, stat, ierr)
    type(chain_context), intent(inout) :: context
    Vec, intent(in) :: x
    Mat, intent(in) :: matrix
    real(real64), intent(in) :: sign, diagonal
    integer, intent(out) :: stat
    PetscErrorCode, intent(out) :: ierr
    real(real64), pointer :: old(:), new(:)
    integer :: half, row, slice_first, slice_last, k, band_column, point, slot, dof, points
    PetscInt :: count, row_index
    logical :: outside
    MPI_Comm :: comm

    associate (problem => context%problem, band => context%band, columns => context%columns, values => context%values)
      half = problem%band_half_width()
      dof = size(context%pattern, 1)
      points = context%total/dof
      PetscCall(DMGlobalToLocalBegin(context%da, x, INSERT_VALUES, context%new_local, ierr))
      PetscCall(DMGlobalToLocalEnd(context%da, x, INSERT_VALUES, context%new_local, ierr))
      PetscCall(borrow_read(context%new_local, context%local_size, new, ierr))
      old => new
      if (problem%rule /= partials_exact) then
        PetscCall(borrow_read(context%old_local, context%local_size, old, ierr))
      end if
      stat = failure_none
      outside = .false.
      do slice_first = context%first_row, context%last_row, size(context%rows)
        slice_last = min(context%last_row, slice_first + size(context%rows) - 1)
        call problem%field_rows(old, new, context%base, slice_first, slice_last, context%rows(1:slice_last - slice_first + 1), &
                                band(:, 1:slice_last - slice_first + 1), stat)
        if (stat /= failure_none) exit
        do row = slice_first, slice_last
          associate (row_band => band(:, row - slice_first + 1))
            point = (row - 1)/dof + 1
            if (point >= 3 .and. point <= points - 3 .and. .not. context%check_pattern) then
              ! An interior row: its entries sit at fixed places of its band (create_petsc).
              slot = row - (point - 1)*dof
              count = context%interior_counts(slot)
              values(1:count) = sign*row_band(context%interior_band(1:count, slot))
              values(context%interior_diagonal(slot)) = values(context%interior_diagonal(slot)) + diagonal
            else
              call pattern_columns(context, row, columns, count)
              do k = 1, int(count)
                ! row_band(c - g + half + 1) holds row g, column c (1-based; columns are 0-based)
                band_column = int(columns(k)) + 1 - row + half + 1
                values(k) = sign*row_band(band_column)
                if (columns(k) == row - 1) values(k) = values(k) + diagonal
                if (context%check_pattern) row_band(band_column) = 0.0_real64
              end do
              if (context%check_pattern) outside = outside .or. any(abs(row_band) > 0.0_real64)
            end if
          end associate
          row_index = row - 1
          PetscCall(MatSetValuesRow(matrix, row_index, values, ierr))
        end do
      end do
      if (problem%rule /= partials_exact) then
        PetscCall(give_back_read(context%old_local, old, ierr))
      end if
      PetscCall(give_back_read(context%new_local, new, ierr))
    end associate
    PetscCall(MatAssemblyBegin(matrix, MAT_FINAL_ASSEMBLY, ierr))
    PetscCall(MatAssemblyEnd(matrix, MAT_FINAL_ASSEMBLY, ierr))
    if (context%check_pattern) then            ! every rank fails alike (none waits in the solve)
      PetscCall(PetscObjectGetComm(context%da, comm, ierr))
      PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, outside, 1, MPI_LOGICAL, MPI_LOR, comm, ierr))
    end if
    if (outside) then
      ierr = PETSC_ERR_PLIB
      SETERRQ(PETSC_COMM_SELF, ierr, 'chain_jacobian: a derivative outside coupling_pattern (-chain_check_pattern)')
    end if
    PetscCall(agree_on_domain(context, stat, ierr))
  end subroutine jacobian_into

  ! Every rank takes the verdict of the rank whose springs left their domain (stat, the largest
  ! code), so that all tell SNES alike (SNESSetFunctionDomainError is logically collective): a
  ! rank that alone flagged a Newton iterate took another path through SNESSolve than the others
  ! (its line search failed, theirs did not), their collectives no longer matched, and the run
  ! hung (2 ranks, 12 springs near rest, step 5752 of 100000).
  subroutine agree_on_domain(context, stat, ierr)
    type(chain_context), intent(in) :: context
    integer, intent(inout) :: stat
    PetscErrorCode, intent(out) :: ierr
    MPI_Comm :: comm

    PetscCall(PetscObjectGetComm(context%da, comm, ierr))
    PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, stat, 1, MPI_INTEGER, MPI_MAX, comm, ierr))
  end subroutine agree_on_domain

  ! SNES convergence test: Newton's verdict (newton_verdict) at the step's tolerance.
  subroutine converged_or_rounding(snes, iteration, x_norm, update_norm, residual_norm, reason, context, ierr)
    SNES, intent(in) :: snes
    PetscInt, intent(in) :: iteration
    PetscReal, intent(in) :: x_norm, update_norm, residual_norm
    SNESConvergedReason, intent(out) :: reason
    type(chain_context), intent(inout) :: context
    PetscErrorCode, intent(out) :: ierr

    call newton_verdict(snes, iteration, x_norm, update_norm, residual_norm, context%newton_tol, context%update_floor, &
                        reason, ierr)
  end subroutine converged_or_rounding

  !> Newton's verdict on the chain: converged at |R| <= min(the SNES's absolute tolerance,
  !> newton_tol) after an update of at most the same (a first guess only at R = 0), or (after an
  !> update) at an update below max(update_floor, 16 eps |x|), the
  !> rounding of the state, which Newton cannot go below; diverged at the iteration limit or on a
  !> non-finite norm. Shared by the step's SNES and the implicit stages' (spring_chain_stage_solve).
  subroutine newton_verdict(snes, iteration, x_norm, update_norm, residual_norm, newton_tol, update_floor, reason, ierr)
    SNES, intent(in) :: snes
    PetscInt, intent(in) :: iteration
    PetscReal, intent(in) :: x_norm, update_norm, residual_norm
    real(real64), intent(in) :: newton_tol, update_floor
    SNESConvergedReason, intent(out) :: reason
    PetscErrorCode, intent(out) :: ierr
    PetscReal :: atol, rtol, stol
    PetscInt :: max_iterations, max_evaluations

    PetscCall(SNESGetTolerances(snes, atol, rtol, stol, max_iterations, max_evaluations, ierr))
    if (.not. (residual_norm <= huge(residual_norm))) then
      reason = SNES_DIVERGED_FNORM_NAN
    else if (newton_converged(int(iteration), residual_norm, update_norm, x_norm, min(atol, newton_tol), 0.0_real64, &
                              0.0_real64, 0.0_real64)) then
      ! the dense path's tolerance test (its rounding test, with scales 0, left to the next branch):
      ! the residual and the update that made it below the tolerance, a first guess only at R = 0
      ! (the residual alone just below 1e-8 let a 10-spring chain's energy balance reach 37 ulps)
      reason = SNES_CONVERGED_FNORM_ABS
    else if (iteration > 0 .and. update_norm <= max(update_floor, 16.0_real64*epsilon(1.0_real64)*x_norm)) then
      reason = SNES_CONVERGED_SNORM_RELATIVE
    else if (iteration >= max_iterations) then
      reason = SNES_DIVERGED_MAX_IT
    else
      reason = SNES_CONVERGED_ITERATING
    end if
  end subroutine newton_verdict

end module spring_chain_dmda_assembly
