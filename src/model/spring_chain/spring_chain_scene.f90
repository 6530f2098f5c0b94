!> The spring chain's input (docs/input.md, docs/formulation.md section 10), served by the dense
!> path: &model (model_name = 'spring_chain', links = N masses, ends, span, dimension, gravity,
!> spring_law, each spring's data as one value for every spring or n_s values, the links'
!> conductivity as one value or n_s - 1, the masses as one value or N) and &initial (the masses'
!> positions x and momenta p, by default a uniform stretch at rest; gamma and the temperatures theta
!> as one value or n_s). &model is read twice, as the pendulum's: first with arrays long enough for
!> any chain, to learn N, the ends, the dimension and the rung, then with the scene's own fields.
!> A per-spring field takes exactly one value or as many as its parts; anything else is refused
!> naming the file, group, field and the allowed counts. No constraints.
module spring_chain_scene
  use, intrinsic :: iso_fortran_env, only: real64
  use namelist_text, only: namelist_item, joined
  use namelist_group, only: group_field, real_field, reals_field, integer_field, text_field, read_group, &
                            value_origin, given_origin, absolute_temperature, field_names
  use number_text, only: integer_text, reals_text
  use model_parameters, only: spring_law_names, law_thermoviscoelastic, law_elastic
  use failures, only: failure_none, failure_type, fail, failure_input, failure_code_name
  use model_interface, only: generic_model
  use model_constraint, only: constraint_slot
  use model_scene, only: scene
  use thermo_variable_kinds, only: tau_entropy
  use spring_chain_spring, only: spring_data, rung_of, rung_thermoviscoelastic, rung_elastic
  use spring_chain_layout, only: chain_layout, make_chain_layout, ends_fixed_free, ends_fixed_fixed
  use spring_chain_model, only: spring_chain, make_spring_chain
  implicit none (type, external)
  private
  public :: spring_chain_name, new_spring_chain_scene

  character(len=*), parameter :: spring_chain_name = 'spring_chain'
  !> The most masses a chain may have (the sparse path's; the dense path takes dense_max_links).
  integer, parameter :: max_links = 100000
  !> An element no value was given for (compared with >= and <: reals are not compared for equality).
  real(real64), parameter :: unset = huge(1.0_real64)
  !> &model's fields of the viscous branch, and the thermal ones.
  character(len=*), parameter :: viscous_fields(5) = [character(len=24) :: 'mu_neq_const', 'mu_neq_slope', &
                                                      'viscosity_const', 'viscosity_activation', 'beta_v']
  character(len=*), parameter :: thermal_fields(5) = [character(len=24) :: 'mu_eq_slope', 'heat_capacity', &
                                                      'theta_ref', 'beta', 'conductivity']

  !> The values of the two groups, in their namelist names; arrays sized for the scene's chain.
  type, extends(scene) :: chain_scene
    character(len=24) :: model_name = spring_chain_name
    integer :: links = 2
    character(len=16) :: ends = ends_fixed_free
    real(real64) :: span = unset
    integer :: dimension = 3
    real(real64) :: gravity(3) = [0.0_real64, 0.0_real64, -9.81_real64]
    character(len=24) :: spring_law = law_thermoviscoelastic
    real(real64), allocatable :: natural_length(:), mu_eq_const(:), mu_eq_slope(:), mu_neq_const(:), mu_neq_slope(:)
    real(real64), allocatable :: heat_capacity(:), viscosity_const(:), viscosity_activation(:), theta_ref(:)
    real(real64), allocatable :: beta(:), beta_v(:), conductivity(:), mass(:)
    real(real64), allocatable :: x(:), p(:), gamma(:), theta(:)
    real(real64) :: stretch = 1.0_real64
  contains
    procedure :: group_names
    procedure :: fields
    procedure :: read
    procedure :: build
    procedure :: default_theta_r
    procedure :: constraint_count
    procedure :: without_temperatures
    procedure :: springs
    procedure :: rung
  end type chain_scene

contains

  !> A scene of the chain with the defaults (the model registry's maker): N = 2 hanging in 3D.
  subroutine new_spring_chain_scene(made)
    class(scene), allocatable, intent(out) :: made
    type(chain_scene) :: defaults

    call size_arrays(defaults, defaults%springs(), defaults%links, defaults%dimension)
    call complete_defaults(defaults)
    allocate (made, source=defaults)
  end subroutine new_spring_chain_scene

  !> n_s: N springs ('fixed-free') or N + 1 ('fixed-fixed').
  pure integer function springs(self)
    class(chain_scene), intent(in) :: self

    springs = self%links
    if (self%ends == ends_fixed_fixed) springs = self%links + 1
  end function springs

  !> The ladder's rung (spring_chain_spring's rung_*).
  pure integer function rung(self)
    class(chain_scene), intent(in) :: self

    rung = rung_of(trim(self%spring_law))
  end function rung

  ! Every array sized for n_s springs, N masses in d components, no value given.
  pure subroutine size_arrays(self, n_s, masses, d)
    type(chain_scene), intent(inout) :: self
    integer, intent(in) :: n_s, masses, d

    self%natural_length = spread(unset, 1, n_s)
    self%mu_eq_const = self%natural_length
    self%mu_eq_slope = self%natural_length
    self%mu_neq_const = self%natural_length
    self%mu_neq_slope = self%natural_length
    self%heat_capacity = self%natural_length
    self%viscosity_const = self%natural_length
    self%viscosity_activation = self%natural_length
    self%theta_ref = self%natural_length
    self%beta = self%natural_length
    self%beta_v = self%natural_length
    self%gamma = self%natural_length
    self%theta = self%natural_length
    self%conductivity = spread(unset, 1, max(1, n_s - 1))
    self%mass = spread(unset, 1, masses)
    self%x = spread(unset, 1, d*masses)
    self%p = self%x
  end subroutine size_arrays

  !> &model, &initial.
  pure subroutine group_names(self, names)
    class(chain_scene), intent(in) :: self
    character(len=16), allocatable, intent(out) :: names(:)

    names = [character(len=16) :: 'model', 'initial']
  end subroutine group_names

  !> The fields of one group (docs/input.md), for the scene's chain.
  function fields(self, group) result(table)
    class(chain_scene), intent(in), target :: self
    character(len=*), intent(in) :: group
    type(group_field), allocatable :: table(:)

    select case (group)
    case ('model')
      table = model_fields(self)
      if (self%rung() /= rung_thermoviscoelastic) table = without(table, viscous_fields)
      if (self%rung() == rung_elastic) table = without(table, thermal_fields)
    case ('initial')
      table = initial_fields(self)
      if (self%rung() /= rung_thermoviscoelastic) table = without(table, [character(len=24) :: 'gamma'])
      if (self%rung() == rung_elastic) table = without(table, [character(len=24) :: 'theta'])
      if (self%ends == ends_fixed_fixed) table = without(table, [character(len=24) :: 'stretch'])
    case default
      allocate (table(0))
    end select
  end function fields

  ! Every field of &model, bound to the scene's arrays (open length: their counts are checked
  ! after reading, by per_part_counts).
  function model_fields(self) result(table)
    class(chain_scene), intent(in), target :: self
    type(group_field), allocatable :: table(:)
    character(len=*), parameter :: each = ' (one value for every spring, or n_s: one per spring)'

    table = [ &
      text_field('model_name', self%model_name, "the model: 'spring_chain'", spring_chain_name), &
      integer_field('links', self%links, 'an integer from 1 to '//integer_text(max_links)//': N, the number of '// &
                    'point masses (the dense path: Jacobians of (N (2 dimension + 2))^2 entries)', &
                    minimum=1, maximum=max_links), &
      text_field('ends', self%ends, "'fixed-free' (a hanging chain: n_s = N springs, spring 1 from the support at "// &
                 "the origin to mass 1) or 'fixed-fixed' (n_s = N + 1: spring N + 1 from mass N to a second support "// &
                 "at span e_x)", ends_fixed_free//' '//ends_fixed_fixed), &
      real_field('span', self%span, "a real number > 0 [m]: the second support's distance along x "// &
                 "('fixed-fixed'; default: the sum of the natural lengths)", 'm', minimum=0.0_real64, exclusive=.true.), &
      integer_field('dimension', self%dimension, '1 (motion along x), 2 (planar, y vertical) or 3 (spatial, z '// &
                    'vertical): gravity, x and p take dimension values per mass', minimum=1, maximum=3), &
      reals_field('gravity', self%gravity(1:self%dimension), 'dimension real numbers [m/s^2] (default 0, 0, -9.81; '// &
                  '0, -9.81 in 2D; 0 in 1D)', 'm/s^2', open_length=.true.), &
      text_field('spring_law', self%spring_law, "'thermoviscoelastic' (every spring with a viscous branch and "// &
                 "gamma_a; a spring with beta_v = mu_neq_const = mu_neq_slope = 0 has none in effect), "// &
                 "'thermoelastic' (no gamma, mu_neq_*, viscosity_*, beta_v) or 'elastic' (no temperatures either: "// &
                 "no theta, mu_eq_slope, heat_capacity, theta_ref, beta, conductivity)", spring_law_names), &
      reals_field('mass', self%mass, 'real numbers > 0 [kg], one for every mass or N (default 1)', 'kg', &
                  minimum=0.0_real64, exclusive=.true., open_length=.true.), &
      per_spring('natural_length', self%natural_length, 'real numbers > 0 [m]'//each//'; default 2', 'm', 0.0_real64, &
                 .true.), &
      per_spring('mu_eq_const', self%mu_eq_const, 'real numbers > 0 [J] (eq. (17))'//each//'; default 200', 'J', &
                 0.0_real64, .true.), &
      per_spring('mu_eq_slope', self%mu_eq_slope, 'real numbers >= 0 [J/K] (eq. (17))'//each//'; default 0.5', 'J/K', &
                 0.0_real64, .false.), &
      per_spring('mu_neq_const', self%mu_neq_const, 'real numbers >= 0 [J/m^2] (eq. (17))'//each//'; default 5', &
                 'J/m^2', 0.0_real64, .false.), &
      per_spring('mu_neq_slope', self%mu_neq_slope, 'real numbers >= 0 [J/(K m^2)] (eq. (17))'//each//'; default 0.1', &
                 'J/(K m^2)', 0.0_real64, .false.), &
      per_spring('heat_capacity', self%heat_capacity, 'real numbers > 0 [J/K]'//each//'; default 10', 'J/K', &
                 0.0_real64, .true.), &
      per_spring('viscosity_const', self%viscosity_const, 'real numbers > 0 [J s/m^2] (eq. (17))'//each// &
                 '; default 100', 'J s/m^2', 0.0_real64, .true.), &
      per_spring('viscosity_activation', self%viscosity_activation, 'real numbers > 0 [K] (eq. (17))'//each// &
                 '; default 10', 'K', 0.0_real64, .true.), &
      absolute_temperature(per_spring('theta_ref', self%theta_ref, 'real numbers > 0 [K]'//each//'; default 300', 'K', &
                                      0.0_real64, .true.)), &
      per_spring('beta', self%beta, 'real numbers [J/K]'//each//'; default 0.02', 'J/K', -huge(1.0_real64), .false.), &
      per_spring('beta_v', self%beta_v, 'real numbers >= 0'//each//'; default 0.5', '1', 0.0_real64, .false.), &
      reals_field('conductivity', self%conductivity, 'real numbers >= 0 [J/(K s)]: the links (a, a+1), one value '// &
                  'for every link or n_s - 1; default 1 (ends adiabatic)', 'J/(K s)', minimum=0.0_real64, &
                  open_length=.true.)]
  end function model_fields

  ! &initial's fields.
  function initial_fields(self) result(table)
    class(chain_scene), intent(in), target :: self
    type(group_field), allocatable :: table(:)

    table = [ &
      reals_field('x', self%x, 'N times dimension real numbers [m]: the masses'' positions, mass by mass (default: '// &
                  'each spring at stretch times its natural length along x from the support; ''fixed-fixed'': '// &
                  'scaled to end at span)', 'm', open_length=.true.), &
      reals_field('p', self%p, 'N times dimension real numbers [N s]: the masses'' momenta, mass by mass (default 0)', &
                  'N s', open_length=.true.), &
      real_field('stretch', self%stretch, 'a real number > 0: the default positions'' stretch of every spring, '// &
                 'l_a = stretch l^0_a (''fixed-free'')', '1', minimum=0.0_real64, exclusive=.true.), &
      reals_field('gamma', self%gamma, 'real numbers [m]: the dampers'' elongations, one for every spring or n_s '// &
                  '(default 0)', 'm', open_length=.true.), &
      absolute_temperature(reals_field('theta', self%theta, 'real numbers > 0 [K], one for every spring or n_s, each '// &
                                       'below theta_ref + mu_eq_const/mu_eq_slope (default 280)', 'K', &
                                       minimum=0.0_real64, exclusive=.true., open_length=.true.))]
  end function initial_fields

  ! A per-spring real array field (open length; minimum, exclusive).
  function per_spring(name, values, allowed, units, minimum, exclusive) result(field)
    character(len=*), intent(in) :: name, allowed, units
    real(real64), intent(in), target :: values(:)
    real(real64), intent(in) :: minimum
    logical, intent(in) :: exclusive
    type(group_field) :: field

    field = reals_field(name, values, allowed, units, minimum=minimum, exclusive=exclusive, open_length=.true.)
  end function per_spring

  ! The table without the fields called `names`.
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

  !> Reads &model (twice: the chain's shape, then its fields), checks every per-part count, then
  !> &initial, and builds the initial state once to refuse one outside the model's domain.
  subroutine read(self, text, origin, extra, failure)
    class(chain_scene), intent(inout), target :: self
    character(len=*), intent(in) :: text, origin
    type(namelist_item), intent(in) :: extra(:)
    type(failure_type), intent(out) :: failure
    type(chain_scene), target :: probe
    class(generic_model), allocatable :: model
    real(real64), allocatable :: z0(:)
    real(real64), allocatable :: stiffness(:)
    character(len=:), allocatable :: where
    integer :: stat, a

    ! First pass: every field, arrays long enough for any chain.
    call size_arrays(probe, max_links + 1, max_links, 3)
    probe%dimension = 3
    call read_group(text, 'model', model_fields(probe), origin, failure, extra)
    if (failure%failed()) return
    self%links = probe%links
    self%ends = probe%ends
    self%dimension = probe%dimension
    self%spring_law = probe%spring_law
    if (self%dimension == 2) self%gravity = [0.0_real64, -9.81_real64, 0.0_real64]
    if (self%dimension == 1) self%gravity = 0.0_real64
    call size_arrays(self, self%springs(), self%links, self%dimension)
    call refuse_other_parts(self, text, 'model', model_fields(probe), origin, extra, failure)
    if (failure%failed()) return
    call read_group(text, 'model', self%fields('model'), origin, failure, extra)
    if (failure%failed()) return
    where = given_origin(text, 'model', self%fields('model'), origin, 'span', extra)
    if (self%ends /= ends_fixed_fixed .and. len(where) > 0) then
      call fail(failure, failure_input, where// &
                ": &model: span is not allowed with ends = '"//trim(self%ends)//"'; allowed: span with ends = "// &
                "'fixed-fixed' (the second support's distance)", 'span')
      return
    end if
    call refuse_other_parts(self, text, 'initial', initial_fields(probe), origin, extra, failure)
    if (failure%failed()) return
    call read_group(text, 'initial', self%fields('initial'), origin, failure, extra)
    if (failure%failed()) return
    call check_counts(self, text, origin, extra, failure)
    if (failure%failed()) return
    call complete_defaults(self)
    if (self%rung() /= rung_elastic) then
      stiffness = self%mu_eq_const - self%mu_eq_slope*(self%theta - self%theta_ref)
      a = findloc(stiffness > 0.0_real64, .false., dim=1)
      if (a > 0) then
        call fail(failure, failure_input, value_origin(text, 'initial', 'theta', origin, extra)//': &initial: theta = '// &
                  reals_text(self%theta)//' is not allowed: spring '//integer_text(a)//'''s stiffness mu_eq(theta) of '// &
                  'eq. (17) is '//reals_text([stiffness(a)])//' J; allowed: temperatures below theta_ref + '// &
                  'mu_eq_const/mu_eq_slope', 'theta')
        return
      end if
    end if
    call initial_state(self, tau_entropy, model, z0, stat)
    if (stat /= failure_none) call fail(failure, failure_input, value_origin(text, 'initial', 'x', origin, extra)// &
      ': &initial: the initial state is not allowed (a spring''s potentials give '//failure_code_name(stat)// &
      '); allowed: masses apart from each other and the supports, temperatures in each spring''s domain', 'x')
  end subroutine read

  ! A field that another part of the chain has (in `every_field`, not in the scene's table) is
  ! refused with the part that lacks it, rather than as an unknown field.
  subroutine refuse_other_parts(self, text, group, every_field, origin, extra, failure)
    class(chain_scene), intent(in), target :: self
    character(len=*), intent(in) :: text, group, origin
    type(group_field), intent(in) :: every_field(:)
    type(namelist_item), intent(in) :: extra(:)
    type(failure_type), intent(out) :: failure
    type(group_field), allocatable :: own(:)
    character(len=:), allocatable :: where
    integer :: k

    own = self%fields(group)
    do k = 1, size(every_field)
      if (any(field_names(own) == every_field(k)%name)) cycle
      where = given_origin(text, group, every_field, origin, trim(every_field(k)%name), extra)
      if (len(where) == 0) cycle
      call fail(failure, failure_input, where//': &'//group//': '//trim(every_field(k)%name)//' is not a field of '// &
                "spring_law = '"//trim(self%spring_law)//"', ends = '"//trim(self%ends)//"'; allowed: "// &
                joined(field_names(own), ', '), trim(every_field(k)%name))
      return
    end do
  end subroutine refuse_other_parts

  ! Every array field holds one value (the first element) or all of its elements, or none.
  subroutine check_counts(self, text, origin, extra, failure)
    class(chain_scene), intent(inout), target :: self
    character(len=*), intent(in) :: text, origin
    type(namelist_item), intent(in) :: extra(:)
    type(failure_type), intent(out) :: failure
    type(group_field), allocatable :: table(:)
    integer :: k, g, given, n
    character(len=8), parameter :: groups(2) = [character(len=8) :: 'model', 'initial']
    character(len=:), allocatable :: counts

    do g = 1, 2
      table = self%fields(trim(groups(g)))
      do k = 1, size(table)
        if (.not. associated(table(k)%real_values) .or. table(k)%name == 'gravity') cycle
        n = size(table(k)%real_values)
        given = count(table(k)%real_values < unset)
        if (given == 0 .or. given == n) cycle
        if (given == 1 .and. table(k)%real_values(1) < unset .and. .not. any(table(k)%name == ['x', 'p'])) cycle
        select case (trim(table(k)%name))
        case ('x', 'p')
          counts = integer_text(n)//' (N = '//integer_text(self%links)//' masses times dimension = '// &
                   integer_text(self%dimension)//')'
        case ('mass')
          counts = '1 or '//integer_text(n)//' (N, links = '//integer_text(self%links)//')'
        case ('conductivity')
          counts = '1 or '//integer_text(n)//' (n_s - 1 links)'
        case default
          counts = '1 or '//integer_text(n)//' (n_s = '//integer_text(n)//' springs: links = '// &
                   integer_text(self%links)//", ends = '"//trim(self%ends)//"')"
        end select
        call fail(failure, failure_input, value_origin(text, trim(groups(g)), trim(table(k)%name), origin, extra)// &
                  ': &'//trim(groups(g))//': '//trim(table(k)%name)//' has '//integer_text(given)//' value'// &
                  trim(merge('s', ' ', given > 1))//'; allowed: '//counts//' values', trim(table(k)%name))
        return
      end do
    end do
  end subroutine check_counts

  ! One value given: every element; none: the default (spring_data's, mass 1, conductivity 1,
  ! p 0, gamma 0, theta 280, span the sum of the natural lengths, x the uniform stretch).
  pure subroutine complete_defaults(self)
    type(chain_scene), intent(inout) :: self
    type(spring_data) :: d
    real(real64) :: along
    integer :: i

    call fill(self%natural_length, d%natural_length)
    call fill(self%mu_eq_const, d%mu_eq_const)
    call fill(self%mu_eq_slope, d%mu_eq_slope)
    call fill(self%mu_neq_const, d%mu_neq_const)
    call fill(self%mu_neq_slope, d%mu_neq_slope)
    call fill(self%heat_capacity, d%heat_capacity)
    call fill(self%viscosity_const, d%viscosity_const)
    call fill(self%viscosity_activation, d%viscosity_activation)
    call fill(self%theta_ref, d%theta_ref)
    call fill(self%beta, d%beta)
    call fill(self%beta_v, d%beta_v)
    call fill(self%conductivity, 1.0_real64)
    call fill(self%mass, 1.0_real64)
    call fill(self%p, 0.0_real64)
    call fill(self%gamma, 0.0_real64)
    call fill(self%theta, 280.0_real64)
    if (self%span >= unset) self%span = sum(self%natural_length)
    if (all(self%x >= unset)) then
      self%x = 0.0_real64
      along = 0.0_real64
      do i = 1, self%links
        along = along + self%natural_length(i)
        if (self%ends == ends_fixed_fixed) then
          self%x((i - 1)*self%dimension + 1) = self%span*along/sum(self%natural_length)
        else
          self%x((i - 1)*self%dimension + 1) = self%stretch*along
        end if
      end do
    end if

  contains

    pure subroutine fill(values, default)
      real(real64), intent(inout) :: values(:)
      real(real64), intent(in) :: default

      if (all(values >= unset)) then
        values = default
      else if (count(values < unset) == 1) then
        values = values(1)
      end if
    end subroutine fill
  end subroutine complete_defaults

  !> The chain in thermodynamic variable `variable` and its initial state (no constraints).
  subroutine build(self, variable, model, z0, constraints, failure)
    class(chain_scene), intent(in) :: self
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

  ! The model in `variable` and the initial state from the temperatures; stat a domain code.
  subroutine initial_state(self, variable, model, z0, stat)
    class(chain_scene), intent(in) :: self
    integer, intent(in) :: variable
    class(generic_model), allocatable, intent(out) :: model
    real(real64), allocatable, intent(out) :: z0(:)
    integer, intent(out) :: stat
    type(spring_chain) :: chain
    type(spring_data), allocatable :: data(:)
    type(chain_layout) :: layout
    integer :: a, d

    d = self%dimension
    layout = make_chain_layout(self%links, d, trim(self%ends), self%rung(), self%span)
    allocate (data(self%springs()))
    do a = 1, size(data)
      data(a) = spring_data(self%natural_length(a), self%mu_eq_const(a), self%mu_eq_slope(a), self%mu_neq_const(a), &
                            self%mu_neq_slope(a), self%heat_capacity(a), self%viscosity_const(a), &
                            self%viscosity_activation(a), self%theta_ref(a), self%beta(a), self%beta_v(a))
    end do
    chain = make_spring_chain(layout, data, self%mass, self%conductivity(1:size(data) - 1), self%gravity(1:d), variable)
    allocate (z0(chain%state_size))
    call chain%state_from_temperatures(reshape(self%x, [d, self%links]), reshape(self%p, [d, self%links]), &
                                       self%gamma, self%theta, z0, stat)
    if (stat == failure_none) call positive_lengths(chain, z0, stat)
    allocate (model, source=chain)
  end subroutine initial_state

  ! stat = domain code of a spring of zero length (C_a = 0: no direction, ln l undefined).
  pure subroutine positive_lengths(chain, z, stat)
    type(spring_chain), intent(in) :: chain
    real(real64), intent(in) :: z(:)
    integer, intent(inout) :: stat
    real(real64) :: x(3), f(2), theta
    integer :: a, n

    n = chain%layout%invariant_count
    do a = 1, chain%layout%springs
      call chain%invariants(z, a, x(1:n))
      call chain%springs(a)%values_and_temperature(x(1:n), f, theta, stat)   ! (an elastic one has no theta)
      if (stat /= failure_none) return
    end do
  end subroutine positive_lengths

  !> theta_ref of spring 1 (the Lyapunov reference temperature unless &output sets theta_r).
  pure function default_theta_r(self) result(theta_r)
    class(chain_scene), intent(in) :: self
    real(real64) :: theta_r

    theta_r = self%theta_ref(1)
  end function default_theta_r

  !> None: the chain takes no constraints.
  pure integer function constraint_count(self)
    class(chain_scene), intent(in) :: self

    constraint_count = 0
  end function constraint_count

  !> Elastic springs have no thermodynamic variables: why, for run-level fields that need them.
  pure function without_temperatures(self) result(reason)
    class(chain_scene), intent(in) :: self
    character(len=:), allocatable :: reason

    reason = ''
    if (self%rung() == rung_elastic) reason = "spring_law = '"//trim(self%spring_law)// &
                                              "' has no thermodynamic variables and no entropy"
  end function without_temperatures

end module spring_chain_scene
