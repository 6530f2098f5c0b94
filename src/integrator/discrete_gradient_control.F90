!> Step-size control of the discrete-gradient schemes (src/integrator/discrete_gradient_stepper;
!> docs/integrators.md, Adaptive steps): one accepted step of the size the PI controller
!> (src/integrator/step_size_control) chooses, every trial step solved from the old state and
!> rejected when its root is missing or unphysical or its local error estimate
!> (src/integrator/local_error_estimate) exceeds the tolerance per unit step; and the estimate
!> itself, from the continuous field, which is kept from one step's end to the next step's start.
!> (A .F90 file, compiled as the PETSc sources are, without -std: the parent's scope, which it
!> inherits, holds the PETSc types of its SNES solver.)
submodule (discrete_gradient_stepper) discrete_gradient_control
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
  use failures, only: failure_none
  use constrained_flow, only: constrained_field
  use local_error_estimate, only: hermite_defect_estimate, weighted_rms_norm
  use number_text, only: integer_text, scientific_text
  implicit none (type, external)

contains

  ! One accepted step from x_old at t_old, of the step the controller proposes (module header):
  ! trial steps are solved from the old state (predictor: the last accepted step, scaled), and
  ! each one whose root is missing, unphysical or too inaccurate is rejected and retried smaller.
  ! The run stops when the trial step falls below rejection_underflow (relative to max(1 s, t)) or
  ! max_rejections_per_step were rejected.
  module procedure adaptive_step
    type(root_search) :: search
    real(real64) :: h, h_unshortened, err, estimate_norm, guess(size(x_old))
    real(real64), dimension(self%problem%model%state_size) :: f_old, f_new
    integer :: n, stat, attempt, rejected(3)
    logical :: landing

    n = self%problem%model%state_size
    rejected = 0
    h = 0.0_real64
    err = ieee_value(1.0_real64, ieee_quiet_nan)
    estimate_norm = err
    report%accepted = .false.
    x_new = x_old
    call field_at(self, x_old(1:n), f_old, stat)
    if (stat /= failure_none) then
      tally%reason = 'the continuous vector field is undefined at the step''s start (the state left the model''s domain)'
      call record_rejections()
      return
    end if
    do attempt = 1, max_rejections_per_step + 1
      call self%controller%trial_step(t_old, min(self%t_end, self%stop_time), h, landing)
      if (h < rejection_underflow*max(1.0_real64, abs(t_old))) then
        tally%reason = 'step-size underflow: the trial step fell below '//scientific_text(h)//' s (last rejection: ' &
                       //tally%reason//')'
        exit
      else if (attempt > max_rejections_per_step) then
        tally%reason = 'more than '//integer_text(max_rejections_per_step)//' trial steps rejected (last: ' &
                       //tally%reason//')'
        exit
      end if
      guess = x_old
      if (allocated(self%x_last)) then
        if (same_state(self%x_last, x_old)) guess = x_old + (h/self%h_last)*self%increment
      end if
      call solve_step(self, x_old, h, guess, x_new, .false., search, failure)
      tally%newton_iterations = tally%newton_iterations + search%newton_iterations
      tally%solves = tally%solves + search%solves
      tally%rejected = tally%rejected + search%rejected_roots
      if (len(search%last_rejection) > 0) tally%last_rejection = search%last_rejection
      if (failure%failed()) return
      if (.not. search%accepted) then
        if (search%rejected_roots > 0) then
          rejected(rejection_domain) = rejected(rejection_domain) + 1
        else
          rejected(rejection_no_root) = rejected(rejection_no_root) + 1
        end if
        tally%reason = search%reason
        call self%controller%reject_failure(h)
        cycle
      end if
      call estimate_norm_of(self, x_old(1:n), f_old, x_new(1:n), h, estimate_norm, f_new, stat)
      if (stat /= failure_none) then
        rejected(rejection_domain) = rejected(rejection_domain) + 1
        tally%reason = 'the continuous vector field is undefined at the step''s end or middle'
        call self%controller%reject_failure(h)
        cycle
      end if
      ! Error per unit step: the estimate's norm per second of the step against the tolerance, or
      ! at the estimate's rounding level (which tiny steps would otherwise never get below).
      err = estimate_norm/(self%tolerance*h/unit_time + rounding_level)
      if (err > 1.0_real64) then
        rejected(rejection_error) = rejected(rejection_error) + 1
        tally%reason = 'the error estimate per second '//scientific_text(err*self%tolerance)//' exceeded the tolerance'
        call self%controller%reject_error(h, err)
        cycle
      end if
      h_unshortened = self%controller%h
      call self%controller%accept(h, err)
      ! A step shortened to land on an output time does not shrink the next one.
      if (landing) self%controller%h = max(self%controller%h, h_unshortened)
      report%accepted = .true.
      tally%substeps = 1
      tally%strategy = search%strategy
      tally%reason = ''
      self%z_field = x_new(1:n)
      self%field = f_new
      self%x_last = x_new
      self%increment = x_new - x_old
      self%h_last = h
      report%chose_time = .true.
      report%time = t_old + h
      if (landing) report%time = min(self%t_end, self%stop_time)
      exit
    end do
    call record_rejections()

  contains

    subroutine record_rejections()
      report%rejected_steps = sum(rejected)
      report%diagnostics = [1.0_real64, estimate_norm, h, real(sum(rejected), real64), real(rejected, real64)]
      if (report%accepted) return
      report%diagnostics(2:3) = ieee_value(1.0_real64, ieee_quiet_nan)
      report%chose_time = .true.       ! where the last trial step would have ended
      report%time = t_old + h
    end subroutine record_rejections
  end procedure adaptive_step

  ! The weighted norm of the local error estimate of the step of h from z_old to z_new (NaN where
  ! the field is undefined); the field at z_new is kept for the next step.
  module procedure estimate_step
    real(real64), dimension(size(z_old)) :: f_old, f_new
    real(real64) :: estimate_norm
    integer :: stat

    norm = ieee_value(1.0_real64, ieee_quiet_nan)
    call field_at(self, z_old, f_old, stat)
    if (stat /= failure_none) return
    call estimate_norm_of(self, z_old, f_old, z_new, h, estimate_norm, f_new, stat)
    if (stat /= failure_none) return
    norm = estimate_norm
    self%z_field = z_new
    self%field = f_new
  end procedure estimate_step

  ! The weighted norm (times -eme_error_scale) of the local error estimate of the step of h from
  ! z_old, where the field is f_old, to z_new, and the field f_new at z_new; stat /= failure_none
  ! where a field is undefined.
  subroutine estimate_norm_of(self, z_old, f_old, z_new, h, norm, f_new, stat)
    class(step_solver), intent(in) :: self
    real(real64), intent(in) :: z_old(:), f_old(:), z_new(:), h
    real(real64), intent(out) :: norm, f_new(:)
    integer, intent(out) :: stat
    real(real64) :: estimate(size(z_old))

    norm = ieee_value(1.0_real64, ieee_quiet_nan)
    call hermite_defect_estimate(self%problem%model, self%problem%constraints, z_old, f_old, z_new, h, estimate, &
                                 f_new, stat)
    if (stat == failure_none) norm = self%error_scale*weighted_rms_norm(estimate, z_old, z_new)
  end subroutine estimate_norm_of

  ! The continuous field at z, from the last step's end when z is that state.
  subroutine field_at(self, z, f, stat)
    class(step_solver), intent(inout) :: self
    real(real64), intent(in) :: z(:)
    real(real64), intent(out) :: f(:)
    integer, intent(out) :: stat

    stat = failure_none
    if (allocated(self%z_field)) then
      if (same_state(self%z_field, z)) then
        f = self%field
        return
      end if
    end if
    call constrained_field(self%problem%model, self%problem%constraints, z, f, stat)
    if (stat /= failure_none) return
    self%z_field = z
    self%field = f
  end subroutine field_at

  ! Whether a and b are the same state, bit for bit (the last step's end, kept).
  pure logical function same_state(a, b)
    real(real64), intent(in) :: a(:), b(:)

    same_state = size(a) == size(b)
    if (same_state) same_state = maxval(abs(a - b)) <= 0.0_real64
  end function same_state

end submodule discrete_gradient_control
