!> The root attributes a write of a run file stores beside its rows (src/run/run_output's
!> write_file): the run's outcome so far, and a continued run's history and input.
submodule (run_output) run_output_attributes
  use provenance, only: iso_time
  implicit none

contains

  module procedure continued_attributes

    call self%store%file%set_text('history', self%history, failure)
    if (.not. failure%failed()) call self%store%file%set_text('namelist', self%continued_namelist, failure)
    if (.not. failure%failed()) call self%store%file%set_real('t_end', self%continued_t_end, failure)
    if (.not. failure%failed()) call self%store%file%set_integer('max_steps', self%continued_max_steps, failure)
  end procedure continued_attributes

  module procedure summary_attributes
    logical :: units, texts
    units = self%store%file%fresh         ! the units attributes go with the first write
    texts = .true.
    if (present(numbers_only)) texts = .not. numbers_only
    if (texts) then
      call self%store%file%set_text('status', status, failure)
      if (.not. failure%failed()) call self%store%file%set_text('failure_kind', summary%failure_kind, failure)
    end if
    if (present(final)) then
      if (.not. failure%failed() .and. final) call self%store%file%set_text('end_time', iso_time(), failure)
      ! A complete run's accuracy warnings (docs/integrators.md), beside its status.
      if (allocated(summary%warnings) .and. status == 'complete') then
        if (.not. failure%failed() .and. final .and. len(summary%warnings) > 0) &
          call self%store%file%set_text('warnings', summary%warnings, failure)
      end if
    end if
    call number('steps_planned', real(summary%steps_planned, real64), '1', .true.)
    call number('steps_completed', real(self%disk_steps, real64), '1', .true.)
    call number('step_rows', real(self%store%tables(step_rows)%written, real64), '1', .true.)
    call number('newton_iterations_total', real(self%disk_newton, real64), '1', .true.)
    if (.not. failure%failed()) call self%store%file%set_reals('run_figures', [summary%energy_drift, &
                                           summary%min_entropy_increment, &
                                           summary%max_lyapunov_increment, summary%angular_momentum_drift, &
                                           summary%min_temperature, real(summary%halved_steps, real64), &
                                           real(summary%rejected_steps, real64)], failure)
    if (.not. failure%failed() .and. units) call self%store%file%set_texts('run_figures_units', &
                                                        [character(len=3) :: '1', 'J/K', 'J', 'J s', 'K', '1', '1'], &
                                                        failure)
    call number('resolved_steps', real(summary%resolved_steps, real64), '1', .true.)
    if (.not. failure%failed()) call self%store%file%set_reals('balance_max_ulps', summary%max_balance, failure)
    if (.not. failure%failed() .and. units) call self%store%file%set_text('balance_max_ulps_units', '1', failure)
    call number('solve_time_seconds', summary%solve_seconds, 's', .false.)
    call number('wall_time_seconds', summary%wall_seconds, 's', .false.)
    call number('solve_cpu_time_seconds', summary%solve_cpu_seconds, 's', .false.)
    call number('cpu_time_seconds', summary%cpu_seconds, 's', .false.)
    self%store%file%fresh = .false.

  contains

    subroutine number(name, value, unit, integer_valued)
      character(len=*), intent(in) :: name, unit
      real(real64), intent(in) :: value
      logical, intent(in) :: integer_valued

      if (failure%failed()) return
      ! A count beyond the default integer's range (Newton iterations of a billion steps) is
      ! written as a double, which holds it exactly.
      if (integer_valued .and. abs(value) < real(huge(1), real64)) then
        if (units) call self%store%file%set_integer(name, nint(value), failure, units=unit)
        if (.not. units) call self%store%file%set_integer(name, nint(value), failure)
      else
        if (units) call self%store%file%set_real(name, value, failure, units=unit)
        if (.not. units) call self%store%file%set_real(name, value, failure)
      end if
    end subroutine number
  end procedure summary_attributes

end submodule run_output_attributes
