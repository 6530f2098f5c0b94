!> The code's own command-line options of a run, read from PETSc's options database (so they
!> mix with PETSc's own, appear in -options_left, and PETSc's -help lists them with their
!> descriptions: src/solver/petsc_options.c registers them): -eme_progress [true|false]
!> (progress lines on stderr; by default only when stderr is a terminal) and -eme_overwrite
!> (replace an existing complete result, as &output overwrite = .true. does) and -eme_continue
!> (continue the run its file holds, docs/faults.md), -eme_split and -eme_dense (a chain on the
!> split or the dense path on one process, whatever its size, docs/performance.md). Also the options
!> database as text, for the provenance a run file records.
module run_options
#include <petsc/finclude/petscsys.h>
  use petscsys
  use, intrinsic :: iso_c_binding, only: c_int, c_char, c_null_char
  use filesystem, only: stderr_is_terminal
  implicit none
  private
  public :: progress_wanted, overwrite_requested, continue_requested, split_requested, dense_requested, &
            petsc_options_in_force

  !> The run's own flags as the options database sets them (src/solver/petsc_options.c; 0 or 1).
  type :: run_flags
    integer(c_int) :: progress = 0, progress_given = 0, overwrite = 0, resume = 0, split = 0, dense = 0
  end type run_flags

  interface
    function eme_read_run_options(progress, progress_given, overwrite, resume, split, dense) &
      bind(C, name='eme_read_run_options') result(ierr)
      import :: c_int
      integer(c_int), intent(inout) :: progress, progress_given, overwrite, resume, split, dense
      integer(c_int) :: ierr
    end function eme_read_run_options

    function eme_options_in_force(text, size) bind(C, name='eme_options_in_force') result(ierr)
      import :: c_int, c_char
      character(kind=c_char), intent(out) :: text(*)
      integer(c_int), value :: size
      integer(c_int) :: ierr
    end function eme_options_in_force
  end interface

contains

  !> Whether eme_run prints progress lines: -eme_progress as given, else when stderr is a terminal.
  logical function progress_wanted()
    type(run_flags) :: flags

    flags = read_flags()
    if (flags%progress_given /= 0) then
      progress_wanted = flags%progress /= 0
    else
      progress_wanted = stderr_is_terminal()
    end if
  end function progress_wanted

  !> Whether the command line asks to replace an existing complete result (-eme_overwrite).
  logical function overwrite_requested()
    type(run_flags) :: flags

    flags = read_flags()
    overwrite_requested = flags%overwrite /= 0
  end function overwrite_requested

  !> Whether the command line asks to continue the run that the output file holds (-eme_continue).
  logical function continue_requested()
    type(run_flags) :: flags

    flags = read_flags()
    continue_requested = flags%resume /= 0
  end function continue_requested

  !> Whether the command line asks for the split path on one process too (-eme_split).
  logical function split_requested()
    type(run_flags) :: flags

    flags = read_flags()
    split_requested = flags%split /= 0
  end function split_requested

  !> Whether the command line asks for the dense path for a chain that would be split (-eme_dense).
  logical function dense_requested()
    type(run_flags) :: flags

    flags = read_flags()
    dense_requested = flags%dense /= 0
  end function dense_requested

  !> The options database as text ('-name value ...'), as the run uses it.
  function petsc_options_in_force() result(text)
    character(len=:), allocatable :: text
    character(kind=c_char, len=16384) :: buffer

    buffer = ''
    if (eme_options_in_force(buffer, len(buffer, kind=c_int)) /= 0) then
      text = 'unknown: PETSc could not list its options'
    else
      text = trim(buffer(1:index(buffer, c_null_char) - 1))
    end if
  end function petsc_options_in_force

  ! The run options as the database sets them (0 or 1; a value PETSc cannot read as a logical
  ! counts as not given: all 0).
  function read_flags() result(flags)
    type(run_flags) :: flags

    if (eme_read_run_options(flags%progress, flags%progress_given, flags%overwrite, flags%resume, flags%split, &
                             flags%dense) /= 0) flags = run_flags()
  end function read_flags

end module run_options
