!> The HDF5 file of one run (README, Output layout): its datasets, declared once in
!> `output_schema` with their names, rows (one per point t_n, or one per step), units and
!> descriptions, and its root attributes: the integrator (with its registry entry), every field
!> of the model's namelist groups under its namelist name, and provenance. `eme_run
!> --output-schema` prints the table; the Python tests check real files against it.
module run_output
  use, intrinsic :: iso_fortran_env, only: real64, int64, output_unit
  use hdf5_series, only: hdf5_file, series_table, check_run_file, file_in_use
  use namelist_group, only: group_field, field_real, field_integer, field_logical
  use model_interface, only: generic_model
  use model_constraint, only: constraint_slot
  use integrator_registry, only: integrator_entry
  use thermo_variable, only: thermo_variable_names
  use discrete_gradient, only: discrete_gradient_names, metric_names, metric_nondimensional, quotient_threshold
  use run_config, only: run_configuration
  use stepper, only: step_report, step_diagnostic
  use build_info, only: code_version
  use filesystem, only: sync_file, os_error_text
  implicit none (type, external)
  private
  public :: run_file, run_summary, extra_attribute, output_dataset, output_schema, print_output_schema
  public :: failure_none, failure_solver, failure_domain, failure_input, failure_io, failure_interrupted, &
            failure_library

  !> One dataset of the layout. `columns` names a vector's columns; the run fills in the
  !> entries of the model's state (<state>), of its subsystems (<subsystems>) and of the active
  !> constraints (<constraints>), prefixed as written (theta_<subsystems> gives theta_1 theta_2).
  !> Datasets of constraints exist only when a constraint is active.
  type :: output_dataset
    character(len=24) :: name
    character(len=5) :: rows                !! 'point' (N+1 rows) or 'step' (N rows)
    character(len=24) :: columns            !! '' for a (rows) dataset
    character(len=8) :: units
    logical :: integer_valued
    character(len=200) :: description
  end type output_dataset

  type(output_dataset), parameter :: output_schema(15) = [ &
    output_dataset('time', 'point', '', 's', .false., 'time t_n of each point'), &
    output_dataset('state', 'point', '<state>', 'SI', .false., &
                   'the state z in the run''s thermodynamic variable; `columns` names its entries'), &
    output_dataset('temperature', 'point', 'theta_<subsystems>', 'K', .false., 'spring temperatures'), &
    output_dataset('energy', 'point', '', 'J', .false., 'total energy E = T + V_g + U_1 + U_2'), &
    output_dataset('entropy', 'point', '', 'J/K', .false., 'total entropy S = S_1 + S_2'), &
    output_dataset('lyapunov', 'point', '', 'J', .false., 'V = E - theta_r S, eq. (14)'), &
    output_dataset('angular_momentum', 'point', 'J_x J_y J_z', 'J s', .false., 'J = q1 x p1 + q2 x p2'), &
    output_dataset('boundary_heat', 'point', '', 'J', .false., &
                   'heat supplied through constraints since t = 0, sum of dt times their heat supply (zero without)'), &
    output_dataset('constraint_residual', 'point', 'g_<constraints>', 'SI', .false., &
                   'g(z) of the active constraints (see the attribute constraint_meanings)'), &
    output_dataset('newton_iterations', 'step', '', '1', .true., &
                   'Newton iterations of the step, summed over every solve it took'), &
    output_dataset('scheme_temperature', 'step', 'Theta_<subsystems>', 'K', .false., &
                   '<the integrator''s entry in the registry says>'), &
    output_dataset('solver_strategy', 'step', '', '1', .true., &
                   'what found the root: 1 predictor, 2 old state, 3 continuation in dt (same dt); 4-6 the same with the &
                   &fallback line search; 0 for PETSc TS'), &
    output_dataset('snes_solves', 'step', '', '1', .true., &
                   'SNESSolve calls of the step (continuation stages included), or TS steps taken for PETSc TS'), &
    output_dataset('rejected_roots', 'step', '', '1', .true., &
                   'converged roots rejected as unphysical (non-positive temperature), or TS steps rejected'), &
    output_dataset('multiplier', 'step', 'lambda_<constraints>', 'SI', .false., &
                   'Lagrange multipliers of the active constraints (see the attribute constraint_meanings)')]

  !> Why a run did not complete, in a word (file attribute and study index column `failure_kind`).
  character(len=*), parameter :: failure_none = 'none'              !! complete (or not yet run)
  character(len=*), parameter :: failure_solver = 'solver'          !! no acceptable root, or the solver diverged
  character(len=*), parameter :: failure_domain = 'domain'          !! the state left the model's domain
  character(len=*), parameter :: failure_input = 'input'            !! the input cannot be run as given
  character(len=*), parameter :: failure_io = 'io'                  !! the output could not be written
  character(len=*), parameter :: failure_interrupted = 'interrupted'  !! SIGTERM or SIGINT
  character(len=*), parameter :: failure_library = 'library'        !! PETSc or HDF5 failed

  !> The figures a run is judged by, as the summary table prints them.
  type :: run_summary
    character(len=:), allocatable :: status       !! 'complete' or 'incomplete: <reason>'
    character(len=:), allocatable :: failure_kind !! one of the failure_* words above
    integer :: steps_planned = 0
    integer :: steps_completed = 0
    integer :: newton_iterations = 0
    real(real64) :: energy_drift = 0.0_real64            !! max_n |E_n - E_0 - Q_n| / |E_0|, Q: boundary heat
    real(real64) :: min_entropy_increment = huge(1.0_real64)    !! NaN without a completed step
    real(real64) :: max_lyapunov_increment = -huge(1.0_real64)  !! NaN without a completed step
    real(real64) :: angular_momentum_drift = 0.0_real64  !! max_n |J_z,n - J_z,0|
    real(real64) :: wall_seconds = 0.0_real64             !! the whole run, file set-up and closing included
    real(real64) :: solve_seconds = 0.0_real64            !! the time loop alone
  end type run_summary

  !> A root attribute a caller adds to the file (an ensemble case names its study and case): a
  !> text if `text` is allocated, else the integer `number`.
  type :: extra_attribute
    character(len=32) :: name = ''
    character(len=:), allocatable :: text
    integer :: number = 0
  end type extra_attribute

  real(real64), parameter :: write_interval = 1.0_real64   !! seconds between writes of a long run
  integer, parameter :: buffer_bytes = 4*1024*1024          !! rows held in memory between writes, at most

  !> A run's file and its two tables of rows (points and steps). It is built in memory and
  !> reaches the disk when the run ends or after write_interval seconds (or a full buffer),
  !> whichever comes first; from then on, buffered rows are appended in a window at least every
  !> write_interval seconds (src/io/hdf5_series). Between windows the file on disk is closed
  !> and readable, and its points and steps agree in length (steps_completed says how many).
  type :: run_file
    type(hdf5_file) :: file
    type(series_table) :: points, steps
    character(len=:), allocatable :: path
    logical :: enabled = .false.        !! .false.: nothing is recorded (an index-only study)
    logical :: on_disk = .false.        !! the file exists at `path`
    logical :: durable = .true.         !! the finished file is synced to disk (fsync)
    integer(int64) :: last_write = 0, clock_rate = 1
  contains
    procedure :: create
    procedure :: record_point
    procedure :: record_step
    procedure :: write_due
    procedure :: write_rows
    procedure :: finish
  end type run_file

contains

  !> Prepares the run file for `path` in memory with its attributes and the datasets' layout:
  !> the schema's, then one per step for each of the integrator's own diagnostics (attribute
  !> source = integrator). Nothing is written to `path` yet. stat = -1 if HDF5 failed.
  subroutine create(self, path, config, entry, model, constraints, diagnostics, extras, stat)
    class(run_file), intent(inout) :: self
    character(len=*), intent(in) :: path
    type(run_configuration), intent(in) :: config
    type(integrator_entry), intent(in) :: entry
    class(generic_model), intent(in) :: model
    type(constraint_slot), intent(in) :: constraints(:)
    type(step_diagnostic), intent(in) :: diagnostics(:)
    type(extra_attribute), intent(in) :: extras(:)
    integer, intent(out) :: stat
    type(output_dataset) :: spec
    integer :: k

    self%path = path
    self%enabled = .true.
    call system_clock(self%last_write, self%clock_rate)
    call self%file%create_in_memory(stat)
    if (stat == 0) call write_run_attributes(self%file, config, entry, model, constraints, stat)
    do k = 1, size(extras)
      if (stat /= 0) exit
      if (allocated(extras(k)%text)) then
        call self%file%set_text(trim(extras(k)%name), extras(k)%text, stat)
      else
        call self%file%set_integer(trim(extras(k)%name), extras(k)%number, stat)
      end if
    end do
    do k = 1, size(output_schema)
      spec = output_schema(k)
      if (index(spec%columns, '<constraints>') > 0 .and. size(constraints) == 0) cycle
      if (spec%rows == 'point') then
        call define(self%points)
      else
        call define(self%steps)
      end if
    end do
    do k = 1, size(diagnostics)
      call self%steps%define(trim(diagnostics(k)%name), 1, .false., trim(diagnostics(k)%units), &
                             trim(diagnostics(k)%description), rows='step', source='integrator')
    end do
    ! Both tables gain a row per step: together they buffer at most buffer_bytes.
    self%points%capacity_rows = max(1024, buffer_bytes/(8*(self%points%row_width + self%steps%row_width)))
    self%steps%capacity_rows = self%points%capacity_rows

  contains

    subroutine define(table)
      type(series_table), intent(inout) :: table
      character(len=:), allocatable :: columns, description

      columns = expanded_columns(spec%columns, model, constraints)
      description = trim(spec%description)
      if (spec%name == 'scheme_temperature') description = trim(entry%scheme_temperature)
      call table%define(trim(spec%name), max(1, count_words(columns)), len(columns) > 0, trim(spec%units), &
                        description, integer_valued=spec%integer_valued, columns=columns, rows=trim(spec%rows))
    end subroutine define
  end subroutine create

  !> Buffers one row of every per-point dataset, in the schema's order.
  subroutine record_point(self, time, z, theta, energy, entropy, lyapunov, momentum, heat, residuals)
    class(run_file), intent(inout) :: self
    real(real64), intent(in) :: time, z(:), theta(:), energy, entropy, lyapunov, momentum(3), heat, residuals(:)

    if (self%enabled) call self%points%append([time, z, theta, energy, entropy, lyapunov, momentum, heat, residuals])
  end subroutine record_point

  !> Buffers one row of every per-step dataset, in the schema's order, then the integrator's
  !> diagnostics.
  subroutine record_step(self, report, multipliers)
    class(run_file), intent(inout) :: self
    type(step_report), intent(in) :: report
    real(real64), intent(in) :: multipliers(:)
    real(real64), allocatable :: diagnostics(:)

    if (.not. self%enabled) return
    allocate (diagnostics(0))
    if (allocated(report%diagnostics)) diagnostics = report%diagnostics
    call self%steps%append([real(report%newton_iterations, real64), report%scheme_temperature, &
                            real(report%strategy, real64), real(report%solves, real64), &
                            real(report%rejected, real64), multipliers, diagnostics])
  end subroutine record_step

  !> Whether buffered rows are due on disk: write_interval seconds since the last write, or a
  !> full buffer. Call it after a whole step (its step row and end point) was recorded.
  logical function write_due(self)
    class(run_file), intent(in) :: self
    integer(int64) :: now

    write_due = .false.
    if (.not. self%enabled) return
    if (self%points%full() .or. self%steps%full()) then
      write_due = .true.
    else
      call system_clock(now)
      write_due = real(now - self%last_write, real64) >= write_interval*real(self%clock_rate, real64)
    end if
  end function write_due

  !> Writes the buffered rows and the run's attributes so far (`summary`, status 'incomplete:
  !> running'): the first time the whole file is created at `path` (datasets chunked, as more rows
  !> will follow), later in a window that appends them. stat: 0, an OS error number (nothing new
  !> reached the disk; the file holds what it held), or -1 (HDF5).
  subroutine write_rows(self, summary, stat)
    class(run_file), intent(inout) :: self
    type(run_summary), intent(in) :: summary
    integer, intent(out) :: stat

    stat = 0
    if (.not. self%enabled) return
    if (.not. self%on_disk) then
      call system_clock(self%last_write)
      call self%points%write(self%file, .false., stat)
      if (stat == 0) call self%steps%write(self%file, .false., stat)
      if (stat == 0) call summary_attributes(self, summary%status, summary, stat)
      if (stat == 0) call self%file%store(self%path, .false., stat)
      if (stat /= 0) return
      call self%file%close(stat)
      self%on_disk = stat == 0
    else
      ! A reader holding the file open defers the write to a later step, until the buffer is full.
      call append_window(self, stat, defer=.not. (self%points%full() .or. self%steps%full()))
      if (stat == file_in_use) then      ! try again in 50 ms
        call system_clock(self%last_write)
        self%last_write = self%last_write - int((write_interval - 0.05_real64)*self%clock_rate, int64)
        stat = 0
        return
      end if
      if (stat == 0) call summary_attributes(self, summary%status, summary, stat, numbers_only=.true.)
      call close_window(self, stat)
    end if
  end subroutine write_rows

  !> Writes what is buffered and the final attributes: status, failure_kind, steps_planned,
  !> steps_completed (the step rows in the file), the summary's figures and times. The file is
  !> then closed and synced (unless not durable) and checked: a file written whole from memory by
  !> its size on disk, one grown in windows by reading it back (every dataset's length against
  !> steps_completed, and the status). stat: 0, an OS error number, -1 (HDF5) or -2 (the disk
  !> does not hold what was written).
  !> If the rows cannot be written for want of space, the file keeps the rows of its last
  !> window, and its status says why if that much can still be written.
  subroutine finish(self, summary, stat)
    class(run_file), intent(inout) :: self
    type(run_summary), intent(in) :: summary
    integer, intent(out) :: stat
    type(run_summary) :: stopped
    character(len=:), allocatable :: status_read
    integer :: steps_read, check_stat, ignored

    stat = 0
    if (.not. self%enabled) return
    if (.not. self%on_disk) then
      ! Written whole from memory; store checks that the disk holds every byte.
      call self%points%write(self%file, .true., stat)
      if (stat == 0) call self%steps%write(self%file, .true., stat)
      if (stat == 0) call summary_attributes(self, summary%status, summary, stat)
      if (stat == 0) call self%file%store(self%path, self%durable, stat)
      call self%file%close(ignored)
      self%on_disk = stat == 0
      return
    else
      call append_window(self, stat)
      if (stat > 0) then
        ! No room for the rows: keep those of the last window, and say why in the status.
        stopped = summary
        stopped%failure_kind = failure_io
        call self%file%open_existing(self%path, .true., check_stat)
        if (check_stat == 0) call summary_attributes(self, 'incomplete: cannot write the output file: '// &
                                                     os_error_text(stat), stopped, check_stat)
        call self%file%close(ignored)
        return
      end if
      if (stat == 0) call summary_attributes(self, summary%status, summary, stat)
      call close_window(self, stat)
      if (stat == 0 .and. self%durable) call sync_file(self%path, stat)
      if (stat /= 0) return
    end if
    call check_run_file(self%path, status_read, steps_read, check_stat)
    if (check_stat /= 0 .or. status_read /= summary%status .or. steps_read /= self%steps%written) stat = -2
  end subroutine finish

  ! Opens the file on disk for appending the buffered rows, after reserving their space (plus
  ! room for attributes), and writes them. defer: return file_in_use if a reader has it open.
  subroutine append_window(self, stat, defer)
    type(run_file), intent(inout) :: self
    integer, intent(out) :: stat
    logical, intent(in), optional :: defer
    integer :: wait_ms

    wait_ms = 5000
    if (present(defer)) then
      if (defer) wait_ms = -1
    end if
    call self%file%open_existing(self%path, .true., stat, reserve=self%points%window_bytes() + &
                                 self%steps%window_bytes() + 65536_int64, wait_ms=wait_ms)
    if (stat /= 0) return
    call system_clock(self%last_write)
    call self%points%write(self%file, .false., stat)
    if (stat == 0) call self%steps%write(self%file, .false., stat)
  end subroutine append_window

  ! Closes a window; stat keeps its first failure.
  subroutine close_window(self, stat)
    type(run_file), intent(inout) :: self
    integer, intent(inout) :: stat
    integer :: close_stat

    call self%file%close(close_stat)
    if (stat == 0) stat = close_stat
  end subroutine close_window

  ! The final root attributes; steps_completed is the step rows in the file. numbers_only: the
  ! texts (status, failure_kind) are as the file holds them, and numbers are written in place.
  subroutine summary_attributes(self, status, summary, stat, numbers_only)
    type(run_file), intent(inout) :: self
    character(len=*), intent(in) :: status
    type(run_summary), intent(in) :: summary
    integer, intent(out) :: stat
    logical, intent(in), optional :: numbers_only

    stat = 0
    if (.not. present(numbers_only)) then
      call self%file%set_text('status', status, stat)
      if (stat == 0) call self%file%set_text('failure_kind', summary%failure_kind, stat)
    end if
    if (stat == 0) call self%file%set_integer('steps_planned', summary%steps_planned, stat)
    if (stat == 0) call self%file%set_integer('steps_completed', int(self%steps%written), stat)
    if (stat == 0) call self%file%set_integer('newton_iterations_total', summary%newton_iterations, stat)
    if (stat == 0) call self%file%set_reals('run_figures', [summary%energy_drift, summary%min_entropy_increment, &
                                           summary%max_lyapunov_increment, summary%angular_momentum_drift], stat)
    if (stat == 0) call self%file%set_real('solve_time_seconds', summary%solve_seconds, stat)
    if (stat == 0) call self%file%set_real('wall_time_seconds', summary%wall_seconds, stat)
    self%file%fresh = .false.
  end subroutine summary_attributes

  !> The schema as tab-separated lines: name, rows, columns, units, description.
  subroutine print_output_schema()
    type(output_dataset) :: spec
    integer :: k

    write (output_unit, '(a)') 'name'//achar(9)//'rows'//achar(9)//'columns'//achar(9)//'units'//achar(9)//'description'
    do k = 1, size(output_schema)
      spec = output_schema(k)
      write (output_unit, '(a)') trim(spec%name)//achar(9)//trim(spec%rows)//achar(9)//trim(spec%columns)//achar(9) &
        //trim(spec%units)//achar(9)//trim(spec%description)
    end do
  end subroutine print_output_schema

  ! The integrator, the model's input and provenance as root attributes, under the namelists'
  ! names.
  subroutine write_run_attributes(file, config, entry, model, constraints, stat)
    type(hdf5_file), intent(in) :: file
    type(run_configuration), intent(in) :: config
    type(integrator_entry), intent(in) :: entry
    class(generic_model), intent(in) :: model
    type(constraint_slot), intent(in) :: constraints(:)
    integer, intent(out) :: stat
    character(len=16), allocatable :: groups(:)
    character(len=:), allocatable :: gradient, metric, names, meanings
    integer :: a, g, k

    gradient = 'none'
    metric = 'none'
    associate (choice => config%integrator)
      if (entry%uses_discrete_gradient) then
        gradient = trim(discrete_gradient_names(choice%discrete_gradient))
        metric = trim(metric_names(choice%metric))
        if (choice%metric == metric_nondimensional) metric = metric// &
          ': C by (l^0)^2, gamma by 1 m, theta by theta_ref, s by Cap, u by Cap theta_ref'
      end if
      stat = 0
      call text('scheme', trim(entry%name))
      call text('scheme_family', trim(entry%family))
      call text('scheme_label', trim(entry%label))
      call text('scheme_description', trim(entry%description))
      call text('thermo_variable', trim(thermo_variable_names(choice%thermo_variable)))
      call text('discrete_gradient', gradient)
      call text('metric', metric)
      call text('input_file', config%input_file)
      call text('code_version', code_version)
      call real_attribute('dt', choice%dt)
      call real_attribute('t_end', choice%t_end)
      call real_attribute('theta_r', config%theta_r)
      call real_attribute('newton_tol', choice%newton_tol)
      call real_attribute('tolerance', choice%tolerance)
      call real_attribute('ts_tolerance', choice%tolerance)   ! the old name, for old scripts
      if (stat == 0) call file%set_integer('newton_max_iterations', choice%newton_max_iterations, stat)
    end associate
    call real_attribute('quotient_threshold', quotient_threshold)
    if (stat == 0) call file%set_integer('unknowns', model%state_size + size(constraints), stat)
    do a = 1, model%subsystem_count()
      associate (part => model%subsystems(a))
        if (stat == 0) call file%set_reals('metric_scale_'//squeezed(part%name), part%metric_scale, stat)
      end associate
    end do
    call config%scene%group_names(groups)
    do g = 1, size(groups)
      call field_attributes(config%scene%fields(trim(groups(g))))
    end do
    names = ''
    meanings = ''
    do k = 1, size(constraints)
      associate (c => constraints(k)%item)
        if (k > 1) names = names//', '
        names = names//trim(c%name)
        meanings = meanings//trim(c%name)//': '//trim(c%meaning)//' [g: '//trim(c%value_units)//', lambda: ' &
                   //trim(c%multiplier_units)//']; '
      end associate
    end do
    if (len(names) == 0) names = 'none'
    call text('constraints', names)
    if (len(meanings) > 0) call text('constraint_meanings', meanings(1:len(meanings) - 2))

  contains

    ! Each field of a namelist group as an attribute under its name (logicals as 0 or 1).
    subroutine field_attributes(fields)
      type(group_field), intent(in) :: fields(:)
      integer :: i

      do i = 1, size(fields)
        if (stat /= 0) return
        select case (fields(i)%kind)
        case (field_real)
          if (associated(fields(i)%real_value)) then
            call file%set_real(trim(fields(i)%name), fields(i)%real_value, stat)
          else
            call file%set_reals(trim(fields(i)%name), fields(i)%real_values, stat)
          end if
        case (field_integer)
          call file%set_integer(trim(fields(i)%name), fields(i)%integer_value, stat)
        case (field_logical)
          call file%set_integer(trim(fields(i)%name), merge(1, 0, fields(i)%logical_value), stat)
        case default
          call file%set_text(trim(fields(i)%name), trim(fields(i)%text_value), stat)
        end select
      end do
    end subroutine field_attributes

    subroutine text(name, value)
      character(len=*), intent(in) :: name, value
      if (stat == 0) call file%set_text(name, value, stat)
    end subroutine text

    subroutine real_attribute(name, value)
      character(len=*), intent(in) :: name
      real(real64), intent(in) :: value
      if (stat == 0) call file%set_real(name, value, stat)
    end subroutine real_attribute
  end subroutine write_run_attributes

  ! The columns of a schema entry for this run.
  function expanded_columns(template, model, constraints) result(columns)
    character(len=*), intent(in) :: template
    class(generic_model), intent(in) :: model
    type(constraint_slot), intent(in) :: constraints(:)
    character(len=:), allocatable :: columns
    character(len=:), allocatable :: prefix
    integer :: at, i

    columns = ''
    if (template == '<state>') then
      do i = 1, model%state_size
        columns = columns//' '//trim(model%column_names(i))
      end do
    else if (index(template, '<subsystems>') > 0) then
      at = index(template, '<subsystems>')
      prefix = template(1:at - 1)
      do i = 1, model%subsystem_count()
        columns = columns//' '//prefix//achar(iachar('0') + i)
      end do
    else if (index(template, '<constraints>') > 0) then
      at = index(template, '<constraints>')
      prefix = template(1:at - 1)
      do i = 1, size(constraints)
        columns = columns//' '//prefix//trim(constraints(i)%item%name)
      end do
    else
      columns = trim(template)
    end if
    columns = trim(adjustl(columns))
  end function expanded_columns

  pure integer function count_words(text)
    character(len=*), intent(in) :: text
    integer :: i

    count_words = 0
    do i = 1, len(text)
      if (text(i:i) /= ' ' .and. (i == 1)) count_words = count_words + 1
      if (i > 1) then
        if (text(i:i) /= ' ' .and. text(i - 1:i - 1) == ' ') count_words = count_words + 1
      end if
    end do
  end function count_words

  ! A name without blanks ('spring 1' -> 'spring1').
  pure function squeezed(name) result(plain)
    character(len=*), intent(in) :: name
    character(len=:), allocatable :: plain
    integer :: i

    plain = ''
    do i = 1, len_trim(name)
      if (name(i:i) /= ' ') plain = plain//name(i:i)
    end do
  end function squeezed

end module run_output
