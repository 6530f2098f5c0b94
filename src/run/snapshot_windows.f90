!> The snapshots of a run split over ranks on their way to its file (src/run/distributed_simulation):
!> every rank holds its part of each snapshot until the next window of the crash-safe writer
!> (src/io/crash_safe_file), in which rank 0 closes the spare and all ranks append to it with
!> parallel HDF5 (src/io/hdf5_snapshots) what the spare lacks; and a continued run's last
!> snapshot read back, every rank its part (docs/output.md, A chain's file).
module snapshot_windows
  use, intrinsic :: iso_fortran_env, only: real64, int64
  use mpi_f08, only: MPI_Comm, MPI_Comm_rank, MPI_Bcast, MPI_INTEGER, MPI_CHARACTER
  use distributed_model, only: distributed_system, distributed_part, distributed_figures
  use number_text, only: fixed_text
  use thermo_variable_kinds, only: tau_entropy, tau_internal_energy
  use run_output, only: spare_addition
  use hdf5_snapshots, only: snapshot_layout, append_snapshot, read_last_snapshot
  use failures, only: failure_type
  implicit none (type, external)
  private
  public :: held_snapshot, snapshot_window, transfer_part, take_up_snapshot, tau_dataset

  !> Bytes of snapshots a rank holds for the next window at most: more force the window.
  integer(int64), parameter :: snapshot_buffer_bytes = 256_int64*1024*1024

  !> A snapshot held for the file: its time and the rank's part.
  type :: held_snapshot
    real(real64) :: time = 0.0_real64
    type(distributed_part) :: state
  end type held_snapshot

  !> The snapshots a window adds to the spare (crash_safe_file's spare_addition): those of the
  !> window before (`kept`: the spare, one window behind, lacks them) and the new ones; rank 0
  !> calls `add` inside its window, the other ranks `join` at the same point.
  type, extends(spare_addition) :: snapshot_window
    type(MPI_Comm) :: comm
    integer :: rank = 0
    character(len=:), allocatable :: tau_name              !! the snapshot's dataset of tau ('' if none)
    !> kept(1:kept_count) and new(1:new_count) hold them (capacity doubling as snapshots come)
    type(held_snapshot), allocatable :: kept(:), new(:)
    integer :: kept_count = 0, new_count = 0
    integer(int64) :: new_bytes = 0                        !! the new snapshots' values, in bytes
    logical :: added = .false.                             !! rank 0: `add` ran in this window
  contains
    procedure :: open
    procedure :: add
    procedure :: join
    procedure :: hold
    procedure :: written
    procedure :: full
  end type snapshot_window

contains

  !> A window of no snapshots yet on `comm`, tau in the snapshots as dataset `tau_name` ('': none).
  subroutine open(self, comm, tau_name)
    class(snapshot_window), intent(inout) :: self
    type(MPI_Comm), intent(in) :: comm
    character(len=*), intent(in) :: tau_name

    self%comm = comm
    call MPI_Comm_rank(comm, self%rank)
    self%tau_name = tau_name
    allocate (self%kept(0), self%new(4))
  end subroutine open

  !> Appends the window's snapshots to the closed spare at `path` (rank 0, inside its window):
  !> tells the other ranks where, and writes with them.
  subroutine add(self, path, failure)
    class(snapshot_window), intent(inout) :: self
    character(len=*), intent(in) :: path
    type(failure_type), intent(out) :: failure
    integer :: length
    character(len=:), allocatable :: text

    self%added = .true.
    length = len(path)
    call MPI_Bcast(length, 1, MPI_INTEGER, 0, self%comm)
    text = path
    call MPI_Bcast(text, length, MPI_CHARACTER, 0, self%comm)
    call append_held(self, text, failure)
  end subroutine add

  !> The other ranks' side of a window: the spare's path from rank 0 (none if the window did not
  !> reach its addition), and the snapshots written with it.
  subroutine join(self)
    class(snapshot_window), intent(inout) :: self
    integer :: length
    character(len=:), allocatable :: path
    type(failure_type) :: failure

    call MPI_Bcast(length, 1, MPI_INTEGER, 0, self%comm)
    if (length == 0) return
    allocate (character(len=length) :: path)
    call MPI_Bcast(path, length, MPI_CHARACTER, 0, self%comm)
    self%added = .true.
    call append_held(self, path, failure)
  end subroutine join

  ! Every held snapshot, kept then new, appended by all ranks (append_snapshot is collective and
  ! makes every rank agree on a failure).
  subroutine append_held(self, path, failure)
    type(snapshot_window), intent(inout) :: self
    character(len=*), intent(in) :: path
    type(failure_type), intent(out) :: failure
    integer :: k

    do k = 1, self%kept_count
      if (.not. failure%failed()) call transfer_part(path, self%comm%MPI_VAL, self%kept(k)%time, self%kept(k)%state, &
                                                     self%tau_name, .false., failure)
    end do
    do k = 1, self%new_count
      if (.not. failure%failed()) call transfer_part(path, self%comm%MPI_VAL, self%new(k)%time, self%new(k)%state, &
                                                     self%tau_name, .false., failure)
    end do
  end subroutine append_held

  !> Holds `snapshot` for the next window.
  subroutine hold(self, snapshot)
    class(snapshot_window), intent(inout) :: self
    type(held_snapshot), intent(in) :: snapshot
    type(held_snapshot), allocatable :: grown(:)

    if (self%new_count == size(self%new)) then
      allocate (grown(2*size(self%new)))
      grown(1:self%new_count) = self%new(1:self%new_count)
      call move_alloc(grown, self%new)
    end if
    self%new_count = self%new_count + 1
    self%new(self%new_count) = snapshot
    associate (state => snapshot%state)
      self%new_bytes = self%new_bytes + 8_int64*(size(state%positions) + size(state%momenta) + size(state%gamma) + &
                                                 size(state%tau) + size(state%theta))
    end associate
  end subroutine hold

  !> A window reached the file with every held snapshot: its new spare (the old file) lacks this
  !> window's, which are kept for the next.
  subroutine written(self)
    class(snapshot_window), intent(inout) :: self

    call move_alloc(self%new, self%kept)
    self%kept_count = self%new_count
    allocate (self%new(4))
    self%new_count = 0
    self%new_bytes = 0
  end subroutine written

  !> Appends the snapshot of `state` (every rank its part) at `time` to the closed file `path`
  !> (collective on `comm`, a communicator's Fortran handle), or with `reading` reads the file's
  !> last snapshot into `state` (its arrays allocated to the rank's part) and its `time`; tau as
  !> dataset `tau_name` ('': none, tau being the temperature).
  subroutine transfer_part(path, comm, time, state, tau_name, reading, failure)
    character(len=*), intent(in) :: path, tau_name
    integer, intent(in) :: comm
    real(real64), intent(inout) :: time
    type(distributed_part), intent(inout), target :: state
    logical, intent(in) :: reading
    type(failure_type), intent(out) :: failure
    type(snapshot_layout) :: layout
    real(real64), pointer, contiguous :: gamma(:), tau(:), theta(:)

    layout = snapshot_layout(masses=state%masses, springs=state%springs, dimension=state%dimension, &
                             first_mass=state%first_mass, mass_count=size(state%positions, 2), &
                             first_spring=state%first_spring, spring_count=state%spring_count)
    ! Arrays the state has not are absent (a disassociated pointer is an absent argument), tau too
    ! when it is the temperature.
    gamma => null()
    tau => null()
    theta => null()
    if (size(state%theta) > 0) theta => state%theta
    if (size(state%gamma) > 0 .and. size(state%theta) > 0) gamma => state%gamma
    if (size(state%theta) > 0 .and. len(tau_name) > 0) tau => state%tau
    if (reading) then
      call read_last_snapshot(path, comm, layout, time, state%positions, state%momenta, failure, viscous_strains=gamma, &
                              tau=tau, tau_name=tau_name, temperatures=theta)
    else
      call append_snapshot(path, comm, layout, time, state%positions, state%momenta, failure, viscous_strains=gamma, &
                           tau=tau, tau_name=tau_name, temperatures=theta)
    end if
  end subroutine transfer_part

  !> A continued run's state on the ranks of `comm`: the last snapshot of the file `path`, every
  !> rank reading its own part of `system`'s state (tau as `tau_name` names it), which must stand
  !> at `resume_time`, made the system's state with the integrator's state `control_state`;
  !> `values` are its figures. `problem` is '' or why the snapshot cannot be taken up, with what is
  !> allowed (`where` says which input and option asked for it).
  subroutine take_up_snapshot(system, path, comm, tau_name, resume_time, control_state, where, values, problem)
    class(distributed_system), intent(inout) :: system
    character(len=*), intent(in) :: path, tau_name, where
    integer, intent(in) :: comm
    real(real64), intent(in) :: resume_time, control_state(:)
    type(distributed_figures), intent(out) :: values
    character(len=:), allocatable, intent(out) :: problem
    type(distributed_part) :: state
    type(failure_type) :: reading
    real(real64) :: snapshot_time

    problem = ''
    call system%part(state, reading)       ! this rank's part of the state: the shapes to read
    if (.not. reading%failed()) call transfer_part(path, comm, snapshot_time, state, tau_name, .true., reading)
    if (len(tau_name) == 0) state%tau = state%theta      ! tau is the temperature, stored as theta
    if (.not. reading%failed()) then
      if (abs(snapshot_time - resume_time) > 0.0_real64) then
        problem = path//': its last snapshot (t = '//fixed_text(snapshot_time, 6)//' s) is not where its resume '// &
                  'record stands (t = '//fixed_text(resume_time, 6)//' s)'//where//'; allowed: a file of a run '// &
                  'split over ranks, as eme_run wrote it'
        return
      end if
      call system%restore(state, reading)
      if (.not. reading%failed()) call system%restore_state(resume_time, control_state, reading)
    end if
    if (.not. reading%failed()) call system%figures(values, reading)
    if (reading%failed()) problem = path//': its last snapshot cannot be taken up: '//reading%message//where// &
                                    '; allowed: a file of this input''s run split over ranks'
  end subroutine take_up_snapshot

  !> The snapshot's dataset of tau: the run's own variable when it is the entropy or the internal
  ! energy, none when it is the temperature or the model has none.
  function tau_dataset(variable, thermal) result(name)
    integer, intent(in) :: variable
    logical, intent(in) :: thermal
    character(len=:), allocatable :: name

    name = ''
    if (.not. thermal) return
    if (variable == tau_entropy) name = 'entropy'
    if (variable == tau_internal_energy) name = 'internal_energy'
  end function tau_dataset

  !> Whether the rank holds more snapshot bytes than it may (the window is then forced).
  pure logical function full(self)
    class(snapshot_window), intent(in) :: self

    full = self%new_bytes > snapshot_buffer_bytes
  end function full

end module snapshot_windows
