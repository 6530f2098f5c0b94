!> run_config and study_config on the namelists the project ships: the strict reader takes every
!> one of them (none relied on what it now refuses), and each study expands to its cases. Also
!> same_variable, which the study's collision check rests on, and the shortest exact real text
!> of the stored namelist. Runs from the repository root (tests/run_tests.py does).
program test_input_files
  use assertions, only: test_suite
  use unit_testing, only: unit_test, run_unit_tests
  use run_config, only: run_configuration, read_run_config, same_variable
  use study_config, only: study_definition, read_study
  use effective_namelist, only: exact_real_text
  use, intrinsic :: iso_fortran_env, only: real64
  implicit none (type, external)

  call run_unit_tests('test_input_files', [ &
    unit_test('shipped_inputs_are_read', shipped_inputs_are_read), &
    unit_test('shipped_studies_expand', shipped_studies_expand), &
    unit_test('same_variable_knows_old_names', same_variable_knows_old_names), &
    unit_test('reals_are_written_short_and_exact', reals_are_written_short_and_exact)])

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

  !> The stored namelist's reals: as a person writes them where that is exact (typed here), and
  !> read back to the same double whatever the value.
  subroutine reals_are_written_short_and_exact(suite)
    type(test_suite), intent(inout) :: suite
    real(real64), parameter :: typed_values(14) = [0.15_real64, 0.25_real64, 0.1_real64, 0.035_real64, 20.0_real64, &
      280.0_real64, 1.5_real64, -9.81_real64, 1.0e-8_real64, 1.0e-10_real64, 0.001_real64, 1234567.0_real64, &
      2.0e7_real64, -0.5_real64]
    character(len=10), parameter :: typed_texts(14) = [character(len=10) :: '0.15', '0.25', '0.1', '0.035', '20.0', &
      '280.0', '1.5', '-9.81', '1.0e-8', '1.0e-10', '0.001', '1234567.0', '2.0e7', '-0.5']
    real(real64) :: x, back
    character(len=:), allocatable :: text
    integer :: i

    do i = 1, size(typed_values)
      text = exact_real_text(typed_values(i))
      call suite%check_true(trim(typed_texts(i))//' is written '//trim(typed_texts(i)), text == trim(typed_texts(i)), &
                            'got '//text)
    end do
    call random_seed()
    do i = 1, 2000
      call random_number(x)
      x = (x - 0.5_real64)*10.0_real64**(mod(i, 25) - 12)
      text = exact_real_text(x)
      read (text, *) back
      call suite%check_true('a random real reads back exactly', .not. abs(back - x) > 0.0_real64, text)
    end do
  end subroutine reals_are_written_short_and_exact

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
