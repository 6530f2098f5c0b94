!> The double pendulum's input: the groups &model (Table 1's data), &initial (docs/formulation.md
!> section 1's state, with temperatures whatever the thermodynamic variable) and &constraints
!> (g1, g2 of eq. (13)). Defaults are the paper's scene. &model's `spring_law` and `dimension`
!> declare the scene's parts (docs/formulation.md section 9): the other groups then have the
!> fields of those parts only, and a field of another part is refused by name. A constraint must hold at t = 0, or the
!> first step would jump onto it and do work: `length` defaults to |q1(0)| and must equal it,
!> `temperature` defaults to theta(1) and must equal it.
module pendulum_scene
  use, intrinsic :: iso_fortran_env, only: real64
  use namelist_text, only: namelist_item, group_items, item_name, joined
  use number_text, only: reals_text
  use namelist_field, only: group_field, real_field, reals_field, integer_field, logical_field, text_field, &
                            invalid_value_message, absolute_temperature, field_names
  use namelist_group, only: read_group, value_origin
  use model_parameters, only: pendulum_parameters, spring_law_names
  use failures, only: failure_type, fail, failure_input
  use model_interface, only: generic_model
  use model_constraint, only: constraint_slot
  use model_scene, only: scene
  use double_pendulum, only: pendulum_layout, make_layout
  use pendulum_rungs, only: rung_model
  use length_constraint, only: make_fixed_length
  use temperature_constraint, only: make_fixed_temperature
  implicit none (type, external)
  private
  public :: double_pendulum_scene, double_pendulum_name, new_double_pendulum_scene

  character(len=*), parameter :: double_pendulum_name = 'double_pendulum'
  !> &model's fields of the viscous branch, which the thermoelastic law does not have.
  character(len=*), parameter :: viscous_model_fields(5) = [character(len=24) :: 'mu_neq_const', 'mu_neq_slope', &
                                                            'viscosity_const', 'viscosity_activation', 'beta_v']
  !> &model's thermal fields, which the elastic law does not have.
  character(len=*), parameter :: thermal_model_fields(5) = [character(len=24) :: 'mu_eq_slope', 'heat_capacity', &
                                                            'conductivity', 'theta_ref', 'beta']

  !> The values of the three groups, in their namelist names.
  type, extends(scene) :: double_pendulum_scene
    character(len=24) :: model_name = double_pendulum_name
    type(pendulum_parameters) :: params
    real(real64) :: q1(3) = [1.0_real64, 0.0_real64, 0.0_real64]
    real(real64) :: q2(3) = [3.0_real64, 0.0_real64, 0.0_real64]
    real(real64) :: p1(3) = [0.0_real64, 0.0_real64, 0.0_real64]
    real(real64) :: p2(3) = [-1.0_real64, -1.0_real64, 0.0_real64]
    real(real64) :: gamma = 0.0_real64
    real(real64) :: theta(2) = [280.0_real64, 350.0_real64]
    logical :: fix_length = .false.
    real(real64) :: length = 1.0_real64
    logical :: fix_temperature = .false.
    real(real64) :: temperature = 280.0_real64
  contains
    procedure :: group_names
    procedure :: fields
    procedure :: read
    procedure :: build
    procedure :: default_theta_r
    procedure :: constraint_count
    procedure :: without_temperatures
  end type double_pendulum_scene

contains

  !> A scene of the double pendulum with the defaults (the model registry's maker).
  subroutine new_double_pendulum_scene(made)
    class(scene), allocatable, intent(out) :: made

    allocate (double_pendulum_scene :: made)
  end subroutine new_double_pendulum_scene

  !> &model, &initial, &constraints.
  pure subroutine group_names(self, names)
    class(double_pendulum_scene), intent(in) :: self
    character(len=16), allocatable, intent(out) :: names(:)

    names = [character(len=16) :: 'model', 'initial', 'constraints']
  end subroutine group_names

  !> The fields of one group (docs/input.md).
  function fields(self, group) result(table)
    class(double_pendulum_scene), intent(in), target :: self
    character(len=*), intent(in) :: group
    type(group_field), allocatable :: table(:)

    select case (group)
    case ('model')
      table = model_fields(self, every_part=.false.)
    case ('initial')
      table = initial_fields(self, every_part=.false.)
    case ('constraints')
      table = [ &
        logical_field('fix_length', self%fix_length, '.true. or .false.'), &
        real_field('length', self%length, 'a real number > 0 equal to |q1| at t = 0 [m]', 'm', minimum=0.0_real64, &
                   exclusive=.true.), &
        logical_field('fix_temperature', self%fix_temperature, '.true. or .false.'), &
        absolute_temperature(real_field('temperature', self%temperature, 'a real number > 0 equal to theta(1) at '// &
                                        't = 0 [K]', 'K', minimum=0.0_real64, exclusive=.true.))]
      ! A constraint must hold at t = 0.
      table(2)%check_equal = .true.
      table(2)%required = norm2(self%q1)
      table(4)%check_equal = .true.
      table(4)%required = self%theta(1)
      if (.not. self%params%thermal()) table = without(table, [character(len=24) :: 'fix_temperature', 'temperature'])
    case default
      allocate (table(0))
    end select
  end function fields

  !> &model's fields for the scene's spring law and dimension, or (every_part) the fields of
  !> every law with vectors of up to three values: the first pass, which learns the parts.
  function model_fields(self, every_part) result(table)
    class(double_pendulum_scene), intent(in), target :: self
    logical, intent(in) :: every_part
    type(group_field), allocatable :: table(:)
    integer :: d

    d = merge(3, self%params%dimension, every_part)
    associate (p => self%params)
      table = [ &
        text_field('model_name', self%model_name, "the model: 'double_pendulum'", double_pendulum_name), &
        text_field('spring_law', p%spring_law, "'thermoviscoelastic' (the paper's springs), 'thermoelastic' "// &
                   "(no viscous branch: no gamma, mu_neq_*, viscosity_* or beta_v) or 'elastic' (no thermal "// &
                   "variables either: springs of stiffness mu_eq_const; no theta, mu_eq_slope, heat_capacity, "// &
                   "conductivity, theta_ref, beta or fix_temperature)", spring_law_names), &
        integer_field('dimension', p%dimension, '3 (spatial) or 2 (planar, y vertical: q1, q2, p1, p2 and '// &
                      'gravity take two values; gravity defaults to 0, -9.81)', minimum=2, maximum=3), &
        reals_field('mass', p%mass, 'two real numbers > 0 [kg]', 'kg', minimum=0.0_real64, exclusive=.true.), &
        reals_field('natural_length', p%natural_length, 'two real numbers > 0 [m]', 'm', minimum=0.0_real64, &
                    exclusive=.true.), &
        reals_field('mu_eq_const', p%mu_eq_const, 'two real numbers > 0 [J] (eq. (17))', 'J', minimum=0.0_real64, &
                    exclusive=.true.), &
        reals_field('mu_eq_slope', p%mu_eq_slope, 'two real numbers >= 0 [J/K] (eq. (17); 0: a stiffness that '// &
                    'does not depend on temperature)', 'J/K', minimum=0.0_real64), &
        real_field('mu_neq_const', p%mu_neq_const, 'a real number > 0 [J/m^2] (eq. (17); thermoviscoelastic)', &
                   'J/m^2', minimum=0.0_real64, exclusive=.true.), &
        real_field('mu_neq_slope', p%mu_neq_slope, 'a real number > 0 [J/(K m^2)] (eq. (17); thermoviscoelastic)', &
                   'J/(K m^2)', minimum=0.0_real64, exclusive=.true.), &
        reals_field('heat_capacity', p%heat_capacity, 'two real numbers > 0 [J/K]', 'J/K', minimum=0.0_real64, &
                    exclusive=.true.), &
        real_field('viscosity_const', p%viscosity_const, 'a real number > 0 [J s/m^2] (eq. (17); '// &
                   'thermoviscoelastic)', 'J s/m^2', minimum=0.0_real64, exclusive=.true.), &
        real_field('viscosity_activation', p%viscosity_activation, 'a real number > 0 [K] (eq. (17); '// &
                   'thermoviscoelastic)', 'K', minimum=0.0_real64, exclusive=.true.), &
        real_field('conductivity', p%conductivity, 'a real number >= 0 [J/(K s)]', 'J/(K s)', minimum=0.0_real64), &
        absolute_temperature(real_field('theta_ref', p%theta_ref, 'a real number > 0 [K]', 'K', minimum=0.0_real64, &
                                        exclusive=.true.)), &
        real_field('beta', p%beta, 'a real number [J/K]', 'J/K'), &
        real_field('beta_v', p%beta_v, 'a real number >= 0 (thermoviscoelastic)', '1', minimum=0.0_real64), &
        reals_field('gravity', p%gravity(1:d), vector_text(d, '[m/s^2]'), 'm/s^2', open_length=every_part)]
      if (.not. (every_part .or. p%viscous())) table = without(table, viscous_model_fields)
      if (.not. (every_part .or. p%thermal())) table = without(table, thermal_model_fields)
    end associate
  end function model_fields

  !> &initial's fields for the scene's parts (every_part: all of them, vectors of up to three).
  function initial_fields(self, every_part) result(table)
    class(double_pendulum_scene), intent(in), target :: self
    logical, intent(in) :: every_part
    type(group_field), allocatable :: table(:)
    integer :: d

    d = merge(3, self%params%dimension, every_part)
    table = [ &
      reals_field('q1', self%q1(1:d), vector_text(d, 'not all zero [m]'), 'm', nonzero=.true., open_length=every_part), &
      reals_field('q2', self%q2(1:d), vector_text(d, 'not all zero [m]'), 'm', nonzero=.true., open_length=every_part), &
      reals_field('p1', self%p1(1:d), vector_text(d, '[N s]'), 'N s', open_length=every_part), &
      reals_field('p2', self%p2(1:d), vector_text(d, '[N s]'), 'N s', open_length=every_part), &
      real_field('gamma', self%gamma, 'a real number [m] (thermoviscoelastic)', 'm'), &
      absolute_temperature(reals_field('theta', self%theta, 'two real numbers > 0 [K], below theta_ref + '// &
                                       'mu_eq_const/mu_eq_slope (where a spring''s stiffness, eq. (17), would reach 0; '// &
                                       'no bound where mu_eq_slope = 0)', &
                                       'K', minimum=0.0_real64, exclusive=.true.))]
    if (.not. (every_part .or. self%params%viscous())) table = without(table, [character(len=24) :: 'gamma'])
    if (.not. (every_part .or. self%params%thermal())) table = without(table, [character(len=24) :: 'theta'])
  end function initial_fields

  ! The table without the fields called `names` (a loop: gfortran 12 mishandles array
  ! constructors and pack of types with allocatable character components).
  function without(table, names) result(kept)
    type(group_field), intent(in) :: table(:)
    character(len=*), intent(in) :: names(:)
    type(group_field), allocatable :: kept(:)
    integer :: i, k

    allocate (kept(count([(all(names /= table(i)%name), i=1, size(table))])))
    k = 0
    do i = 1, size(table)
      if (any(names == table(i)%name)) cycle
      k = k + 1
      kept(k) = table(i)
    end do
  end function without

  ! "three real numbers, <rest>" or "two ..." for a vector of the scene's dimension.
  pure function vector_text(dimension, rest) result(text)
    integer, intent(in) :: dimension
    character(len=*), intent(in) :: rest
    character(len=:), allocatable :: text

    if (dimension == 3) then
      text = 'three real numbers (two with dimension = 2), '//rest
    else
      text = 'two real numbers (dimension = 2), '//rest
    end if
  end function vector_text

  !> Reads &model, &initial and &constraints in that order (the constraints' defaults come from
  !> the initial state). &model is read twice: first with every law's fields, to learn the
  !> scene's parts, then with the fields of those parts.
  subroutine read(self, text, origin, extra, failure)
    class(double_pendulum_scene), intent(inout), target :: self
    character(len=*), intent(in) :: text, origin
    type(namelist_item), intent(in) :: extra(:)
    type(failure_type), intent(out) :: failure

    type(double_pendulum_scene), target :: probe, every_law   ! every_law keeps the defaults: all fields
    type(group_field), allocatable :: initial_table(:)
    real(real64) :: stiffness(2)

    call read_group(text, 'model', model_fields(probe, every_part=.true.), origin, failure, extra)
    if (failure%failed()) return
    self%params%spring_law = probe%params%spring_law
    self%params%dimension = probe%params%dimension
    if (self%params%dimension == 2) then
      self%params%gravity = [0.0_real64, -9.81_real64, 0.0_real64]
      self%q1(3) = 0.0_real64
      self%q2(3) = 0.0_real64
      self%p1(3) = 0.0_real64
      self%p2(3) = 0.0_real64
    end if
    call refuse_other_parts(self, text, 'model', model_fields(probe, every_part=.true.), self%fields('model'), &
                            origin, extra, failure)
    if (failure%failed()) return
    call read_group(text, 'model', self%fields('model'), origin, failure, extra)
    if (failure%failed()) return
    initial_table = self%fields('initial')
    call refuse_other_parts(self, text, 'initial', initial_fields(probe, every_part=.true.), initial_table, &
                            origin, extra, failure)
    if (failure%failed()) return
    call read_group(text, 'initial', initial_table, origin, failure, extra)
    if (failure%failed()) return
    call refuse_other_parts(self, text, 'constraints', every_law%fields('constraints'), &
                            self%fields('constraints'), origin, extra, failure)
    if (failure%failed()) return
    ! mu^eq_a(theta_a) of eq. (17) at t = 0: a spring with no stiffness has no equilibrium.
    associate (p => self%params)
      stiffness = p%mu_eq_const - p%mu_eq_slope*(self%theta - p%theta_ref)
    end associate
    if (self%params%thermal() .and. any(stiffness <= 0.0_real64)) then
      call fail(failure, failure_input, invalid_value_message(value_origin(text, 'initial', 'theta', origin, extra), &
                'initial', initial_table(findloc(initial_table%name, 'theta', dim=1)))// &
                ' (the stiffness mu_eq(theta) of eq. (17) is '//reals_text(stiffness)//' J)', 'theta')
      return
    end if
    self%length = norm2(self%q1)
    self%temperature = self%theta(1)
    call read_group(text, 'constraints', self%fields('constraints'), origin, failure, extra)
  end subroutine read

  ! A field that another part of the model has (in `every_field`, not in `scene_fields`) is
  ! refused with the part that lacks it, rather than as an unknown field.
  subroutine refuse_other_parts(self, text, group, every_field, scene_fields, origin, extra, failure)
    class(double_pendulum_scene), intent(in) :: self
    character(len=*), intent(in) :: text, group, origin
    type(group_field), intent(in) :: every_field(:), scene_fields(:)
    type(namelist_item), intent(in) :: extra(:)
    type(failure_type), intent(out) :: failure
    type(namelist_item), allocatable :: items(:)
    character(len=:), allocatable :: name
    integer :: i

    call group_items(text, group, field_names(every_field), origin, items, extra)
    do i = 1, size(items)
      name = item_name(items(i)%item)
      if (any(field_names(scene_fields) == name) .or. .not. any(field_names(every_field) == name)) cycle
      call fail(failure, failure_input, items(i)%origin//': &'//group//': '//name// &
                ' is not a field of spring_law = '''//trim(self%params%spring_law)//''' ('// &
                trim(merge('it has no viscous branch    ', 'elastic springs have no heat', self%params%thermal()))// &
                '); allowed: '//joined(field_names(scene_fields), ', '), name)
      return
    end do
  end subroutine refuse_other_parts

  !> The pendulum of the scene's rung (pendulum_rungs: generated from src/model/pendulum/description.py, or the
  !> hand-written elastic one) in thermodynamic variable `variable`, the initial state and the constraints.
  subroutine build(self, variable, model, z0, constraints, failure)
    class(double_pendulum_scene), intent(in) :: self
    integer, intent(in) :: variable
    class(generic_model), allocatable, intent(out) :: model
    real(real64), allocatable, intent(out) :: z0(:)
    type(constraint_slot), allocatable, intent(out) :: constraints(:)
    type(failure_type), intent(out) :: failure
    type(pendulum_layout) :: layout
    real(real64) :: x(3)
    integer :: a, k, n, stat

    call rung_model(self%params, variable, model)
    layout = make_layout(self%params%dimension, self%params%viscous(), self%params%thermal())
    allocate (z0(model%state_size))
    z0 = 0.0_real64
    associate (d => layout%dimension)
      z0(layout%q(1:d, 1)) = self%q1(1:d)
      z0(layout%q(1:d, 2)) = self%q2(1:d)
      z0(layout%p(1:d, 1)) = self%p1(1:d)
      z0(layout%p(1:d, 2)) = self%p2(1:d)
    end associate
    if (layout%viscous) z0(layout%gamma) = self%gamma
    ! Each spring's tau from its temperature at its mechanical invariants (its potentials' closed form).
    do a = 1, size(model%subsystems)
      associate (part => model%subsystems(a))
        if (part%tau_column == 0) cycle
        n = part%invariant_count
        call model%invariants(z0, a, x(1:n))
        call part%potentials%tau_from_temperature(x(1:n - 1), self%theta(a), z0(part%tau_column), stat)
      end associate
      if (stat /= 0) then
        call fail(failure, stat, '&initial: the initial state lies outside the model''s domain', '&initial')
        exit
      end if
    end do
    allocate (constraints(self%constraint_count()))
    k = 0
    if (self%fix_length) then
      k = k + 1
      allocate (constraints(k)%item, source=make_fixed_length(self%length, self%params%mass(1), layout))
    end if
    if (self%fix_temperature) then
      k = k + 1
      allocate (constraints(k)%item, source=make_fixed_temperature(1, self%temperature))
    end if
  end subroutine build

  !> theta_ref, or the fixed temperature of spring 1 under g2 (docs/formulation.md section 7).
  pure function default_theta_r(self) result(theta_r)
    class(double_pendulum_scene), intent(in) :: self
    real(real64) :: theta_r

    theta_r = self%params%theta_ref
    if (self%fix_temperature) theta_r = self%temperature
  end function default_theta_r

  !> Number of active constraints.
  pure integer function constraint_count(self)
    class(double_pendulum_scene), intent(in) :: self

    constraint_count = count([self%fix_length, self%fix_temperature])
  end function constraint_count

  !> Elastic springs have no thermodynamic variables: why, for run-level fields that need them.
  pure function without_temperatures(self) result(reason)
    class(double_pendulum_scene), intent(in) :: self
    character(len=:), allocatable :: reason

    reason = ''
    if (.not. self%params%thermal()) reason = 'spring_law = '''//trim(self%params%spring_law)// &
                                              ''' has no thermodynamic variables and no entropy'
  end function without_temperatures

end module pendulum_scene
