!> The index of a study: output_dir/index.h5, whose dataset /cases has one row per case
!> (h5py: f['cases'][:]): case, file, one column per sweep, status ('complete', 'failed: <reason>',
!> 'incomplete: interrupted by <signal>' or 'pending'), failure_kind and the case's figures: those
!> the cases' models can have (no angular_momentum_drift column when no case's model has a conserved
!> momentum, no min_entropy_increment, max_lyapunov_increment or min_temperature when none has
!> temperatures; the journal, the ranks' messages and a case's result keep all metric_count
!> figures, NaN where a model has none, so that only the file's columns depend on the model). The
!> dataset /integrators holds the integrator registry (name, label, family, capabilities), so
!> the scripts that chart a study name and order its schemes as the code does. The attribute
!> case_1_input is case 1's input as namelist text (all groups and fields, defaults included):
!> every case shares it but for the swept fields, so the scene is known without a case file.
!>
!> Crash safety. index.h5 is never written in place: a new one is written as index.h5.tmp and
!> renamed over it, when the study starts, every 2 s while cases end, and at the end. A case's
!> result counts as recorded once its line is appended to output_dir/index.journal (one line
!> per result, appended whole); a restart replays the journal over index.h5. A case file holds
!> its case number, overrides and figures too, so a missing or damaged index is rebuilt from the
!> case files (and the journal). On a restart every case recorded complete is checked against its
!> file (it opens, says complete, its datasets have the recorded number of rows and pass their
!> checksums, its summary attributes are what its datasets give, and it names the case's
!> overrides), and a case that fails the check runs again. An earlier run's cases are matched
!> to this study's by their swept values (index.h5) or overrides (journal, case files), so a
!> study whose sweeps grew keeps its finished cases and renames their files. In an index-only study (&study index_only) there are no case
!> files: index.h5 and the journal are the record.
!> The columns and their figures are src/run/study_columns's; matching an earlier run's cases to
!> this study's is src/run/study_case_matching's.
module study_index
  use, intrinsic :: iso_fortran_env, only: real64, int64
  use study_config, only: study_definition
  use hdf5_table, only: table_columns
  use filesystem, only: remove_file, append_text
  use provenance, only: machine_load, machine_load_now
  use study_case_files, only: case_overrides
  use study_journal, only: case_result, status_length, kind_length, metric_count, journal_line
  use study_columns, only: m_warned, m_rank, m_run_count
  use failures, only: failure_type, fail, failure_io
  implicit none (type, external)
  private
  public :: case_index, case_result, status_length, kind_length, metric_count, m_rank, &
            m_run_count, m_warned

  real(real64), parameter :: index_interval = 2.0_real64   !! seconds between rewrites of index.h5

  !> The open index of a study and every case's result.
  type :: case_index
    type(study_definition), pointer :: study => null()
    type(table_columns) :: columns
    type(case_result), allocatable :: results(:)
    integer, allocatable :: shown(:)               !! the metrics that are columns of /cases, in order
    character(len=24) :: units(metric_count) = ''  !! the metrics' units in the base file's model
    character(len=:), allocatable :: index_path, journal_path
    character(len=:), allocatable :: started       !! when this run of the study began (ISO 8601)
    !> The machine's load when this run of the study began and ended (end: once it has), and the
    !> study's ranks, which the load counts among its processes (docs/studies.md, Timings).
    type(machine_load) :: load_start, load_end
    logical :: ended = .false.
    integer :: ranks = 1
    integer(int64) :: last_write = 0, clock_rate = 1
  contains
    procedure :: open => open_index
    procedure :: record
    procedure :: close => close_index
  end type case_index

  ! Implemented in study_index_restore.
  interface
    !> Creates the output directory and a fresh index.h5 with a row per case, keeping the results
    !> of earlier runs of the same study (from index.h5, the journal and the case files) that still
    !> check out; pending(c) says which cases are to run. An earlier run's cases are matched to
    !> this study's by their swept values, not their numbers: a study whose sweeps grew keeps every
    !> finished case and renames its file where its number moved. `notes` tells the user what the
    !> restart found (empty if nothing to say). A failure: failure_input (refused) if output_dir
    !> holds a finished case that this study does not have (a changed value) or ran from another
    !> base scene; failure_io (or failure_library: HDF5) if the output directory cannot be written.
    !> `ranks`: the study's MPI ranks (default 1), recorded beside the machine's load.
    module subroutine open_index(self, study, pending, notes, failure, ranks)
      class(case_index), intent(inout) :: self
      type(study_definition), intent(in), target :: study
      logical, allocatable, intent(out) :: pending(:)
      character(len=:), allocatable, intent(out) :: notes
      type(failure_type), intent(out) :: failure
      integer, intent(in), optional :: ranks
    end subroutine open_index
  end interface

  ! Implemented in study_index_write.
  interface
    ! Writes index.h5: built in memory, written as index.h5.tmp (synced) and renamed over index.h5.
    module subroutine write_index(self, failure)
      type(case_index), intent(inout) :: self
      type(failure_type), intent(out) :: failure
    end subroutine write_index
  end interface

contains

  !> Stores case c's result (its run count one higher): appended to the journal at once, and in
  !> index.h5 at the next rewrite (at most index_interval seconds later, or at close).
  subroutine record(self, c, result, failure)
    class(case_index), intent(inout) :: self
    integer, intent(in) :: c
    type(case_result), intent(in) :: result
    type(failure_type), intent(out) :: failure
    character(len=:), allocatable :: reason
    integer(int64) :: now

    self%results(c)%status = result%status
    self%results(c)%failure_kind = result%failure_kind
    self%results(c)%metrics(1:m_rank) = result%metrics(1:m_rank)
    self%results(c)%metrics(m_run_count) = self%results(c)%metrics(m_run_count) + 1
    call append_text(self%journal_path, journal_line(c, self%results(c), case_overrides(self%study, c)), .false., &
                     failure)
    if (failure%failed()) then
      reason = failure%message
      call fail(failure, failure_io, 'cannot append to '//self%journal_path//' ('//self%study%input_file//'): '// &
                reason, self%journal_path)
      return
    end if
    call system_clock(now)
    if (real(now - self%last_write, real64) >= index_interval*real(self%clock_rate, real64)) then
      call write_index(self, failure)
      self%last_write = now
    end if
  end subroutine record

  !> Writes the final index.h5, with the machine's load at the end, and empties the journal,
  !> whose lines it now holds.
  subroutine close_index(self, failure)
    class(case_index), intent(inout) :: self
    type(failure_type), intent(out) :: failure
    character(len=:), allocatable :: reason

    self%load_end = machine_load_now()
    self%ended = .true.
    call write_index(self, failure)
    if (failure%failed()) return
    call remove_file(self%journal_path, failure)
    if (failure%failed()) then
      reason = failure%message
      call fail(failure, failure_io, 'cannot remove '//self%journal_path//': '//reason, self%journal_path)
    end if
  end subroutine close_index

end module study_index
