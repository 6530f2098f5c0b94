!> One relaxed step on the chain split over ranks (spring_chain_relaxed_run): the stages
!> k_i = f(g_i) of the chain's field (spring_chain_dmda's field_at; implicit ones solved together,
!> spring_chain_stage_solve) and d = h sum_i b_i k_i, the
!> rank sums at z (e_S, the rounding floor, the conserved components: one MPI_Allreduce), then the
!> relaxation's root gamma (spring_chain_relaxed_root) within the gamma band, and the time it
!> reaches, t + gamma h, as the dense path's relaxed_step (src/integrator/relaxed_stepper). A
!> submodule because it works on the run's vectors and its per-step record.
#include <petsc/finclude/petscdmda.h>
submodule (spring_chain_relaxed_run) spring_chain_relaxed_step
  use relaxation_root, only: find_relaxation_root
  use vector_arrays, only: borrow_read, give_back_read
  use spring_chain_relaxation_share, only: rounding_floor_share, momentum_share
  use spring_chain_relaxed_root, only: split_relaxation
  implicit none

contains

  ! One relaxed step of h from the state held at self%t, committed when ok: the stages, d and e_S,
  ! the rounding floor and the conserved components at z (one sum over the ranks), then the
  ! relaxation, and the time reached: t + gamma h, or the landing time when `landing`. A step whose
  ! relaxed time would pass the landing time, or leave less than landing_slack h before it, is redone
  ! as the landing step. When not ok the state is z again and last_failure says why.
  module procedure relaxed_step
    type(split_relaxation) :: relaxation
    real(real64) :: sums(2 + size(self%axes, 2)), gamma, resolution, largest
    integer :: evaluations, stat, failed_stage
    logical :: solved
    PetscErrorCode :: ierr

    ok = .false.
    error_norm = 0.0_real64
    self%attempts = self%attempts + 1
    call stages_petsc(self, h, failed_stage, solved, largest, ierr)
    if (ierr == 0 .and. solved .and. failed_stage == 0 .and. largest <= huge(largest)) call sums_petsc(self, sums, stat, ierr)
    call fail_on_code(failure, ierr, 'evaluating the chain''s relaxed stages')
    if (failure%failed()) return
    if (.not. solved) then
      return
    else if (failed_stage > 0) then
      self%last_failure = 'stage '//integer_text(failed_stage)//' left the model''s domain or is not finite'
      return
    else if (.not. (largest <= huge(largest))) then
      self%last_failure = 'a non-finite stage'
      return
    else if (stat /= failure_none) then
      self%last_failure = 'the state left the model''s domain'
      return
    end if
    associate (entropy_estimate => sums(1), floor => sums(2))
      if (any(self%tableau%b < 0.0_real64) .and. entropy_estimate < 0.0_real64) then
        self%last_failure = 'the entropy guard: the step''s entropy estimate is negative'
        return
      end if
      self%momenta = sums(3:)
      relaxation%run => self
      call find_relaxation_root(relaxation, max(floor, tiny(1.0_real64)), gamma, ok, evaluations, resolution)
      if (ok .and. abs(gamma - 1.0_real64) > max(self%gamma_band, resolution)) then
        ok = .false.
        self%gamma_rejections = self%gamma_rejections + 1
        self%last_failure = 'gamma = '//fixed_text(gamma, 6)//' outside the band |gamma - 1| <= '// &
                            scientific_text(self%gamma_band)//' of the tolerance'
      else if (.not. ok) then
        self%last_failure = 'no relaxation root gamma in [0.2, 2]'
      end if
      if (ok .and. .not. landing .and. self%t + (gamma + landing_slack)*h >= self%landing_time()) then
        call VecCopy(self%start_state, self%chain%x, ierr)
        call fail_on_code(failure, ierr, 'restoring the chain''s state before its landing step')
        if (failure%failed()) return
        self%attempts = self%attempts - 1
        call relaxed_step(self, self%landing_time() - self%t, .true., ok, error_norm, failure)
        return
      end if
      if (ok .and. self%tableau%embedded) then
        call step_error_norm(self, h, error_norm, ierr)
        call fail_on_code(failure, ierr, 'the error norm of the chain''s relaxed step')
        if (failure%failed()) return
      end if
      if (.not. ok) then
        call VecCopy(self%start_state, self%chain%x, ierr)
        call fail_on_code(failure, ierr, 'restoring the chain''s state after a rejected relaxed step')
        return
      end if
      if (landing) then
        self%t = self%landing_time()
      else
        self%t = self%t + gamma*h
      end if
      self%last_gamma = gamma
      self%entropy_production = self%entropy_production + gamma*entropy_estimate
      if (abs(gamma - 1.0_real64) > resolution) self%max_gamma_deviation = max(self%max_gamma_deviation, &
                                                                                 abs(gamma - 1.0_real64))
    end associate
  end procedure relaxed_step

  ! z of the substep kept (start_state, start_local), the stages k_i = f(g_i) (explicit: in turn;
  ! implicit: solved together, `solved` false when Newton did not, last_failure saying why) and
  ! d = h sum_i b_i k_i; failed_stage: the first stage outside a spring's domain on any rank
  ! (0: none); largest: max |d_j| over the ranks (not finite if a stage was not).
  subroutine stages_petsc(self, h, failed_stage, solved, largest, ierr)
    class(relaxed_chain_run), intent(inout) :: self
    real(real64), intent(in) :: h
    integer, intent(out) :: failed_stage
    logical, intent(out) :: solved
    real(real64), intent(out) :: largest
    PetscErrorCode, intent(out) :: ierr
    integer :: i, j, stat, iterations, reason
    MPI_Comm :: comm

    failed_stage = 0
    solved = .true.
    largest = 0.0_real64
    PetscCall(PetscObjectGetComm(self%chain%context%da, comm, ierr))
    PetscCall(VecCopy(self%chain%x, self%start_state, ierr))
    PetscCall(DMGlobalToLocalBegin(self%chain%context%da, self%start_state, INSERT_VALUES, self%start_local, ierr))
    PetscCall(DMGlobalToLocalEnd(self%chain%context%da, self%start_state, INSERT_VALUES, self%start_local, ierr))
    if (self%tableau%implicit) then
      PetscCall(self%stage_solver%solve(self%start_state, h, self%k, solved, iterations, self%residual_norm, reason, ierr))
      self%newton_iterations = self%newton_iterations + iterations
      if (.not. solved) then
        self%last_failure = 'Newton did not solve the stages (SNES reason '//integer_text(reason)//', |R| = '// &
                            scientific_text(self%residual_norm, 3)//')'
        return
      end if
    end if
    do i = 1, merge(0, size(self%tableau%b), self%tableau%implicit)
      PetscCall(VecCopy(self%start_state, self%stage, ierr))
      do j = 1, i - 1
        ! (explicit tableaux have many zeros below the diagonal)
        if (abs(self%tableau%a(i, j)) > 0.0_real64) then
          PetscCall(VecAXPY(self%stage, h*self%tableau%a(i, j), self%k(j), ierr))
        end if
      end do
      PetscCall(self%chain%field_at(self%stage, self%k(i), stat, ierr))
      if (stat /= failure_none) failed_stage = i
      PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, failed_stage, 1, MPI_INTEGER, MPI_MAX, comm, ierr))
      if (failed_stage > 0) return
    end do
    PetscCall(VecSet(self%direction, 0.0_real64, ierr))
    do i = 1, size(self%tableau%b)
      PetscCall(VecAXPY(self%direction, h*self%tableau%b(i), self%k(i), ierr))
    end do
    PetscCall(VecNorm(self%direction, NORM_INFINITY, largest, ierr))
  end subroutine stages_petsc

  ! Summed over the ranks: e_S = sum_a d(s_a), the rounding floor 8 eps sum_j |z_j| |dE/dz_j| and
  ! the conserved components at z, into sums(1), sums(2) and sums(3:); stat: a domain code.
  subroutine sums_petsc(self, sums, stat, ierr)
    class(relaxed_chain_run), intent(inout) :: self
    real(real64), intent(out) :: sums(:)
    integer, intent(out) :: stat
    PetscErrorCode, intent(out) :: ierr
    real(real64), pointer :: d(:), z(:)
    real(real64) :: gram(size(self%axes, 2), size(self%axes, 2))
    integer :: a, shift
    MPI_Comm :: comm

    sums = 0.0_real64
    associate (c => self%chain%context, layout => self%chain%context%problem%layout, &
               points => [self%chain%first_point, self%chain%last_point])
      shift = c%first_row - 1
      PetscCall(borrow_read(self%direction, c%last_row - shift, d, ierr))
      if (layout%invariant_count >= 2) then
        do a = points(1), min(layout%springs, points(2))
          sums(1) = sums(1) + d(layout%tau_index(a) - shift)
        end do
      end if
      PetscCall(give_back_read(self%direction, d, ierr))
      PetscCall(borrow_read(self%start_local, c%local_size, z, ierr))
      call rounding_floor_share(c%problem, z, c%base, points, sums(2), stat)
      call momentum_share(layout, self%axes, z, c%base, [points(1), min(layout%masses, points(2))], gram, sums(3:))
      PetscCall(give_back_read(self%start_local, z, ierr))
      sums(2) = 8*epsilon(1.0_real64)*sums(2)
      PetscCall(PetscObjectGetComm(c%da, comm, ierr))
      PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, stat, 1, MPI_INTEGER, MPI_MAX, comm, ierr))
      PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, sums, size(sums), MPI_DOUBLE_PRECISION, MPI_SUM, comm, ierr))
    end associate
  end subroutine sums_petsc

end submodule spring_chain_relaxed_step
