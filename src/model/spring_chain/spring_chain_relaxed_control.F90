!> relaxed_dp853's step control on the chain split over ranks (spring_chain_relaxed_run's adaptive
!> steps): one accepted step of the size DOP853's controller chooses (adaptive_step: reaching
!> t + gamma h, or landing on t_end or the next output time; refused steps undone and retried
!> smaller), DOP853's error norm with each rank's sums over its rows added by MPI_Allreduce (the
!> same on every rank, independent of the rank count up to the rounding of that sum), and what a
!> continued run needs to go on bit for bit: the next trial step and the record behind the
!> accuracy warnings.
#include <petsc/finclude/petscdmda.h>
submodule (spring_chain_relaxed_run) spring_chain_relaxed_control
  use failures, only: failure_mismatch
  use vector_arrays, only: borrow_read, give_back_read
  use dop853_control, only: error_squares, dop853_error_norm, accepted_step_factor, rejected_step_factor, &
                            max_error_rejections
  implicit none

contains

  ! err5 and err3 from the estimates sum_i e5_i k_i and sum_i e3_i k_i (in the stage and direction
  ! vectors, free once the step is relaxed), the step's start and its relaxed end.
  module procedure step_error_norm
    real(real64), pointer :: estimate5(:), estimate3(:), z(:), z_new(:)
    real(real64) :: squares(2)
    MPI_Comm :: comm
    integer :: i, rows

    error_norm = huge(1.0_real64)
    PetscCall(VecSet(self%stage, 0.0_real64, ierr))
    PetscCall(VecSet(self%direction, 0.0_real64, ierr))
    do i = 1, size(self%tableau%e5)
      if (abs(self%tableau%e5(i)) > 0.0_real64) then
        PetscCall(VecAXPY(self%stage, self%tableau%e5(i), self%k(i), ierr))
      end if
      if (abs(self%tableau%e3(i)) > 0.0_real64) then
        PetscCall(VecAXPY(self%direction, self%tableau%e3(i), self%k(i), ierr))
      end if
    end do
    rows = self%chain%context%last_row - self%chain%context%first_row + 1
    PetscCall(borrow_read(self%stage, rows, estimate5, ierr))
    PetscCall(borrow_read(self%direction, rows, estimate3, ierr))
    PetscCall(borrow_read(self%start_state, rows, z, ierr))
    PetscCall(borrow_read(self%chain%x, rows, z_new, ierr))
    squares = error_squares(self%tolerance, estimate5, estimate3, z, z_new)
    PetscCall(give_back_read(self%chain%x, z_new, ierr))
    PetscCall(give_back_read(self%start_state, z, ierr))
    PetscCall(give_back_read(self%direction, estimate3, ierr))
    PetscCall(give_back_read(self%stage, estimate5, ierr))
    PetscCall(PetscObjectGetComm(self%chain%context%da, comm, ierr))
    PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, squares, 2, MPI_DOUBLE_PRECISION, MPI_SUM, comm, ierr))
    error_norm = dop853_error_norm(h, squares, self%unknowns)
  end procedure step_error_norm

  ! [h_next, run_rejections, run_halvings, max_gamma_deviation]: the adaptive run's next trial
  ! step, and every relaxed run's record for its accuracy warnings (as the dense path's).
  module procedure resume_state
    values = [self%h_next, real(self%run_rejections, real64), real(self%run_halvings, real64), self%max_gamma_deviation]
  end procedure resume_state

  module procedure restore_state
    real(real64), allocatable :: expected(:)

    call self%resume_state(expected)
    self%t = time
    ! A fixed-step run's file written before 2026-11-30 stored no record (its warnings then count
    ! from the continuation on).
    if (.not. self%tableau%embedded .and. size(values) == 0) return
    if (size(values) /= size(expected)) then
      call fail(failure, failure_mismatch, 'the stored step control ('//integer_text(size(values))//' values) does '// &
                'not fit this run''s ('//integer_text(size(expected))//')', 'relaxed_chain_run%restore_state')
      return
    end if
    self%h_next = values(1)
    self%run_rejections = nint(values(2))
    self%run_halvings = nint(values(3))
    self%max_gamma_deviation = values(4)
  end procedure restore_state

  ! One accepted step from the state held at self%t, as the dense path's relaxed_step_control takes
  ! it: h the next trial step, shortened to land on t_end or the next output time when it (nearly)
  ! reaches it; a step relaxed but refused by the error norm is undone (state, time and record) and
  ! retried smaller, one without a relaxation root halved. ok = .false. after max_error_rejections,
  ! or when h falls to round-off (last_failure says why).
  module procedure adaptive_step
    real(real64) :: h, error_norm, production, gamma, deviation, t_start
    logical :: landing
    integer :: tries
    PetscErrorCode :: ierr

    ok = .false.
    h = self%h_next
    t_start = self%t
    do tries = 1, max_error_rejections
      landing = self%t + (1.0_real64 + landing_slack)*h >= self%landing_time()
      if (landing) h = self%landing_time() - self%t
      production = self%entropy_production
      gamma = self%last_gamma
      deviation = self%max_gamma_deviation
      call relaxed_step(self, h, landing, ok, error_norm, failure)
      if (failure%failed()) return
      if (ok .and. error_norm <= 1.0_real64) then
        if (.not. landing) self%h_next = h*accepted_step_factor(error_norm, tries > 1)
        return
      end if
      self%rejections = self%rejections + 1
      if (ok) then
        ! Relaxed, but not accepted by the error test: undone, and retried smaller.
        ok = .false.
        self%t = t_start
        self%entropy_production = production
        self%last_gamma = gamma
        self%max_gamma_deviation = deviation
        self%last_failure = 'the error norm '//scientific_text(error_norm)//' exceeded 1'
        call VecCopy(self%start_state, self%chain%x, ierr)
        call fail_on_code(failure, ierr, 'restoring the chain''s state after a rejected relaxed step')
        if (failure%failed()) return
        h = h*rejected_step_factor(error_norm)
      else
        self%halvings = self%halvings + 1
        h = 0.5_real64*h
      end if
      if (h <= 1.0e-14_real64*max(1.0_real64, abs(self%t))) exit
    end do
    self%last_failure = 'the adaptive step shrank below round-off or was rejected '//integer_text(max_error_rejections)// &
                        ' times (last: '//self%last_failure//')'
  end procedure adaptive_step

end submodule spring_chain_relaxed_control
