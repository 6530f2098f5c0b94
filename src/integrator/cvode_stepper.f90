!> SUNDIALS CVODE baselines on the continuous GENERIC field f(z) = L grad E + K grad S of any
!> model (docs/formulation.md section 4) with its analytic Jacobian, through src/integrator/cvode_shim.c:
!>   cvode_bdf    variable-order BDF (orders 1-5), Newton on CVODE's dense direct solver with
!>                the analytic Jacobian
!>   cvode_adams  variable-order Adams-Moulton (orders 1-12) with fixed-point iteration, the
!>                nonstiff pairing SUNDIALS recommends
!> Both choose their steps for the &integrator tolerance (relative and absolute, per step) and
!> stop exactly on every output time n dt. A field evaluated outside the model's domain is a
!> recoverable failure: CVODE retries with a smaller step. They take no constraints (the
!> registry says so and the input refuses them).
module cvode_stepper
  use, intrinsic :: iso_fortran_env, only: real64
  use, intrinsic :: iso_c_binding, only: c_int, c_long, c_double, c_char, c_ptr, c_funptr, c_null_ptr, c_null_char, &
                                         c_funloc, c_loc, c_f_pointer, c_associated
  use model_interface, only: generic_model
  use model_constraint, only: constraint_slot
  use integrator_settings, only: integrator_choice
  use stepper, only: time_stepper, step_report, step_diagnostic, solver_report, accept_in_domain
  use solver_description, only: add_setting, text_setting, number_setting
  use number_text, only: fixed_text
  use failures, only: failure_type, fail, fail_on_code, failure_input, failure_mismatch
  implicit none (type, external)
  private
  public :: cvode_baseline, new_cvode_bdf, new_cvode_adams

  !> What the callbacks evaluate.
  type :: field_context
    class(generic_model), allocatable :: model
  end type field_context

  !> One CVODE run. Do not copy it after `start`: CVODE holds the address of `context`.
  type, extends(time_stepper) :: cvode_baseline
    logical :: bdf = .true.
    real(real64) :: tolerance = 0.0_real64   !! CVODE's relative and absolute tolerance
    type(field_context) :: context
    type(c_ptr) :: handle = c_null_ptr
    !> CVODE's cumulative counts at the last output step (eme_cvode_statistics).
    integer(c_long) :: counts(6) = 0
    real(real64) :: time = 0.0_real64          !! the time CVODE's state is at (after the last output step)
    type(c_ptr) :: context_address = c_null_ptr   !! c_loc(context), which CVODE hands the callbacks
  contains
    procedure :: start
    procedure :: advance
    procedure :: release
    procedure :: diagnostics
    procedure :: describe_solver
    procedure :: resume_state
    procedure :: restore_state
    procedure, private :: create
  end type cvode_baseline

  interface
    integer(c_int) function eme_cvode_create(n, bdf, t0, y0, relative, absolute, rhs, jacobian, context, handle) &
      bind(C, name='eme_cvode_create')
      import :: c_int, c_double, c_funptr, c_ptr
      integer(c_int), value, intent(in) :: n, bdf
      real(c_double), value, intent(in) :: t0, relative, absolute
      real(c_double), intent(in) :: y0(*)
      type(c_funptr), value, intent(in) :: rhs, jacobian
      type(c_ptr), value, intent(in) :: context
      type(c_ptr), intent(out) :: handle
    end function eme_cvode_create

    integer(c_int) function eme_cvode_advance(handle, t_out, y, t_reached) bind(C, name='eme_cvode_advance')
      import :: c_int, c_double, c_ptr
      type(c_ptr), value, intent(in) :: handle
      real(c_double), value, intent(in) :: t_out
      real(c_double), intent(out) :: y(*)
      real(c_double), intent(out) :: t_reached
    end function eme_cvode_advance

    integer(c_int) function eme_cvode_statistics(handle, counts, last_order, last_step) &
      bind(C, name='eme_cvode_statistics')
      import :: c_int, c_long, c_double, c_ptr
      type(c_ptr), value, intent(in) :: handle
      integer(c_long), intent(out) :: counts(6)
      integer(c_int), intent(out) :: last_order
      real(c_double), intent(out) :: last_step
    end function eme_cvode_statistics

    subroutine eme_cvode_flag_name(flag, text, length) bind(C, name='eme_cvode_flag_name')
      import :: c_int, c_char
      integer(c_int), value, intent(in) :: flag, length
      character(kind=c_char), intent(out) :: text(*)
    end subroutine eme_cvode_flag_name

    subroutine eme_cvode_free(handle) bind(C, name='eme_cvode_free')
      import :: c_ptr
      type(c_ptr), intent(inout) :: handle
    end subroutine eme_cvode_free
  end interface

