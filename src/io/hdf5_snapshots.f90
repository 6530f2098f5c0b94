!> Snapshots of a state split over MPI ranks, appended with parallel HDF5 to an existing file that
!> no process holds open (docs/output.md, Snapshots): every rank writes its own masses and springs,
!> no rank gathers the whole state. The writing is src/io/hdf5_snapshot_storage.c's, the group's
!> datasets and dimension scales src/io/hdf5_snapshot_layout.c's (not hdf5_snapshots.c: a C file
!> and a module of one name would make one object); this module checks the Fortran arrays against
!> the layout and turns the C status into a failure_type.
module hdf5_snapshots
  use, intrinsic :: iso_c_binding, only: c_char, c_double, c_int, c_long_long, c_ptr, c_loc, c_null_ptr, c_null_char
  use, intrinsic :: iso_fortran_env, only: real64
  use mpi_f08, only: MPI_Comm, MPI_Comm_rank, MPI_Allreduce, MPI_IN_PLACE, MPI_INTEGER, MPI_MIN
  use failures, only: failure_type, fail, failure_input, failure_io, failure_mismatch, failure_library
  implicit none (type, external)
  private
  public :: snapshot_layout, append_snapshot, read_last_snapshot

  !> Where this rank's part of a state lies: the whole state's numbers of masses, springs and
  !> components, and this rank's first mass and spring (1-based) and how many of each it holds.
  !> The ranks' parts follow each other in rank order (as a 1-D PETSc DMDA owns them).
  type :: snapshot_layout
    integer :: masses = 0          !! N, the masses of the whole state
    integer :: springs = 0         !! n_s, its springs
    integer :: dimension = 3       !! d, components of a position or momentum
    integer :: first_mass = 1      !! this rank's first mass
    integer :: mass_count = 0      !! this rank's masses
    integer :: first_spring = 1    !! this rank's first spring
    integer :: spring_count = 0    !! this rank's springs
  end type snapshot_layout

  integer, parameter :: message_capacity = 1024

  ! The codes of eme_h5_append_snapshot.
  integer, parameter :: snapshot_input = 1, snapshot_io = 2, snapshot_mismatch = 3

  interface
    integer(c_int) function eme_h5_append_snapshot(path, comm, time, masses, springs, dimension, first_mass, mass_count, &
                                                   first_spring, spring_count, q, p, gamma, tau, theta, tau_name, message, &
                                                   capacity) bind(c, name='eme_h5_append_snapshot')
      import :: c_char, c_double, c_int, c_long_long, c_ptr
      character(kind=c_char), intent(in) :: path(*), tau_name(*)
      integer(c_int), value, intent(in) :: comm, dimension, capacity
      real(c_double), value, intent(in) :: time
      integer(c_long_long), value, intent(in) :: masses, springs, first_mass, mass_count, first_spring, spring_count
      type(c_ptr), value, intent(in) :: q, p, gamma, tau, theta
      character(kind=c_char), intent(inout) :: message(*)
    end function eme_h5_append_snapshot

    integer(c_int) function eme_h5_read_last_snapshot(path, comm, masses, springs, dimension, first_mass, mass_count, &
                                                      first_spring, spring_count, q, p, gamma, tau, theta, tau_name, time, &
                                                      message, capacity) bind(c, name='eme_h5_read_last_snapshot')
      import :: c_char, c_double, c_int, c_long_long, c_ptr
      character(kind=c_char), intent(in) :: path(*), tau_name(*)
      integer(c_int), value, intent(in) :: comm, dimension, capacity
      integer(c_long_long), value, intent(in) :: masses, springs, first_mass, mass_count, first_spring, spring_count
      type(c_ptr), value, intent(in) :: q, p, gamma, tau, theta
      real(c_double), intent(out) :: time
      character(kind=c_char), intent(inout) :: message(*)
    end function eme_h5_read_last_snapshot
  end interface

  !> Stands for a present array of no values (a rank without springs), which C must tell from an
  !> absent one.
  real(c_double), target, save :: no_values(1) = 0

