!> index.h5 written whole (src/run/study_index): /cases with its columns' units, the attributes of
!> the study (its input, provenance, machine load) and the integrator registry, as index.h5.tmp
!> renamed over it.
!> (A .F90 file: docs/development.md, Modules that grow.)
submodule (study_index) study_index_write
  use hdf5_files, only: hdf5_file
  use hdf5_table, only: column_integer
  use integrator_registry, only: integrator_entry, registered_integrators
  use build_info, only: code_version
  use provenance, only: write_provenance
  use run_options, only: petsc_options_in_force
  use run_config, only: field_units, run_configuration, read_run_config
  use effective_namelist, only: namelist_of_run
  use namelist_text, only: item_name
  use study_case_files, only: case_name
  use study_columns, only: case_parameters
  use number_text, only: integer_text
  use failures, only: failure_library
  implicit none

contains

  module procedure write_index
    type(hdf5_file) :: file
    real(real64), allocatable :: numbers(:, :), parameters(:)
    character(len=status_length), allocatable :: texts(:, :)
    character(len=64), allocatable :: parameter_texts(:)
    character(len=:), allocatable :: reason
    type(failure_type) :: ignored
    integer :: c, n_numbers, n_texts

    n_numbers = self%columns%numeric_count()
    n_texts = self%columns%text_count()
    allocate (numbers(n_numbers, size(self%results)), texts(n_texts, size(self%results)))
    do c = 1, size(self%results)
      call case_parameters(self%study, c, parameters, parameter_texts)
      numbers(:, c) = [parameters, self%results(c)%metrics(self%shown)]
      texts(1, c) = ''
      if (.not. self%study%index_only) texts(1, c) = case_name(c)
      texts(2:n_texts - 2, c) = parameter_texts
      texts(n_texts - 1, c) = self%results(c)%status
      texts(n_texts, c) = self%results(c)%failure_kind
    end do
    call file%create_in_memory(failure)
    if (.not. failure%failed()) call self%columns%write(file%id, 'cases', numbers, texts, failure)
    if (.not. failure%failed()) call file%set_text('study', self%study%input_file, failure)
    if (.not. failure%failed()) call file%set_text('base', self%study%base, failure)
    if (.not. failure%failed()) call file%set_text('combine', self%study%combine, failure)
    ! What every case shares (all but the swept fields): the scene without opening a case file.
    if (.not. failure%failed()) call file%set_text('case_1_input', namelist_of_run(self%study%cases(1)%config), failure)
    if (.not. failure%failed()) call file%set_integer('index_only', merge(1, 0, self%study%index_only), failure)
    if (.not. failure%failed()) call file%set_integer('repeats', self%study%repeats, failure)
    if (.not. failure%failed()) call file%set_text('code_version', code_version, failure)
    if (.not. failure%failed()) call write_provenance(file, 'EME study '//self%study%input_file//': '// &
                                         integer_text(size(self%results))//' cases', petsc_options_in_force(), failure, &
                                         started=self%started)
    if (.not. failure%failed()) call load_attributes(file, self, failure)
    if (.not. failure%failed()) call column_units(file, self, failure)
    if (.not. failure%failed()) call write_registry(file, failure)
    if (.not. failure%failed()) call file%store(self%index_path, .true., failure)
    call file%close(ignored)
    if (failure%code == failure_io) then           ! the OS's words
      reason = failure%message
      call fail(failure, failure_io, 'cannot write '//self%index_path//' ('//self%study%input_file//'): '//reason, &
                self%index_path)
    else if (failure%failed()) then
      call fail(failure, failure_library, 'HDF5 failed to build '//self%index_path, self%index_path)
    end if
  end procedure write_index

  ! The attribute column_units of /cases: the units of every column, in order ('' for a text):
  ! the swept fields' and the figures' in the units of the base file's model (the gas containers'
  ! are nondimensional).
  subroutine column_units(file, self, failure)
    type(hdf5_file), intent(in) :: file
    type(case_index), intent(in) :: self
    type(failure_type), intent(out) :: failure
    character(len=24) :: units(2 + sum(self%study%sweeps%elements) + 2 + size(self%shown))
    type(run_configuration), target :: base
    type(failure_type) :: base_failure
    integer :: s, next

    call read_run_config(self%study%base, base, base_failure)
    units = ''
    units(1) = '1'                        ! case; file is a text
    next = 3
    do s = 1, size(self%study%sweeps)
      associate (sweep => self%study%sweeps(s))
        if (.not. sweep%textual) then
          if (.not. base_failure%failed()) then
            units(next:next + sweep%elements - 1) = field_units(item_name(sweep%field), base)
          else
            units(next:next + sweep%elements - 1) = field_units(item_name(sweep%field))
          end if
        end if
        next = next + sweep%elements
      end associate
    end do
    units(next + 2:) = self%units(self%shown)       ! after status and failure_kind
    call file%set_dataset_texts('cases', 'column_units', units, failure)
  end subroutine column_units

  ! The machine's load averages (1, 5 and 15 minutes) and cores online when this run of the study
  ! began, and when it ended (once it has), and its ranks: what its timings shared the machine with.
  subroutine load_attributes(file, self, failure)
    type(hdf5_file), intent(in) :: file
    type(case_index), intent(in) :: self
    type(failure_type), intent(out) :: failure

    call file%set_reals('load_average_start', self%load_start%averages, failure)
    if (.not. failure%failed()) call file%set_integer('cores_start', self%load_start%cores, failure)
    if (.not. failure%failed()) call file%set_integer('ranks', self%ranks, failure)
    if (.not. self%ended) return
    if (.not. failure%failed()) call file%set_reals('load_average_end', self%load_end%averages, failure)
    if (.not. failure%failed()) call file%set_integer('cores_end', self%load_end%cores, failure)
  end subroutine load_attributes

  ! The dataset /integrators: one row per registered integrator.
  subroutine write_registry(file, failure)
    type(hdf5_file), intent(in) :: file
    type(failure_type), intent(out) :: failure
    type(table_columns) :: columns
    type(integrator_entry), allocatable :: entries(:)
    character(len=status_length), allocatable :: texts(:, :)
    real(real64), allocatable :: numbers(:, :)
    integer :: i

    allocate (entries, source=registered_integrators())
    allocate (texts(4, size(entries)), numbers(4, size(entries)))

    call columns%add('name', len(entries(1)%name))
    call columns%add('label', len(entries(1)%label))
    call columns%add('family', len(entries(1)%family))
    call columns%add('description', len(entries(1)%description))
    call columns%add('takes_constraints', column_integer)
    call columns%add('uses_discrete_gradient', column_integer)
    call columns%add('adaptive', column_integer)
    call columns%add('error_control', column_integer)
    do i = 1, size(entries)
      texts(:, i) = [character(len=status_length) :: entries(i)%name, entries(i)%label, entries(i)%family, &
                     entries(i)%description]
      numbers(:, i) = merge(1.0_real64, 0.0_real64, [entries(i)%takes_constraints, entries(i)%uses_discrete_gradient, &
                                                     entries(i)%adaptive, entries(i)%error_control])
    end do
    call columns%write(file%id, 'integrators', numbers, texts, failure)
  end subroutine write_registry

end submodule study_index_write
