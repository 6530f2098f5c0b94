!> mpirun -n P chain_bench FILE.nml [-chain_steps K] [-chain_dump PREFIX] [-chain_snapshots FILE.h5
!> [-chain_snapshot_every K]] [PETSc options]: a spring
!> chain (&model model_name = 'spring_chain') run on the sparse, distributed path
!> (src/model/spring_chain/spring_chain_dmda) with the input's fixed-step EME or midpoint rule, for
!> the input's steps or K, writing no run file. Rank 0 prints one line of key=value figures: the
!> size, the steps and Newton iterations, E and S at the start and the end, the largest
!> |E_{n+1} - E_n|/|E_n|, the smallest S_{n+1} - S_n, and the time loop's CPU and wall seconds
!> (rank 0's), per step and per Newton iteration per unknown. -chain_dump PREFIX writes each rank's
!> rows of the final state to PREFIX.<rank> ("index value" lines). -chain_snapshots FILE.h5 writes
!> the state at the start, every K-th step (default 1) and the last into FILE.h5's /snapshots
!> with parallel HDF5, each rank its own part (src/io/hdf5_snapshots; docs/output.md, Snapshots),
!> and adds the snapshots' count and seconds (rank 0's wall time) to the figures. It is the instrument of the
!> chain's scaling benchmark (docs/performance.md) and of the tests that compare the path with the
!> dense one and one rank with two; eme_run does not run this path yet.
!> Exit status: 0 done, 2 bad input or usage, 3 the run stopped (a step did not converge), 1 a
!> library failed. --help, -h, -help and --version print and exit with status 0.
program chain_bench
#include <petsc/finclude/petscsys.h>
  use petscsys
  use, intrinsic :: iso_fortran_env, only: error_unit, output_unit, real64, int64
  use run_config, only: run_configuration, read_run_config
  use integrator_settings, only: step_count
  use model_interface, only: generic_model
  use model_constraint, only: constraint_slot
  use failures, only: failure_type, fail, failure_input, failure_not_converged
  use number_text, only: integer_text
  use command_line, only: has_argument
  use library_versions, only: print_versions
  use spring_chain_sparse_run, only: sparse_chain_run, sparse_run_result
  use distributed_model, only: distributed_settings
  use thermo_variable_kinds, only: tau_entropy, tau_internal_energy
  use hdf5_snapshots, only: snapshot_layout, append_snapshot
  use hdf5, only: hid_t, h5open_f, h5fcreate_f, h5fclose_f, H5F_ACC_TRUNC_F
  implicit none

  type(run_configuration) :: config
  type(distributed_settings) :: settings
  real(real64) :: dt
  integer :: step_total
  type(sparse_run_result) :: result
  type(sparse_chain_run) :: run
  type(failure_type) :: failure
  class(generic_model), allocatable :: model
  real(real64), allocatable :: z0(:)
  type(constraint_slot), allocatable :: constraints(:)
  character(len=4096) :: input, dump, snapshots
  PetscInt :: steps, every
  PetscBool :: found, dump_given, snapshots_given
  integer :: snapshot_count = 0
  real(real64) :: snapshot_seconds = 0.0_real64
  PetscErrorCode :: ierr
  PetscMPIInt :: rank
  integer :: exit_status, n

  ! --help, -h, PETSc's -help and --version answer at once, wherever they stand.
  if (has_argument([character(len=6) :: '--help', '-h', '-help'])) then
    call print_usage(output_unit)
    stop
  else if (has_argument(['--version'])) then
    call print_versions(output_unit, 'chain_bench')
    stop
  end if
  PetscCallA(PetscInitialize(ierr))
  PetscCallMPIA(MPI_Comm_rank(PETSC_COMM_WORLD, rank, ierr))
  exit_status = 0
  input = ''
  if (command_argument_count() >= 1) call get_command_argument(1, input)
  if (len_trim(input) == 0 .or. input(1:1) == '-') then
    if (rank == 0) call print_usage(error_unit)
    exit_status = 2
  else
    call read_run_config(trim(input), config, failure)
    if (.not. failure%failed()) call config%scene%build(config%integrator%thermo_variable, model, z0, constraints, failure)
    ! This benchmark times fixed steps, each one Newton solve; eme_run adapts them.
    if (.not. failure%failed() .and. config%integrator%tolerance_given) &
      call fail(failure, failure_input, config%input_file//', &integrator: tolerance: chain_bench takes fixed steps '// &
                'only (eme_run runs the chain''s adaptive steps); allowed: leave it out', 'tolerance')
    if (.not. failure%failed()) then
      settings%input_file = config%input_file
      settings%scheme = config%integrator%scheme
      settings%discrete_gradient = config%integrator%discrete_gradient
      settings%metric = config%integrator%metric
      dt = config%integrator%dt
      settings%dt = dt
      settings%tolerance = config%integrator%tolerance
      step_total = int(min(step_count(config%integrator), int(huge(1), int64)))
      settings%newton_tol = config%integrator%newton_tol
      settings%newton_max_iterations = config%integrator%newton_max_iterations
      settings%tolerance_given = config%integrator%tolerance_given
      PetscCallA(PetscOptionsGetInt(PETSC_NULL_OPTIONS, PETSC_NULL_CHARACTER, '-chain_steps', steps, found, ierr))
      if (found) step_total = int(steps)
      PetscCallA(PetscOptionsGetString(PETSC_NULL_OPTIONS, PETSC_NULL_CHARACTER, '-chain_dump', dump, dump_given, ierr))
      PetscCallA(PetscOptionsGetString(PETSC_NULL_OPTIONS, PETSC_NULL_CHARACTER, '-chain_snapshots', snapshots, snapshots_given, ierr))
      every = 1
      PetscCallA(PetscOptionsGetInt(PETSC_NULL_OPTIONS, PETSC_NULL_CHARACTER, '-chain_snapshot_every', every, found, ierr))
      if (snapshots_given) call create_snapshot_file(trim(snapshots))
      if (.not. failure%failed()) call run%start(settings, model, z0, PETSC_COMM_WORLD, failure)
      if (snapshots_given) call write_snapshot(0.0_real64)
      do n = 1, step_total
        if (failure%failed()) exit
        call run%advance(n, dt, failure)
        if (snapshots_given .and. (mod(n, int(every)) == 0 .or. n == step_total)) call write_snapshot(n*dt)
      end do
      if (dump_given) call run%dump(trim(dump), failure)
      call run%finish(failure)
      result = run%result
    end if
    if (failure%failed()) then
      if (rank == 0) write (error_unit, '(a)') 'chain_bench: '//failure%text()
      exit_status = 1
      if (failure%code == failure_input) exit_status = 2
      if (failure%code == failure_not_converged) exit_status = 3
    end if
    if (rank == 0 .and. result%steps > 0) call print_figures(result)
  end if
  call PetscFinalize(ierr)
  if (exit_status /= 0) stop exit_status, quiet=.true.

