!> The case files of a study: case c's file output_dir/case_NNNNN.h5, its overrides of the base
!> scene as one line, and what a restart reads back from a case file: whether it checks out
!> (complete, with the recorded number of steps, its checksums and summary attributes holding,
!> and its overrides this case's) and, when the index has lost it, the result and overrides of a
!> complete case file, which the index matches to a case by its overrides.
module study_case_files
  use, intrinsic :: iso_fortran_env, only: real64
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
  use study_config, only: study_definition
  use study_journal, only: case_result
  use hdf5_files, only: hdf5_file, check_run_file
  use failures, only: failure_type
  implicit none (type, external)
  private
  public :: case_file, case_name, case_overrides, case_file_checks_out, read_case_file

contains

  !> The file of case c: output_dir/case_NNNNN.h5.
  pure function case_file(study, c) result(path)
    type(study_definition), intent(in) :: study
    integer, intent(in) :: c
    character(len=:), allocatable :: path

    path = study%output_dir//'/'//case_name(c)
  end function case_file

  !> Case c's overrides of the base scene as one line ('dt = 0.1; scheme = ''eme''').
  pure function case_overrides(study, c) result(text)
    type(study_definition), intent(in) :: study
    integer, intent(in) :: c
    character(len=:), allocatable :: text
    integer :: s

    text = ''
    do s = 1, size(study%cases(c)%overrides)
      if (s > 1) text = text//'; '
      text = text//trim(study%cases(c)%overrides(s)%item)
    end do
  end function case_overrides

  !> Whether case c's file reads back complete with `steps` steps, its datasets whole (their
  !> checksums) and its summary attributes as its datasets give them, and names case c's
  !> overrides (files written before they did are taken on their status alone).
  logical function case_file_checks_out(study, c, steps_recorded)
    type(study_definition), intent(in) :: study
    integer, intent(in) :: c, steps_recorded
    character(len=:), allocatable :: status, overrides
    type(hdf5_file) :: file
    integer :: steps
    type(failure_type) :: failure, ignored

    call check_run_file(case_file(study, c), status, steps, failure, whole=.true.)
    case_file_checks_out = .not. failure%failed() .and. status == 'complete' .and. steps == steps_recorded
    if (.not. case_file_checks_out) return
    call file%open_existing(case_file(study, c), .false., failure)
    if (.not. failure%failed()) call file%get_text('study_overrides', overrides, failure)
    call file%close(ignored)
    if (.not. failure%failed()) case_file_checks_out = overrides == case_overrides(study, c)
  end function case_file_checks_out
  !> The result and overrides of the case file at `path`, if it reads back complete (as
  !> case_file_checks_out) and names its study's case (study_case, study_overrides): found. The
  !> caller matches it to a case by its overrides, not by its number, which moves when sweeps grow.
  subroutine read_case_file(path, result, overrides, found)
    character(len=*), intent(in) :: path
    type(case_result), intent(out) :: result
    character(len=:), allocatable, intent(out) :: overrides
    logical, intent(out) :: found
    type(hdf5_file) :: file
    character(len=:), allocatable :: status, warnings
    real(real64), allocatable :: number(:), figures(:), planned(:), newton(:), wall(:), solve(:), rank(:), &
                                 cpu(:), solve_cpu(:)
    integer :: steps
    type(failure_type) :: failure, ignored, unmeasured, warned

    found = .false.
    overrides = ''
    call check_run_file(path, status, steps, failure, whole=.true.)
    if (failure%failed() .or. status /= 'complete') return
    call file%open_existing(path, .false., failure)
    if (failure%failed()) return
    call file%get_reals('study_case', number, failure)
    if (.not. failure%failed()) call file%get_text('study_overrides', overrides, failure)
    if (.not. failure%failed()) call file%get_reals('run_figures', figures, failure)
    if (.not. failure%failed()) call file%get_reals('steps_planned', planned, failure)
    if (.not. failure%failed()) call file%get_reals('newton_iterations_total', newton, failure)
    if (.not. failure%failed()) call file%get_reals('wall_time_seconds', wall, failure)
    if (.not. failure%failed()) call file%get_reals('solve_time_seconds', solve, failure)
    if (.not. failure%failed()) call file%get_reals('study_rank', rank, failure)
    ! A file written before CPU times were recorded has none: NaN, not measured.
    if (.not. failure%failed()) call file%get_reals('cpu_time_seconds', cpu, unmeasured)
    if (.not. failure%failed() .and. .not. unmeasured%failed()) &
      call file%get_reals('solve_cpu_time_seconds', solve_cpu, unmeasured)
    if (unmeasured%failed()) then
      cpu = [ieee_value(1.0_real64, ieee_quiet_nan)]
      solve_cpu = cpu
    end if
    ! A complete run whose accuracy is in doubt has the attribute warnings (docs/integrators.md).
    call file%get_text('warnings', warnings, warned)
    call file%close(ignored)
    if (failure%failed()) return
    if (size(number) /= 1 .or. size(figures) /= 7) return
    result%status = 'complete'
    result%failure_kind = 'none'
    result%metrics = [real(steps, real64), planned(1), newton(1), wall(1), solve(1), cpu(1), solve_cpu(1), figures, &
                      merge(0.0_real64, 1.0_real64, warned%failed()), rank(1), 1.0_real64]
    found = .true.
  end subroutine read_case_file

  pure function case_name(c) result(name)
    integer, intent(in) :: c
    character(len=:), allocatable :: name
    character(len=16) :: buffer

    write (buffer, '("case_", i5.5, ".h5")') c
    name = trim(buffer)
  end function case_name

end module study_case_files
