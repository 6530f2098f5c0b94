!> Test helper of tests/e2e/test_snapshots.py (built as build/bin/snapshot_probe): appends
!> snapshots of known values to an existing HDF5 file through hdf5_snapshots, from every rank of
!> MPI_COMM_WORLD, each writing its own part. Snapshot k of the state holds, for mass i, component
!> c and spring a (all 1-based):
!>   time = 0.5 k + 0.125,  q = i + 0.1 c + 1000 k,  p = -q,
!>   gamma = -(a + 0.5) - 1000 k,  theta = 300 + a + 1000 k,  tau = 0.25 a + 7 + 1000 k.
!> Arguments, each name=value: file (required), masses, springs (default: masses), dimension
!> (default 3), snapshots (default 1), first (the first k, default 0), mass_split and spring_split
!> (each rank's count, comma-separated; default: as even as can be, the first ranks one more),
!> tau (entropy, internal_energy or none; default entropy), gamma and theta (yes or no; default
!> yes), timing (yes: rank 0 prints each append's wall time, the slowest rank's, in seconds).
!> Exit status 0; 1 when an append fails (rank 0 prints the failure); 2 for a wrong argument.
program snapshot_probe
  use, intrinsic :: iso_fortran_env, only: real64, error_unit, output_unit
  use mpi_f08, only: MPI_Comm, MPI_COMM_WORLD, MPI_Init, MPI_Finalize, MPI_Comm_rank, MPI_Comm_size, MPI_Wtime, &
                     MPI_Barrier, MPI_Allreduce, MPI_IN_PLACE, MPI_DOUBLE_PRECISION, MPI_MAX
  use failures, only: failure_type
  use hdf5_snapshots, only: snapshot_layout, append_snapshot
  implicit none

  type(snapshot_layout) :: layout
  type(failure_type) :: failure
  character(len=:), allocatable :: path, tau_name, wrong
  character(len=256) :: argument
  integer, allocatable :: mass_split(:), spring_split(:)
  real(real64), allocatable :: positions(:, :), momenta(:, :), gammas(:), thetas(:), taus(:)
  logical :: with_gamma, with_theta, timing
  integer :: rank, ranks, snapshots, first, k, i, c, a
  real(real64) :: started, seconds

  call MPI_Init()
  call MPI_Comm_rank(MPI_COMM_WORLD, rank)
  call MPI_Comm_size(MPI_COMM_WORLD, ranks)
  path = ''
  tau_name = 'entropy'
  wrong = ''
  layout%springs = -1
  snapshots = 1
  first = 0
  with_gamma = .true.
  with_theta = .true.
  timing = .false.
  allocate (mass_split(0), spring_split(0))
  do i = 1, command_argument_count()
    call get_command_argument(i, argument)
    call read_argument(trim(argument))
  end do
  if (layout%springs < 0) layout%springs = layout%masses
  if (len(wrong) == 0 .and. len(path) == 0) wrong = 'file= is required'
  if (len(wrong) == 0) mass_split = split_or_even(mass_split, layout%masses, 'mass_split')
  if (len(wrong) == 0) spring_split = split_or_even(spring_split, layout%springs, 'spring_split')
  if (len(wrong) > 0) call finish(2, 'snapshot_probe: '//wrong)

  layout%mass_count = mass_split(rank + 1)
  layout%first_mass = 1 + sum(mass_split(:rank))
  layout%spring_count = spring_split(rank + 1)
  layout%first_spring = 1 + sum(spring_split(:rank))
  allocate (positions(layout%dimension, max(layout%mass_count, 0)), momenta(layout%dimension, max(layout%mass_count, 0)))
  allocate (gammas(max(layout%spring_count, 0)), thetas(max(layout%spring_count, 0)), taus(max(layout%spring_count, 0)))
  do k = first, first + snapshots - 1
    do i = 1, layout%mass_count
      do c = 1, layout%dimension
        positions(c, i) = (layout%first_mass + i - 1) + 0.1_real64 * c + 1000.0_real64 * k
      end do
    end do
    momenta = -positions
    do a = 1, layout%spring_count
      gammas(a) = -((layout%first_spring + a - 1) + 0.5_real64) - 1000.0_real64 * k
      thetas(a) = 300.0_real64 + (layout%first_spring + a - 1) + 1000.0_real64 * k
      taus(a) = 0.25_real64 * (layout%first_spring + a - 1) + 7.0_real64 + 1000.0_real64 * k
    end do
    call MPI_Barrier(MPI_COMM_WORLD)
    started = MPI_Wtime()
    call append(0.5_real64 * k + 0.125_real64)
    seconds = MPI_Wtime() - started
    call MPI_Allreduce(MPI_IN_PLACE, seconds, 1, MPI_DOUBLE_PRECISION, MPI_MAX, MPI_COMM_WORLD)
    if (failure%failed()) call finish(1, 'snapshot_probe: '//failure%text())
    if (timing .and. rank == 0) write (output_unit, '(a, i0, a, es12.5)') 'snapshot ', k, ' seconds ', seconds
  end do
  call finish(0, '')

contains

  ! Appends the snapshot with the datasets the arguments ask for.
  subroutine append(time)
    real(real64), intent(in) :: time

    if (tau_name == 'none') then
      if (with_gamma .and. with_theta) then
        call append_snapshot(path, MPI_COMM_WORLD%MPI_VAL, layout, time, positions, momenta, failure, viscous_strains=gammas, &
                             temperatures=thetas)
      else if (with_theta) then
        call append_snapshot(path, MPI_COMM_WORLD%MPI_VAL, layout, time, positions, momenta, failure, temperatures=thetas)
      else if (with_gamma) then
        call append_snapshot(path, MPI_COMM_WORLD%MPI_VAL, layout, time, positions, momenta, failure, viscous_strains=gammas)
      else
        call append_snapshot(path, MPI_COMM_WORLD%MPI_VAL, layout, time, positions, momenta, failure)
      end if
    else if (with_gamma .and. with_theta) then
      call append_snapshot(path, MPI_COMM_WORLD%MPI_VAL, layout, time, positions, momenta, failure, viscous_strains=gammas, &
                           tau=taus, tau_name=tau_name, temperatures=thetas)
    else if (with_theta) then
      call append_snapshot(path, MPI_COMM_WORLD%MPI_VAL, layout, time, positions, momenta, failure, tau=taus, &
                           tau_name=tau_name, temperatures=thetas)
    else if (with_gamma) then
      call append_snapshot(path, MPI_COMM_WORLD%MPI_VAL, layout, time, positions, momenta, failure, viscous_strains=gammas, &
                           tau=taus, tau_name=tau_name)
    else
      call append_snapshot(path, MPI_COMM_WORLD%MPI_VAL, layout, time, positions, momenta, failure, tau=taus, tau_name=tau_name)
    end if
  end subroutine append

  ! Reads one name=value argument into the settings (or the first complaint into `wrong`).
  subroutine read_argument(text)
    character(len=*), intent(in) :: text
    character(len=:), allocatable :: name, value
    integer :: equals, stat

    equals = index(text, '=')
    if (equals == 0 .and. len(wrong) == 0) wrong = 'arguments are name=value: '//text
    if (equals == 0) return
    name = text(:equals - 1)
    value = text(equals + 1:)
    stat = 0
    select case (name)
    case ('file')
      path = value
    case ('masses')
      read (value, *, iostat=stat) layout%masses
    case ('springs')
      read (value, *, iostat=stat) layout%springs
    case ('dimension')
      read (value, *, iostat=stat) layout%dimension
    case ('snapshots')
      read (value, *, iostat=stat) snapshots
    case ('first')
      read (value, *, iostat=stat) first
    case ('mass_split', 'spring_split')
      call read_split(value, name, stat)
    case ('tau')
      tau_name = value
    case ('gamma')
      with_gamma = value == 'yes'
    case ('theta')
      with_theta = value == 'yes'
    case ('timing')
      timing = value == 'yes'
    case default
      stat = 1
    end select
    if (stat /= 0 .and. len(wrong) == 0) wrong = 'cannot read the argument '//text
  end subroutine read_argument

  ! Reads a comma-separated split of one count per rank.
  subroutine read_split(value, name, stat)
    character(len=*), intent(in) :: value, name
    integer, intent(out) :: stat
    integer, allocatable :: counts(:)

    allocate (counts(ranks))
    read (value, *, iostat=stat) counts
    if (stat /= 0) return
    if (name == 'mass_split') then
      mass_split = counts
    else
      spring_split = counts
    end if
  end subroutine read_split

  ! The given split, or `total` split as evenly as can be over the ranks.
  function split_or_even(given, total, name) result(counts)
    integer, intent(in) :: given(:), total
    character(len=*), intent(in) :: name
    integer, allocatable :: counts(:)
    integer :: r

    if (size(given) > 0) then
      counts = given
      return
    end if
    counts = [(total / ranks + merge(1, 0, r < mod(total, ranks)), r = 0, ranks - 1)]
    if (total < 0) wrong = name//': no count given'
  end function split_or_even

  ! Ends the program on every rank with `code`; rank 0 prints `message` if there is one.
  subroutine finish(code, message)
    integer, intent(in) :: code
    character(len=*), intent(in) :: message

    if (rank == 0 .and. len(message) > 0) write (error_unit, '(a)') message
    call MPI_Finalize()
    stop code, quiet=.true.
  end subroutine finish

end program snapshot_probe
