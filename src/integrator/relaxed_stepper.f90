!> Relaxed Runge-Kutta integrators (docs/integrators.md): every step keeps E exactly, every conserved
!> component of the momenta exactly, S non-decreasing and V = E - theta_R S non-increasing, at order 4 to 8.
!>
!> The step runs in entropy variables (tau = s), whatever the run's thermodynamic variable: there
!> S is linear in z, L grad S = 0 everywhere, and every stage has positive temperatures. With
!> d = h sum_i b_i f(g_i) and e_S = h sum_i b_i grad S.f(g_i) = h sum_i b_i sigma(g_i), sigma >= 0,
!> the relaxed update P(z + gamma d) (projected onto the constraints and the conserved momenta;
!> src/integrator/relaxation) has
!>   S_{n+1} - S_n = gamma e_S   exactly (to rounding),
!> which is >= 0 when every b_i >= 0 (RK4, Cooper-Verner 8, Gauss-Legendre 3) and is guarded
!> otherwise (Dormand-Prince 8(5,3): a step with e_S < 0 is rejected). Time advances by gamma h;
!> the step that reaches t_end lands on it (t + h, no time relaxation: the local error stays
!> O(h^p)). A step with a non-finite stage, no relaxation root in [0.2, 2], a failed stage solve
!> or a failed guard is rejected and replaced by two relaxed half steps, recursively, to
!> max_halvings levels; an unrelaxed step is never accepted.
!>
!> Fixed-step schemes take nominal steps of dt; relaxed_dp853 adapts h to the &integrator
!> tolerance (absolute and relative per step, DOP853's error norm and controller), dt being its
!> first trial step. The implicit Gauss-Legendre stages are solved by PETSc SNES.
!>
!> The relaxation parameter is an error signal: gamma = 1 + O(h**(p-1)) for a method of order p,
!> so at steps whose local error is about the tolerance tol, |gamma - 1| ~ tol**((p-1)/(p+1)). With
!> a tolerance in force (relaxed_dp853 always; the fixed-step schemes when &integrator tolerance is
!> given) a step with |gamma - 1| > 10 tol**((p-1)/(p+1)) is rejected like a step
!> without a relaxation root (measured on the paper and low-viscosity scenes with relaxed_dp853 at
!> tolerances 1e-4 to 1e-10: |gamma - 1| has its median at 0.003 to 0.02 of tol**(7/9) and its
!> largest value at 2.5 times it; docs/integrators.md).
!>
!> Accuracy warnings: without a tolerance in force nothing bounds the local error of a fixed
!> step, and E, the momenta and dS >= 0 hold all the same (the thermoelastic scene,
!> inputs/romero_thermoelastic.nml, with relaxed_rk4 at dt = 0.15 s: 1297 trial steps halved,
!> |gamma - 1| up to 0.80, the entropy production 3.42 times the true one). A run that halved a step without a tolerance, or whose
!> gamma moved more than gamma_warning_deviation from 1 (beyond what rounding resolves), says so
!> at its end (accuracy_warnings; docs/integrators.md, Accuracy warnings).
!>
!> Constraints enter through their continuous-time forms (src/integrator/constrained_flow): g1
!> by its index-1 force and the projection, g2 as a heat bath at thetabar, for which the relaxed
!> functional is V = E - thetabar S with V_{n+1} - V_n = -thetabar gamma e_S <= 0.
module relaxed_stepper
  use, intrinsic :: iso_fortran_env, only: real64
  use failures, only: failure_none, failure_type, fail, failure_code_name, failure_input, failure_mismatch
  use thermo_variable_kinds, only: tau_entropy
  use model_interface, only: generic_model
  use model_constraint, only: constraint_slot
  use butcher_tableaux, only: butcher_tableau, tableau_named
  use relaxation_root, only: max_halvings, gamma_band, gamma_warning_deviation
  use dop853_control, only: landing_slack
  use constrained_flow, only: constrained_field, project_state
  use collocation_stages, only: stage_system
  use snes_solver, only: newton_solver
  use integrator_settings, only: integrator_choice
  use stepper, only: time_stepper, step_report, step_diagnostic, solver_report
  use solver_description, only: add_setting, text_setting, no_solver
  use number_text, only: integer_text, fixed_text, reals_text
  implicit none (type, external)
  private
  public :: relaxed_runge_kutta, new_relaxed_runge_kutta
  public :: max_halvings
  ! For the submodule relaxed_step_control only: gfortran gives a module's private procedures
  ! internal linkage, which submodules, compiled apart, cannot reach.
  public :: relaxed_step, landing_time

  !> A relaxed Runge-Kutta integrator and its state in entropy variables.
  type, extends(time_stepper) :: relaxed_runge_kutta
    type(butcher_tableau) :: tableau
    logical :: adaptive = .false.
    class(generic_model), allocatable :: model          !! the run's model in entropy variables
    class(generic_model), allocatable :: user_model     !! the run's model in its own variable
    type(constraint_slot), allocatable :: constraints(:)   !! the active constraints' continuous forms
    real(real64), allocatable :: z(:)                   !! the state, in entropy variables
    real(real64) :: t = 0.0_real64
    real(real64) :: t_end = 0.0_real64
    real(real64) :: tolerance = 0.0_real64
    real(real64) :: gamma_band = huge(1.0_real64)       !! the largest |gamma - 1| accepted
    real(real64) :: h_next = 0.0_real64                 !! the adaptive method's next trial step
    ! The implicit method's stage system and its solver.
    type(stage_system) :: stages
    type(newton_solver) :: solver
    real(real64) :: newton_tol = 0.0_real64
    integer :: newton_max_iterations = 0
    real(real64), allocatable :: last_stages(:)         !! the last step's K, the next predictor
    ! What the current output step did, and what the last committed step replaced.
    integer :: attempts = 0, rejections = 0, halvings = 0, newton_iterations = 0, gamma_rejections = 0
    real(real64) :: last_gamma = 1.0_real64, entropy_production = 0.0_real64
    character(len=:), allocatable :: last_failure
    real(real64), allocatable :: z_saved(:)
    real(real64) :: t_saved = 0.0_real64, gamma_saved = 1.0_real64, production_saved = 0.0_real64
    ! The run's record for its accuracy warnings: rejected and halved attempts of the accepted
    ! steps, and the largest |gamma - 1| of an accepted (sub)step beyond its rounding resolution.
    integer :: run_rejections = 0, run_halvings = 0
    real(real64) :: max_gamma_deviation = 0.0_real64, deviation_saved = 0.0_real64
    real(real64) :: dt = 0.0_real64                    !! the nominal step, for the warnings' words
  contains
    procedure :: start
    procedure :: advance
    procedure :: release
    procedure :: diagnostics
    procedure :: describe_solver
    procedure :: resume_state
    procedure :: restore_state
    procedure :: accuracy_warnings
    procedure, private :: restore
  end type relaxed_runge_kutta

  interface
    !> One accepted step of relaxed_dp853 at its tolerance (src/integrator/relaxed_step_control).
    module subroutine adaptive_step(self, ok, failure)
      class(relaxed_runge_kutta), intent(inout) :: self
      logical, intent(out) :: ok
      type(failure_type), intent(out) :: failure
    end subroutine adaptive_step
    !> DOP853's error norm of the step of h with stage derivatives k to z_new
    !> (src/integrator/relaxed_step_control).
    module function step_error_norm(self, h, k, z_new) result(error_norm)
      class(relaxed_runge_kutta), intent(in) :: self
      real(real64), intent(in) :: h, k(:, :), z_new(:)
      real(real64) :: error_norm
    end function step_error_norm
  end interface

  ! Implemented in relaxed_stepper_step.
  interface
    ! A step of h (landing: the time goes to t + h exactly), or, if it is rejected, two halves,
    ! recursively; ok = .false. when halving went past max_halvings.
    module recursive subroutine step_or_halve(self, h, landing, depth, ok, failure)
      class(relaxed_runge_kutta), intent(inout) :: self
      real(real64), intent(in) :: h
      logical, intent(in) :: landing
      integer, intent(in) :: depth
      logical, intent(out) :: ok
      type(failure_type), intent(out) :: failure
    end subroutine step_or_halve

    ! One relaxed step of h from the current state, committed when ok (state, time, figures):
    ! the stages, d = h sum_i b_i k_i and e_S = h sum_i b_i sum_a k_i(tau_a), then the relaxation.
    ! landing: the time goes to t + h exactly. A step whose relaxed time would pass t_end, or leave
    ! less than landing_slack h before it, is redone as the landing step. error_norm: DOP853's
    ! error norm (0 without embedded weights).
    module recursive subroutine relaxed_step(self, h, landing, ok, error_norm, failure)
      class(relaxed_runge_kutta), intent(inout) :: self
      real(real64), intent(in) :: h
      logical, intent(in) :: landing
      logical, intent(out) :: ok
      real(real64), intent(out) :: error_norm
      type(failure_type), intent(out) :: failure
    end subroutine relaxed_step

    !> The time the next step lands on when it reaches it: t_end, or an earlier output time.
    pure module real(real64) function landing_time(self)
      class(relaxed_runge_kutta), intent(in) :: self
    end function landing_time
  end interface

contains

  !> A relaxed Runge-Kutta integrator; `start` takes the tableau its registry name (scheme)
  !> names (src/integrator/butcher_tableaux, registered_tableaux).
  subroutine new_relaxed_runge_kutta(integrator)
    class(time_stepper), allocatable, intent(out) :: integrator

    allocate (relaxed_runge_kutta :: integrator)
  end subroutine new_relaxed_runge_kutta

  !> The per-step figures of a relaxed step.
  function diagnostics(self) result(specs)
    class(relaxed_runge_kutta), intent(in) :: self
    type(step_diagnostic), allocatable :: specs(:)

    specs = [step_diagnostic('relaxation_gamma', '1', &
                             'gamma of the step''s last relaxed (sub)step: E(z + gamma d) = E(z); time advanced by gamma h'), &
             step_diagnostic('rejected_steps', '1', &
                             'attempts rejected in the step (no relaxation root, a non-finite stage, a failed stage '// &
                             'solve, the entropy guard, or the adaptive error test), each replaced by smaller steps', &
                             'sum'), &
             step_diagnostic('halved_steps', '1', &
                             'rejected attempts replaced by two halves (every rejection but the error test''s)', 'sum'), &
             step_diagnostic('entropy_production', 'J/K', &
                             'gamma e_S summed over the step''s substeps: the entropy change the step''s stages give', &
                             'sum'), &
             step_diagnostic('rejected_gamma', '1', &
                             'attempts rejected because |gamma - 1| left the band of the tolerance (with a '// &
                             'tolerance in force), each replaced by smaller steps', 'sum')]
  end function diagnostics

  !> The implicit stages' SNES (Gauss-Legendre) as it was set up; none for explicit stages.
  function describe_solver(self) result(report)
    class(relaxed_runge_kutta), intent(in) :: self
    type(solver_report) :: report
    type(failure_type) :: failure

    if (.not. self%tableau%implicit) then
      report = no_solver('explicit stages')
      return
    end if
    call self%solver%describe(report, failure)
    if (failure%failed()) call add_setting(report, text_setting('error', 'PETSc could not describe the SNES'))
  end function describe_solver

  !> The run's models (its own variable and entropy variables) and the initial state.
  subroutine start(self, choice, model, constraints, z0, failure)
    class(relaxed_runge_kutta), intent(inout), target :: self
    type(integrator_choice), intent(in) :: choice
    class(generic_model), intent(in) :: model
    type(constraint_slot), intent(in) :: constraints(:)
    real(real64), intent(in) :: z0(:)
    type(failure_type), intent(out) :: failure
    integer :: stat
    logical :: found

    call tableau_named(self%scheme, self%tableau, found)
    if (.not. found) then
      call fail(failure, failure_input, 'no tableau named '''//trim(self%scheme)//'''', 'relaxed_runge_kutta%start')
      return
    end if
    ! Embedded weights: adaptive at the tolerance (relaxed_dp853).
    self%adaptive = self%tableau%embedded
    self%constraints = constraints
    if (allocated(self%user_model)) deallocate (self%user_model)
    allocate (self%user_model, source=model)
    if (allocated(self%model)) deallocate (self%model)
    call model%in_variable(tau_entropy, self%model)
    if (allocated(self%z)) deallocate (self%z)
    allocate (self%z(size(z0)))
    call model%convert_state(z0, self%model, self%z, stat)
    ! The input has checked that z0 satisfies the constraints; this removes the conversion's round-off.
    if (stat == failure_none) call project_state(self%model, constraints, self%model%conserved_momenta(self%z), self%z, stat)
    if (stat /= failure_none) call fail(failure, stat, 'the initial state cannot be taken to the entropy '// &
                                        'variables and projected: '//failure_code_name(stat), 'relaxed_runge_kutta%start')
    self%t = 0.0_real64
    self%t_end = choice%t_end
    self%tolerance = choice%tolerance
    self%gamma_band = huge(1.0_real64)
    if (self%adaptive .or. choice%tolerance_given) self%gamma_band = gamma_band(choice%tolerance, self%tableau%order)
    self%h_next = choice%dt
    self%dt = choice%dt
    self%run_rejections = 0
    self%run_halvings = 0
    self%max_gamma_deviation = 0.0_real64
    self%newton_tol = choice%newton_tol
    self%newton_max_iterations = choice%newton_max_iterations
    if (allocated(self%last_stages)) deallocate (self%last_stages)
    if (self%tableau%implicit .and. .not. failure%failed()) then
      if (allocated(self%stages%model)) deallocate (self%stages%model)
      allocate (self%stages%model, source=self%model)
      self%stages%constraints = constraints
      self%stages%a = self%tableau%a
      self%stages%z = self%z
      self%stages%h = choice%dt
      call self%solver%prepare(self%stages, choice%newton_tol, choice%newton_max_iterations, failure)
    end if
  end subroutine start

  !> One output step: a relaxed step of dt (fixed-step schemes) or one accepted adaptive step,
  !> landing on t_end when it reaches it. x_old is not needed: the integrator keeps its state.
  subroutine advance(self, x_old, t_old, dt, guess, x_new, report, failure)
    class(relaxed_runge_kutta), intent(inout), target :: self
    real(real64), intent(in) :: x_old(:), t_old, dt, guess(:)
    real(real64), intent(out) :: x_new(:)
    type(step_report), intent(out) :: report
    type(failure_type), intent(out) :: failure
    real(real64) :: energy, entropy, z_start(size(self%z)), t_start, f(size(self%z)), energy_change
    logical :: ok
    integer :: stat, n, k

    z_start = self%z
    t_start = self%t
    self%attempts = 0
    self%rejections = 0
    self%halvings = 0
    self%gamma_rejections = 0
    self%newton_iterations = 0
    self%entropy_production = 0.0_real64
    self%last_failure = ''
    report%reason = ''
    report%last_rejection = ''
    allocate (report%scheme_temperature(self%model%temperature_count()))
    report%scheme_temperature = 0.0_real64
    if (self%adaptive) then
      call adaptive_step(self, ok, failure)
    else if (self%t + (1.0_real64 + landing_slack)*dt >= landing_time(self)) then
      call step_or_halve(self, landing_time(self) - self%t, .true., 0, ok, failure)
    else
      call step_or_halve(self, dt, .false., 0, ok, failure)
    end if
    report%chose_time = .true.
    report%time = self%t
    report%solves = self%attempts
    report%rejected = self%rejections
    report%newton_iterations = self%newton_iterations
    report%halvings = self%halvings
    report%rejected_steps = self%rejections
    report%diagnostics = [self%last_gamma, real(self%rejections, real64), real(self%halvings, real64), &
                          self%entropy_production, real(self%gamma_rejections, real64)]
    if (self%tableau%implicit) then
      report%residual_norm = self%solver%last_residual_norm
      report%converged_reason = self%solver%last_reason
    end if
    if (failure%failed()) return
    if (.not. ok) then
      report%reason = self%last_failure
      return
    end if
    n = size(self%z)
    call self%model%convert_state(self%z, self%user_model, x_new(1:n), stat)
    if (stat == failure_none) call self%user_model%observe(x_new(1:n), energy, entropy, report%scheme_temperature, stat)
    ! The multipliers: the index-1 lambda at the new state; a heat bath's mean power over the step.
    if (stat == failure_none .and. size(self%constraints) > 0) &
      call constrained_field(self%model, self%constraints, self%z, f, stat, multipliers=x_new(n + 1:))
    do k = 1, size(self%constraints)
      if (stat /= failure_none .or. .not. self%constraints(k)%item%supplies_heat) cycle
      call self%model%energy_difference(z_start, self%z, energy_change, stat)
      x_new(n + k) = energy_change/(self%t - t_start)
    end do
    report%accepted = stat == failure_none
    if (.not. report%accepted) report%reason = 'the state left the model''s domain'
    self%run_rejections = self%run_rejections + self%rejections
    self%run_halvings = self%run_halvings + self%halvings
  end subroutine advance

  !> A complete run's warning, with its counts and figure, when its accuracy is in doubt: a
  !> fixed-step run without a tolerance that rejected (and halved) a step, or any run whose gamma
  !> moved more than gamma_warning_deviation from 1 (an adaptive run's rejections are its control
  !> at work, as are a fixed-step run's under a tolerance's gamma band); '' otherwise.
  function accuracy_warnings(self) result(text)
    class(relaxed_runge_kutta), intent(in) :: self
    character(len=:), allocatable :: text
    logical :: uncontrolled

    text = ''
    uncontrolled = .not. (self%adaptive .or. self%gamma_band < huge(1.0_real64))
    if (uncontrolled .and. self%run_rejections > 0) &
      text = integer_text(self%run_rejections)//' trial steps rejected ('//integer_text(self%run_halvings)// &
             ' halved)'
    if (self%max_gamma_deviation > gamma_warning_deviation) then
      if (len(text) > 0) text = text//' and '
      text = text//'|gamma - 1| up to '//fixed_text(self%max_gamma_deviation, 3)//' (over '// &
             fixed_text(gamma_warning_deviation, 1)//')'
    end if
    if (len(text) == 0) return
    if (self%adaptive .or. .not. uncontrolled) then
      text = text//': the steps of '//trim(self%scheme)//' at this tolerance are long for its accuracy (E, the '// &
             'momenta and dS >= 0 hold all the same); a smaller &integrator tolerance is the remedy (docs/integrators.md)'
    else
      text = text//': dt = '//reals_text([self%dt])//' s is too long for '//trim(self%scheme)// &
             '''s accuracy, which nothing controlled (E, the momenta and dS >= 0 hold all the same); '// &
             '&integrator tolerance is the remedy (docs/integrators.md)'
    end if
  end function accuracy_warnings

  !> Frees the stage solver's PETSc objects.
  subroutine release(self, failure)
    class(relaxed_runge_kutta), intent(inout) :: self
    type(failure_type), intent(out) :: failure

    if (self%solver%created) call self%solver%destroy(failure)
  end subroutine release

  ! Undoes the last committed step (the adaptive method's error test refused it).
  subroutine restore(self)
    class(relaxed_runge_kutta), intent(inout) :: self

    self%z = self%z_saved
    self%t = self%t_saved
    self%last_gamma = self%gamma_saved
    self%entropy_production = self%production_saved
    self%max_gamma_deviation = self%deviation_saved
  end subroutine restore

  !> What a step leaves for the next (a continued run restores it, bit for bit): the time, the
  !> adaptive method's next trial step, the state in entropy variables (the run's file holds it in
  !> the run's own variable, which converts back only to rounding), for implicit stages the
  !> last step's stage derivatives (the next predictor), the record behind the accuracy warnings,
  !> and the stage solver's LU factors (its chord refinement). Layout: t, h_next, n, z(1:n), m,
  !> last_stages(1:m) (m = 0: none), run_rejections, run_halvings, max_gamma_deviation, then the
  !> factors as lu_factors' as_values.
  subroutine resume_state(self, values)
    class(relaxed_runge_kutta), intent(in) :: self
    real(real64), allocatable, intent(inout) :: values(:)
    integer :: n, m, count

    ! Kept from call to call (a record is noted after every row): nothing is allocated per step.
    n = size(self%z)
    m = 0
    if (allocated(self%last_stages)) m = size(self%last_stages)
    count = 7 + n + m + 2
    if (self%tableau%implicit) count = 7 + n + m + self%solver%context%lu%value_count()
    if (allocated(values)) then
      if (size(values) /= count) deallocate (values)
    end if
    if (.not. allocated(values)) allocate (values(count))
    values(1:3) = [self%t, self%h_next, real(n, real64)]
    values(4:3 + n) = self%z
    values(4 + n) = real(m, real64)
    if (m > 0) values(5 + n:4 + n + m) = self%last_stages
    values(5 + n + m:7 + n + m) = [real(self%run_rejections, real64), real(self%run_halvings, real64), &
                                   self%max_gamma_deviation]
    values(8 + n + m:) = 0.0_real64
    if (self%tableau%implicit) call self%solver%context%lu%put_values(values(8 + n + m:))
  end subroutine resume_state

  !> Takes back what resume_state gave (after `start`); a failure (failure_mismatch) if `values`
  !> do not fit its layout for this run's state.
  subroutine restore_state(self, values, x, x_previous, failure)
    class(relaxed_runge_kutta), intent(inout) :: self
    real(real64), intent(in) :: values(:), x(:), x_previous(:)
    type(failure_type), intent(out) :: failure
    integer :: n, m, solver_order
    logical :: ok

    call fail(failure, failure_mismatch, 'the stored integrator state does not fit the relaxed scheme''s layout', &
              'relaxed_runge_kutta%restore_state')
    n = size(self%z)
    if (size(values) < 4 + n) return
    if (nint(values(3)) /= n) return
    m = nint(values(4 + n))
    if (m /= 0 .and. m /= n*self%tableau%stages) return
    if (size(values) < 7 + n + m) return
    solver_order = 0
    if (self%tableau%implicit) solver_order = self%solver%n
    call self%solver%context%lu%from_values(values(8 + n + m:), solver_order, ok)
    if (.not. ok) return
    self%t = values(1)
    self%h_next = values(2)
    self%z = values(4:3 + n)
    if (allocated(self%last_stages)) deallocate (self%last_stages)
    if (m > 0) self%last_stages = values(5 + n:4 + n + m)
    self%run_rejections = nint(values(5 + n + m))
    self%run_halvings = nint(values(6 + n + m))
    self%max_gamma_deviation = values(7 + n + m)
    failure = failure_type()
  end subroutine restore_state

end module relaxed_stepper
