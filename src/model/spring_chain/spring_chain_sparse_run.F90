!> A chain's run on the sparse, distributed path (spring_chain_dmda): the scene's chain and initial
!> state, fixed steps of EME (the input's discrete gradient and metric) or of the midpoint rule,
!> and per step the balances summed over the ranks: E, S, dE and dS as sums of the parts'
!> differences, and Newton's iterations. What the path cannot run (another integrator, adaptive
!> steps, a model other than the chain) is refused with the reason.
module spring_chain_sparse_run
#include <petsc/finclude/petscsys.h>
  use petscsys
  use, intrinsic :: iso_fortran_env, only: real64
  use failures, only: failure_type, fail, failure_input, failure_not_converged, failure_io
  use number_text, only: integer_text, scientific_text
  use model_interface, only: generic_model
  use spring_chain_model, only: spring_chain
  use spring_chain_step, only: chain_step_problem
  use spring_chain_partials, only: partials_discrete_gradient, partials_midpoint
  use spring_chain_dmda, only: distributed_chain, chain_step_outcome
  implicit none
  private
  public :: sparse_chain_run, sparse_run_result, sparse_run_settings, chain_problem_of

  !> What the run is asked to do (the input's &integrator, src/integrator/integrator_settings).
  type :: sparse_run_settings
    character(len=:), allocatable :: input_file      !! named in refusals
    character(len=16) :: scheme = 'eme'
    integer :: discrete_gradient = 1
    integer :: metric = 1
    real(real64) :: dt = 0.0_real64
    integer :: steps = 0
    real(real64) :: newton_tol = 1.0e-8_real64
    integer :: newton_max_iterations = 50
    logical :: tolerance_given = .false.
  end type sparse_run_settings

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

  !> A run on the sparse path in named steps: start, advance step by step, finish (the caller
  !> writes snapshots between steps).
  type :: sparse_chain_run
    type(sparse_run_settings) :: settings
    type(distributed_chain) :: chain
    type(sparse_run_result) :: result
  contains
    procedure :: start
    procedure :: advance
    procedure :: finish
  end type sparse_chain_run

contains

  !> The chain's step problem (without an old state) for the input's integrator, or a refusal.
  subroutine chain_problem_of(settings, model, problem, failure)
    type(sparse_run_settings), intent(in) :: settings
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
      call fail(failure, failure_input, settings%input_file//', &integrator: scheme: the chain''s sparse, distributed '// &
                'path has no '''//trim(settings%scheme)//''' (its steps need the whole state on one '// &
                'process); allowed: ''eme'', ''midpoint''', 'scheme')
      return
    end select
    if (settings%tolerance_given) then
      call fail(failure, failure_input, settings%input_file//', &integrator: tolerance: the chain''s sparse, '// &
                'distributed path takes fixed steps only; allowed: leave it out', 'tolerance')
      return
    end if
    problem%gradient = settings%discrete_gradient
    problem%metric = settings%metric
  end subroutine chain_problem_of

  !> Sets up `model` (a chain) from z0 on `comm` as `settings` say: the DMDA, the state, E_0, S_0.
  subroutine start(self, settings, model, z0, comm, failure)
    class(sparse_chain_run), intent(inout), target :: self
    type(sparse_run_settings), intent(in) :: settings
    class(generic_model), intent(in) :: model
    real(real64), intent(in) :: z0(:)
    MPI_Comm, intent(in) :: comm
    type(failure_type), intent(out) :: failure
    type(chain_step_problem) :: problem
    real(real64) :: delta_energy, delta_entropy
    integer :: ierr
    PetscMPIInt :: ranks

    self%settings = settings
    call chain_problem_of(settings, model, problem, failure)
    if (failure%failed()) return
    call MPI_Comm_size(comm, ranks, ierr)
    self%result%ranks = ranks
    self%result%springs = problem%layout%springs
    self%result%unknowns = problem%layout%state_size()
    call self%chain%create(problem, comm, settings%newton_tol, settings%newton_max_iterations, failure)
    if (.not. failure%failed()) call self%chain%set_state(z0, failure)
    if (.not. failure%failed()) call self%chain%sums(self%result%energy_0, self%result%entropy_0, delta_energy, &
                                                     delta_entropy, failure)
    self%result%energy = self%result%energy_0
    self%result%entropy = self%result%entropy_0
  end subroutine start

  !> Step n: the step, its balances summed over the ranks, and the run's figures (the loop's CPU
  !> and wall time count these alone). A step Newton does not converge is a failure.
  subroutine advance(self, n, failure)
    class(sparse_chain_run), intent(inout) :: self
    integer, intent(in) :: n
    type(failure_type), intent(out) :: failure
    type(chain_step_outcome) :: outcome
    real(real64) :: delta_energy, delta_entropy, energy_before, cpu_start, cpu_end, wall_start

    associate (result => self%result)
      wall_start = MPI_Wtime()
      call cpu_time(cpu_start)
      energy_before = result%energy
      call self%chain%step(self%settings%dt, outcome, failure)
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

  !> Ends the run: `dump` names files DUMP.<rank> that receive each rank's rows of the final state
  !> ("index value" lines, 1-based); the PETSc objects are freed. failure keeps the first failure.
  subroutine finish(self, failure, dump)
    class(sparse_chain_run), intent(inout) :: self
    type(failure_type), intent(inout) :: failure
    character(len=*), intent(in), optional :: dump
    type(failure_type) :: freeing

    if (present(dump) .and. .not. failure%failed()) call dump_rows(self%chain, dump, failure)
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
