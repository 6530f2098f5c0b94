!> What a model reads and builds for a run: its namelist groups (the scene: parameters, initial
!> state, constraints) and, for a thermodynamic variable, the model of src/structure/
!> model_interface, its initial state and its active constraints. src/model/model_registry
!> names the scenes; run_config reads the run-level groups (&integrator, &output) around them.
module model_scene
  use, intrinsic :: iso_fortran_env, only: real64
  use namelist_text, only: namelist_item
  use namelist_field, only: group_field
  use model_interface, only: generic_model
  use model_constraint, only: constraint_slot
  use distributed_model, only: distributed_system
  use failures, only: failure_type
  implicit none (type, external)
  private
  public :: scene, array_reader

  !> Where a scene reads the arrays its input names in files (a chain's &initial file): given by
  !> src/io (HDF5, hdf5_array_reader) before `read`, absent where nothing is read (--help).
  type, abstract :: array_reader
  contains
    procedure(read_array_interface), deferred :: read_array
    procedure(member_names_interface), deferred :: member_names
  end type array_reader

  !> A model's input.
  type, abstract :: scene
    class(array_reader), allocatable :: arrays   !! for the files the input names
  contains
    procedure(group_names_interface), deferred :: group_names
    procedure(fields_interface), deferred :: fields
    procedure(read_interface), deferred :: read
    procedure(build_interface), deferred :: build
    procedure(theta_interface), deferred :: default_theta_r
    procedure(count_interface), deferred :: constraint_count
    procedure :: without_temperatures
    procedure :: distributed
  end type scene

  abstract interface
    !> Dataset `name` of the file at `path`: its values in the file's (C, row-major) order and its
    !> shape as h5py gives it; found = .false. if the file has no such dataset; a failure
    !> (failure_io) if the file cannot be read or the dataset holds no numbers, naming why.
    subroutine read_array_interface(self, path, name, values, shape, found, failure, row)
      import :: array_reader, real64, failure_type
      class(array_reader), intent(in) :: self
      character(len=*), intent(in) :: path, name
      real(real64), allocatable, intent(out) :: values(:)
      integer, allocatable, intent(out) :: shape(:)
      logical, intent(out) :: found
      type(failure_type), intent(out) :: failure
      integer, intent(in), optional :: row   !! one row along the first axis (from 0): shape drops that axis
    end subroutine read_array_interface

    !> The names of the members (datasets, groups) of the root group of the file at `path`, in
    !> name order; a failure (failure_io) if the file cannot be read, naming why.
    subroutine member_names_interface(self, path, names, failure)
      import :: array_reader, failure_type
      class(array_reader), intent(in) :: self
      character(len=*), intent(in) :: path
      character(len=256), allocatable, intent(out) :: names(:)
      type(failure_type), intent(out) :: failure
    end subroutine member_names_interface

    !> The namelist groups the scene reads, in reading order.
    pure subroutine group_names_interface(self, names)
      import :: scene
      class(scene), intent(in) :: self
      character(len=16), allocatable, intent(out) :: names(:)
    end subroutine group_names_interface

    !> The fields of group `group`, bound to the scene's variables.
    function fields_interface(self, group) result(fields)
      import :: scene, group_field
      class(scene), intent(in), target :: self
      character(len=*), intent(in) :: group
      type(group_field), allocatable :: fields(:)
    end function fields_interface

    !> Reads and checks the scene's groups from `text` (the input file `origin`, comments
    !> removed) and the `extra` items; a failure (failure_input) with a message naming file,
    !> group and field.
    subroutine read_interface(self, text, origin, extra, failure)
      import :: scene, namelist_item, failure_type
      class(scene), intent(inout), target :: self
      character(len=*), intent(in) :: text, origin
      type(namelist_item), intent(in) :: extra(:)
      type(failure_type), intent(out) :: failure
    end subroutine read_interface

    !> The model in thermodynamic variable `variable` (thermo_variable's tau_*), its initial
    !> state z0 and its active constraints; a failure (its domain code) if the initial state is
    !> outside the domain.
    subroutine build_interface(self, variable, model, z0, constraints, failure)
      import :: scene, generic_model, constraint_slot, real64, failure_type
      class(scene), intent(in) :: self
      integer, intent(in) :: variable
      class(generic_model), allocatable, intent(out) :: model
      real(real64), allocatable, intent(out) :: z0(:)
      type(constraint_slot), allocatable, intent(out) :: constraints(:)
      type(failure_type), intent(out) :: failure
    end subroutine build_interface

    !> The Lyapunov reference temperature theta_R a run uses unless &output sets it [K].
    pure function theta_interface(self) result(theta_r)
      import :: scene, real64
      class(scene), intent(in) :: self
      real(real64) :: theta_r
    end function theta_interface

    !> Number of active constraints.
    pure integer function count_interface(self)
      import :: scene
      class(scene), intent(in) :: self
    end function count_interface
  end interface

contains

  !> Why the scene has no temperatures ('' when it has them, the default): a scene of a
  !> mechanical model (elastic springs) has no thermodynamic variable and no V = E - theta_r S,
  !> so &integrator thermo_variable and &output theta_r are refused with this reason.
  pure function without_temperatures(self) result(reason)
    class(scene), intent(in) :: self
    character(len=:), allocatable :: reason

    reason = ''
  end function without_temperatures

  !> The scene's model as one that can be split over MPI ranks (src/model/distributed_model),
  !> stepped by `scheme` (&integrator scheme), not yet started; unallocated (the default) where
  !> the model runs on one process only.
  subroutine distributed(self, scheme, system)
    class(scene), intent(in) :: self
    character(len=*), intent(in) :: scheme
    class(distributed_system), allocatable, intent(out) :: system     ! (left unallocated)
  end subroutine distributed

end module model_scene
