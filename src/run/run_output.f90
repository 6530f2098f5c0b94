!> The HDF5 file of one run (docs/output.md): its datasets, declared once in
!> `output_schema` with their names, rows (one per point t_n, or one per step), units, descriptions
!> and how a row that stands for several steps combines them (&output every), and its root
!> attributes: the integrator (with its registry entry and its solver's settings as used), every
!> field of the model's namelist groups under its namelist name with its units (<name>_units),
!> and provenance (command line, PETSc options, the effective namelist, versions, host, dates).
!> `/time` and `/step` are the dimension scales of the per-point and per-step datasets.
!> `eme_run --output-schema` prints the table; the Python tests check real files against it.
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
  use effective_namelist, only: namelist_of_run
  use provenance, only: write_provenance, iso_time
  use stepper, only: step_report, step_diagnostic, solver_report
  use build_info, only: code_version
  use filesystem, only: sync_file, exchange_files, copy_file, remove_file, os_error_text
  implicit none (type, external)
  private
  public :: run_file, run_summary, extra_attribute, output_dataset, output_schema, print_output_schema
  public :: failure_none, failure_solver, failure_domain, failure_input, failure_io, failure_interrupted, &
            failure_library

  !> One dataset of the layout. `columns` names a vector's columns; the run fills in the
  !> entries of the model's state (<state>), of its subsystems (<subsystems>) and of the active
  !> constraints (<constraints>), prefixed as written (theta_<subsystems> gives theta_1 theta_2).
  !> Units '<columns>': per column (the attribute column_units, from the model or the
  !> constraints). Datasets of constraints exist only when a constraint is active. `combine`: what
  !> a row holds that stands for several steps (&output every = N): the last step's value, or the
  !> sum, min, max or mean over the steps.
  type :: output_dataset
    character(len=24) :: name
    character(len=5) :: rows                !! 'point' (N+1 rows) or 'step' (N rows)
    character(len=24) :: columns            !! '' for a (rows) dataset
    character(len=9) :: units
    logical :: integer_valued
    character(len=4) :: combine
    character(len=240) :: description
  end type output_dataset

  !> Units of a dataset whose columns differ in units.
  character(len=*), parameter :: per_column = '<columns>'

  type(output_dataset), parameter :: output_schema(22) = [ &
    output_dataset('time', 'point', '', 's', .false., 'last', &
                   'time t_n of each point; the dimension scale of every per-point dataset'), &
    output_dataset('state', 'point', '<state>', per_column, .false., 'last', &
                   'the state z in the run''s thermodynamic variable; `columns` names its entries'), &
    output_dataset('temperature', 'point', 'theta_<subsystems>', 'K', .false., 'last', 'spring temperatures'), &
    output_dataset('energy', 'point', '', 'J', .false., 'last', 'total energy E = T + V_g + U_1 + U_2'), &
    output_dataset('entropy', 'point', '', 'J/K', .false., 'last', 'total entropy S = S_1 + S_2'), &
    output_dataset('lyapunov', 'point', '', 'J', .false., 'last', 'V = E - theta_r S, eq. (14)'), &
    output_dataset('angular_momentum', 'point', 'J_x J_y J_z', 'J s', .false., 'last', 'J = q1 x p1 + q2 x p2'), &
    output_dataset('boundary_heat', 'point', '', 'J', .false., 'last', &
                   'heat supplied through constraints since t = 0, sum of dt times their heat supply (zero without)'), &
    output_dataset('constraint_residual', 'point', 'g_<constraints>', per_column, .false., 'last', &
                   'g(z) of the active constraints (see the attribute constraint_meanings)'), &
    output_dataset('step', 'step', '', '1', .true., 'last', &
                   'the number n (from 1) of the last step the row stands for: the row''s step, or with &output '// &
                   'every = N the N steps up to n; the dimension scale of every per-step dataset'), &
    output_dataset('step_end_time', 'step', '', 's', .false., 'last', &
                   'the time at the end of the row''s (last) step: the time coordinate of every per-step dataset '// &
                   '(their attribute coordinates)'), &
    output_dataset('newton_iterations', 'step', '', '1', .true., 'sum', &
                   'Newton iterations of the step, summed over every solve it took (retries, continuation stages, '// &
                   'substeps); newton_iterations_total / steps_completed is the mean per step'), &
    output_dataset('scheme_temperature', 'step', 'Theta_<subsystems>', 'K', .false., 'last', &
                   '<the integrator''s entry in the registry says>'), &
    output_dataset('solver_strategy', 'step', '', '1', .true., 'max', &
                   'what found the root: 1 predictor, 2 old state, 3 continuation in dt (same dt); 4-6 the same with the &
                   &fallback line search; 0 for PETSc TS'), &
    output_dataset('snes_solves', 'step', '', '1', .true., 'sum', &
                   'SNESSolve calls of the step (continuation stages included), or TS steps taken for PETSc TS'), &
    output_dataset('rejected_roots', 'step', '', '1', .true., 'sum', &
                   'converged roots rejected as unphysical (non-positive temperature), or TS steps rejected'), &
    output_dataset('residual_norm', 'step', '', '1', .false., 'max', &
                   '2-norm of the final residual of the step''s last nonlinear solve, as the solver''s convergence '// &
                   'test measured it (root attribute solver_snes_atol); NaN where the step solves no nonlinear system '// &
                   '(explicit stages, CVODE)'), &
    output_dataset('converged_reason', 'step', '', '1', .true., 'last', &
                   'the solver''s converged reason of the step''s last solve, in its own numbering (flag_values, '// &
                   'flag_meanings): SNESConvergedReason, TSConvergedReason, CVode''s flag; 0 without a solver'), &
    output_dataset('cpu_seconds', 'step', '', 's', .false., 'sum', 'CPU time of the step (the integrator''s advance)'), &
    output_dataset('min_entropy_increment', 'step', '', 'J/K', .false., 'min', &
                   'S_n - S_(n-1) of the step; of a row that stands for several steps, the smallest of theirs'), &
    output_dataset('max_lyapunov_increment', 'step', '', 'J', .false., 'max', &
                   'V_n - V_(n-1) of the step; of a row that stands for several steps, the largest of theirs'), &
    output_dataset('multiplier', 'step', 'lambda_<constraints>', per_column, .false., 'mean', &
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
    !> The lowest temperature of any subsystem at any recorded point; NaN once one is not finite.
    real(real64) :: min_temperature = huge(1.0_real64)
    integer :: halved_steps = 0          !! failed attempts of the completed steps replaced by two halves
    integer :: rejected_steps = 0        !! trial steps that step-size control rejected (adaptive runs)
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
  !> write_interval seconds (src/io/hdf5_series). The file at `path` is never written in place,
  !> because a kill inside HDF5's writes can leave a file it cannot read: a window writes the
  !> copy `path`.spare, which lags one window behind, and then exchanges the two names. So `path`
  !> always names a closed, readable file whose points and steps agree in length (step_rows says
  !> how many step rows, steps_completed how many steps they stand for). With every = N, a point
  !> row is kept every N steps (and the last), and a step row stands for the steps since the
  !> previous point row.
  type :: run_file
    type(hdf5_file) :: file
    type(series_table) :: points, steps
    character(len=:), allocatable :: path, spare
    logical :: enabled = .false.        !! .false.: nothing is recorded (an index-only study)
    logical :: on_disk = .false.        !! the file exists at `path`
    integer :: failure = 0              !! the first failed write (its stat): later windows fail with it
    logical :: durable = .true.         !! the finished file is synced to disk (fsync)
    integer(int64) :: last_write = 0, clock_rate = 1
    integer :: every = 1                !! steps per row (&output every)
    logical :: by_interval = .false.    !! rows at output times instead (&output interval)
    integer :: last_step = 0            !! the last step recorded
    integer :: newton_pending = 0       !! Newton iterations of the steps not yet in a row
    integer :: committed_steps = 0, committed_newton = 0   !! of the steps in rows (buffered or written)
    integer :: disk_steps = 0, disk_newton = 0             !! of the steps in rows on disk
  contains
    procedure :: create
    procedure :: record_solver
    procedure :: record_point
    procedure :: record_step
    procedure :: write_due
    procedure :: write_rows
    procedure :: finish
  end type run_file

contains

  !> Prepares the run file for `path` in memory with its attributes and the datasets' layout:
  !> the schema's, then one per step for each of the integrator's own diagnostics (attribute
  !> source = integrator). `petsc_options` are the options in force (the database's text).
  !> Nothing is written to `path` yet. stat = -1 if HDF5 failed.
  subroutine create(self, path, config, entry, model, constraints, diagnostics, extras, petsc_options, stat)
    class(run_file), intent(inout) :: self
    character(len=*), intent(in) :: path
    type(run_configuration), intent(in), target :: config
    type(integrator_entry), intent(in) :: entry
    class(generic_model), intent(in) :: model
    type(constraint_slot), intent(in) :: constraints(:)
    type(step_diagnostic), intent(in) :: diagnostics(:)
    type(extra_attribute), intent(in) :: extras(:)
    character(len=*), intent(in) :: petsc_options
    integer, intent(out) :: stat
    type(output_dataset) :: spec
    integer :: k

    self%path = path
    self%spare = path//'.spare'
    self%enabled = .true.
    self%every = config%output_every
    self%by_interval = config%output_interval > 0.0_real64
    self%points%compression = config%compression
    self%steps%compression = config%compression
    self%points%scale = .true.
    self%steps%scale = .true.
    call system_clock(self%last_write, self%clock_rate)
    call self%file%create_in_memory(stat)
    if (stat == 0) call write_run_attributes(self%file, config, entry, model, constraints, stat)
    if (stat == 0) call write_provenance(self%file, 'EME run of '//config%input_file//': '//trim(entry%label)//', '// &
                                         trim(thermo_variable_names(config%integrator%thermo_variable)), &
                                         petsc_options, stat)
    if (stat == 0) call self%file%set_text('namelist', namelist_of_run(config), stat)
    do k = 1, size(extras)
      if (stat /= 0) exit
      if (allocated(extras(k)%text)) then
        call self%file%set_text(trim(extras(k)%name), extras(k)%text, stat)
      else
        call self%file%set_integer(trim(extras(k)%name), extras(k)%number, stat, units='1')
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
                             trim(diagnostics(k)%description), rows='step', source='integrator', &
                             combine=diagnostics(k)%combine, coordinates=coordinates(diagnostics(k)%name, 'step'))
    end do
    ! Both tables gain a row per step: together they buffer at most buffer_bytes.
    self%points%capacity_rows = max(1024, buffer_bytes/(8*(self%points%row_width + self%steps%row_width)))
    self%steps%capacity_rows = self%points%capacity_rows

  contains

    subroutine define(table)
      type(series_table), intent(inout) :: table
      character(len=:), allocatable :: columns, description
      character(len=16), allocatable :: units(:)
      character(len=:), allocatable :: common

      columns = expanded_columns(spec%columns, model, constraints)
      description = trim(spec%description)
      if (spec%name == 'scheme_temperature') description = trim(entry%scheme_temperature)
      if (len(columns) == 0) then
        call table%define(trim(spec%name), 1, .false., trim(spec%units), description, &
                          integer_valued=spec%integer_valued, rows=trim(spec%rows), combine=spec%combine, &
                          coordinates=coordinates(spec%name, spec%rows))
        return
      end if
      units = column_units(spec, model, constraints, count_words(columns))
      ! Columns of different units (the state) carry column_units only: no one units is right.
      common = trim(units(1))
      if (any(units /= units(1))) common = ''
      call table%define(trim(spec%name), count_words(columns), .true., common, description, &
                        integer_valued=spec%integer_valued, columns=columns, rows=trim(spec%rows), &
                        column_units=units, combine=spec%combine, coordinates=coordinates(spec%name, spec%rows))
    end subroutine define
  end subroutine create

  ! The CF auxiliary coordinate of a dataset: step_end_time for a per-step one (but the step
  ! scale and step_end_time itself), none for the others.
  pure function coordinates(name, rows) result(text)
    character(len=*), intent(in) :: name, rows
    character(len=:), allocatable :: text

    text = ''
    if (rows == 'step' .and. name /= 'step' .and. name /= 'step_end_time') text = 'step_end_time'
  end function coordinates

  !> The solver the integrator used (after its `start`): each setting as a root attribute
  !> solver_<name> (numbers with solver_<name>_units), and the legend of /converged_reason.
  subroutine record_solver(self, report, stat)
    class(run_file), intent(inout) :: self
    type(solver_report), intent(in) :: report
    integer, intent(out) :: stat
    integer :: k

    stat = 0
    if (.not. self%enabled) return
    do k = 1, size(report%settings)
      associate (item => report%settings(k))
        if (allocated(item%text)) then
          call self%file%set_text('solver_'//trim(item%name), item%text, stat)
        else if (item%integer_valued) then
          call self%file%set_integer('solver_'//trim(item%name), nint(item%value), stat, units=trim(item%units))
        else
          call self%file%set_real('solver_'//trim(item%name), item%value, stat, units=trim(item%units))
        end if
      end associate
      if (stat /= 0) return
    end do
    call self%steps%set_flags('converged_reason', report%reason_codes, report%reason_names)
  end subroutine record_solver

  !> Records the point after step n (or the initial point) for every per-point dataset, in the
  !> schema's order. The rows of steps not yet in the file are completed every `every` steps, or
  !> with &output interval when `row_due` (the initial point at once).
  subroutine record_point(self, time, z, theta, energy, entropy, lyapunov, momentum, heat, residuals, row_due)
    class(run_file), intent(inout) :: self
    real(real64), intent(in) :: time, z(:), theta(:), energy, entropy, lyapunov, momentum(3), heat, residuals(:)
    logical, intent(in) :: row_due
    logical :: due

    if (.not. self%enabled) return
    call self%points%accumulate([time, z, theta, energy, entropy, lyapunov, momentum, heat, residuals])
    if (self%by_interval) then
      due = row_due
    else
      due = self%steps%pending_count >= self%every
    end if
    if (self%steps%pending_count == 0 .or. due) call commit_rows(self)
  end subroutine record_point

  !> Records step n, ending at `time`, for every per-step dataset, in the schema's order, then the
  !> integrator's diagnostics: `cpu_seconds` its CPU time, `entropy_increment` S_n - S_(n-1) and
  !> `lyapunov_increment` V_n - V_(n-1). Call it before the step's record_point.
  subroutine record_step(self, n, time, report, multipliers, cpu_seconds, entropy_increment, lyapunov_increment)
    class(run_file), intent(inout) :: self
    integer, intent(in) :: n
    real(real64), intent(in) :: time      !! the step's end time
    type(step_report), intent(in) :: report
    real(real64), intent(in) :: multipliers(:), cpu_seconds, entropy_increment, lyapunov_increment
    real(real64), allocatable :: diagnostics(:)

    if (.not. self%enabled) return
    allocate (diagnostics(0))
    if (allocated(report%diagnostics)) diagnostics = report%diagnostics
    call self%steps%accumulate([real(n, real64), time, real(report%newton_iterations, real64), &
                                report%scheme_temperature, &
                                real(report%strategy, real64), real(report%solves, real64), &
                                real(report%rejected, real64), report%residual_norm, &
                                real(report%converged_reason, real64), cpu_seconds, entropy_increment, &
                                lyapunov_increment, multipliers, diagnostics])
    self%last_step = n
    self%newton_pending = self%newton_pending + report%newton_iterations
  end subroutine record_step

  ! Completes the pending point row and the step row of the steps since the last one.
  subroutine commit_rows(self)
    type(run_file), intent(inout) :: self

    call self%points%commit()
    if (self%steps%pending_count == 0) return
    call self%steps%commit()
    self%committed_steps = self%last_step
    self%committed_newton = self%committed_newton + self%newton_pending
    self%newton_pending = 0
  end subroutine commit_rows

  ! After both tables' buffers reached the file: the steps its rows stand for.
  subroutine rows_on_disk(self)
    type(run_file), intent(inout) :: self

    self%disk_steps = self%committed_steps
    self%disk_newton = self%committed_newton
  end subroutine rows_on_disk

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
  !> running'): the first time the whole file is created at `path` and as its spare (datasets
  !> chunked, as more rows will follow), later in a window that appends them. stat: 0, an OS
  !> error number (nothing new reached `path`; it holds what it held), or -1 (HDF5).
  subroutine write_rows(self, summary, stat)
    class(run_file), intent(inout) :: self
    type(run_summary), intent(in) :: summary
    integer, intent(out) :: stat
    integer :: close_stat

    stat = 0
    if (.not. self%enabled) return
    if (.not. self%on_disk) then
      call system_clock(self%last_write)
      call self%points%write(self%file, .false., stat)
      if (stat == 0) call self%steps%write(self%file, .false., stat)
      if (stat == 0) call rows_on_disk(self)
      if (stat == 0) call summary_attributes(self, summary%status, summary, stat)
      if (stat == 0) call self%file%store(self%path, .false., stat)
      if (stat /= 0) return
      self%on_disk = .true.
      call self%file%store(self%spare, .false., stat)
      self%failure = stat
      call self%file%close(close_stat)
      if (stat == 0) stat = close_stat
    else
      ! A reader holding the spare open (it opened the file before the last exchange) defers the
      ! write to a later step, until the buffer is full.
      call write_window(self, summary%status, summary, stat, defer=.not. (self%points%full() .or. self%steps%full()))
      if (stat == file_in_use) then      ! try again in 50 ms
        call system_clock(self%last_write)
        self%last_write = self%last_write - int((write_interval - 0.05_real64)*self%clock_rate, int64)
        stat = 0
      end if
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
    if (self%steps%pending_count > 0) call commit_rows(self)
    if (.not. self%on_disk) then
      ! Written whole from memory; store checks that the disk holds every byte.
      call self%points%write(self%file, .true., stat)
      if (stat == 0) call self%steps%write(self%file, .true., stat)
      if (stat == 0) call rows_on_disk(self)
      if (stat == 0) call summary_attributes(self, summary%status, summary, stat, final=.true.)
      if (stat == 0) call self%file%store(self%path, self%durable, stat)
      call self%file%close(ignored)
      call remove_file(self%spare, ignored)       ! of an earlier run killed with this output
      self%on_disk = stat == 0
      return
    else
      call write_window(self, summary%status, summary, stat, final=.true.)
      call remove_file(self%spare, ignored)
      if (stat > 0) then
        ! No room for the rows: keep those of the last window, and say why in the status (written
        ! in place, as the spare is gone; the space it held makes room).
        stopped = summary
        stopped%failure_kind = failure_io
        call self%file%open_existing(self%path, .true., check_stat)
        if (check_stat == 0) call summary_attributes(self, 'incomplete: cannot write the output file: '// &
                                                     os_error_text(stat), stopped, check_stat, final=.true.)
        call self%file%close(ignored)
        return
      end if
      if (stat == 0 .and. self%durable) call sync_file(self%path, stat)
      if (stat /= 0) return
    end if
    call check_run_file(self%path, status_read, steps_read, check_stat)
    if (check_stat /= 0 .or. status_read /= summary%status .or. steps_read /= self%disk_steps) stat = -2
  end subroutine finish

  ! A window: opens the spare after reserving space for the rows it lacks (those of the last window
  ! and the buffered ones, plus room for attributes), appends them, writes the attributes (all of
  ! them if `final`, else the numbers) and closes it; then the spare takes the name `path` and the
  ! old file becomes the spare, which lacks only this window's rows. A reader that opened the
  ! file before the last exchange may still have the spare open: with `defer` the window waits
  ! (stat = file_in_use), else the spare is replaced by a copy of `path` and the reader keeps
  ! its file as it was. After a failure the spare is not used again.
  subroutine write_window(self, status, summary, stat, defer, final)
    type(run_file), intent(inout) :: self
    character(len=*), intent(in) :: status
    type(run_summary), intent(in) :: summary
    integer, intent(out) :: stat
    logical, intent(in), optional :: defer, final
    integer(int64) :: points_kept, steps_kept
    integer :: close_stat, steps_before, newton_before
    logical :: last, waiting

    stat = self%failure
    if (stat /= 0) return
    waiting = .false.
    if (present(defer)) waiting = defer
    last = .false.
    if (present(final)) last = final
    call open_spare(stat)
    if (stat == file_in_use .and. waiting) return
    if (stat == file_in_use) then
      call copy_file(self%path, self%spare, stat)
      call self%points%forget(self%points%written)
      call self%steps%forget(self%steps%written)
      if (stat == 0) call open_spare(stat)
    end if
    if (stat == 0) then
      call system_clock(self%last_write)
      points_kept = self%points%written
      steps_kept = self%steps%written
      steps_before = self%disk_steps
      newton_before = self%disk_newton
      call self%points%write(self%file, .false., stat, keep=.true.)
      if (stat == 0) call self%steps%write(self%file, .false., stat, keep=.true.)
      if (stat == 0) call rows_on_disk(self)
      if (stat == 0) call summary_attributes(self, status, summary, stat, numbers_only=.not. last, final=last)
      call self%file%close(close_stat)
      if (stat == 0) stat = close_stat
      if (stat == 0) call exchange_files(self%spare, self%path, stat)
      if (stat /= 0) then          ! `path` holds what it held
        self%disk_steps = steps_before
        self%disk_newton = newton_before
      end if
    end if
    self%failure = stat
    if (stat /= 0) return
    call self%points%forget(points_kept)
    call self%steps%forget(steps_kept)

  contains

    subroutine open_spare(stat)
      integer, intent(out) :: stat

      call self%file%open_existing(self%spare, .true., stat, reserve=self%points%window_bytes() + &
                                   self%steps%window_bytes() + 65536_int64, wait_ms=-1)
    end subroutine open_spare
  end subroutine write_window

  ! The root attributes of the run's outcome: steps_completed counts the steps the file's rows
  ! stand for, step_rows the step rows, newton_iterations_total the Newton iterations of those
  ! steps; `final` adds end_time. numbers_only: the texts (status, failure_kind) are as the file
  ! holds them, and numbers are written in place.
  subroutine summary_attributes(self, status, summary, stat, numbers_only, final)
    type(run_file), intent(inout) :: self
    character(len=*), intent(in) :: status
    type(run_summary), intent(in) :: summary
    integer, intent(out) :: stat
    logical, intent(in), optional :: numbers_only, final
    logical :: units, texts

    stat = 0
    units = self%file%fresh         ! the units attributes go with the first write
    texts = .true.
    if (present(numbers_only)) texts = .not. numbers_only
    if (texts) then
      call self%file%set_text('status', status, stat)
      if (stat == 0) call self%file%set_text('failure_kind', summary%failure_kind, stat)
    end if
    if (present(final)) then
      if (stat == 0 .and. final) call self%file%set_text('end_time', iso_time(), stat)
    end if
    call number('steps_planned', real(summary%steps_planned, real64), '1', .true.)
    call number('steps_completed', real(self%disk_steps, real64), '1', .true.)
    call number('step_rows', real(self%steps%written, real64), '1', .true.)
    call number('newton_iterations_total', real(self%disk_newton, real64), '1', .true.)
    if (stat == 0) call self%file%set_reals('run_figures', [summary%energy_drift, summary%min_entropy_increment, &
                                           summary%max_lyapunov_increment, summary%angular_momentum_drift, &
                                           summary%min_temperature, real(summary%halved_steps, real64), &
                                           real(summary%rejected_steps, real64)], stat)
    if (stat == 0 .and. units) call self%file%set_texts('run_figures_units', &
                                                        [character(len=3) :: '1', 'J/K', 'J', 'J s', 'K', '1', '1'], stat)
    call number('solve_time_seconds', summary%solve_seconds, 's', .false.)
    call number('wall_time_seconds', summary%wall_seconds, 's', .false.)
    self%file%fresh = .false.

  contains

    subroutine number(name, value, unit, integer_valued)
      character(len=*), intent(in) :: name, unit
      real(real64), intent(in) :: value
      logical, intent(in) :: integer_valued

      if (stat /= 0) return
      if (integer_valued) then
        if (units) call self%file%set_integer(name, nint(value), stat, units=unit)
        if (.not. units) call self%file%set_integer(name, nint(value), stat)
      else
        if (units) call self%file%set_real(name, value, stat, units=unit)
        if (.not. units) call self%file%set_real(name, value, stat)
      end if
    end subroutine number
  end subroutine summary_attributes

  !> The schema as tab-separated lines: name, rows, columns, units, description.
  subroutine print_output_schema()
    type(output_dataset) :: spec
    integer :: k

    write (output_unit, '(a)') 'name'//achar(9)//'rows'//achar(9)//'columns'//achar(9)//'units'//achar(9)// &
      'combine'//achar(9)//'description'
    do k = 1, size(output_schema)
      spec = output_schema(k)
      write (output_unit, '(a)') trim(spec%name)//achar(9)//trim(spec%rows)//achar(9)//trim(spec%columns)//achar(9) &
        //trim(spec%units)//achar(9)//trim(spec%combine)//achar(9)//trim(spec%description)
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
      call real_attribute('dt', choice%dt, 's')
      call real_attribute('t_end', choice%t_end, 's')
      call real_attribute('theta_r', config%theta_r, 'K')
      call real_attribute('newton_tol', choice%newton_tol, '1')
      call real_attribute('tolerance', choice%tolerance, '1')
      call real_attribute('ts_tolerance', choice%tolerance, '1')   ! the old name, for old scripts
      if (stat == 0) call file%set_integer('newton_max_iterations', choice%newton_max_iterations, stat, units='1')
    end associate
    call real_attribute('quotient_threshold', quotient_threshold, '1')
    if (stat == 0) call file%set_integer('unknowns', model%state_size + size(constraints), stat, units='1')
    if (stat == 0) call file%set_integer('output_every', config%output_every, stat, units='1')
    if (stat == 0) call file%set_real('output_interval', config%output_interval, stat, units='s')
    if (stat == 0) call file%set_integer('compression', config%compression, stat, units='1')
    do a = 1, model%subsystem_count()
      associate (part => model%subsystems(a))
        if (stat == 0) call file%set_reals('metric_scale_'//squeezed(part%name), part%metric_scale, stat, &
                                           units='those of the subsystem''s invariants (attribute metric)')
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
            call file%set_real(trim(fields(i)%name), fields(i)%real_value, stat, units=trim(fields(i)%units))
          else
            call file%set_reals(trim(fields(i)%name), fields(i)%real_values, stat, units=trim(fields(i)%units))
          end if
        case (field_integer)
          call file%set_integer(trim(fields(i)%name), fields(i)%integer_value, stat, units='1')
        case (field_logical)
          call file%set_integer(trim(fields(i)%name), merge(1, 0, fields(i)%logical_value), stat, units='1')
        case default
          call file%set_text(trim(fields(i)%name), trim(fields(i)%text_value), stat)
        end select
      end do
    end subroutine field_attributes

    subroutine text(name, value)
      character(len=*), intent(in) :: name, value
      if (stat == 0) call file%set_text(name, value, stat)
    end subroutine text

    subroutine real_attribute(name, value, units)
      character(len=*), intent(in) :: name, units
      real(real64), intent(in) :: value
      if (stat == 0) call file%set_real(name, value, stat, units=units)
    end subroutine real_attribute
  end subroutine write_run_attributes

  ! The units of a vector dataset's `count` columns: the model's (<state>), the constraints'
  ! (<constraints>: g's for constraint_residual, lambda's for multiplier), else the schema's.
  function column_units(spec, model, constraints, count) result(units)
    type(output_dataset), intent(in) :: spec
    class(generic_model), intent(in) :: model
    type(constraint_slot), intent(in) :: constraints(:)
    integer, intent(in) :: count
    character(len=16) :: units(count)
    integer :: k

    if (spec%columns == '<state>') then
      call model%column_units(units)
    else if (index(spec%columns, '<constraints>') > 0) then
      do k = 1, count
        if (spec%name == 'multiplier') then
          units(k) = constraints(k)%item%multiplier_units
        else
          units(k) = constraints(k)%item%value_units
        end if
      end do
    else
      units = spec%units
    end if
  end function column_units

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
