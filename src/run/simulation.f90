!> One run from a validated configuration to its HDF5 file: the time loop shared by eme_run and
!> eme_ensemble. The model and its initial state come from the configuration's scene, the
!> integrator from the registry; the loop advances it one output step at a time and records
!> every point and step (src/run/run_output). A step that cannot be solved ends the run cleanly:
!> every step before it stays in the file, whose `status` attribute then reads
!> 'incomplete: <reason>'.
module simulation
  use, intrinsic :: iso_fortran_env, only: real64, int64
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
  use model_interface, only: generic_model
  use model_constraint, only: constraint_slot
  use integrator_settings, only: step_count
  use integrator_registry, only: integrator_entry, find_integrator
  use stepper, only: time_stepper, step_report
  use run_config, only: run_configuration
  use run_output, only: run_file
  use filesystem, only: make_parent_directories
  use number_text, only: integer_text, fixed_text
  implicit none (type, external)
  private
  public :: run_summary, run_simulation, run_observer

  !> The figures a run is judged by, as the summary table prints them.
  type :: run_summary
    character(len=:), allocatable :: status       !! 'complete' or 'incomplete: <reason>'
    integer :: steps_planned = 0
    integer :: steps_completed = 0
    integer :: newton_iterations = 0
    real(real64) :: energy_drift = 0.0_real64            !! max_n |E_n - E_0 - Q_n| / |E_0|, Q: boundary heat
    real(real64) :: min_entropy_increment = huge(1.0_real64)    !! NaN without a completed step
    real(real64) :: max_lyapunov_increment = -huge(1.0_real64)  !! NaN without a completed step
    real(real64) :: angular_momentum_drift = 0.0_real64  !! max_n |J_z,n - J_z,0|
    real(real64) :: wall_seconds = 0.0_real64             !! the whole run, file set-up and closing included
    real(real64) :: solve_seconds = 0.0_real64            !! the time loop alone
  end type run_summary

  !> Something that wants control after every accepted step (the ensemble's scheduler serves
  !> other ranks from there while rank 0 computes a case).
  type, abstract :: run_observer
  contains
    procedure(after_step_interface), deferred :: after_step
  end type run_observer

  abstract interface
    !> Called after each accepted step.
    subroutine after_step_interface(self)
      import :: run_observer
      class(run_observer), intent(inout) :: self
    end subroutine after_step_interface
  end interface

