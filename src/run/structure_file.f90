!> The GENERIC structure of a scene as an HDF5 file (the paper's Fig. 2; docs/figures.md): for each
!> thermodynamic variable tau = s, theta, u, the Poisson matrix L and the friction matrix K of
!> eq. (8) (src/structure/structure_matrices: L = M_S L0 M_S^T, K = M_E K0 M_E^T) with grad E and
!> grad S, at the scene's initial state, in the run files' state layout. One group per variable
!> (/entropy, /temperature, /internal_energy) with the datasets L, K, grad_E, grad_S and state,
!> each with the attribute columns; the root has the scene's input file and provenance.
module structure_file
  use, intrinsic :: iso_fortran_env, only: real64
  use hdf5, only: hid_t, hsize_t, h5open_f, h5fcreate_f, h5fclose_f, h5gcreate_f, h5gclose_f, H5F_ACC_TRUNC_F
  use h5lt, only: h5ltmake_dataset_double_f, h5ltset_attribute_string_f
  use model_interface, only: generic_model
  use model_constraint, only: constraint_slot
  use structure_matrices, only: poisson_matrix, friction_matrix, energy_gradient, entropy_gradient
  use thermo_variable_kinds, only: thermo_variable_names, tau_entropy, tau_internal_energy
  use run_config, only: run_configuration
  use hdf5_files, only: hdf5_file
  use provenance, only: write_provenance
  use run_options, only: petsc_options_in_force
  use namelist_text, only: joined
  use failures, only: failure_type, fail, failure_input, failure_library
  implicit none (type, external)
  private
  public :: write_structure_file

contains

  !> Writes the structure of `config`'s scene at its initial state to `path`. A failure if the
  !> scene cannot be built (its own), its partials are undefined (failure_input) or HDF5 fails
  !> (failure_library, `path` as origin).
  subroutine write_structure_file(config, path, failure)
    type(run_configuration), intent(in) :: config
    character(len=*), intent(in) :: path
    type(failure_type), intent(out) :: failure
    class(generic_model), allocatable :: model
    type(constraint_slot), allocatable :: constraints(:)
    real(real64), allocatable :: z0(:), partials(:, :, :)
    integer(hid_t) :: file, group
    type(hdf5_file) :: root
    integer :: variable, n, close_stat, stat
    type(failure_type) :: step
    character(len=:), allocatable :: columns

    call h5open_f(stat)
    if (stat == 0) call h5fcreate_f(path, H5F_ACC_TRUNC_F, file, stat)
    if (stat /= 0) then
      call fail(failure, failure_library, 'HDF5 cannot create '//path, path)
      return
    end if
    root%id = file
    root%fresh = .true.
    call write_provenance(root, 'GENERIC structure (L, K of eq. (8)) of '//config%input_file//' at its initial '// &
                          'state, for each thermodynamic variable', petsc_options_in_force(), step)
    if (.not. step%failed()) call root%set_text('input_file', config%input_file, step)
    if (step%failed()) stat = -1
    do variable = tau_entropy, tau_internal_energy
      if (stat /= 0) exit
      call config%scene%build(variable, model, z0, constraints, step)
      if (step%failed()) then
        ! The scene's own words, as the driver printed them before (no origin added).
        call fail(failure, step%code, step%message)
        stat = step%code
        exit
      end if
      n = model%state_size
      allocate (partials(model%max_invariants, 2, model%subsystem_count()))
      call model%exact_partials(z0, partials, stat=stat)
      if (stat /= 0) then
        call fail(failure, failure_input, config%input_file//': the initial state is outside the model''s domain', &
                  config%input_file)
        exit
      end if
      columns = joined(model%column_names, ' ')
      call h5gcreate_f(file, trim(thermo_variable_names(variable)), group, stat)
      if (stat == 0) call matrix('L', poisson_matrix(model, z0, partials), 'Poisson matrix L = M_S L0 M_S^T, eq. (8)')
      if (stat == 0) call matrix('K', friction_matrix(model, z0, partials), 'friction matrix K = M_E K0 M_E^T, eq. (8)')
      if (stat == 0) call vector('grad_E', energy_gradient(model, z0, partials), 'the gradient of E in z')
      if (stat == 0) call vector('grad_S', entropy_gradient(model, z0, partials), 'the gradient of S in z')
      if (stat == 0) call vector('state', z0, 'the state z where L and K are evaluated (the initial state)')
      call h5gclose_f(group, close_stat)
      if (stat == 0) stat = close_stat
      deallocate (partials)
      if (stat /= 0 .and. .not. failure%failed()) call fail(failure, failure_library, 'HDF5 failed to write '//path, path)
    end do
    call h5fclose_f(file, close_stat)
    if (stat == 0 .and. close_stat /= 0) then
      stat = close_stat
      call fail(failure, failure_library, 'HDF5 failed to close '//path, path)
    end if
    if (stat /= 0 .and. .not. failure%failed()) call fail(failure, failure_library, 'HDF5 failed to write '//path, path)

  contains

    subroutine matrix(name, values, description)
      character(len=*), intent(in) :: name, description
      real(real64), intent(in) :: values(:, :)

      ! Row-major on disk, as h5py reads it: entry (i, j) of the matrix is dataset[i, j].
      call h5ltmake_dataset_double_f(group, name, 2, [integer(hsize_t) :: n, n], transpose(values), stat)
      call describe(name, description)
    end subroutine matrix

    subroutine vector(name, values, description)
      character(len=*), intent(in) :: name, description
      real(real64), intent(in) :: values(:)

      call h5ltmake_dataset_double_f(group, name, 1, [integer(hsize_t) :: n], values, stat)
      call describe(name, description)
    end subroutine vector

    subroutine describe(name, description)
      character(len=*), intent(in) :: name, description

      if (stat == 0) call h5ltset_attribute_string_f(group, name, 'description', description, stat)
      if (stat == 0) call h5ltset_attribute_string_f(group, name, 'columns', columns, stat)
    end subroutine describe
  end subroutine write_structure_file

end module structure_file
