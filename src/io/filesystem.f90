!> File-system operations (src/io/posix_files.c) with Fortran strings. Each returns a failure:
!> failure_io with the OS's words for its error number as the message (os_error_text) and the
!> path as origin; callers put their context before those words. The lock of an output
!> (lock_output) makes one process its only writer (docs/faults.md).
module filesystem
  use, intrinsic :: iso_c_binding, only: c_char, c_int, c_long, c_null_char
  use failures, only: failure_type, fail, failure_io
  implicit none (type, external)
  private
  public :: make_directories, make_parent_directories, rename_file, exchange_files, copy_file, remove_file, &
            file_exists, append_text, reserve_space, sync_file, os_error_text, os_failure, stderr_is_terminal, &
            output_lock, lock_output, unlock_output, lock_taken, lock_held_elsewhere, lock_not_offered, &
            recheck_lock

  !> What lock_output found, besides a failure: the lock is this process's; another live process
  !> holds it; the file system offers no working lock (the output is then written unguarded).
  integer, parameter :: lock_taken = 0, lock_held_elsewhere = -1, lock_not_offered = -2
  ! What lock_state finds: the lock file is still the one this process locked; it was removed;
  ! another file has its name (another writer's).
  integer, parameter :: lock_intact = 0, lock_removed = 1, lock_replaced = 2

  !> The lock of an output while this process holds it: the lock file, open.
  type :: output_lock
    character(len=:), allocatable :: path
    integer(c_int) :: descriptor = -1
  end type output_lock

  interface
    function c_make_directories(path) result(status) bind(c, name='eme_make_directories')
      import :: c_char, c_int
      character(kind=c_char), intent(in) :: path(*)
      integer(c_int) :: status
    end function c_make_directories
    function c_rename_file(from, to, sync) result(status) bind(c, name='eme_rename_file')
      import :: c_char, c_int
      character(kind=c_char), intent(in) :: from(*), to(*)
      integer(c_int), value :: sync
      integer(c_int) :: status
    end function c_rename_file
    function c_exchange_files(newer, path) result(status) bind(c, name='eme_exchange_files')
      import :: c_char, c_int
      character(kind=c_char), intent(in) :: newer(*), path(*)
      integer(c_int) :: status
    end function c_exchange_files
    function c_copy_file(from, to) result(status) bind(c, name='eme_copy_file')
      import :: c_char, c_int
      character(kind=c_char), intent(in) :: from(*), to(*)
      integer(c_int) :: status
    end function c_copy_file
    function c_remove_file(path) result(status) bind(c, name='eme_remove_file')
      import :: c_char, c_int
      character(kind=c_char), intent(in) :: path(*)
      integer(c_int) :: status
    end function c_remove_file
    function c_file_exists(path) result(status) bind(c, name='eme_file_exists')
      import :: c_char, c_int
      character(kind=c_char), intent(in) :: path(*)
      integer(c_int) :: status
    end function c_file_exists
    function c_append_text(path, text, length, sync) result(status) bind(c, name='eme_append_text')
      import :: c_char, c_int, c_long
      character(kind=c_char), intent(in) :: path(*), text(*)
      integer(c_long), value :: length
      integer(c_int), value :: sync
      integer(c_int) :: status
    end function c_append_text
    function c_reserve_space(path, bytes) result(status) bind(c, name='eme_reserve_space')
      import :: c_char, c_int, c_long
      character(kind=c_char), intent(in) :: path(*)
      integer(c_long), value :: bytes
      integer(c_int) :: status
    end function c_reserve_space
    function c_sync_file(path) result(status) bind(c, name='eme_sync_file')
      import :: c_char, c_int
      character(kind=c_char), intent(in) :: path(*)
      integer(c_int) :: status
    end function c_sync_file
    subroutine c_os_error_text(error, text, capacity) bind(c, name='eme_os_error_text')
      import :: c_char, c_int
      integer(c_int), value :: error, capacity
      character(kind=c_char), intent(out) :: text(*)
    end subroutine c_os_error_text
    function c_lock_output(path, descriptor, holder, capacity) result(status) bind(c, name='eme_lock_output')
      import :: c_char, c_int
      character(kind=c_char), intent(in) :: path(*)
      integer(c_int), intent(out) :: descriptor
      character(kind=c_char), intent(out) :: holder(*)
      integer(c_int), value :: capacity
      integer(c_int) :: status
    end function c_lock_output
    function c_lock_state(path, descriptor) result(state) bind(c, name='eme_lock_state')
      import :: c_char, c_int
      character(kind=c_char), intent(in) :: path(*)
      integer(c_int), value :: descriptor
      integer(c_int) :: state
    end function c_lock_state
    subroutine c_unlock_output(path, descriptor) bind(c, name='eme_unlock_output')
      import :: c_char, c_int
      character(kind=c_char), intent(in) :: path(*)
      integer(c_int), value :: descriptor
    end subroutine c_unlock_output
    function c_stderr_is_terminal() result(status) bind(c, name='eme_stderr_is_terminal')
      import :: c_int
      integer(c_int) :: status
    end function c_stderr_is_terminal
  end interface

contains

  !> mkdir -p path.
  subroutine make_directories(path, failure)
    character(len=*), intent(in) :: path
    type(failure_type), intent(out) :: failure

    call os_failure(failure, int(c_make_directories(trim(path)//c_null_char)), path)
  end subroutine make_directories

  !> Creates the directory that will hold `file` (nothing to do for a bare file name).
  subroutine make_parent_directories(file, failure)
    character(len=*), intent(in) :: file
    type(failure_type), intent(out) :: failure
    integer :: slash

    slash = index(file, '/', back=.true.)
    if (slash > 1) call make_directories(file(1:slash - 1), failure)
  end subroutine make_parent_directories

  !> Renames `from` to `to`, replacing `to` atomically; with `sync` (default) the directory entry
  !> is on disk on return.
  subroutine rename_file(from, to, failure, sync)
    character(len=*), intent(in) :: from, to
    type(failure_type), intent(out) :: failure
    logical, intent(in), optional :: sync
    logical :: durable

    durable = .true.
    if (present(sync)) durable = sync
    call os_failure(failure, int(c_rename_file(trim(from)//c_null_char, trim(to)//c_null_char, &
                                               merge(1_c_int, 0_c_int, durable))), from)
  end subroutine rename_file

  !> Gives the file `newer` the name `path`, and the file that had that name the name `newer`;
  !> `path` names a whole file at every instant (src/io/posix_files.c).
  subroutine exchange_files(newer, path, failure)
    character(len=*), intent(in) :: newer, path
    type(failure_type), intent(out) :: failure

    call os_failure(failure, int(c_exchange_files(trim(newer)//c_null_char, trim(path)//c_null_char)), path)
  end subroutine exchange_files

  !> Copies the file `from` as `to`, which is replaced whole (a process that has the old `to` open
  !> keeps it as it was).
  subroutine copy_file(from, to, failure)
    character(len=*), intent(in) :: from, to
    type(failure_type), intent(out) :: failure

    call os_failure(failure, int(c_copy_file(trim(from)//c_null_char, trim(to)//c_null_char)), from)
  end subroutine copy_file

  !> Removes `path`; a missing file is no error.
  subroutine remove_file(path, failure)
    character(len=*), intent(in) :: path
    type(failure_type), intent(out) :: failure

    call os_failure(failure, int(c_remove_file(trim(path)//c_null_char)), path)
  end subroutine remove_file

  !> Whether `path` is an existing regular file.
  logical function file_exists(path)
    character(len=*), intent(in) :: path

    file_exists = c_file_exists(trim(path)//c_null_char) == 1
  end function file_exists

  !> Appends `text` (whole lines) to `path`, creating it; with `sync` it is on disk on return.
  subroutine append_text(path, text, sync, failure)
    character(len=*), intent(in) :: path, text
    logical, intent(in) :: sync
    type(failure_type), intent(out) :: failure

    call os_failure(failure, int(c_append_text(trim(path)//c_null_char, text, int(len(text), c_long), &
                                               merge(1_c_int, 0_c_int, sync))), path)
  end subroutine append_text

  !> Allocates `bytes` of disk space at the end of the existing file `path`, so that writes into
  !> them cannot fail for want of space (ENOSPC or EFBIG come back here instead).
  subroutine reserve_space(path, bytes, failure)
    character(len=*), intent(in) :: path
    integer(c_long), intent(in) :: bytes
    type(failure_type), intent(out) :: failure

    call os_failure(failure, int(c_reserve_space(trim(path)//c_null_char, bytes)), path)
  end subroutine reserve_space

  !> Puts the data of the existing file `path` on disk (fsync).
  subroutine sync_file(path, failure)
    character(len=*), intent(in) :: path
    type(failure_type), intent(out) :: failure

    call os_failure(failure, int(c_sync_file(trim(path)//c_null_char)), path)
  end subroutine sync_file

  !> The OS's words for error number `error` ('No space left on device').
  function os_error_text(error) result(text)
    integer, intent(in) :: error
    character(len=:), allocatable :: text
    character(len=256) :: buffer

    call c_os_error_text(int(error, c_int), buffer, int(len(buffer), c_int))
    text = buffer(1:max(0, index(buffer, c_null_char) - 1))
  end function os_error_text

  !> Sets `failure` to failure_io with the OS's words for `error` (an errno) and `origin` (the path);
  !> error 0 leaves it as it was. The one place where the OS's error numbers become failures.
  subroutine os_failure(failure, error, origin)
    type(failure_type), intent(inout) :: failure
    integer, intent(in) :: error
    character(len=*), intent(in) :: origin

    if (error /= 0) call fail(failure, failure_io, os_error_text(error), origin)
  end subroutine os_failure

  !> Whether standard error is a terminal.
  logical function stderr_is_terminal()
    stderr_is_terminal = c_stderr_is_terminal() == 1
  end function stderr_is_terminal

  !> Takes the lock file `path` (created, with its folder) for this process: an exclusive lock
  !> the OS releases when the process ends, however it ends, so the lock file a killed writer
  !> left behind is taken again. `found`: lock_taken (held until unlock_output or the end of the
  !> process), lock_held_elsewhere (`holder` names the live process that holds it, e.g. 'process
  !> 4242 on host node7', or is empty), lock_not_offered (the file system has no working lock;
  !> nothing is held); a failure (the OS's words) if the lock file cannot be made.
  subroutine lock_output(lock, path, found, holder, failure)
    type(output_lock), intent(out) :: lock
    character(len=*), intent(in) :: path
    integer, intent(out) :: found
    character(len=:), allocatable, intent(out) :: holder
    type(failure_type), intent(out) :: failure
    character(len=512) :: buffer
    integer :: status

    lock%path = path
    status = int(c_lock_output(trim(path)//c_null_char, lock%descriptor, buffer, int(len(buffer), c_int)))
    holder = buffer(1:max(0, index(buffer, c_null_char) - 1))
    found = lock_taken
    if (status == lock_held_elsewhere .or. status == lock_not_offered) then
      found = status
    else
      call os_failure(failure, status, path)
    end if
  end subroutine lock_output

  ! Whether the lock file is still the one this process locked (lock_intact), or was removed
  ! (lock_removed) or replaced (lock_replaced) behind its back: the lock guards nothing once its
  ! file lost its name. lock_intact for a lock not held (nothing to guard).
  integer function lock_state(lock)
    type(output_lock), intent(in) :: lock

    lock_state = lock_intact
    if (lock%descriptor < 0) return
    lock_state = int(c_lock_state(lock%path//c_null_char, lock%descriptor))
    if (lock_state < 0) lock_state = lock_intact
  end function lock_state

  ! After the lock was lost (lock_state): takes the lock file at its path again, as lock_output
  ! (found: lock_taken, lock_held_elsewhere with its holder, ...); the lost one is let go.
  subroutine take_lock_again(lock, found, holder, failure)
    type(output_lock), intent(inout) :: lock
    integer, intent(out) :: found
    character(len=:), allocatable, intent(out) :: holder
    type(failure_type), intent(out) :: failure
    type(output_lock) :: again

    call lock_output(again, lock%path, found, holder, failure)
    call unlock_output(lock)          ! (its file lost the name: nothing is removed)
    lock = again
  end subroutine take_lock_again

  !> Before a write: whether `lock` is still this process's (lock_state). If its file was removed
  !> or replaced (`lost`), another writer can be in: the lock is taken again if it can be
  !> (`retaken`; else `holder` names who holds it now), and `what` says what became of it
  !> ('removed', 'replaced by another process''s').
  subroutine recheck_lock(lock, lost, retaken, what, holder)
    type(output_lock), intent(inout) :: lock
    logical, intent(out) :: lost, retaken
    character(len=:), allocatable, intent(out) :: what, holder
    integer :: state, found
    type(failure_type) :: taking

    state = lock_state(lock)
    lost = state /= lock_intact
    retaken = .false.
    what = ''
    holder = ''
    if (.not. lost) return
    select case (state)
    case (lock_removed)
      what = 'removed'
    case (lock_replaced)
      what = 'replaced by another process''s'
    end select
    call take_lock_again(lock, found, holder, taking)
    retaken = found == lock_taken .and. .not. taking%failed()
    if (.not. retaken .and. len(holder) == 0) holder = 'another process'
  end subroutine recheck_lock

  !> Lets go of the lock (its file is removed if it still has its name); nothing to do if it is
  !> not held.
  subroutine unlock_output(lock)
    type(output_lock), intent(inout) :: lock

    if (lock%descriptor < 0) return
    call c_unlock_output(lock%path//c_null_char, lock%descriptor)
    lock%descriptor = -1
  end subroutine unlock_output

end module filesystem
