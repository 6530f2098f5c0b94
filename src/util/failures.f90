!> One failure type for the whole library (docs/development.md, "Errors"): a named code from one
!> enumeration, a message and where it happened, as fortran-lang/stdlib's state_type and
!> mctc-lib's error_type carry them. Library procedures return it and never stop the program;
!> only drivers print it and exit. Pure kernels called on every Newton iteration (the
!> potentials, the invariants, the field) return only the code, which their first caller that
!> can afford a message wraps into a failure_type.
module failures
  implicit none (type, external)
  private
  public :: failure_type, fail, failure_code_name, fail_on_code
  public :: failure_none, domain_nonpositive_length, domain_nonpositive_temperature, domain_overflow, domain_degenerate
  public :: failure_input, failure_io, failure_library, failure_not_converged, failure_mismatch, &
            failure_interrupted

  !> The one enumeration of what can go wrong. Codes 1 to 4 are the domain codes the kernels
  !> return; the model's words (model_interface) say what "length" or "temperature" means in it.
  enum, bind(c)
    enumerator :: failure_none = 0                  !! nothing failed
    enumerator :: domain_nonpositive_length = 1     !! a state outside the model's domain: a length <= 0
    enumerator :: domain_nonpositive_temperature = 2 !! a state outside the domain: a temperature <= 0
    enumerator :: domain_overflow = 3               !! an evaluation overflowed (or cannot be done)
    !> conditions that determine the state are degenerate there (the constraints' and the conserved
    !> momentum's gradients dependent: relaxed schemes' projection)
    enumerator :: domain_degenerate = 4
    enumerator :: failure_input = 5                 !! an input names a value that is not allowed
    enumerator :: failure_io = 6                    !! a file or directory could not be read or written
    enumerator :: failure_library = 7               !! PETSc, HDF5, SUNDIALS, MPI or the C runtime failed
    enumerator :: failure_not_converged = 8         !! an iteration (Newton, a root search) did not converge
    enumerator :: failure_mismatch = 9              !! data does not fit what reads it (a resume record, a file)
    enumerator :: failure_interrupted = 10          !! a signal or a limit stopped the work
  end enum

  !> What went wrong: `code` (failure_none when nothing did), a message for people and the
  !> procedure or file where it happened.
  type :: failure_type
    integer :: code = failure_none
    character(len=:), allocatable :: message
    character(len=:), allocatable :: origin
  contains
    procedure :: failed
    procedure :: text
  end type failure_type

contains

  !> Sets `report` to a failure with `code`, `message` and its `origin`.
  pure subroutine fail(report, code, message, origin)
    type(failure_type), intent(out) :: report
    integer, intent(in) :: code
    character(len=*), intent(in) :: message
    character(len=*), intent(in), optional :: origin

    report%code = code
    report%message = message
    if (present(origin)) report%origin = origin
  end subroutine fail

  !> Turns a library's nonzero return code (a PetscErrorCode, a C shim's int) into a
  !> failure_library at `origin`, with `what` as the message (the library's code appended); a zero
  !> code leaves `report` as it was. The one place where such codes become failures.
  pure subroutine fail_on_code(report, code, origin, what)
    type(failure_type), intent(inout) :: report
    integer, intent(in) :: code
    character(len=*), intent(in) :: origin
    character(len=*), intent(in), optional :: what
    character(len=12) :: number

    if (code == 0) return
    write (number, '(i0)') code
    if (present(what)) then
      call fail(report, failure_library, what//' (code '//trim(number)//')', origin)
    else
      call fail(report, failure_library, 'a library call failed with code '//trim(number), origin)
    end if
  end subroutine fail_on_code

  !> True when something went wrong.
  elemental logical function failed(self)
    class(failure_type), intent(in) :: self

    failed = self%code /= failure_none
  end function failed

  !> The failure as one line for people: "message (in origin)", or the code's name alone; the
  !> origin is left out where the message already names it (an input's field, a file's path).
  pure function text(self) result(line)
    class(failure_type), intent(in) :: self
    character(len=:), allocatable :: line

    if (allocated(self%message)) then
      line = self%message
    else
      line = failure_code_name(self%code)
    end if
    if (allocated(self%origin)) then
      if (len(self%origin) > 0 .and. index(line, self%origin) == 0) line = line//' (in '//self%origin//')'
    end if
  end function text

  !> What a code means, in words that fit any model.
  pure function failure_code_name(code) result(name)
    integer, intent(in) :: code
    character(len=:), allocatable :: name

    select case (code)
    case (failure_none)
      name = 'no failure'
    case (domain_nonpositive_length)
      name = 'a non-positive length'
    case (domain_nonpositive_temperature)
      name = 'a non-positive temperature'
    case (domain_overflow)
      name = 'an overflow'
    case (domain_degenerate)
      name = 'degenerate conditions'
    case (failure_input)
      name = 'an input that is not allowed'
    case (failure_io)
      name = 'a file that could not be read or written'
    case (failure_library)
      name = 'a library error'
    case (failure_not_converged)
      name = 'an iteration that did not converge'
    case (failure_mismatch)
      name = 'data that does not fit'
    case (failure_interrupted)
      name = 'an interruption'
    case default
      name = 'an unknown failure'
    end select
  end function failure_code_name

end module failures
