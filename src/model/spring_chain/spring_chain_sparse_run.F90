!> The chain on the sparse, distributed path as a model split over ranks (src/model/
!> distributed_model; spring_chain_dmda does the work): the scene's chain and initial state, steps
!> of EME (the input's discrete gradient and metric) or of the midpoint rule, the balances'
!> figures summed over the ranks, and the rank's part of the state for a snapshot. The PETSc TS
!> integrators extend it (spring_chain_ts_run), as do the relaxed Runge-Kutta schemes
!> (spring_chain_relaxed_run). What the path cannot run (another integrator, a model other than
!> the chain) is refused with the reason. A step here is one Newton solve of the step; eme_run's
!> halving of fixed steps and its adaptive steps (&integrator tolerance) are
!> src/integrator/distributed_step_control's, over this system's rows and field. chain_bench's
!> bookkeeping (`advance`, `result`) rides on the same steps.
module spring_chain_sparse_run
#include <petsc/finclude/petscsnes.h>
  use petscsnes
  use, intrinsic :: iso_fortran_env, only: real64
  use failures, only: failure_type, fail, failure_input, failure_not_converged, failure_io
  use number_text, only: integer_text, scientific_text
  use model_interface, only: generic_model
  use solver_description, only: solver_report, add_setting, text_setting, number_setting, set_petsc_reasons, &
                                reasons_snes
  use distributed_model, only: distributed_system, distributed_settings, distributed_step, distributed_figures, &
                               distributed_part
  use spring_chain_model, only: spring_chain
  use spring_chain_step, only: chain_step_problem
  use spring_chain_partials, only: partials_discrete_gradient, partials_midpoint, partials_exact
  use spring_chain_dmda, only: distributed_chain, stencil_width
  use spring_chain_linear_solver, only: settings_in_code
  use snes_description, only: describe_snes
  implicit none
  private
  public :: sparse_chain_run, sparse_run_result, chain_problem_of, ts_schemes, step_schemes, chain_snes_report

  !> The integrators whose steps are this module's (one SNES solve a step).
  character(len=*), parameter :: step_schemes(2) = [character(len=8) :: 'eme', 'midpoint']

  !> The PETSc TS integrators (src/integrator/ts_stepper's registry names) that run the chain's
  !> field split over ranks (spring_chain_ts_run).
  character(len=*), parameter :: ts_schemes(4) = [character(len=11) :: 'ts_midpoint', 'ts_bdf2', 'ts_rk4', 'ts_rk5dp']

  !> What a run did, the same on every rank but the times (each rank's own).
  type :: sparse_run_result
    integer :: springs = 0
    integer :: unknowns = 0
    integer :: ranks = 1
    integer :: steps = 0                                !! accepted steps
    integer :: newton_iterations = 0                    !! over the run
    integer :: max_newton_iterations = 0                !! in one step
    real(real64) :: energy_0 = 0.0_real64, energy = 0.0_real64
    real(real64) :: entropy_0 = 0.0_real64, entropy = 0.0_real64
    real(real64) :: max_energy_error = 0.0_real64       !! max over steps of |E_{n+1} - E_n|/|E_n|
    real(real64) :: min_entropy_increment = huge(1.0_real64)
    real(real64) :: loop_cpu_seconds = 0.0_real64       !! this rank's CPU time in the time loop
    real(real64) :: loop_wall_seconds = 0.0_real64
  end type sparse_run_result

  !> The chain split over ranks: start, then step (or chain_bench's advance) step by step, finish.
  !> Do not copy it after `start`: PETSc holds the address of its chain's context.
  type, extends(distributed_system) :: sparse_chain_run
    type(distributed_settings) :: settings
    type(distributed_chain) :: chain
    type(sparse_run_result) :: result
  contains
    procedure :: start
    procedure :: set_up
    procedure :: step
    procedure :: tighten_linear_solves
    procedure :: figures
    procedure :: part
    procedure :: restore
    procedure :: state_rows
    procedure :: set_state_rows
    procedure :: field_rows
    procedure :: advance
    procedure :: dump
    procedure :: finish
    procedure :: describe_solver
  end type sparse_chain_run

contains

  !> The chain's step problem (without an old state) for the input's integrator, or a refusal.
  subroutine chain_problem_of(settings, model, problem, failure)
    type(distributed_settings), intent(in) :: settings
    class(generic_model), intent(in) :: model
    type(chain_step_problem), intent(out) :: problem
    type(failure_type), intent(out) :: failure

    select type (model)
    type is (spring_chain)
      problem%layout = model%layout
      problem%springs = model%springs
      problem%masses = model%masses
      problem%conductivity = model%conductivity
      problem%gravity = model%gravity
    class default
      call fail(failure, failure_input, settings%input_file//', &model: model_name: the sparse, distributed path '// &
                'runs the spring chain only; allowed: ''spring_chain''', 'model_name')
      return
    end select
    select case (settings%scheme)
    case ('eme')
      problem%rule = partials_discrete_gradient
    case ('midpoint')
      problem%rule = partials_midpoint
    case default
      ! A relaxed Runge-Kutta tableau (spring_chain_relaxed_run, explicit or implicit) or PETSc TS.
      if (settings%tableau%stages == 0 .and. .not. any(settings%scheme == ts_schemes)) then
        call fail(failure, failure_input, settings%input_file//', &integrator: scheme: the chain''s sparse, distributed '// &
                  'path has no '''//trim(settings%scheme)//''' (its steps need the whole state on one '// &
                  'process); allowed: ''eme'', ''midpoint'', the relaxed schemes (relaxed_rk4, '// &
                  'relaxed_rk8, relaxed_dp853, relaxed_gauss6) and the PETSc TS integrators ''ts_midpoint'', ''ts_bdf2'', ''ts_rk4'', ''ts_rk5dp''', &
                  'scheme')
        return
      end if
      ! PETSc TS and the relaxed stages integrate the field at the exact partials; ts_rk5dp's
      ! tolerance is its own, a relaxed scheme's bounds its gamma.
      problem%rule = partials_exact
    end select
    problem%gradient = settings%discrete_gradient
    problem%metric = settings%metric
  end subroutine chain_problem_of

  !> Sets up `model` (a chain) from z0 on `comm` as `settings` say: the DMDA, the state, E_0, S_0
  !> and the steps' SNES.
  subroutine start(self, settings, model, z0, comm, failure)
    class(sparse_chain_run), intent(inout), target :: self
    type(distributed_settings), intent(in) :: settings
    class(generic_model), intent(in) :: model
    real(real64), intent(in) :: z0(:)
    integer, intent(in) :: comm
    type(failure_type), intent(out) :: failure

    ! (a PETSc TS integrator's steps are spring_chain_ts_run's, which the scene gives for it)
    if (any(settings%scheme == ts_schemes)) then
      call fail(failure, failure_input, settings%input_file//', &integrator: scheme: '''//trim(settings%scheme)// &
                ''' runs through eme_run (PETSc TS), not these steps; allowed: ''eme'', ''midpoint''', 'scheme')
      return
    end if
    call self%set_up(settings, model, z0, comm, failure)
    if (.not. failure%failed()) call self%chain%create_snes(settings%newton_tol, settings%newton_max_iterations, failure)
  end subroutine start

  !> `start` but the steps' solver: the DMDA, the state, E_0, S_0 (a refusal for what the path
  !> cannot run).
  subroutine set_up(self, settings, model, z0, comm, failure)
    class(sparse_chain_run), intent(inout), target :: self
    type(distributed_settings), intent(in) :: settings
    class(generic_model), intent(in) :: model
    real(real64), intent(in) :: z0(:)
    integer, intent(in) :: comm
    type(failure_type), intent(out) :: failure
    type(chain_step_problem) :: problem
    real(real64) :: delta_energy, delta_entropy
    integer :: ierr
    PetscMPIInt :: ranks

    self%settings = settings
    call chain_problem_of(settings, model, problem, failure)
    if (failure%failed()) return
    call MPI_Comm_size(comm, ranks, ierr)
    ! (every rank refuses alike: one rank's PETSc error at a partition too fine left the others
    ! waiting in DMSetUp for ever)
    if (problem%layout%points() < stencil_width*ranks) then
      call fail(failure, failure_input, settings%input_file//', &model: links: a chain split over '// &
                integer_text(int(ranks))//' ranks needs at least '//integer_text(stencil_width)//' points a rank ('// &
                integer_text(stencil_width*int(ranks))//'); this one has '//integer_text(problem%layout%points())// &
                ' (one a mass, and a fixed-fixed chain''s last spring one more): more links or fewer ranks', 'links')
      return
    end if
    self%result%ranks = ranks
    self%result%springs = problem%layout%springs
    self%result%unknowns = problem%layout%state_size()
    call self%chain%create(problem, comm, failure)
    if (.not. failure%failed()) call self%chain%set_state(z0, failure)
    if (.not. failure%failed()) call self%chain%sums(self%result%energy_0, self%result%entropy_0, delta_energy, &
                                                     delta_entropy, failure)
    self%result%energy = self%result%energy_0
    self%result%entropy = self%result%entropy_0
  end subroutine set_up

  !> Step n: the step, its balances summed over the ranks, and the run's figures (the loop's CPU
  !> and wall time count these alone). A step Newton does not converge is a failure.
  subroutine advance(self, n, dt, failure)
    class(sparse_chain_run), intent(inout) :: self
    integer, intent(in) :: n
    real(real64), intent(in) :: dt
    type(failure_type), intent(out) :: failure
    type(distributed_step) :: outcome
    real(real64) :: delta_energy, delta_entropy, energy_before, cpu_start, cpu_end, wall_start

    associate (result => self%result)
      wall_start = MPI_Wtime()
      call cpu_time(cpu_start)
      energy_before = result%energy
      call self%step(dt, outcome, failure)
      if (.not. failure%failed() .and. .not. outcome%converged) &
        call fail(failure, failure_not_converged, 'step '//integer_text(n)//': Newton did not converge (SNES reason '// &
                  integer_text(outcome%reason)//', |R| = '//scientific_text(outcome%residual_norm, 3)//')')
      if (.not. failure%failed()) call self%chain%sums(result%energy, result%entropy, delta_energy, delta_entropy, failure)
      call cpu_time(cpu_end)
      result%loop_cpu_seconds = result%loop_cpu_seconds + (cpu_end - cpu_start)
      result%loop_wall_seconds = result%loop_wall_seconds + (MPI_Wtime() - wall_start)
      if (failure%failed()) return
      result%steps = n
      result%newton_iterations = result%newton_iterations + outcome%iterations
      result%max_newton_iterations = max(result%max_newton_iterations, outcome%iterations)
      result%max_energy_error = max(result%max_energy_error, abs(delta_energy)/abs(energy_before))
      result%min_entropy_increment = min(result%min_entropy_increment, delta_entropy)
    end associate
  end subroutine advance

  !> One step of size dt (distributed_system).
  subroutine step(self, dt, outcome, failure)
    class(sparse_chain_run), intent(inout) :: self
    real(real64), intent(in) :: dt
    type(distributed_step), intent(out) :: outcome
    type(failure_type), intent(out) :: failure

    call self%chain%step(dt, outcome, failure)
  end subroutine step

  !> The steps' linear solves without their rounding floor while `on` (distributed_system),
  !> where the chain's default set one (several ranks: spring_chain_dmda).
  subroutine tighten_linear_solves(self, on, available, failure)
    class(sparse_chain_run), intent(inout) :: self
    logical, intent(in) :: on
    logical, intent(out) :: available
    type(failure_type), intent(out) :: failure

    call self%chain%linear_floor_in_use(available, failure)
    if (available) self%chain%tight = on
  end subroutine tighten_linear_solves

  !> The figures of the state and the last step, summed over the ranks (distributed_system).
  subroutine figures(self, values, failure)
    class(sparse_chain_run), intent(inout) :: self
    type(distributed_figures), intent(out) :: values
    type(failure_type), intent(out) :: failure

    call self%chain%figures(values, failure)
  end subroutine figures

  !> The rank's part of the state for a snapshot (distributed_system).
  subroutine part(self, state, failure)
    class(sparse_chain_run), intent(inout) :: self
    type(distributed_part), intent(out) :: state
    type(failure_type), intent(out) :: failure

    call self%chain%state_part(state%positions, state%momenta, state%gamma, state%tau, state%theta, failure)
    associate (layout => self%chain%context%problem%layout)
      state%masses = layout%masses
      state%springs = layout%springs
      state%dimension = layout%dimension
      state%first_mass = self%chain%first_point
      state%first_spring = self%chain%first_point
      state%spring_count = max(0, min(layout%springs, self%chain%last_point) - self%chain%first_point + 1)
    end associate
  end subroutine part

  !> Makes the rank's part `state` (as `part` gives it) the current state (distributed_system).
  subroutine restore(self, state, failure)
    class(sparse_chain_run), intent(inout) :: self
    type(distributed_part), intent(in) :: state
    type(failure_type), intent(out) :: failure

    call self%chain%set_part(state%positions, state%momenta, state%gamma, state%tau, failure)
  end subroutine restore

  !> The rank's rows of the state (distributed_system).
  subroutine state_rows(self, z, failure)
    class(sparse_chain_run), intent(inout) :: self
    real(real64), allocatable, intent(out) :: z(:)
    type(failure_type), intent(out) :: failure
    integer :: first

    call self%chain%owned_state(z, first, failure)
  end subroutine state_rows

  !> The state from the rank's rows z, its step's old state from z_old (distributed_system).
  subroutine set_state_rows(self, z, z_old, failure)
    class(sparse_chain_run), intent(inout) :: self
    real(real64), intent(in) :: z(:), z_old(:)
    type(failure_type), intent(out) :: failure

    call self%chain%set_rows(z, z_old, failure)
  end subroutine set_state_rows

  !> The rank's rows of the chain's continuous field at the state of rows z (distributed_system).
  subroutine field_rows(self, z, f, stat, failure)
    class(sparse_chain_run), intent(inout) :: self
    real(real64), intent(in) :: z(:)
    real(real64), intent(out) :: f(:)
    integer, intent(out) :: stat
    type(failure_type), intent(out) :: failure

    call self%chain%field_of(z, f, stat, failure)
  end subroutine field_rows

  !> The steps' SNES as the run file records it (distributed_system).
  function describe_solver(self) result(report)
    class(sparse_chain_run), intent(in) :: self
    type(solver_report) :: report

    report = chain_snes_report(self%chain%snes, 'PETSc SNES on a DMDA split over the ranks: Newton, sparse '// &
                               'Jacobian, LU (GMRES on block-Jacobi LU on several ranks) unless the options choose '// &
                               'a KSP', self%settings%newton_tol, 'eps |z|, z the state the step starts from')
  end function describe_solver

  !> What a run file records of a chain's SNES `snes` (a step's, or the implicit stages'): `name`,
  !> Newton's tolerance, the SNES and its linear solver as the options left them
  !> (src/solver/snes_description) with what spring_chain_linear_solver set in code, `floor_rule`
  !> for the linear solves' absolute tolerance where that module sets it, and PETSc's names of the
  !> converged reasons.
  function chain_snes_report(snes, name, newton_tol, floor_rule) result(report)
    SNES, intent(in) :: snes
    character(len=*), intent(in) :: name, floor_rule
    real(real64), intent(in) :: newton_tol
    type(solver_report) :: report
    type(failure_type) :: ignored
    character(len=:), allocatable :: ordering
    logical :: floor_set
    KSP :: ksp
    PetscErrorCode :: ierr

    call add_setting(report, text_setting('name', name))
    call add_setting(report, number_setting('newton_tol', newton_tol, '1'))
    call add_setting(report, text_setting('snes_convergence_test', '|R| <= min(newton_tol, snes_atol) after an update '// &
                                          'of at most that, or an update below the rounding of the state (16 eps |z|)'))
    call SNESGetKSP(snes, ksp, ierr)
    if (ierr == 0) call settings_in_code(ksp, ordering, floor_set, ierr)
    if (ierr == 0 .and. floor_set) then
      call describe_snes(snes, report, ierr, ordering, floor_rule)
    else if (ierr == 0) then
      call describe_snes(snes, report, ierr, ordering)
    end if
    if (ierr /= 0) call add_setting(report, text_setting('error', 'PETSc could not describe the SNES'))
    call set_petsc_reasons(report, reasons_snes, ignored)
  end function chain_snes_report

  !> Each rank's rows of the state to PREFIX.<rank> ("index value" lines, 1-based).
  subroutine dump(self, prefix, failure)
    class(sparse_chain_run), intent(inout) :: self
    character(len=*), intent(in) :: prefix
    type(failure_type), intent(inout) :: failure

    if (.not. failure%failed()) call dump_rows(self%chain, prefix, failure)
  end subroutine dump

  !> Frees the PETSc objects; failure keeps the first failure.
  subroutine finish(self, failure)
    class(sparse_chain_run), intent(inout) :: self
    type(failure_type), intent(inout) :: failure
    type(failure_type) :: freeing

    call self%chain%destroy(freeing)
    if (.not. failure%failed() .and. freeing%failed()) failure = freeing
  end subroutine finish

  ! Each rank's rows of the state to PREFIX.<rank>, one "index value" line per unknown.
  subroutine dump_rows(chain, prefix, failure)
    type(distributed_chain), intent(inout) :: chain
    character(len=*), intent(in) :: prefix
    type(failure_type), intent(inout) :: failure
    real(real64), allocatable :: z(:)
    integer :: first, unit, stat, k, rank, ierr
    MPI_Comm :: comm

    call chain%owned_state(z, first, failure)
    if (failure%failed()) return
    call PetscObjectGetComm(chain%context%da, comm, ierr)
    call MPI_Comm_rank(comm, rank, ierr)
    open (newunit=unit, file=prefix//'.'//integer_text(rank), status='replace', action='write', iostat=stat)
    if (stat == 0) write (unit, '(i0, 1x, es25.17e3)', iostat=stat) (first + k - 1, z(k), k=1, size(z))
    if (stat == 0) close (unit, iostat=stat)
    if (stat /= 0) call fail(failure, failure_io, 'cannot write '''//prefix//'.'//integer_text(rank)//'''')
  end subroutine dump_rows

end module spring_chain_sparse_run
