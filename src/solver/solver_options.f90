!> The step solver's run-time choices from PETSc's options database (src/solver/petsc_options.c
!> registers them, so that PETSc's -help lists them with their descriptions), and which options a
!> user gave, by part of their name. Each switch undoes one of the step's speed-ups, for
!> measuring what it buys (docs/performance.md):
!>   -eme_chord_predictor false   no chord refinement of the predictor
!>   -eme_fused_kernel false      the generic residual on the full unknowns instead of the model's
!>                                fused, condensed step (src/scheme/condensed_step), where it has one
!>   -eme_lean_snes false         SNES builds the Jacobian (SNESComputeJacobian) and takes its
!>                                'basic' line search
!>   -eme_direct_newton true      the lean way's iteration by hand (src/solver/hand_newton's
!>                                newton_iterate, the same iterates) instead of inside SNESSolve
!>   -eme_modified_newton false   a new Jacobian for every Newton iteration (but the final chord
!>                                step) instead of keeping the LU factors while they contract
!>   -eme_final_chord false       (with -eme_modified_newton false) not even the final chord step
!> and the modified Newton's threshold (src/solver/modified_newton):
!>   -eme_chord_iterations M      keep the LU factors while their contraction reaches the acceptance
!>                                level within M chord iterations (1 to 10)
!> and one for the step itself:
!>   -eme_max_halvings N          halve a step whose root is not found, recursively, N times at most
!> and two for the local error estimate (src/integrator/local_error_estimate):
!>   -eme_error_estimate          record it also at fixed steps
!>   -eme_error_scale F           multiply it by F before the step-size controller sees it
module solver_options
  use, intrinsic :: iso_c_binding, only: c_int, c_char, c_null_char, c_double
  use, intrinsic :: iso_fortran_env, only: real64
  use modified_newton, only: default_chord_iterations
  use failures, only: failure_type, fail_on_code
  implicit none (type, external)
  private
  public :: step_solver_options, read_solver_options, option_given, read_step_control_options, option_value

  !> The switches, the modified Newton's threshold and the halving depth, with their defaults.
  type :: step_solver_options
    logical :: chord_predictor = .true.
    logical :: fused_kernel = .true.
    logical :: lean_snes = .true.
    logical :: direct_newton = .false.
    logical :: final_chord = .true.
    logical :: modified_newton = .true.
    integer :: chord_iterations = default_chord_iterations
    integer :: max_halvings = 6
  end type step_solver_options

  interface
    function eme_read_solver_options(chord_predictor, fused_kernel, lean_snes, direct_newton, final_chord, &
                                     modified_newton, chord_iterations, max_halvings) &
      bind(C, name='eme_read_solver_options') result(ierr)
      import :: c_int
      integer(c_int), intent(inout) :: chord_predictor, fused_kernel, lean_snes, direct_newton, final_chord, &
                                       modified_newton, chord_iterations, max_halvings
      integer(c_int) :: ierr
    end function eme_read_solver_options

    function eme_read_step_control_options(record, scale) bind(C, name='eme_read_step_control_options') result(ierr)
      import :: c_int, c_double
      integer(c_int), intent(inout) :: record
      real(c_double), intent(inout) :: scale
      integer(c_int) :: ierr
    end function eme_read_step_control_options

    function eme_option_given(text, given) bind(C, name='eme_option_given') result(ierr)
      import :: c_int, c_char
      character(kind=c_char), intent(in) :: text(*)
      integer(c_int), intent(out) :: given
      integer(c_int) :: ierr
    end function eme_option_given

    function eme_option_value(name, value, size, set) bind(C, name='eme_option_value') result(ierr)
      import :: c_int, c_char
      character(kind=c_char), intent(in) :: name(*)
      character(kind=c_char), intent(out) :: value(*)
      integer(c_int), value :: size
      integer(c_int), intent(out) :: set
      integer(c_int) :: ierr
    end function eme_option_value
  end interface

contains

  !> The switches as the options database sets them. A failure (failure_library) for a PETSc
  !> error (e.g. a value that is not a logical, a depth outside 0..30 or chord iterations outside
  !> 1..10).
  subroutine read_solver_options(options, failure)
    type(step_solver_options), intent(out) :: options
    type(failure_type), intent(out) :: failure
    integer(c_int) :: flags(6), depth, chords
    integer :: ierr

    flags = merge(1_c_int, 0_c_int, [options%chord_predictor, options%fused_kernel, options%lean_snes, &
                                     options%final_chord, options%modified_newton, options%direct_newton])
    depth = int(options%max_halvings, c_int)
    chords = int(options%chord_iterations, c_int)
    ierr = int(eme_read_solver_options(flags(1), flags(2), flags(3), flags(6), flags(4), flags(5), chords, depth))
    options%max_halvings = int(depth)
    options%chord_predictor = flags(1) /= 0
    options%fused_kernel = flags(2) /= 0
    options%lean_snes = flags(3) /= 0
    options%final_chord = flags(4) /= 0
    options%modified_newton = flags(5) /= 0
    options%direct_newton = flags(6) /= 0
    options%chord_iterations = int(chords)
    call fail_on_code(failure, ierr, 'read_solver_options', 'PETSc refused an -eme_ solver option')
  end subroutine read_solver_options

  !> -eme_error_estimate (default .false.) and -eme_error_scale (default 1). A failure
  !> (failure_library) for a PETSc error (a value of the wrong kind, or a scale that is not positive).
  subroutine read_step_control_options(record_estimate, error_scale, failure)
    logical, intent(out) :: record_estimate
    real(real64), intent(out) :: error_scale
    type(failure_type), intent(out) :: failure
    integer :: ierr
    integer(c_int) :: record
    real(c_double) :: scale

    record = 0
    scale = 1.0_c_double
    ierr = int(eme_read_step_control_options(record, scale))
    record_estimate = record /= 0
    error_scale = real(scale, real64)
    call fail_on_code(failure, ierr, 'read_step_control_options', 'PETSc refused an -eme_error_ option')
  end subroutine read_step_control_options

  !> Whether the name of an option the user gave contains `text` (e.g. 'view', '-snes_compare').
  !> A PETSc-style helper (ierr, for PetscCall) of snes_solver's PETSc-side routines.
  subroutine option_given(text, given, ierr)
    character(len=*), intent(in) :: text
    logical, intent(out) :: given
    integer, intent(out) :: ierr
    integer(c_int) :: found

    ierr = int(eme_option_given(text//c_null_char, found))
    given = found /= 0
  end subroutine option_given

  !> Whether the option `name` (exactly, e.g. '-snes_mf') is set, and its value ('' if it has
  !> none). A PETSc-style helper (ierr, for PetscCall) of snes_solver's PETSc-side routines.
  subroutine option_value(name, value, set, ierr)
    character(len=*), intent(in) :: name
    character(len=*), intent(out) :: value
    logical, intent(out) :: set
    integer, intent(out) :: ierr
    character(kind=c_char) :: buffer(len(value) + 1)
    integer(c_int) :: found
    integer :: i

    ierr = int(eme_option_value(name//c_null_char, buffer, int(size(buffer), c_int), found))
    set = found /= 0
    value = ''
    do i = 1, len(value)
      if (buffer(i) == c_null_char) exit
      value(i:i) = buffer(i)
    end do
  end subroutine option_value

end module solver_options