contains

  ! The usage line and what the program does.
  subroutine print_usage(unit)
    integer, intent(in) :: unit

    write (unit, '(a)') 'usage: mpirun -n P chain_bench FILE.nml [-chain_steps K] [-chain_dump PREFIX] '// &
      '[-chain_snapshots FILE.h5 [-chain_snapshot_every K]] [PETSc options]'
    write (unit, '(a)') '  runs the spring chain of FILE.nml on the sparse, distributed path (EME or the midpoint '// &
      'rule, fixed steps) and prints its figures; --help, -h, -help: this text; --version: the versions. Exit '// &
      'status: 0 done, 2 bad input or usage, 3 a step did not converge, 1 a library failed.'
  end subroutine print_usage

  ! An empty HDF5 file for the snapshots, made by rank 0 before any rank appends.
  subroutine create_snapshot_file(path)
    character(len=*), intent(in) :: path
    integer(hid_t) :: file
    integer :: status

    status = 0
    if (rank == 0) then
      call h5open_f(status)
      if (status == 0) call h5fcreate_f(path, H5F_ACC_TRUNC_F, file, status)
      if (status == 0) call h5fclose_f(file, status)
    end if
    call MPI_Barrier(PETSC_COMM_WORLD, ierr)
    if (status /= 0) call fail(failure, failure_input, "-chain_snapshots: cannot create '"//path//"'")
  end subroutine create_snapshot_file

  ! The state at `time` into /snapshots, every rank its part.
  subroutine write_snapshot(time)
    real(real64), intent(in) :: time
    real(real64), allocatable :: positions(:, :), momenta(:, :), gamma(:), tau(:), theta(:)
    type(snapshot_layout) :: layout
    real(real64) :: start

    if (failure%failed()) return
    start = MPI_Wtime()
    call run%chain%state_part(positions, momenta, gamma, tau, theta, failure)
    if (failure%failed()) return
    associate (chain => run%chain, chain_layout => run%chain%context%problem%layout)
      layout = snapshot_layout(masses=chain_layout%masses, springs=chain_layout%springs, dimension=chain_layout%dimension, &
                               first_mass=chain%first_point, mass_count=size(positions, 2), &
                               first_spring=chain%first_point, spring_count=chain%last_point - chain%first_point + 1)
    end associate
    ! Arrays the state has not are passed unallocated: absent (tau too when it is the temperature).
    if (size(gamma) == 0) deallocate (gamma)
    if (size(tau) == 0 .or. len(tau_dataset()) == 0) deallocate (tau)
    if (size(theta) == 0) deallocate (theta)
    call append_snapshot(trim(snapshots), PETSC_COMM_WORLD, layout, time, positions, momenta, failure, &
                         viscous_strains=gamma, tau=tau, tau_name=tau_dataset(), temperatures=theta)
    snapshot_count = snapshot_count + 1
    snapshot_seconds = snapshot_seconds + (MPI_Wtime() - start)
  end subroutine write_snapshot

  ! The snapshot's dataset of tau: none when tau is the temperature.
  function tau_dataset() result(name)
    character(len=:), allocatable :: name

    select case (config%integrator%thermo_variable)
    case (tau_entropy)
      name = 'entropy'
    case (tau_internal_energy)
      name = 'internal_energy'
    case default
      name = ''
    end select
  end function tau_dataset

  ! One line of key=value figures.
  subroutine print_figures(r)
    type(sparse_run_result), intent(in) :: r

    write (output_unit, '(a, 4(a, i0), a, i0, a, i0, 4(a, es24.16e3), 2(a, es10.3), 4(a, es10.3))') 'chain_bench:', &
      ' springs=', r%springs, ' unknowns=', r%unknowns, ' ranks=', r%ranks, ' steps=', r%steps, &
      ' newton=', r%newton_iterations, ' max_newton=', r%max_newton_iterations, &
      ' energy_0=', r%energy_0, ' energy=', r%energy, ' entropy_0=', r%entropy_0, ' entropy=', r%entropy, &
      ' max_energy_error=', r%max_energy_error, ' min_entropy_increment=', r%min_entropy_increment, &
      ' cpu_per_step=', r%loop_cpu_seconds/r%steps, ' wall_per_step=', r%loop_wall_seconds/r%steps, &
      ' cpu_per_newton_unknown=', r%loop_cpu_seconds/max(1, r%newton_iterations)/r%unknowns, &
      ' loop_cpu=', r%loop_cpu_seconds
    if (snapshot_count > 0) write (output_unit, '(a, i0, a, es10.3)') 'chain_bench: snapshots=', snapshot_count, &
      ' snapshot_seconds=', snapshot_seconds
  end subroutine print_figures

end program chain_bench
