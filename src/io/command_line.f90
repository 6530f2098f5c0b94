!> The drivers' command line: the program's own options (--help, -h, --version, ...), exactly
!> one input file, and PETSc options before or after it. A PETSc option ('-name') takes the next
!> argument as its value, as PETSc reads it, unless that argument ends in '.nml': then it is the
!> input file. `initialize_petsc` hands PETSc the command line without the input file, so that
!> no option takes it for its value (-help FILE.nml, -info FILE.nml). `check_own_options` checks
!> the -eme_* options' values before anything reads them; `check_petsc_file_options` the files
!> PETSc's options would write, before PETSc starts and after; `unused_petsc_options` lists the
!> options nothing used, as -options_left would.
module command_line
  use, intrinsic :: iso_c_binding, only: c_char, c_int, c_null_char
  use number_text, only: integer_text
  use namelist_text, only: joined
  use failures, only: failure_type, fail, fail_on_code, failure_input, failure_library
  implicit none (type, external)
  private
  public :: command_arguments, parse_command_line, initialize_petsc, check_own_options, petsc_help_requested
  public :: unused_petsc_options, benchmark_repeats, petsc_error_text, check_petsc_file_options, has_argument, &
            launcher_rank, forget_petsc_file_options

  !> What the command line asked for.
  type :: command_arguments
    character(len=:), allocatable :: input_file          !! '' when none was given
    character(len=32), allocatable :: flags(:)           !! the program's own options that were given
    integer :: file_position = 0                         !! the input file's place on the command line (0: none)
    character(len=:), allocatable :: given_files         !! every argument taken for an input file, each on a line
  contains
    procedure :: has_flag
  end type command_arguments

  interface
    ! src/io/petsc_option_checks.c
    function c_petsc_initialize(arguments, count) result(status) bind(c, name='eme_petsc_initialize')
      import :: c_char, c_int
      character(kind=c_char), intent(in) :: arguments(*)
      integer(c_int), value :: count
      integer(c_int) :: status
    end function c_petsc_initialize
    function c_help_requested() result(requested) bind(c, name='eme_petsc_help_requested')
      import :: c_int
      integer(c_int) :: requested
    end function c_help_requested
    function c_unused_options(text, size) result(status) bind(c, name='eme_petsc_unused_options')
      import :: c_char, c_int
      character(kind=c_char), intent(out) :: text(*)
      integer(c_int), value :: size
      integer(c_int) :: status
    end function c_unused_options
    ! src/solver/petsc_options.c
    function c_check_own_options(message, size) result(status) bind(c, name='eme_check_own_options')
      import :: c_char, c_int
      character(kind=c_char), intent(out) :: message(*)
      integer(c_int), value :: size
      integer(c_int) :: status
    end function c_check_own_options
    function c_capture_errors() result(status) bind(c, name='eme_petsc_capture_errors')
      import :: c_int
      integer(c_int) :: status
    end function c_capture_errors
    subroutine c_error_text(text, size) bind(c, name='eme_petsc_error_text')
      import :: c_char, c_int
      character(kind=c_char), intent(out) :: text(*)
      integer(c_int), value :: size
    end subroutine c_error_text
    ! src/io/petsc_option_files.c
    function c_check_option_files(started, arguments, count, files, folders, study_folders, message, size) &
        result(status) bind(c, name='eme_petsc_check_option_files')
      import :: c_char, c_int
      integer(c_int), value :: started, count, study_folders, size
      character(kind=c_char), intent(in) :: arguments(*), files(*), folders(*)
      character(kind=c_char), intent(out) :: message(*)
      integer(c_int) :: status
    end function c_check_option_files
    function c_forget_file_options() result(status) bind(c, name='eme_petsc_forget_file_options')
      import :: c_int
      integer(c_int) :: status
    end function c_forget_file_options
    function c_launcher_rank() result(rank) bind(c, name='eme_launcher_rank')
      import :: c_int
      integer(c_int) :: rank
    end function c_launcher_rank
  end interface

