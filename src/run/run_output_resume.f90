!> What a run file notes to be continued from (src/run/run_output's resume record: the point, the
!> figures and the state after the last completed row), and a file taken up again by a continued
!> run (docs/faults.md, Continuing a run).
submodule (run_output) run_output_resume
  use effective_namelist, only: namelist_of_run
  use provenance, only: iso_time, command_line
  implicit none

contains

  module procedure note_resume_state
    logical :: noted

    call note_point(self, n, time, outputs_passed, energy_0, jz_0, boundary_heat, summary, noted)
    if (.not. noted) return
    associate (record => self%resume)
      if (.not. allocated(record%x)) allocate (record%x(size(x)), record%x_previous(size(x)))
      record%x = x
      record%x_previous = x_previous
      call integrator%resume_state(record%integrator_state)
    end associate
  end procedure note_resume_state

  module procedure note_snapshot_point
    logical :: noted

    call note_point(self, n, time, 0, energy_0, 0.0_real64, 0.0_real64, summary, noted)
    if (.not. noted) return
    self%resume%x = [real(real64) ::]
    self%resume%x_previous = [real(real64) ::]
    self%resume%integrator_state = running_sums
  end procedure note_snapshot_point

  ! The resume record's point and figures after step n, if record_point has just completed a row
  ! with it (`noted`).
  subroutine note_point(self, n, time, outputs_passed, energy_0, jz_0, boundary_heat, summary, noted)
    class(run_file), intent(inout) :: self
    integer(int64), intent(in) :: n
    real(real64), intent(in) :: time, energy_0, jz_0, boundary_heat
    integer, intent(in) :: outputs_passed
    type(run_summary), intent(in) :: summary
    logical, intent(out) :: noted

    noted = .false.
    if (.not. self%enabled .or. self%committed_steps /= n) return
    if (self%store%tables(step_rows)%pending_count > 0) return
    noted = .true.
    associate (record => self%resume)
      record%held = .true.
      record%step = n
      record%time = time
      record%outputs_passed = outputs_passed
      record%energy_0 = energy_0
      record%jz_0 = jz_0
      record%boundary_heat = boundary_heat
      record%point_rows = self%store%tables(point_rows)%first_row + self%store%tables(point_rows)%buffered
      record%step_rows = self%store%tables(step_rows)%first_row + self%store%tables(step_rows)%buffered
      call record%keep_summary(summary)
    end associate
  end subroutine note_point

  module procedure continue_file
    if (.not. self%enabled) return
    call self%store%resume_from([record%point_rows, record%step_rows], failure)
    self%last_step = record%step
    self%committed_steps = record%step
    self%disk_steps = record%step
    self%committed_newton = record%summary%newton_iterations
    self%disk_newton = record%summary%newton_iterations
    self%resume = record
    ! The file keeps its provenance; its CF history says when and how it was continued, and its
    ! input the end time and step budget that applied.
    self%history = record%history//new_line('a')//iso_time()//': '//command_line()
    self%continued_namelist = namelist_of_run(config)
    self%continued_t_end = config%integrator%t_end
    self%continued_max_steps = config%integrator%max_steps
  end procedure continue_file

end submodule run_output_resume
