!> The two gas containers' input: &model (model_name = 'gas_containers', the friction
!> coefficient) and &initial (the piston's q and p, and the containers' entropies, whatever the
!> run's thermodynamic variable). No constraints: g1 and g2 are the pendulum's.
module gas_scene
  use, intrinsic :: iso_fortran_env, only: real64
  use namelist_text, only: namelist_item
  use namelist_group, only: group_field, real_field, reals_field, text_field, read_group, value_origin
  use number_text, only: reals_text
  use model_interface, only: generic_model
  use model_constraint, only: constraint_slot
  use model_scene, only: scene
  use failures, only: failure_none, failure_type, fail, failure_input, failure_code_name
  use thermo_variable_kinds, only: tau_entropy
  use gas_model, only: gas_containers, make_gas_containers
  implicit none (type, external)
  private
  public :: gas_containers_name, new_gas_containers_scene

  character(len=*), parameter :: gas_containers_name = 'gas_handwritten'

  !> The values of the two groups, in their namelist names.
  type, extends(scene) :: gas_containers_scene
    character(len=24) :: model_name = gas_containers_name
    real(real64) :: friction = 8.0_real64
    real(real64) :: q = 1.0_real64
    real(real64) :: p = 2.0_real64
    real(real64) :: entropy(2) = [1.5_real64, 3.0_real64]
  contains
    procedure :: group_names
    procedure :: fields
    procedure :: read
    procedure :: build
    procedure :: default_theta_r
    procedure :: constraint_count
  end type gas_containers_scene

contains

  !> A scene of the two gas containers with the defaults (the model registry's maker).
  subroutine new_gas_containers_scene(made)
    class(scene), allocatable, intent(out) :: made

    allocate (gas_containers_scene :: made)
  end subroutine new_gas_containers_scene

  !> &model, &initial.
  pure subroutine group_names(self, names)
    class(gas_containers_scene), intent(in) :: self
    character(len=16), allocatable, intent(out) :: names(:)

    names = [character(len=16) :: 'model', 'initial']
  end subroutine group_names

  !> The fields of one group (docs/input.md).
  function fields(self, group) result(table)
    class(gas_containers_scene), intent(in), target :: self
    character(len=*), intent(in) :: group
    type(group_field), allocatable :: table(:)

    select case (group)
    case ('model')
      table = [text_field('model_name', self%model_name, "the model: 'gas_containers'", gas_containers_name), &
               real_field('friction', self%friction, 'a real number >= 0 (K0 = friction [[1, -1], [-1, 1]])', '1', &
                          minimum=0.0_real64)]
    case ('initial')
      table = [real_field('q', self%q, 'a real number in (0, 2): the piston, the first container''s volume', '1', &
                          minimum=0.0_real64, exclusive=.true.), &
               real_field('p', self%p, 'a real number: the piston''s momentum', '1'), &
               reals_field('entropy', self%entropy, 'two real numbers: the containers'' entropies', '1')]
    case default
      allocate (table(0))
    end select
  end function fields

  !> Reads &model and &initial; q must leave both containers a volume.
  subroutine read(self, text, origin, extra, failure)
    class(gas_containers_scene), intent(inout), target :: self
    character(len=*), intent(in) :: text, origin
    type(namelist_item), intent(in) :: extra(:)
    type(failure_type), intent(out) :: failure
    class(generic_model), allocatable :: model
    real(real64), allocatable :: z0(:)
    integer :: stat

    call read_group(text, 'model', self%fields('model'), origin, failure, extra)
    if (failure%failed()) return
    call read_group(text, 'initial', self%fields('initial'), origin, failure, extra)
    if (failure%failed()) return
    if (self%q >= 2.0_real64) then
      call fail(failure, failure_input, origin//': &initial: q is not allowed: the second container''s volume 2 - q '// &
                'would not be > 0; allowed: a real number in (0, 2)', 'q')
      return
    end if
    ! The state must lie in the model's domain: finite and positive internal energies, through which
    ! every variable's state is converted. Refused here, where the input's origin is known (build
    ! knows no file).
    call initial_state(self, tau_entropy, model, z0, stat)
    if (stat /= failure_none) call fail(failure, failure_input, value_origin(text, 'initial', 'entropy', origin, extra)// &
      ': &initial: entropy = '//reals_text(self%entropy)//' with q = '//reals_text([self%q])//' is not allowed (the '// &
      'containers'' internal energies give '//failure_code_name(stat)//'); allowed: entropies whose containers'' '// &
      'internal energies (exp(entropy(a))/v_a)^(2/3), v_1 = q and v_2 = 2 - q, are finite (below 1e277) and > 0', &
      'entropy')
  end subroutine read

  !> The model in thermodynamic variable `variable` and the initial state (no constraints).
  subroutine build(self, variable, model, z0, constraints, failure)
    class(gas_containers_scene), intent(in) :: self
    integer, intent(in) :: variable
    class(generic_model), allocatable, intent(out) :: model
    real(real64), allocatable, intent(out) :: z0(:)
    type(constraint_slot), allocatable, intent(out) :: constraints(:)
    type(failure_type), intent(out) :: failure
    integer :: stat

    allocate (constraints(0))
    call initial_state(self, variable, model, z0, stat)
    if (stat /= failure_none) call fail(failure, stat, '&initial: the initial state lies outside the model''s domain', &
                                        '&initial')
  end subroutine build

  ! The model in thermodynamic variable `variable` and the initial state given in entropies; stat
  ! a domain code if that state lies outside the model's domain.
  subroutine initial_state(self, variable, model, z0, stat)
    class(gas_containers_scene), intent(in) :: self
    integer, intent(in) :: variable
    class(generic_model), allocatable, intent(out) :: model
    real(real64), allocatable, intent(out) :: z0(:)
    integer, intent(out) :: stat
    type(gas_containers) :: in_entropy

    in_entropy = make_gas_containers(self%friction, tau_entropy)
    allocate (model, source=make_gas_containers(self%friction, variable))
    allocate (z0(model%state_size))
    call in_entropy%convert_state([self%q, self%p, self%entropy], model, z0, stat)
  end subroutine initial_state

  !> theta_R = 1 (the model is nondimensional).
  pure function default_theta_r(self) result(theta_r)
    class(gas_containers_scene), intent(in) :: self
    real(real64) :: theta_r

    theta_r = 1.0_real64
  end function default_theta_r

  !> None: the containers take no constraints.
  pure integer function constraint_count(self)
    class(gas_containers_scene), intent(in) :: self

    constraint_count = 0
  end function constraint_count

end module gas_scene
