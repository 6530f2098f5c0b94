!> How an output file was made, as root attributes of a run file and of a study index (docs/output.md): the command line, the PETSc options in force, the versions of the code and of
!> every library, the host and the start time, and the CF global attributes (title, institution,
!> source, history, references, Conventions) that netCDF and xarray readers look for; and the
!> machine's load, which a study index records at its start and end (docs/studies.md).
module provenance
  use, intrinsic :: iso_c_binding, only: c_char, c_int, c_null_char, c_double
  use, intrinsic :: iso_fortran_env, only: real64
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
  use hdf5_files, only: hdf5_file
  use failures, only: failure_type
  use namelist_text, only: lowercase
  use library_versions, only: library_names, library_version
  use build_info, only: code_version
  implicit none (type, external)
  private
  public :: write_provenance, iso_time, command_line, machine_load, machine_load_now

  !> The machine's load at one moment: what a timing taken then shared the cores with.
  type :: machine_load
    real(real64) :: averages(3) = 0.0_real64   !! the 1-, 5- and 15-minute load averages; NaN where the OS gives none
    integer :: cores = 0                       !! the cores online (0 if unknown)
  end type machine_load

  !> The paper the code implements (the CF `references` attribute).
  character(len=*), parameter :: paper = 'V. Valdes y Beck, P. Betsch: Energy-Momentum-Entropy consistent time '// &
    'integration of dissipative thermomechanical systems in an extended framework of GENERIC. Proceedings in '// &
    'Applied Mathematics and Mechanics (PAMM), 2023'

  interface
    ! src/io/host_name.c
    subroutine c_host_name(text, size) bind(c, name='eme_host_name')
      import :: c_char, c_int
      character(kind=c_char), intent(out) :: text(*)
      integer(c_int), value :: size
    end subroutine c_host_name
    ! src/io/host_name.c: -1 for a load average the OS does not give, 0 for unknown cores
    subroutine c_machine_load(averages, cores) bind(c, name='eme_machine_load')
      import :: c_double, c_int
      real(c_double), intent(out) :: averages(3)
      integer(c_int), intent(out) :: cores
    end subroutine c_machine_load
  end interface

contains

  !> The provenance attributes of `file`, whose content `title` describes in a line, made by a
  !> program that began at `started` (default: now). The CF `institution` is the environment
  !> variable EME_INSTITUTION ('unknown' without it).
  subroutine write_provenance(file, title, petsc_options, failure, started)
    type(hdf5_file), intent(in) :: file
    character(len=*), intent(in) :: title, petsc_options
    type(failure_type), intent(out) :: failure
    character(len=*), intent(in), optional :: started
    character(kind=c_char, len=256) :: host
    character(len=256) :: institution
    character(len=:), allocatable :: began, command
    integer :: i, length, env_stat

    call c_host_name(host, len(host, kind=c_int))
    if (present(started)) then
      began = started
    else
      began = iso_time()
    end if
    command = command_line()
    call get_environment_variable('EME_INSTITUTION', institution, length, env_stat)
    if (env_stat /= 0 .or. length == 0) institution = 'unknown'
    call file%set_text('command_line', command, failure)
    if (.not. failure%failed()) call file%set_text('petsc_options', petsc_options, failure)
    do i = 2, size(library_names)
      if (.not. failure%failed()) call file%set_text('version_'//lowercase(trim(library_names(i))), &
                                        library_version(trim(library_names(i))), failure)
    end do
    if (.not. failure%failed()) call file%set_text('host', host(1:index(host, c_null_char) - 1), failure)
    if (.not. failure%failed()) call file%set_text('start_time', began, failure)
    if (.not. failure%failed()) call file%set_text('Conventions', 'CF-1.8', failure)
    if (.not. failure%failed()) call file%set_text('title', title, failure)
    if (.not. failure%failed()) call file%set_text('institution', trim(institution), failure)
    if (.not. failure%failed()) call file%set_text('source', 'eme '//code_version//' (Fortran and C; PETSc '// &
                                      library_version('PETSc')//', HDF5 '//library_version('HDF5')//')', failure)
    if (.not. failure%failed()) call file%set_text('history', began//': '//command, failure)
    if (.not. failure%failed()) call file%set_text('references', paper, failure)
  end subroutine write_provenance

  !> The program's command line, an argument quoted for a POSIX shell where it needs it.
  function command_line() result(text)
    character(len=:), allocatable :: text
    character(len=:), allocatable :: argument
    character(len=*), parameter :: plain = 'abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789-_./=:,+@%'
    integer :: i, length

    text = ''
    do i = 0, command_argument_count()
      call get_command_argument(i, length=length)
      allocate (character(len=length) :: argument)
      call get_command_argument(i, argument)
      if (i > 0) text = text//' '
      if (len(argument) > 0 .and. verify(argument, plain) == 0) then
        text = text//argument
      else
        text = text//shell_quoted(argument)
      end if
      deallocate (argument)
    end do
  end function command_line

  ! The text in single quotes, a quote inside written as '\''.
  pure function shell_quoted(text) result(quoted)
    character(len=*), intent(in) :: text
    character(len=:), allocatable :: quoted
    character(len=*), parameter :: quote = achar(39), escaped = achar(39)//achar(92)//achar(39)//achar(39)
    integer :: i

    quoted = quote
    do i = 1, len(text)
      if (text(i:i) == quote) then
        quoted = quoted//escaped
      else
        quoted = quoted//text(i:i)
      end if
    end do
    quoted = quoted//quote
  end function shell_quoted

  !> The machine's load averages and cores online now (getloadavg and sysconf).
  function machine_load_now() result(load)
    type(machine_load) :: load
    real(c_double) :: averages(3)
    integer(c_int) :: cores

    call c_machine_load(averages, cores)
    load%averages = real(averages, real64)
    where (averages < 0) load%averages = ieee_value(1.0_real64, ieee_quiet_nan)
    load%cores = int(cores)
  end function machine_load_now

  !> Now as ISO 8601 local time with its UTC offset, e.g. 2024-05-01T14:03:07+02:00.
  function iso_time() result(text)
    character(len=:), allocatable :: text
    integer :: v(8)
    character(len=32) :: buffer

    call date_and_time(values=v)
    write (buffer, '(i4.4, "-", i2.2, "-", i2.2, "T", i2.2, ":", i2.2, ":", i2.2, a, i2.2, ":", i2.2)') v(1:3), &
      v(5:7), merge('+', '-', v(4) >= 0), abs(v(4))/60, mod(abs(v(4)), 60)
    text = trim(buffer)
  end function iso_time

end module provenance