contains

  !> Appends the snapshot at `time` of the state whose part on this rank is `layout`, collectively
  !> over `comm`: positions and momenta (dimension, mass_count), and per spring (spring_count) the
  !> viscous strains, the thermodynamic variable `tau` (named `tau_name`: 'entropy' or
  !> 'internal_energy'; absent when tau is theta) and the temperatures [K], each absent when the
  !> state has none. Every rank gets the same failure, which names the file and the dataset.
  subroutine append_snapshot(path, comm, layout, time, positions, momenta, failure, viscous_strains, tau, tau_name, &
                             temperatures)
    character(len=*), intent(in) :: path
    integer, intent(in) :: comm              !! the communicator's Fortran handle (PETSc's; mpi_f08's %MPI_VAL)
    type(snapshot_layout), intent(in) :: layout
    real(real64), intent(in) :: time
    real(real64), intent(in), target, contiguous :: positions(:, :), momenta(:, :)
    type(failure_type), intent(out) :: failure
    real(real64), intent(in), target, contiguous, optional :: viscous_strains(:), tau(:), temperatures(:)
    character(len=*), intent(in), optional :: tau_name
    character(kind=c_char) :: message(message_capacity)
    character(len=:), allocatable :: tau_text
    integer(c_int) :: status

    tau_text = ''
    if (present(tau_name)) tau_text = tau_name
    message = c_null_char
    call check_part(path, comm, layout, positions, momenta, failure, viscous_strains, tau, temperatures)
    if (failure%failed()) return
    status = eme_h5_append_snapshot(path//c_null_char, int(comm, c_int), real(time, c_double), &
                                    int(layout%masses, c_long_long), int(layout%springs, c_long_long), &
                                    int(layout%dimension, c_int), int(layout%first_mass - 1, c_long_long), &
                                    int(layout%mass_count, c_long_long), int(layout%first_spring - 1, c_long_long), &
                                    int(layout%spring_count, c_long_long), address(positions, size(positions)), &
                                    address(momenta, size(momenta)), &
                                    optional_address(viscous_strains), optional_address(tau), &
                                    optional_address(temperatures), tau_text//c_null_char, message, &
                                    int(message_capacity, c_int))
    call fail_on_status(path, status, message, failure)
  end subroutine append_snapshot

  !> Reads the last snapshot of `path` into this rank's part of the state (`layout`), collectively
  !> over `comm`: the arrays as append_snapshot takes them, given allocated to their shapes and
  !> filled here, and the snapshot's `time`. The file's snapshots must be of this state (its
  !> datasets and shapes: failure_mismatch names the dataset otherwise). Every rank gets the same
  !> failure.
  subroutine read_last_snapshot(path, comm, layout, time, positions, momenta, failure, viscous_strains, tau, tau_name, &
                                temperatures)
    character(len=*), intent(in) :: path
    integer, intent(in) :: comm
    type(snapshot_layout), intent(in) :: layout
    real(real64), intent(out) :: time
    real(real64), intent(inout), target, contiguous :: positions(:, :), momenta(:, :)
    type(failure_type), intent(out) :: failure
    real(real64), intent(inout), target, contiguous, optional :: viscous_strains(:), tau(:), temperatures(:)
    character(len=*), intent(in), optional :: tau_name
    character(kind=c_char) :: message(message_capacity)
    character(len=:), allocatable :: tau_text
    real(c_double) :: stored_time
    integer(c_int) :: status

    tau_text = ''
    if (present(tau_name)) tau_text = tau_name
    message = c_null_char
    time = 0.0_real64
    call check_part(path, comm, layout, positions, momenta, failure, viscous_strains, tau, temperatures)
    if (failure%failed()) return
    status = eme_h5_read_last_snapshot(path//c_null_char, int(comm, c_int), &
                                       int(layout%masses, c_long_long), int(layout%springs, c_long_long), &
                                       int(layout%dimension, c_int), int(layout%first_mass - 1, c_long_long), &
                                       int(layout%mass_count, c_long_long), int(layout%first_spring - 1, c_long_long), &
                                       int(layout%spring_count, c_long_long), address(positions, size(positions)), &
                                       address(momenta, size(momenta)), &
                                       optional_address(viscous_strains), optional_address(tau), &
                                       optional_address(temperatures), tau_text//c_null_char, stored_time, message, &
                                       int(message_capacity, c_int))
    call fail_on_status(path, status, message, failure)
    if (.not. failure%failed()) time = stored_time
  end subroutine read_last_snapshot

  ! Fails on every rank (failure_input) if any rank's arrays do not fit its part of `layout`:
  ! positions and momenta (dimension, its masses), the per-spring arrays one value per spring.
  subroutine check_part(path, comm, layout, positions, momenta, failure, viscous_strains, tau, temperatures)
    character(len=*), intent(in) :: path
    integer, intent(in) :: comm
    type(snapshot_layout), intent(in) :: layout
    real(real64), intent(in) :: positions(:, :), momenta(:, :)
    type(failure_type), intent(out) :: failure
    real(real64), intent(in), optional :: viscous_strains(:), tau(:), temperatures(:)
    character(len=12) :: rank_text
    integer :: rank, first_wrong
    type(MPI_Comm) :: communicator

    ! Every rank learns of arrays that do not fit on any (the first such rank), so that none goes
    ! on into the collective transfer.
    communicator%MPI_VAL = comm
    call MPI_Comm_rank(communicator, rank)
    first_wrong = huge(first_wrong)
    if (any(shape(positions) /= [layout%dimension, layout%mass_count]) .or. &
        any(shape(momenta) /= [layout%dimension, layout%mass_count]) .or. &
        .not. (fits(viscous_strains) .and. fits(tau) .and. fits(temperatures))) first_wrong = rank
    call MPI_Allreduce(MPI_IN_PLACE, first_wrong, 1, MPI_INTEGER, MPI_MIN, communicator)
    if (first_wrong /= huge(first_wrong)) then
      write (rank_text, '(i0)') first_wrong
      call fail(failure, failure_input, path//': rank '//trim(rank_text)//'''s arrays do not fit its part of the '// &
                'snapshot: positions and momenta (dimension, its masses), gamma, tau and theta one value per spring '// &
                'of its part', 'snapshot')
    end if

  contains

    ! Whether an optional per-spring array is absent or holds one value per spring of this rank.
    logical function fits(values)
      real(real64), intent(in), optional :: values(:)

      fits = .true.
      if (present(values)) fits = size(values) == layout%spring_count
    end function fits

  end subroutine check_part

  ! The failure of the C side's snapshot_* `status`, with its message (none for 0).
  subroutine fail_on_status(path, status, message, failure)
    character(len=*), intent(in) :: path
    integer(c_int), intent(in) :: status
    character(kind=c_char), intent(in) :: message(:)
    type(failure_type), intent(inout) :: failure
    integer :: i

    if (status == 0) return
    i = 1
    do while (i < size(message) .and. message(i) /= c_null_char)
      i = i + 1
    end do
    select case (status)
    case (snapshot_input)
      call fail(failure, failure_input, text_of(message(:i - 1)), path)
    case (snapshot_io)
      call fail(failure, failure_io, text_of(message(:i - 1)), path)
    case (snapshot_mismatch)
      call fail(failure, failure_mismatch, text_of(message(:i - 1)), path)
    case default
      call fail(failure, failure_library, text_of(message(:i - 1)), path)
    end select
  end subroutine fail_on_status

  ! The address of a present array's `count` values (no_values' for an empty one).
  type(c_ptr) function address(values, count)
    real(real64), intent(in), target :: values(*)
    integer, intent(in) :: count

    if (count == 0) then
      address = c_loc(no_values)
    else
      address = c_loc(values)
    end if
  end function address

  ! The address of an optional array's values, or C's NULL when it is absent.
  type(c_ptr) function optional_address(values)
    real(real64), intent(in), target, contiguous, optional :: values(:)

    optional_address = c_null_ptr
    if (present(values)) optional_address = address(values, size(values))
  end function optional_address

  ! The characters as a Fortran string.
  pure function text_of(characters) result(text)
    character(kind=c_char), intent(in) :: characters(:)
    character(len=:), allocatable :: text
    integer :: i

    allocate (character(len=size(characters)) :: text)
    do i = 1, size(characters)
      text(i:i) = characters(i)
    end do
  end function text_of

end module hdf5_snapshots
