!> run_config and study_config on the namelists the project ships: the strict reader takes every
!> one of them (none relied on what it now refuses), and each study expands to its cases. Also
!> same_variable, which the study's collision check rests on. Runs from the repository root
!> (tests/run_tests.py does).
program test_input_files
  use assertions, only: test_suite
  use unit_testing, only: unit_test, run_unit_tests
  use run_config, only: run_configuration, read_run_config, same_variable
  use study_config, only: study_definition, read_study
  implicit none (type, external)

  call run_unit_tests('test_input_files', [ &
    unit_test('shipped_inputs_are_read', shipped_inputs_are_read), &
    unit_test('shipped_studies_expand', shipped_studies_expand), &
    unit_test('same_variable_knows_old_names', same_variable_knows_old_names)])

contains

  !> Every eme_run namelist in inputs/ reads without an error.
  subroutine shipped_inputs_are_read(suite)
    type(test_suite), intent(inout) :: suite
    character(len=256), allocatable :: files(:)
    type(run_configuration) :: config
    character(len=:), allocatable :: message
    integer :: i, stat

    call list_inputs('-L ''&study'' inputs/*.nml', files)
    call suite%check_true('inputs/ holds eme_run namelists', size(files) >= 16)
    do i = 1, size(files)
      call read_run_config(trim(files(i)), config, stat, message)
      call suite%check_true('reads '//trim(files(i)), stat == 0, message)
    end do
  end subroutine shipped_inputs_are_read

  !> Every study in inputs/ reads, its base included, and has cases.
  subroutine shipped_studies_expand(suite)
    type(test_suite), intent(inout) :: suite
    character(len=256), allocatable :: files(:)
    type(study_definition) :: study
    character(len=:), allocatable :: message
    integer :: i, stat

    call list_inputs('-l ''&study'' inputs/*.nml', files)
    call suite%check_true('inputs/ holds studies', size(files) >= 7)
    do i = 1, size(files)
      call read_study(trim(files(i)), study, stat, message)
      call suite%check_true('expands '//trim(files(i)), stat == 0 .and. size(study%cases) > 0, message)
    end do
  end subroutine shipped_studies_expand

  subroutine same_variable_knows_old_names(suite)
    type(test_suite), intent(inout) :: suite

    call suite%check_true('tolerance and ts_tolerance', same_variable('tolerance', 'ts_tolerance'))
    call suite%check_true('dt and dt', same_variable('dt', 'dt'))
    call suite%check_true('theta and theta', same_variable('theta', 'theta'))
    call suite%check_true('not dt and t_end', .not. same_variable('dt', 't_end'))
    call suite%check_true('not q1 and q2', .not. same_variable('q1', 'q2'))
    call suite%check_true('not an unknown name', .not. same_variable('dtt', 'dtt'))
  end subroutine same_variable_knows_old_names

  ! The files `grep -l` or `grep -L` names (`arguments`), through a listing file.
  subroutine list_inputs(arguments, files)
    character(len=*), intent(in) :: arguments
    character(len=256), allocatable, intent(out) :: files(:)
    character(len=256) :: line
    character(len=*), parameter :: listing = 'build/tests/input_files.txt'
    integer :: unit, stat

    allocate (files(0))
    call execute_command_line('grep '//arguments//' > '//listing//' 2>/dev/null', exitstat=stat)
    open (newunit=unit, file=listing, status='old', action='read', iostat=stat)
    if (stat /= 0) return
    do
      read (unit, '(a)', iostat=stat) line
      if (stat /= 0) exit
      files = [files, line]
    end do
    close (unit, status='delete')
  end subroutine list_inputs

end program test_input_files
