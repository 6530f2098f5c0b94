!> The code's own command-line options of a run, read from PETSc's options database (so they
!> mix with PETSc's own and appear in -options_left): -eme_progress [true|false] (progress lines
!> on stderr; by default only when stderr is a terminal) and -eme_overwrite (replace an existing
!> complete result, as &output overwrite = .true. does).
module run_options
#include <petsc/finclude/petscsys.h>
  use petscsys
  use filesystem, only: stderr_is_terminal
  implicit none
  private
  public :: progress_wanted, overwrite_requested

contains

  !> Whether eme_run prints progress lines: -eme_progress as given, else when stderr is a terminal.
  logical function progress_wanted()
    PetscBool :: value, given
    PetscErrorCode :: ierr

    value = PETSC_FALSE
    call PetscOptionsGetBool(PETSC_NULL_OPTIONS, PETSC_NULL_CHARACTER, '-eme_progress', value, given, ierr)
    if (ierr /= 0) given = PETSC_FALSE
    if (given) then
      progress_wanted = value
    else
      progress_wanted = stderr_is_terminal()
    end if
  end function progress_wanted

  !> Whether the command line asks to replace an existing complete result (-eme_overwrite).
  logical function overwrite_requested()
    PetscBool :: value, given
    PetscErrorCode :: ierr

    value = PETSC_FALSE
    call PetscOptionsGetBool(PETSC_NULL_OPTIONS, PETSC_NULL_CHARACTER, '-eme_overwrite', value, given, ierr)
    overwrite_requested = ierr == 0 .and. given .and. value
  end function overwrite_requested

end module run_options
