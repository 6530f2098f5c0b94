!> A crash-safe HDF5 file that grows by rows (docs/faults.md): whatever stops the writer (a
!> kill, a full disk, a signal), `path` names a closed, readable file whose tables agree in
!> length, holding the rows of its last completed write.
!>
!> The file is built in memory (src/io/hdf5_files) with its tables of rows (src/io/hdf5_series)
!> and reaches the disk in one checked write, at the end or at its first write. From then on,
!> buffered rows are appended in windows, never to `path` itself, because a kill inside HDF5's
!> writes can leave a file it cannot read: a window opens the spare copy `path`.spare, which lags
!> one window behind, after reserving the disk space it will need, appends the rows, lets the
!> caller write its attributes, closes it and exchanges the two names, so that the old file
!> becomes the spare. A reader that opened the file before the last exchange may still hold the
!> spare open: a window that may wait is deferred and retried 50 ms later; one that
!> cannot wait replaces the spare by a copy of `path`, and the reader keeps its file as it was.
!> After a failed write the spare is not used again: `path` keeps what it held.
!>
!> Use: `start`; define the tables' datasets and set attributes on `file`; append rows to the
!> tables; when `write_due`, `begin_rows`, write the attributes that go with the rows into
!> `file`, and `end_rows`; at the end the same with final = .true.
!>
!> Writes fall due by the clock (write_interval), so the sequence of file operations of a run
!> depends on the machine's speed. The testing hook EME_WRITE_EVERY_ROWS=N (environment) makes
!> them fall due every N rows instead, and never by the clock: a test that kills a run at its
!> K-th file operation then meets the same sequence on a busy machine (docs/faults.md).
module crash_safe_file
  use, intrinsic :: iso_fortran_env, only: real64, int64
  use hdf5_files, only: hdf5_file, file_template
  use hdf5_series, only: series_table
  use filesystem, only: sync_file, exchange_files, copy_file, remove_file
  use failures, only: failure_type
  implicit none (type, external)
  private
  public :: safe_file, spare_addition

  !> Bytes reserved beyond the rows of a window, for attributes.
  integer(int64), parameter :: attribute_room = 65536

  !> What a caller adds to the spare in a window, after its rows and attributes and before it
  !> takes the name `path` (a distributed run's snapshots, which every rank writes into the closed
  !> spare: src/run/distributed_simulation). A failure leaves `path` as it was.
  type, abstract :: spare_addition
  contains
    procedure(add_interface), deferred :: add
  end type spare_addition

  abstract interface
    !> Adds to the closed file at `path`.
    subroutine add_interface(self, path, failure)
      import :: spare_addition, failure_type
      class(spare_addition), intent(inout) :: self
      character(len=*), intent(in) :: path
      type(failure_type), intent(out) :: failure
    end subroutine add_interface
  end interface

  !> The file, its tables and where a write stands.
  type :: safe_file
    type(hdf5_file) :: file                       !! in memory until on disk; open from begin_rows to end_rows
    type(series_table), allocatable :: tables(:)
    character(len=:), allocatable :: path, spare
    logical :: on_disk = .false.                  !! the file exists at `path`
    logical :: durable = .true.                   !! the finished file is synced to disk (fsync)
    !> A final write from memory makes chunked, extendible datasets too (a run that may be continued)
    logical :: extendible = .false.
    type(failure_type) :: failure                 !! the first failed write: later windows fail with it
    real(real64) :: write_interval = 1.0_real64   !! seconds between windows
    integer(int64) :: last_write = 0, clock_rate = 1
    integer(int64) :: write_every_rows = 0        !! > 0: writes fall due by rows, not time (testing hook)
    logical, private :: final = .false.           !! the write under way is the last
    logical, private :: whole = .false.           !! ... and writes the file whole from memory
    integer(int64), allocatable, private :: kept(:)   !! each table's rows of the last window, which the spare lacked
  contains
    procedure :: start
    procedure :: buffers_full
    procedure :: write_due
    procedure :: begin_rows
    procedure :: end_rows
    procedure :: open_in_place
    procedure :: resume_from
  end type safe_file

