!> One relaxed step of relaxed_runge_kutta (src/integrator/relaxed_stepper): the stages (explicit,
!> or the implicit stage system solved by SNES), the update d and the entropy increment e_S, the
!> relaxation and its guards, the commit, and the halving of a rejected step.
!> (A .F90 file: docs/development.md, Modules that grow.)
submodule (relaxed_stepper) relaxed_stepper_step
  use relaxation, only: relax
  use retry_strategies, only: root_search, find_root
  use number_text, only: scientific_text
  implicit none

contains

  module procedure step_or_halve
    real(real64) :: target_time, error_norm

    target_time = self%t + h
    call relaxed_step(self, h, landing, ok, error_norm, failure)
    if (ok .or. failure%failed()) return
    self%rejections = self%rejections + 1
    self%halvings = self%halvings + 1
    if (depth == max_halvings) then
      self%last_failure = 'a step halved '//integer_text(max_halvings)//' times still failed (last: ' &
                          //self%last_failure//')'
      return
    end if
    call step_or_halve(self, 0.5_real64*h, .false., depth + 1, ok, failure)
    if (.not. ok .or. failure%failed()) return
    if (landing) then
      call step_or_halve(self, target_time - self%t, .true., depth + 1, ok, failure)
    else
      call step_or_halve(self, 0.5_real64*h, .false., depth + 1, ok, failure)
    end if
  end procedure step_or_halve

  module procedure relaxed_step
    real(real64) :: k(size(self%z), self%tableau%stages), d(size(self%z)), z_new(size(self%z)), e_s, gamma, resolution
    integer :: evaluations, a

    ok = .false.
    error_norm = 0.0_real64
    self%attempts = self%attempts + 1
    call stage_derivatives(self, h, k, ok, failure)
    if (.not. ok .or. failure%failed()) return
    ok = .false.
    d = h*matmul(k, self%tableau%b)
    e_s = 0.0_real64
    do a = 1, self%model%temperature_count()
      e_s = e_s + h*dot_product(self%tableau%b, k(self%model%subsystems(a)%tau_column, :))
    end do
    if (.not. all(abs(d) <= huge(1.0_real64))) then
      self%last_failure = 'a non-finite stage'
      return
    end if
    if (any(self%tableau%b < 0.0_real64) .and. e_s < 0.0_real64) then
      self%last_failure = 'the entropy guard: the step''s entropy estimate is negative'
      return
    end if
    call relax(self%model, self%constraints, self%z, d, e_s, gamma, z_new, ok, evaluations, resolution)
    if (.not. ok) then
      self%last_failure = 'no relaxation root gamma in [0.2, 2]'
      return
    end if
    ! The band cannot ask more of gamma than rounding lets it be resolved (a sliver of a step
    ! before an output time, or the short steps of a tight tolerance).
    if (abs(gamma - 1.0_real64) > max(self%gamma_band, resolution)) then
      ok = .false.
      self%gamma_rejections = self%gamma_rejections + 1
      self%last_failure = 'gamma = '//fixed_text(gamma, 6)//' outside the band |gamma - 1| <= '// &
                          scientific_text(self%gamma_band)//' of the tolerance'
      return
    end if
    if (.not. landing .and. self%t + (gamma + landing_slack)*h >= landing_time(self)) then
      self%attempts = self%attempts - 1
      call relaxed_step(self, landing_time(self) - self%t, .true., ok, error_norm, failure)
      return
    end if
    if (self%tableau%embedded) error_norm = step_error_norm(self, h, k, z_new)
    self%z_saved = self%z
    self%t_saved = self%t
    self%gamma_saved = self%last_gamma
    self%production_saved = self%entropy_production
    self%deviation_saved = self%max_gamma_deviation
    self%z = z_new
    if (landing) then
      self%t = self%t + h
    else
      self%t = self%t + gamma*h
    end if
    self%last_gamma = gamma
    self%entropy_production = self%entropy_production + gamma*e_s
    if (abs(gamma - 1.0_real64) > resolution) self%max_gamma_deviation = max(self%max_gamma_deviation, abs(gamma - 1.0_real64))
  end procedure relaxed_step

  module procedure landing_time

    landing_time = min(self%t_end, self%stop_time)
  end procedure landing_time

  ! The stage derivatives k_i = f(g_i) of a step of h: explicit stages one after another, or the
  ! implicit stage system solved by SNES (k_i recomputed from the final stage values, so the
  ! entropy identity does not depend on the solver's tolerance). ok = .false. with last_failure
  ! when a stage leaves the domain or the solve fails.
  subroutine stage_derivatives(self, h, k, ok, failure)
    class(relaxed_runge_kutta), intent(inout) :: self
    real(real64), intent(in) :: h
    real(real64), intent(out) :: k(:, :)
    logical, intent(out) :: ok
    type(failure_type), intent(out) :: failure
    real(real64) :: g(size(self%z)), y(size(self%z), self%tableau%stages)
    real(real64), allocatable :: start(:), predictor(:), solution(:)
    type(root_search) :: search
    integer :: i, stat, s, n

    ok = .false.
    s = self%tableau%stages
    n = size(self%z)
    if (.not. self%tableau%implicit) then
      do i = 1, s
        g = self%z + h*matmul(k(:, 1:i - 1), self%tableau%a(i, 1:i - 1))
        call constrained_field(self%model, self%constraints, g, k(:, i), stat)
        if (stat /= failure_none) then
          self%last_failure = 'stage '//integer_text(i)//' left the model''s domain or is not finite'
          return
        end if
      end do
      ok = .true.
      return
    end if
    call constrained_field(self%model, self%constraints, self%z, g, stat)
    if (stat /= failure_none) then
      self%last_failure = 'the state left the model''s domain'
      return
    end if
    start = [(g, i = 1, s)]
    predictor = start
    if (allocated(self%last_stages)) predictor = self%last_stages
    allocate (solution(n*s))
    self%stages%z = self%z
    self%stages%h = h
    call find_root(self%solver, self%stages, start, predictor, solution, search, failure)
    self%newton_iterations = self%newton_iterations + search%newton_iterations
    if (failure%failed()) return
    if (.not. search%accepted) then
      self%last_failure = 'the stage equations: '//search%reason
      return
    end if
    self%last_stages = solution
    y = self%stages%stage_values(solution)
    do i = 1, s
      call constrained_field(self%model, self%constraints, y(:, i), k(:, i), stat)
      if (stat /= failure_none) then
        self%last_failure = 'stage '//integer_text(i)//' left the model''s domain'
        return
      end if
    end do
    ok = .true.
  end subroutine stage_derivatives

end submodule relaxed_stepper_step