contains

  !> Variable-order BDF with Newton and the analytic Jacobian.
  subroutine new_cvode_bdf(integrator)
    class(time_stepper), allocatable, intent(out) :: integrator

    allocate (integrator, source=cvode_baseline(bdf=.true.))
  end subroutine new_cvode_bdf

  !> Variable-order Adams-Moulton with fixed-point iteration.
  subroutine new_cvode_adams(integrator)
    class(time_stepper), allocatable, intent(out) :: integrator

    allocate (integrator, source=cvode_baseline(bdf=.false.))
  end subroutine new_cvode_adams

  !> A new CVODE run of `model` from z0 at t = 0 with the &integrator tolerance as relative and
  !> absolute tolerance; an earlier run's CVODE is freed first. A failure if CVODE cannot be set
  !> up (or for constraints, which the input refuses).
  subroutine start(self, choice, model, constraints, z0, failure)
    class(cvode_baseline), intent(inout), target :: self
    type(integrator_choice), intent(in) :: choice
    class(generic_model), intent(in) :: model
    type(constraint_slot), intent(in) :: constraints(:)
    real(real64), intent(in) :: z0(:)
    type(failure_type), intent(out) :: failure

    call self%release(failure)
    if (allocated(self%context%model)) deallocate (self%context%model)
    allocate (self%context%model, source=model)
    self%tolerance = choice%tolerance
    self%context_address = c_loc(self%context)
    call self%create(0.0_real64, z0, failure)
    if (size(constraints) > 0) call fail(failure, failure_input, 'CVODE takes no constraints', 'cvode_baseline%start')
  end subroutine start

  ! CVODE from state z at time t, without history: its first step is of order 1.
  subroutine create(self, t, z, failure)
    class(cvode_baseline), intent(inout) :: self
    real(real64), intent(in) :: t, z(:)
    type(failure_type), intent(out) :: failure
    integer :: code

    self%counts = 0
    self%time = t
    code = eme_cvode_create(int(size(z), c_int), merge(1_c_int, 0_c_int, self%bdf), t, z, self%tolerance, &
                         self%tolerance, c_funloc(field), c_funloc(field_jacobian), self%context_address, self%handle)
    call fail_on_code(failure, code, 'cvode_baseline%create', 'SUNDIALS could not set CVODE up')
  end subroutine create

  !> A continued run cannot restore CVODE's history (its Nordsieck array and order), only its
  !> time: CVODE starts again from the run's last state, at order 1 with a step of its choice,
  !> and the continued run is correct to its tolerance, not bit for bit (docs/faults.md).
  subroutine resume_state(self, values)
    class(cvode_baseline), intent(in) :: self
    real(real64), allocatable, intent(inout) :: values(:)

    values = [self%time]
  end subroutine resume_state

  !> A new CVODE run from the state x at the time resume_state gave; a failure if `values` are
  !> not resume_state's (failure_mismatch), or CVODE cannot be set up.
  subroutine restore_state(self, values, x, x_previous, failure)
    class(cvode_baseline), intent(inout) :: self
    real(real64), intent(in) :: values(:), x(:), x_previous(:)
    type(failure_type), intent(out) :: failure

    if (size(values) /= 1) then
      call fail(failure, failure_mismatch, 'the stored integrator state is not CVODE''s time', &
                'cvode_baseline%restore_state')
      return
    end if
    call self%release(failure)
    if (failure%failed()) return
    call self%create(values(1), x(1:self%context%model%state_size), failure)
  end subroutine restore_state

  !> Integrates from CVODE's current state to t_old + dt exactly. x_old and guess are not
  !> needed: CVODE carries its state and history from one output step to the next.
  subroutine advance(self, x_old, t_old, dt, guess, x_new, report, failure)
    class(cvode_baseline), intent(inout), target :: self
    real(real64), intent(in) :: x_old(:), t_old, dt, guess(:)
    real(real64), intent(out) :: x_new(:)
    type(step_report), intent(out) :: report
    type(failure_type), intent(out) :: failure
    integer(c_long) :: counts(6)
    integer(c_int) :: flag, last_order
    real(c_double) :: t_reached, last_step
    character(kind=c_char, len=40) :: name

    report%reason = ''
    report%last_rejection = ''
    allocate (report%scheme_temperature(self%context%model%temperature_count()))
    report%scheme_temperature = 0.0_real64
    flag = eme_cvode_advance(self%handle, t_old + dt, x_new, t_reached)
    self%time = t_reached
    report%converged_reason = int(flag)
    call fail_on_code(failure, int(eme_cvode_statistics(self%handle, counts, last_order, last_step)), &
                      'cvode_baseline%advance', 'SUNDIALS could not report CVODE''s statistics')
    if (failure%failed()) return
    report%diagnostics = [real(last_order, real64), last_step, real(counts(2) - self%counts(2), real64)]
    report%solves = int(counts(1) - self%counts(1))
    report%newton_iterations = int(counts(4) - self%counts(4))
    report%rejected = int(sum(counts(5:6)) - sum(self%counts(5:6)))
    self%counts = counts
    if (flag /= 0) then
      call eme_cvode_flag_name(flag, name, len(name, kind=c_int))
      report%reason = 'SUNDIALS CVODE failed at t = '//fixed_text(t_reached, 6)//' s: '//name(1:index(name, c_null_char) - 1)
      return
    end if
    call accept_in_domain(self%context%model, x_new, report)
  end subroutine advance

  !> The per-step figures of CVODE's internal steps.
  function diagnostics(self) result(specs)
    class(cvode_baseline), intent(in) :: self
    type(step_diagnostic), allocatable :: specs(:)

    specs = [step_diagnostic('method_order', '1', 'the order of CVODE''s last internal step in the output step'), &
             step_diagnostic('internal_step', 's', 'the size of CVODE''s last internal step in the output step'), &
             step_diagnostic('field_evaluations', '1', 'right-hand side evaluations in the output step', 'sum')]
  end function diagnostics

  !> CVODE's method, nonlinear and linear solvers and tolerances as given to it (CVODE reads no
  !> command-line options), and CVODE's names of the flags CVode returns (/converged_reason: 0
  !> CV_SUCCESS, negative a failure). CVODE's Newton tests its corrections, not a residual:
  !> /residual_norm is NaN.
  function describe_solver(self) result(report)
    class(cvode_baseline), intent(in) :: self
    type(solver_report) :: report
    character(kind=c_char, len=40) :: name
    integer :: flag

    call add_setting(report, text_setting('name', 'SUNDIALS CVODE'))
    if (self%bdf) then
      call add_setting(report, text_setting('cvode_method', 'BDF, orders 1-5'))
      call add_setting(report, text_setting('cvode_nonlinear_solver', 'Newton, dense direct linear solver with the '// &
                                            'analytic Jacobian'))
    else
      call add_setting(report, text_setting('cvode_method', 'Adams-Moulton, orders 1-12'))
      call add_setting(report, text_setting('cvode_nonlinear_solver', 'fixed-point iteration'))
    end if
    call add_setting(report, number_setting('cvode_rtol', self%tolerance))
    call add_setting(report, number_setting('cvode_atol', self%tolerance))
    allocate (report%reason_codes(0), report%reason_names(0))
    do flag = -40, 0
      call eme_cvode_flag_name(int(flag, c_int), name, len(name, kind=c_int))
      name = name(1:index(name, c_null_char) - 1)
      if (name == 'NONE' .or. name == 'unknown flag') cycle
      report%reason_codes = [report%reason_codes, flag]
      report%reason_names = [character(len=40) :: report%reason_names, name]
    end do
  end function describe_solver

  !> Frees CVODE's memory.
  subroutine release(self, failure)
    class(cvode_baseline), intent(inout) :: self
    type(failure_type), intent(out) :: failure

    if (c_associated(self%handle)) call eme_cvode_free(self%handle)
  end subroutine release

  ! CVODE callback: f = f(y); 1 (recoverable) outside the model's domain.
  integer(c_int) function field(t, y, f, context) bind(C)
    real(c_double), value, intent(in) :: t
    real(c_double), intent(in) :: y(*)
    real(c_double), intent(out) :: f(*)
    type(c_ptr), value, intent(in) :: context
    type(field_context), pointer :: run
    integer :: stat

    call c_f_pointer(context, run)
    associate (n => run%model%state_size)
      call run%model%continuous_field(y(1:n), f(1:n), stat)
    end associate
    field = merge(0_c_int, 1_c_int, stat == 0)
  end function field

  ! CVODE callback: the column-major df/dy at y; 1 (recoverable) outside the domain.
  integer(c_int) function field_jacobian(t, y, jacobian, context) bind(C)
    real(c_double), value, intent(in) :: t
    real(c_double), intent(in) :: y(*)
    real(c_double), intent(out) :: jacobian(*)
    type(c_ptr), value, intent(in) :: context
    type(field_context), pointer :: run
    integer :: stat, j

    call c_f_pointer(context, run)
    associate (n => run%model%state_size)
      block
        real(real64) :: f(n)
        real(real64), allocatable :: df_dz(:, :)    ! n x n: allocated (8 MB at 1000 unknowns)

        allocate (df_dz(n, n))
        call run%model%continuous_field(y(1:n), f, stat, df_dz)
        do j = 1, n
          jacobian((j - 1)*n + 1:j*n) = df_dz(:, j)
        end do
      end block
    end associate
    field_jacobian = merge(0_c_int, 1_c_int, stat == 0)
  end function field_jacobian

end module cvode_stepper