contains

  !> An empty file in memory for `path` with `table_count` tables (to be defined by the caller),
  !> made from `template` if given (src/io/hdf5_files: the root attributes of a series of
  !> similar files; settled at the first write). A failure if HDF5 failed.
  subroutine start(self, path, table_count, failure, template)
    class(safe_file), intent(inout) :: self
    character(len=*), intent(in) :: path
    integer, intent(in) :: table_count
    type(failure_type), intent(out) :: failure
    type(file_template), intent(inout), target, optional :: template

    self%path = path
    self%spare = path//'.spare'
    self%write_every_rows = rows_hook()
    allocate (self%tables(table_count))
    allocate (self%kept(table_count))
    call system_clock(self%last_write, self%clock_rate)
    if (present(template)) then
      call self%file%create_from_template(template, failure)
    else
      call self%file%create_in_memory(failure)
    end if
  end subroutine start

  !> Whether a table's buffer is full (its rows must be written before more are appended).
  logical function buffers_full(self)
    class(safe_file), intent(in) :: self
    integer :: k

    buffers_full = .false.
    do k = 1, size(self%tables)
      buffers_full = buffers_full .or. self%tables(k)%full()
    end do
  end function buffers_full

  !> Whether buffered rows are due on disk: write_interval seconds since the last write, or a
  !> full buffer.
  logical function write_due(self)
    class(safe_file), intent(in) :: self
    integer(int64) :: now
    integer :: k

    if (self%buffers_full()) then
      write_due = .true.
    else if (self%write_every_rows > 0) then
      write_due = .false.
      do k = 1, size(self%tables)
        associate (table => self%tables(k))
          write_due = write_due .or. table%first_row + table%buffered - table%written >= self%write_every_rows
        end associate
      end do
    else
      call system_clock(now)
      write_due = real(now - self%last_write, real64) >= self%write_interval*real(self%clock_rate, real64)
    end if
  end function write_due

  !> Writes the buffered rows of every table: the first time into the file in memory (contiguous
  !> datasets if `final`, else chunked ones, as more rows will follow), later in a window into the
  !> spare. The file is then open for the attributes that go with the rows; end_rows finishes the
  !> write. With `defer`, a window whose spare a reader holds open is put off (`deferred`, no
  !> failure: retried 50 ms later; call no end_rows then). A failure: the OS's words or HDF5's.
  subroutine begin_rows(self, final, failure, defer, deferred)
    class(safe_file), intent(inout) :: self
    logical, intent(in) :: final
    type(failure_type), intent(out) :: failure
    logical, intent(in), optional :: defer
    logical, intent(out), optional :: deferred
    character(len=:), allocatable :: layout, table_layout
    logical :: waiting, held, busy
    integer :: k

    self%final = final
    self%whole = .not. self%on_disk
    if (present(deferred)) deferred = .false.
    call system_clock(self%last_write)
    if (self%whole) then
      ! A file made from a template may take its datasets from there: then only their values are
      ! given, before the file opens (settle_template, when the root attributes are all set).
      layout = ''
      do k = 1, size(self%tables)
        table_layout = self%tables(k)%layout(final .and. .not. self%extendible)
        if (len(table_layout) == 0) then
          layout = ''                             ! a table not to be written whole: nothing shared
          exit
        end if
        layout = layout//achar(10)//table_layout
      end do
      call self%file%template_datasets(layout, held)
      do k = 1, size(self%tables)
        if (.not. failure%failed() .and. held) &
          call self%tables(k)%write(self%file, final .and. .not. self%extendible, failure, held=.true.)
      end do
      if (.not. failure%failed()) call self%file%settle_template(failure)
      do k = 1, size(self%tables)
        if (.not. failure%failed() .and. .not. held) &
          call self%tables(k)%write(self%file, final .and. .not. self%extendible, failure)
      end do
      if (.not. failure%failed()) call self%file%keep_template_datasets()
      return
    end if
    failure = self%failure
    if (failure%failed()) return
    waiting = .false.
    if (present(defer)) waiting = defer
    call open_spare(failure, busy)
    if (busy .and. waiting) then
      self%last_write = self%last_write - int((self%write_interval - 0.05_real64)*self%clock_rate, int64)
      failure = failure_type()
      if (present(deferred)) deferred = .true.
      return
    end if
    if (busy) then
      call copy_file(self%path, self%spare, failure)
      do k = 1, size(self%tables)
        call self%tables(k)%forget(self%tables(k)%written)
      end do
      if (.not. failure%failed()) call open_spare(failure, busy)
    end if
    if (failure%failed()) then
      self%failure = failure
      return
    end if
    do k = 1, size(self%tables)
      self%kept(k) = self%tables(k)%written
      if (.not. failure%failed()) call self%tables(k)%write(self%file, .false., failure, keep=.true.)
    end do
    if (failure%failed()) self%failure = failure

  contains

    subroutine open_spare(failure, busy)
      type(failure_type), intent(out) :: failure
      logical, intent(out) :: busy
      integer(int64) :: bytes
      integer :: k

      bytes = attribute_room
      do k = 1, size(self%tables)
        bytes = bytes + self%tables(k)%window_bytes()
      end do
      call self%file%open_existing(self%spare, .true., failure, reserve=bytes, wait_ms=-1, busy=busy)
    end subroutine open_spare
  end subroutine begin_rows

  !> Finishes the write begun by begin_rows; `failure` comes in as the attributes' (none if they
  !> were written) and goes out as the write's. The first time the file is stored at `path` (synced
  !> if durable and final) and, unless final, as the spare; later the spare is closed, receives the
  !> `addition` (in a window only: the first write takes none), and takes the name `path`. At the
  !> end the spare is removed, and a durable file synced. On failure `path` holds what it held.
  subroutine end_rows(self, failure, addition)
    class(safe_file), intent(inout) :: self
    type(failure_type), intent(inout) :: failure
    class(spare_addition), intent(inout), optional :: addition
    type(failure_type) :: closing, ignored
    integer :: k

    if (self%whole) then
      if (.not. failure%failed()) call self%file%store(self%path, self%durable .and. self%final, failure)
      if (self%final) then
        call self%file%close(ignored)
        call remove_file(self%spare, ignored)        ! of an earlier run killed with this output
        self%on_disk = .not. failure%failed()
        return
      end if
      if (failure%failed()) return
      self%on_disk = .true.
      call self%file%store(self%spare, .false., failure)
      self%failure = failure
      call self%file%close(closing)
      if (.not. failure%failed()) failure = closing
      return
    end if
    call self%file%close(closing)           ! (not open if the spare could not be opened)
    if (self%failure%failed()) then
      failure = self%failure
    else
      if (.not. failure%failed()) failure = closing
      if (.not. failure%failed() .and. present(addition)) call addition%add(self%spare, failure)
      if (.not. failure%failed()) call exchange_files(self%spare, self%path, failure)
      self%failure = failure
      if (.not. failure%failed()) then
        do k = 1, size(self%tables)
          call self%tables(k)%forget(self%kept(k))
        end do
      end if
    end if
    if (.not. self%final) return
    call remove_file(self%spare, ignored)
    if (.not. failure%failed() .and. self%durable) call sync_file(self%path, failure)
  end subroutine end_rows

  ! EME_WRITE_EVERY_ROWS from the environment: a positive row count, or 0 (unset or not a count).
  integer(int64) function rows_hook()
    character(len=32) :: text
    integer :: length, stat

    rows_hook = 0
    call get_environment_variable('EME_WRITE_EVERY_ROWS', text, length, stat)
    if (stat /= 0 .or. length == 0) return
    read (text, *, iostat=stat) rows_hook
    if (stat /= 0 .or. rows_hook < 0) rows_hook = 0
  end function rows_hook

  !> Opens `path` itself for writing (no spare, no window): the last resort, after a final
  !> window failed for want of space, to say in an attribute why its rows are missing (the space
  !> the removed spare held makes room). Close `file` afterwards.
  subroutine open_in_place(self, failure)
    class(safe_file), intent(inout) :: self
    type(failure_type), intent(out) :: failure

    call self%file%open_existing(self%path, .true., failure)
  end subroutine open_in_place

  !> Continues the file that `path` holds (its tables defined as when it was made): the file in
  !> memory is dropped, the spare becomes a copy of `path`, and each table k goes on from row
  !> rows(k) (later rows of the file are replaced by the next write). A failure: the OS's words
  !> or HDF5's.
  subroutine resume_from(self, rows, failure)
    class(safe_file), intent(inout) :: self
    integer(int64), intent(in) :: rows(:)
    type(failure_type), intent(out) :: failure
    integer :: k

    call self%file%close(failure)
    if (.not. failure%failed()) call copy_file(self%path, self%spare, failure)
    if (failure%failed()) return
    self%on_disk = .true.
    self%file%fresh = .false.
    do k = 1, size(self%tables)
      self%tables(k)%created = .true.
      self%tables(k)%first_row = rows(k)
      self%tables(k)%written = rows(k)
      self%tables(k)%buffered = 0
    end do
  end subroutine resume_from

end module crash_safe_file
