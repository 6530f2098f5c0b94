!> The steps of the discrete-gradient schemes (src/integrator/discrete_gradient_stepper): a step of
!> dt, or its halves where no strategy finds its root, each solved by the retry strategies (with the
!> constraints' condensed unknowns where the scheme has them), the counts of its solves kept in a
!> tally, and a step solved again from its start with the default solver settings (resolve).
!> (A .F90 file: docs/development.md, Modules that grow.)
submodule (discrete_gradient_stepper) discrete_gradient_step
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
  use retry_strategies, only: find_root
  use number_text, only: integer_text
  implicit none

contains

  module procedure advance
    type(substep_tally) :: tally
    real(real64) :: estimate_norm
    integer :: n

    n = self%problem%model%state_size
    call start_tally(self, tally, size(x_old) - n)
    if (self%adaptive) then
      call adaptive_step(self, x_old, t_old, x_new, tally, report, failure)
      call finish_report(self, tally, x_new, report, failure)
      return
    end if
    call halved_step(self, x_old, dt, guess, x_new, tally, report, failure)
    report%diagnostics = [real(tally%substeps, real64)]
    if (.not. self%estimating .or. failure%failed() .or. .not. report%accepted) return
    call estimate_step(self, x_old(1:n), x_new(1:n), dt, estimate_norm)
    report%diagnostics = [report%diagnostics, estimate_norm]
  end procedure advance

  module procedure resolve
    type(substep_tally) :: tally
    real(real64) :: estimate_norm
    integer :: n

    if (self%fused) then
      call self%default_solver%prepare(self%kernel, 0.0_real64, max(self%max_iterations, 50), failure, &
                                       from_options=.false.)
    else
      call self%default_solver%prepare(self%problem, 0.0_real64, max(self%max_iterations, 50), failure, &
                                       from_options=.false.)
    end if
    if (failure%failed()) return
    n = self%problem%model%state_size
    call start_tally(self, tally, size(x_old) - n)
    self%resolving = .true.
    call halved_step(self, x_old, h, guess, x_new, tally, report, failure)
    self%resolving = .false.
    report%chose_time = self%adaptive
    report%time = t_old + h
    ! The datasets of diagnostics(): substeps, then the estimate, then the adaptive step's figures.
    report%diagnostics = [real(tally%substeps, real64)]
    if (.not. self%estimating) return
    estimate_norm = ieee_value(1.0_real64, ieee_quiet_nan)
    if (.not. failure%failed() .and. report%accepted) call estimate_step(self, x_old(1:n), x_new(1:n), h, estimate_norm)
    report%diagnostics = [report%diagnostics, estimate_norm]
    if (self%adaptive) report%diagnostics = [report%diagnostics, h, 0.0_real64, 0.0_real64, 0.0_real64, 0.0_real64]
  end procedure resolve

  module procedure solve_step
    real(real64) :: start(size(guess))

    associate (n => self%problem%model%state_size)
      self%problem%z_old = x_old(1:n)
      self%problem%dt = h
      ! The old state (with the guessed multipliers) is a root of the step of length 0.
      start = guess
      start(1:n) = x_old(1:n)
    end associate
    if (self%fused) then
      ! The same search on the condensed unknowns y = x(7:); q' follows from y.
      call self%kernel%set_old_state(x_old)
      self%kernel%dt = h
      block
        real(real64) :: y_new(size(guess) - self%kernel%eliminated)

        if (self%resolving) then
          call find_root(self%default_solver, self%kernel, start(self%kernel%eliminated + 1:), &
                         self%kernel%condense(guess), y_new, search, failure, continuing)
        else
          call find_root(self%solver, self%kernel, start(self%kernel%eliminated + 1:), self%kernel%condense(guess), &
                         y_new, search, failure, continuing)
        end if
        x_new = self%kernel%expand(y_new)
      end block
    else if (self%resolving) then
      call find_root(self%default_solver, self%problem, start, guess, x_new, search, failure, continuing)
    else
      call find_root(self%solver, self%problem, start, guess, x_new, search, failure, continuing)
    end if
  end procedure solve_step

  ! A tally of substeps with no substep yet, for a step with n_multipliers multipliers, and the
  ! solver's multiplier integral zeroed.
  subroutine start_tally(self, tally, n_multipliers)
    class(step_solver), intent(inout) :: self
    type(substep_tally), intent(out) :: tally
    integer, intent(in) :: n_multipliers

    if (allocated(self%multiplier_integral)) then
      if (size(self%multiplier_integral) /= n_multipliers) deallocate (self%multiplier_integral)
    end if
    if (.not. allocated(self%multiplier_integral)) allocate (self%multiplier_integral(n_multipliers))
    self%multiplier_integral = 0.0_real64
    tally%reason = ''
    tally%last_rejection = ''
  end subroutine start_tally

  ! The step of h from x_old in halves where needed (step_or_halve), its multipliers the
  ! substeps' time averages, and its report.
  subroutine halved_step(self, x_old, h, guess, x_new, tally, report, failure)
    class(step_solver), intent(inout), target :: self
    real(real64), intent(in) :: x_old(:), h, guess(:)
    real(real64), intent(out) :: x_new(:)
    type(substep_tally), intent(inout) :: tally
    type(step_report), intent(inout) :: report
    type(failure_type), intent(out) :: failure
    integer :: n

    n = self%problem%model%state_size
    call step_or_halve(self, x_old, h, guess, x_new, 0, tally, report%accepted, failure)
    if (.not. failure%failed() .and. report%accepted .and. tally%substeps > 1) x_new(n + 1:) = self%multiplier_integral/h
    call finish_report(self, tally, x_new, report, failure)
  end subroutine halved_step

  ! The report of a step from what its (sub)steps did; on acceptance the temperatures the (last
  ! sub)step's K0 used. The tally's reason and last rejection move into the report.
  subroutine finish_report(self, tally, x_new, report, failure)
    class(step_solver), intent(inout) :: self
    type(substep_tally), intent(inout) :: tally
    real(real64), intent(in) :: x_new(:)
    type(step_report), intent(inout) :: report
    type(failure_type), intent(in) :: failure
    integer :: stat

    report%strategy = tally%strategy
    report%newton_iterations = tally%newton_iterations
    report%solves = tally%solves
    report%rejected = tally%rejected
    ! Moved, not copied: the tally's texts end here (a copy and a free fewer each, every step).
    call move_alloc(tally%reason, report%reason)
    call move_alloc(tally%last_rejection, report%last_rejection)
    report%halvings = max(0, tally%substeps - 1)     ! each halving adds one substep
    if (self%resolving) then
      report%residual_norm = self%default_solver%last_residual_norm
      report%converged_reason = self%default_solver%last_reason
    else
      report%residual_norm = self%solver%last_residual_norm
      report%converged_reason = self%solver%last_reason
    end if
    allocate (report%scheme_temperature(self%problem%model%temperature_count()))
    report%scheme_temperature = 0.0_real64
    if (failure%failed() .or. .not. report%accepted) return
    if (self%fused) then
      call self%kernel%scheme_temperatures(x_new(self%kernel%eliminated + 1:), report%scheme_temperature, stat)
    else
      call self%problem%scheme_temperatures(x_new, report%scheme_temperature, stat)
    end if
    if (stat /= 0) then    ! check_root has accepted the root, so this does not happen
      report%accepted = .false.
      report%reason = 'the scheme temperatures of the root are undefined'
    end if
  end subroutine finish_report

  ! The step of h from x_old, or, if no strategy finds its root, its two halves (each in halves
  ! where needed) from the predictors interpolated and extrapolated from `guess`; `depth` halvings
  ! made h. The last substep leaves its problem set up (scheme_temperatures).
  recursive subroutine step_or_halve(self, x_old, h, guess, x_new, depth, tally, accepted, failure)
    class(step_solver), intent(inout), target :: self
    real(real64), intent(in) :: x_old(:), h, guess(:)
    real(real64), intent(out) :: x_new(:)
    integer, intent(in) :: depth
    type(substep_tally), intent(inout) :: tally
    logical, intent(out) :: accepted
    type(failure_type), intent(out) :: failure
    type(root_search) :: search
    real(real64) :: x_half(size(x_old))

    call solve_step(self, x_old, h, guess, x_new, depth == 0, search, failure)
    tally%newton_iterations = tally%newton_iterations + search%newton_iterations
    tally%solves = tally%solves + search%solves
    tally%rejected = tally%rejected + search%rejected_roots
    if (len(search%last_rejection) > 0) tally%last_rejection = search%last_rejection
    accepted = search%accepted .and. .not. failure%failed()
    if (accepted) then
      tally%substeps = tally%substeps + 1
      tally%strategy = max(tally%strategy, search%strategy)
      self%multiplier_integral = self%multiplier_integral + h*x_new(size(x_old) - size(self%multiplier_integral) + 1:)
      return
    end if
    if (failure%failed()) return
    if (depth == self%max_halvings) then
      tally%reason = search%reason
      if (depth > 0) tally%reason = search%reason//' (also in steps of dt/'//integer_text(2**depth)//')'
      return
    end if
    call step_or_halve(self, x_old, 0.5_real64*h, x_old + 0.5_real64*(guess - x_old), x_half, depth + 1, tally, &
                       accepted, failure)
    if (.not. accepted) return
    call step_or_halve(self, x_half, 0.5_real64*h, 2*x_half - x_old, x_new, depth + 1, tally, accepted, failure)
  end subroutine step_or_halve

end submodule discrete_gradient_step