contains

  !> Reads the command line. `own_options` are the program's options ('--help', '-h', ...), which
  !> take no value. A failure (failure_input) for an unknown '--option', no input file or more
  !> than one; the caller acts on flags such as --help before it looks at the failure.
  subroutine parse_command_line(program_name, own_options, arguments, failure)
    character(len=*), intent(in) :: program_name
    character(len=*), intent(in) :: own_options(:)
    type(command_arguments), intent(out) :: arguments
    type(failure_type), intent(out) :: failure
    character(len=:), allocatable :: argument, files
    logical :: after_petsc_option
    integer :: i, file_count

    allocate (arguments%flags(0))
    arguments%input_file = ''
    arguments%given_files = ''
    files = ''
    file_count = 0
    after_petsc_option = .false.
    do i = 1, command_argument_count()
      argument = command_argument(i)
      if (any(own_options == argument)) then
        arguments%flags = [character(len=32) :: arguments%flags, argument]
        after_petsc_option = .false.
      else if (is_option(argument)) then
        if (argument(1:2) == '--' .and. .not. failure%failed()) &
          call fail(failure, failure_input, 'unknown option '''//argument//'''; allowed: '//joined(own_options, ', ')// &
                    ', one input file, and PETSc options (one ''-'', e.g. -snes_monitor)')
        after_petsc_option = .true.
      else if (after_petsc_option .and. .not. ends_with_nml(argument)) then
        after_petsc_option = .false.    ! the option's value
      else
        file_count = file_count + 1
        if (file_count == 1) then
          arguments%input_file = argument
          arguments%file_position = i
        end if
        files = files//' '''//argument//''''
        arguments%given_files = arguments%given_files//argument//new_line('a')
        after_petsc_option = .false.
      end if
    end do
    if (failure%failed()) return
    if (file_count == 0) then
      call fail(failure, failure_input, 'no input file; usage: '//program_name//' [options] FILE.nml [PETSc options]; '// &
                program_name//' --help tells more')
    else if (file_count > 1) then
      call fail(failure, failure_input, integer_text(file_count)//' input files:'//files//'; allowed: exactly one '// &
                'input file (an argument after a PETSc option is its value unless it ends in .nml)')
    end if
  end subroutine parse_command_line

  !> Whether the program's own option `flag` was given.
  !> A benchmark's REPEATS: its first argument when that is not an option, else `default`;
  !> a failure (failure_input) when it is not a whole number >= 1.
  subroutine benchmark_repeats(default, repeats, failure)
    integer, intent(in) :: default
    integer, intent(out) :: repeats
    type(failure_type), intent(out) :: failure
    character(len=:), allocatable :: first
    integer :: ios

    repeats = default
    if (command_argument_count() < 1) return
    first = command_argument(1)
    if (is_option(first)) return
    read (first, *, iostat=ios) repeats
    if (ios /= 0 .or. repeats < 1) call fail(failure, failure_input, 'REPEATS must be a whole number >= 1', 'REPEATS')
  end subroutine benchmark_repeats

  !> Whether one of `flags` stands anywhere on the command line (before PETSc starts: the
  !> benchmarks answer --help and --version without running).
  logical function has_argument(flags)
    character(len=*), intent(in) :: flags(:)
    integer :: k

    has_argument = .false.
    do k = 1, command_argument_count()
      if (any(flags == command_argument(k))) has_argument = .true.
    end do
  end function has_argument

  pure logical function has_flag(self, flag)
    class(command_arguments), intent(in) :: self
    character(len=*), intent(in) :: flag

    has_flag = any(self%flags == flag)
  end function has_flag

  !> PetscInitialize with the command line without the input file and the program's own options
  !> (PETSc then never takes the file for an option's value). A failure (failure_library, PETSc's
  !> code) if PETSc could not start; petsc_error_text() has PETSc's words.
  subroutine initialize_petsc(arguments, failure)
    type(command_arguments), intent(in) :: arguments
    type(failure_type), intent(out) :: failure
    integer :: stat
    character(len=:), allocatable :: list
    integer :: count

    call petsc_arguments(arguments, list, count)
    ! PETSc's errors come back as codes with a message (petsc_error_text), never as a traceback.
    stat = int(c_capture_errors())
    if (stat == 0) stat = int(c_petsc_initialize(command_argument(0)//c_null_char//list, int(count + 1, c_int)))
    call fail_on_code(failure, stat, 'PetscInitialize', 'PETSc could not start')
  end subroutine initialize_petsc

  !> The first message of PETSc's latest error, on one line ('' if none).
  function petsc_error_text() result(text)
    character(len=:), allocatable :: text
    character(kind=c_char, len=1024) :: buffer

    buffer = ''
    call c_error_text(buffer, len(buffer, kind=c_int))
    text = c_string(buffer)
  end function petsc_error_text

  !> A failure (failure_input, "option -NAME VALUE: ...") if an option would have PETSc write a
  !> file (-log_view :FILE, -snes_view binary:FILE, -info FILE, -history FILE, ...) that is one of
  !> `files` or lies in one of `folders` (each path and what it is on two lines:
  !> output_path's protected_entry), or with `study_folders` in a study's output folder. Before
  !> PetscInitialize (`started` .false.) the options are the command line's, PETSC_OPTIONS' and
  !> their options files' (PETSc opens the files of -history, -info and -log_trace as it starts);
  !> after, PETSc's database, and each viewer file must be writable too (PETSc would find out
  !> only at the end of the run; collective then). failure_library if PETSc cannot list its options.
  subroutine check_petsc_file_options(arguments, started, files, folders, study_folders, failure)
    type(command_arguments), intent(in) :: arguments
    logical, intent(in) :: started, study_folders
    character(len=*), intent(in) :: files, folders
    type(failure_type), intent(out) :: failure
    character(kind=c_char, len=2048) :: buffer
    character(len=:), allocatable :: list
    integer :: status, count

    call petsc_arguments(arguments, list, count)
    buffer = ''
    status = int(c_check_option_files(merge(1_c_int, 0_c_int, started), list//c_null_char, int(count, c_int), &
                                      files//c_null_char, folders//c_null_char, &
                                      merge(1_c_int, 0_c_int, study_folders), buffer, len(buffer, kind=c_int)))
    call option_failure(failure, status, c_string(buffer))
  end subroutine check_petsc_file_options

  !> Before PetscFinalize of a run refused before it ran (exit status 2): the options that have
  !> PETSc write a file are forgotten, so that nothing is written (PETSc writes -log_view's file
  !> as it finalizes).
  subroutine forget_petsc_file_options()
    if (c_forget_file_options() /= 0) return      ! (a database that cannot be listed: nothing to forget)
  end subroutine forget_petsc_file_options

  !> The rank the launcher (mpirun, srun) gave this process before MPI starts, or 0.
  integer function launcher_rank()
    launcher_rank = int(c_launcher_rank())
  end function launcher_rank

  ! The command line as PETSc is given it: without the program's name, the input file and the
  ! program's own options; each argument ended by a NUL, `count` of them.
  subroutine petsc_arguments(arguments, list, count)
    type(command_arguments), intent(in) :: arguments
    character(len=:), allocatable, intent(out) :: list
    integer, intent(out) :: count
    character(len=:), allocatable :: argument
    integer :: i

    list = ''
    count = 0
    do i = 1, command_argument_count()
      argument = command_argument(i)
      if (i == arguments%file_position .or. arguments%has_flag(argument)) cycle
      list = list//argument//c_null_char
      count = count + 1
    end do
  end subroutine petsc_arguments

  ! The C shims' answer about the options (0 all fine, 2 the database could not be listed, else
  ! the option named in `text` is refused) as a failure.
  subroutine option_failure(failure, status, text)
    type(failure_type), intent(inout) :: failure
    integer, intent(in) :: status
    character(len=*), intent(in) :: text

    if (status == 0) return
    if (status == 2) then
      call fail(failure, failure_library, 'PETSc could not list its options database')
    else
      call fail(failure, failure_input, text)
    end if
  end subroutine option_failure

  !> After PetscInitialize: a failure (failure_input) with "-name value: allowed: ..." if an -eme_*
  !> option has a value it does not take (bad input: nothing has been read or written yet).
  subroutine check_own_options(failure)
    type(failure_type), intent(out) :: failure
    character(kind=c_char, len=512) :: buffer
    integer :: status

    buffer = ''
    status = int(c_check_own_options(buffer, len(buffer, kind=c_int)))
    call option_failure(failure, status, c_string(buffer))
  end subroutine check_own_options

  !> Whether PETSc's -help was given (after PetscInitialize).
  logical function petsc_help_requested()
    petsc_help_requested = c_help_requested() /= 0
  end function petsc_help_requested

  !> Before PetscFinalize, on every rank (collective): the PETSc options that nothing used on
  !> any rank, blank-separated ('' on ranks other than 0, and if every option was used).
  function unused_petsc_options() result(names)
    character(len=:), allocatable :: names
    character(kind=c_char, len=4096) :: buffer

    buffer = ''
    names = ''
    if (c_unused_options(buffer, len(buffer, kind=c_int)) /= 0) return
    names = c_string(buffer)
  end function unused_petsc_options

  ! Argument i (0: the program's name), whatever its length.
  function command_argument(i) result(argument)
    integer, intent(in) :: i
    character(len=:), allocatable :: argument
    integer :: length

    call get_command_argument(i, length=length)
    allocate (character(len=length) :: argument)
    if (length > 0) call get_command_argument(i, argument)
  end function command_argument

  ! '-name' or '--name'; a negative number such as -1 or -.5 is a value.
  pure logical function is_option(argument)
    character(len=*), intent(in) :: argument

    is_option = .false.
    if (len(argument) < 2) return
    is_option = argument(1:1) == '-' .and. scan(argument(2:2), '0123456789.') == 0
  end function is_option

  pure logical function ends_with_nml(argument)
    character(len=*), intent(in) :: argument

    ends_with_nml = .false.
    if (len(argument) > 4) ends_with_nml = argument(len(argument) - 3:) == '.nml'
  end function ends_with_nml

  ! The text a C function wrote into `buffer`, up to its NUL (all of it if there is none).
  pure function c_string(buffer) result(text)
    character(len=*), intent(in) :: buffer
    character(len=:), allocatable :: text
    integer :: nul

    nul = index(buffer, c_null_char)
    if (nul == 0) nul = len(buffer) + 1
    text = buffer(1:nul - 1)
  end function c_string

end module command_line