contains

  !> Runs `config` and writes its HDF5 file. stat /= 0 only if the file could not be written
  !> or a library failed; a run that stops early is reported through summary%status.
  !> With `reusable`, the caller's integrator is used when it is of the configured kind (an
  !> ensemble rank keeps its PETSc objects from case to case), replaced otherwise, and left for
  !> the next run; without, the run builds and frees its own.
  subroutine run_simulation(config, summary, stat, message, observer, reusable)
    type(run_configuration), intent(in) :: config
    type(run_summary), intent(out) :: summary
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: message
    class(run_observer), intent(inout), optional :: observer
    class(time_stepper), allocatable, intent(inout), target, optional :: reusable
    class(time_stepper), allocatable, target :: own
    class(time_stepper), pointer :: integrator
    class(generic_model), allocatable :: model
    type(constraint_slot), allocatable :: constraints(:)
    type(integrator_entry) :: entry
    type(step_report) :: report
    type(run_file) :: output
    real(real64), allocatable :: x(:), x_previous(:), x_new(:), z0(:), theta(:), residuals(:)
    real(real64) :: energy, entropy, lyapunov, energy_0, entropy_old, lyapunov_old, jz_0, time, boundary_heat, dt
    real(real64) :: t_end, time_old
    integer(int64) :: clock_start, clock_loop, clock_now, clock_rate
    integer :: n, k, n_state, io_stat, ierr, release_ierr, max_steps
    logical :: found, finished

    call system_clock(clock_start, clock_rate)
    message = ''
    summary%status = 'incomplete: running'
    summary%steps_planned = step_count(config%integrator)
    dt = config%integrator%dt
    t_end = config%integrator%t_end
    call find_integrator(config%integrator%scheme, entry, found)
    call config%scene%build(config%integrator%thermo_variable, model, z0, constraints, stat, message)
    if (stat /= 0) then
      message = config%input_file//': '//message
      return
    end if
    n_state = model%state_size
    ! The unknowns: the state and the multipliers of the active constraints (initial guess 0).
    allocate (x(n_state + size(constraints)), x_previous(n_state + size(constraints)), x_new(n_state + size(constraints)))
    allocate (theta(model%subsystem_count()), residuals(size(constraints)))
    x = 0.0_real64
    x(1:n_state) = z0
    boundary_heat = 0.0_real64

    if (present(reusable)) then
      if (allocated(reusable)) then
        if (reusable%scheme /= entry%name) then
          call reusable%release(ierr)
          deallocate (reusable)
        end if
      end if
      if (.not. allocated(reusable)) call new_integrator(reusable)
      integrator => reusable
    else
      call new_integrator(own)
      integrator => own
    end if
    call make_parent_directories(config%output_file, stat)
    if (stat == 0) call output%create(config, entry, model, constraints, integrator%diagnostics(), summary%steps_planned, &
                                      stat)
    if (stat /= 0) then
      message = 'cannot create the output file '''//config%output_file//''' (&output: file)'
      return
    end if
    call integrator%start(config%integrator, model, constraints, z0, ierr)
    if (ierr /= 0) then
      stat = ierr
      message = 'PETSc failed to set up the solver'
      if (.not. present(reusable)) call integrator%release(release_ierr)
      call close_output('incomplete: PETSc failed to set up the solver')
      return
    end if

    call observe(z0, energy, entropy, lyapunov)
    energy_0 = energy
    jz_0 = angular_momentum_z(z0)
    call record_point(0.0_real64, z0)
    x_previous = x
    call system_clock(clock_loop)
    io_stat = 0
    ! Integrators on the output grid take steps_planned steps to n dt; those that choose their
    ! times go on until they reach t_end (the last step lands on it).
    max_steps = max(1000000, 100*summary%steps_planned)
    finished = summary%steps_planned == 0
    time = 0.0_real64
    n = 0
    do while (.not. finished)
      if (n == max_steps) then
        summary%status = 'incomplete: t_end not reached in '//integer_text(max_steps)//' steps'
        exit
      end if
      n = n + 1
      if (.not. entry%chooses_time) time = (n - 1)*dt
      time_old = time
      ! Predictor: linear extrapolation of the last step (the old state on the first step).
      call integrator%advance(x, time, dt, 2*x - x_previous, x_new, report, ierr)
      summary%newton_iterations = summary%newton_iterations + report%newton_iterations
      if (ierr /= 0) then
        stat = ierr
        message = 'PETSc failed during the solve'
        summary%status = 'incomplete: PETSc error in step '//integer_text(n)
        exit
      end if
      if (entry%chooses_time) then
        time = report%time
        finished = time >= t_end
      else
        time = n*dt
        finished = n == summary%steps_planned
      end if
      if (.not. report%accepted) then
        summary%status = 'incomplete: step '//integer_text(n)//' (t = '//fixed_text(time, 4)//' s): '//report%reason
        exit
      end if
      call output%record_step(report, x_new(n_state + 1:), io_stat)
      if (io_stat /= 0) exit
      ! A multiplier is the step's mean rate (lambda_2: heat power), so the heat is rate times the step.
      do k = 1, size(constraints)
        boundary_heat = boundary_heat + (time - time_old)*constraints(k)%item%heat_supply(x_new(n_state + k))
      end do
      entropy_old = entropy
      lyapunov_old = lyapunov
      x_previous = x
      x = x_new
      call observe(x(1:n_state), energy, entropy, lyapunov)
      call record_point(time, x(1:n_state))
      if (io_stat /= 0) exit
      summary%steps_completed = n
      summary%energy_drift = max(summary%energy_drift, abs(energy - energy_0 - boundary_heat)/abs(energy_0))
      summary%min_entropy_increment = min(summary%min_entropy_increment, entropy - entropy_old)
      summary%max_lyapunov_increment = max(summary%max_lyapunov_increment, lyapunov - lyapunov_old)
      summary%angular_momentum_drift = max(summary%angular_momentum_drift, abs(angular_momentum_z(x(1:n_state)) - jz_0))
      if (present(observer)) call observer%after_step()
    end do
    if (summary%steps_completed == 0) then
      summary%min_entropy_increment = ieee_value(1.0_real64, ieee_quiet_nan)
      summary%max_lyapunov_increment = ieee_value(1.0_real64, ieee_quiet_nan)
    end if
    if (io_stat /= 0) then
      stat = io_stat
      message = 'cannot write to '//config%output_file
      summary%status = 'incomplete: cannot write the output file'
    else if (finished .and. summary%steps_completed == n) then
      summary%status = 'complete'
      ! An integrator that chooses its times planned t_end/dt steps; it took n.
      summary%steps_planned = n
    end if
    call system_clock(clock_now)
    summary%solve_seconds = real(clock_now - clock_loop, real64)/real(clock_rate, real64)
    if (.not. present(reusable)) then
      call integrator%release(release_ierr)
      if (release_ierr /= 0 .and. stat == 0) then
        stat = release_ierr
        message = 'PETSc failed to free the solver'
      end if
    end if
    call close_output(summary%status)
    call system_clock(clock_now)
    summary%wall_seconds = real(clock_now - clock_start, real64)/real(clock_rate, real64)

  contains

    subroutine new_integrator(made)
      class(time_stepper), allocatable, intent(out) :: made

      call entry%build(made)
      made%scheme = entry%name
    end subroutine new_integrator

    subroutine observe(z, energy, entropy, lyapunov)
      real(real64), intent(in) :: z(:)
      real(real64), intent(out) :: energy, entropy, lyapunov
      integer :: domain

      call model%observe(z, energy, entropy, theta, domain)
      lyapunov = energy - config%theta_r*entropy
    end subroutine observe

    ! One point: the state with what it is judged by, and the active constraints' g.
    subroutine record_point(time, z)
      real(real64), intent(in) :: time, z(:)
      integer :: k, domain

      do k = 1, size(constraints)
        call constraints(k)%item%value(model, z, residuals(k), domain)
      end do
      call output%record_point(time, z, theta, energy, entropy, lyapunov, model%angular_momentum(z), boundary_heat, &
                               residuals, io_stat)
    end subroutine record_point

    subroutine close_output(status)
      character(len=*), intent(in) :: status
      integer :: close_stat

      call system_clock(clock_now)
      call output%finish(status, summary%steps_planned, summary%steps_completed, summary%solve_seconds, &
                         real(clock_now - clock_start, real64)/real(clock_rate, real64), close_stat)
      if (close_stat /= 0 .and. stat == 0) then
        stat = close_stat
        message = 'cannot write to '//config%output_file
      end if
    end subroutine close_output

    pure function angular_momentum_z(z) result(jz)
      real(real64), intent(in) :: z(:)
      real(real64) :: jz
      real(real64) :: j(3)

      j = model%angular_momentum(z)
      jz = j(3)
    end function angular_momentum_z
  end subroutine run_simulation

end module simulation
