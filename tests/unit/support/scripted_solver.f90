!> Test doubles for tests/unit/test_retry_strategies: a one-unknown problem with known roots and
!> a root finder that follows a script instead of solving, and records what it was asked.
module scripted_solver
  use, intrinsic :: iso_fortran_env, only: real64
  use nonlinear_problem, only: nonlinear_system
  use retry_strategies, only: root_finder
  use failures, only: failure_type
  implicit none (type, external)
  private
  public :: line_problem, scripted_finder

  !> R(x) = x - s target: one unknown, root s target; roots above `limit` are unphysical.
  type, extends(nonlinear_system) :: line_problem
    real(real64) :: target = 1.0_real64
    real(real64) :: limit = huge(1.0_real64)
    real(real64) :: s = 1.0_real64
  contains
    procedure :: unknowns => line_unknowns
    procedure :: evaluate => line_evaluate
    procedure :: check_root => line_check_root
    procedure :: set_continuation => line_set_continuation
  end type line_problem

  !> Converges only from starts within `reach` of the root, and records every solve's start
  !> and continuation parameter; `lands_at`, if set, is where it converges instead of the root.
  type, extends(root_finder) :: scripted_finder
    real(real64) :: reach = huge(1.0_real64)
    real(real64) :: lands_at = -huge(1.0_real64)
    logical :: fallback = .false.
    logical :: converge_only_with_fallback = .false.
    integer :: solves = 0
    real(real64) :: starts(200) = 0.0_real64
    real(real64) :: fractions(200) = 0.0_real64
    logical :: with_fallback(200) = .false.
    integer :: refinements = 0
  contains
    procedure :: solve => scripted_solve
    procedure :: refine => scripted_refine
    procedure :: use_fallback => scripted_use_fallback
  end type scripted_finder

contains

  pure integer function line_unknowns(self)
    class(line_problem), intent(in) :: self

    line_unknowns = 1 + 0*int(self%s)
  end function line_unknowns

  pure subroutine line_evaluate(self, x, residual, jacobian, stat)
    class(line_problem), intent(in) :: self
    real(real64), intent(in) :: x(:)
    real(real64), intent(out) :: residual(:)
    real(real64), intent(out), optional :: jacobian(:, :)
    integer, intent(out) :: stat

    residual = x - self%s*self%target
    if (present(jacobian)) jacobian = 1.0_real64
    stat = 0
  end subroutine line_evaluate

  pure subroutine line_check_root(self, x, problem_text)
    class(line_problem), intent(in) :: self
    real(real64), intent(in) :: x(:)
    character(len=:), allocatable, intent(out) :: problem_text

    problem_text = ''
    if (x(1) > self%limit) problem_text = 'above the limit'
  end subroutine line_check_root

  pure subroutine line_set_continuation(self, s)
    class(line_problem), intent(inout) :: self
    real(real64), intent(in) :: s

    self%s = s
  end subroutine line_set_continuation

  subroutine scripted_solve(self, problem, initial, root, converged, reason, iterations, failure)
    class(scripted_finder), intent(inout) :: self
    class(nonlinear_system), intent(inout), target :: problem
    real(real64), intent(in) :: initial(:)
    real(real64), intent(out) :: root(:)
    logical, intent(out) :: converged
    character(len=:), allocatable, intent(out) :: reason
    integer, intent(out) :: iterations
    type(failure_type), intent(out) :: failure
    real(real64) :: residual(size(initial))
    integer :: stat

    iterations = 3
    self%solves = self%solves + 1
    self%starts(self%solves) = initial(1)
    self%with_fallback(self%solves) = self%fallback
    call problem%evaluate(initial, residual, stat=stat)
    select type (problem)
    type is (line_problem)
      self%fractions(self%solves) = problem%s
    end select
    converged = abs(residual(1)) <= self%reach .and. (self%fallback .or. .not. self%converge_only_with_fallback)
    root = initial - residual
    if (self%lands_at > -huge(1.0_real64)) then
      converged = .true.
      root = self%lands_at
    end if
    reason = ''
    if (.not. converged) reason = 'Newton did not converge: out of reach'
  end subroutine scripted_solve

  subroutine scripted_refine(self, problem, x)
    class(scripted_finder), intent(inout) :: self
    class(nonlinear_system), intent(inout) :: problem
    real(real64), intent(inout) :: x(:)
    real(real64) :: residual(size(x))
    integer :: stat

    self%refinements = self%refinements + 1
    call problem%evaluate(x, residual, stat=stat)
    x = x - 0.5_real64*residual       ! half a Newton step: visible in the solve's start
  end subroutine scripted_refine

  subroutine scripted_use_fallback(self, on, failure)
    class(scripted_finder), intent(inout) :: self
    logical, intent(in) :: on
    type(failure_type), intent(out) :: failure

    self%fallback = on

  end subroutine scripted_use_fallback

end module scripted_solver
