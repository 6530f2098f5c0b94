!> The spring chain's namelist tables (docs/input.md): every field of &model and &initial bound to
!> a chain_input's values, with its units and what it allows. Before the choices are read
!> (chain_input's `chosen`) a table holds every field any chain takes, for --help, a study's field
!> names and the first pass of reading; after, only the fields of the chain chosen: the rung drops
!> the fields of the parts its springs lack, family = 'rod' the springs' own values (the rod gives
!> them), family = 'springs' the rod's, &initial file the values the file holds, and each
!> perturbation the parameters of the others.
module spring_chain_fields
  use, intrinsic :: iso_fortran_env, only: real64
  use namelist_field, only: group_field, real_field, reals_field, integer_field, text_field, absolute_temperature
  use number_text, only: integer_text
  use spring_chain_spring, only: rung_thermoviscoelastic, rung_elastic, spring_law_names
  use spring_chain_layout, only: ends_fixed_free, ends_fixed_fixed
  use spring_chain_input, only: chain_input, max_links, family_rod, family_springs, family_names, perturbation_none, &
                                perturbation_mode, perturbation_names
  implicit none (type, external)
  private
  public :: chain_fields, choices_text

  !> &model's fields of the viscous branch, and the thermal ones (springs' and rod's).
  character(len=*), parameter :: viscous_fields(8) = [character(len=24) :: 'mu_neq_const', 'mu_neq_slope', &
    'viscosity_const', 'viscosity_activation', 'beta_v', 'maxwell_stiffness', 'maxwell_slope', 'viscosity']
  character(len=*), parameter :: thermal_fields(9) = [character(len=24) :: 'mu_eq_slope', 'heat_capacity', &
    'theta_ref', 'beta', 'conductivity', 'stiffness_slope', 'thermal_stress', 'rod_heat_capacity', &
    'rod_conductivity']
  !> The springs' own values, which family = 'rod' gives from the rod, and the rod's data.
  character(len=*), parameter :: spring_fields(10) = [character(len=24) :: 'natural_length', 'mu_eq_const', &
    'mu_eq_slope', 'mu_neq_const', 'mu_neq_slope', 'heat_capacity', 'viscosity_const', 'beta', 'conductivity', 'mass']
  character(len=*), parameter :: rod_fields(10) = [character(len=24) :: 'rod_length', 'mass_per_length', &
    'axial_stiffness', 'stiffness_slope', 'thermal_stress', 'rod_heat_capacity', 'maxwell_stiffness', &
    'maxwell_slope', 'viscosity', 'rod_conductivity']
  !> &initial's values that a file gives, and the perturbation's parameters.
  character(len=*), parameter :: state_fields(5) = [character(len=24) :: 'x', 'p', 'stretch', 'gamma', 'theta']
  character(len=*), parameter :: perturbation_fields(4) = [character(len=24) :: 'perturbation', 'mode_number', &
    'amplitude', 'seed']

contains

  !> The fields of group `group` ('model' or 'initial'; none for another) for `input`'s chain.
  function chain_fields(input, group) result(table)
    type(chain_input), intent(in), target :: input
    character(len=*), intent(in) :: group
    type(group_field), allocatable :: table(:)

    select case (group)
    case ('model')
      table = model_fields(input)
      if (.not. input%chosen) return
      if (input%rung() /= rung_thermoviscoelastic) table = without(table, viscous_fields)
      if (input%rung() == rung_elastic) table = without(table, thermal_fields)
      if (input%family == family_rod) table = without(table, spring_fields)
      if (input%family == family_springs) table = without(table, rod_fields)
      if (input%ends /= ends_fixed_fixed) table = without(table, [character(len=24) :: 'span'])
      if (allocated(input%from_file)) table = without(table, input%from_file)
    case ('initial')
      table = initial_fields(input)
      if (.not. input%chosen) return
      if (input%rung() /= rung_thermoviscoelastic) table = without(table, [character(len=24) :: 'gamma'])
      if (input%rung() == rung_elastic) table = without(table, [character(len=24) :: 'theta'])
      if (input%ends == ends_fixed_fixed) table = without(table, [character(len=24) :: 'stretch'])
      if (len_trim(input%file) > 0) then
        table = without(table, [state_fields, perturbation_fields])
      else
        table = without(table, [character(len=24) :: 'snapshot'])
        select case (trim(input%perturbation))
        case (perturbation_none)
          table = without(table, perturbation_fields(2:))
        case (perturbation_mode)
          table = without(table, [character(len=24) :: 'seed'])
        case default
          table = without(table, [character(len=24) :: 'mode_number'])
        end select
      end if
    case default
      allocate (table(0))
    end select
  end function chain_fields

  !> The choices that select group `group`'s fields, as written ("spring_law = '...', ...").
  function choices_text(input, group) result(text)
    type(chain_input), intent(in) :: input
    character(len=*), intent(in) :: group
    character(len=:), allocatable :: text

    text = "spring_law = '"//trim(input%spring_law)//"', ends = '"//trim(input%ends)//"'"
    if (group == 'model') then
      text = text//", family = '"//trim(input%family)//"'"
    else if (len_trim(input%file) > 0) then
      text = text//", file = '"//trim(input%file)//"'"
    else
      text = text//", perturbation = '"//trim(input%perturbation)//"'"
    end if
  end function choices_text

  ! Every field of &model, bound to the input's arrays (open length: their counts are checked
  ! after reading).
  function model_fields(input) result(table)
    type(chain_input), intent(in), target :: input
    type(group_field), allocatable :: table(:)
    character(len=*), parameter :: each = ' (one value for every spring, or n_s: one per spring)'
    character(len=*), parameter :: springs_only = "; family = 'springs' only"
    character(len=*), parameter :: rod_only = "; family = 'rod' only"

    table = [ &
      text_field('model_name', input%model_name, "the model: 'spring_chain'", 'spring_chain'), &
      integer_field('links', input%links, 'an integer from 1 to '//integer_text(max_links)//': N, the number of '// &
                    'point masses (the dense path: Jacobians of (N (2 dimension + 2))^2 entries)', &
                    minimum=1, maximum=max_links), &
      text_field('ends', input%ends, "'fixed-free' (a hanging chain: n_s = N springs, spring 1 from the support at "// &
                 "the origin to mass 1) or 'fixed-fixed' (n_s = N + 1: spring N + 1 from mass N to a second support "// &
                 "at span e_x)", ends_fixed_free//' '//ends_fixed_fixed), &
      real_field('span', input%span, "a real number > 0 [m]: the second support's distance along x "// &
                 "('fixed-fixed'; default: the sum of the natural lengths)", 'm', minimum=0.0_real64, exclusive=.true.), &
      integer_field('dimension', input%dimension, '1 (motion along x), 2 (planar, y vertical) or 3 (spatial, z '// &
                    'vertical): gravity, x and p take dimension values per mass', minimum=1, maximum=3), &
      reals_field('gravity', input%gravity(1:input%dimension), 'dimension real numbers [m/s^2] (default 0, 0, '// &
                  '-9.81; 0, -9.81 in 2D; 0 in 1D)', 'm/s^2', open_length=.true.), &
      text_field('spring_law', input%spring_law, "'thermoviscoelastic' (every spring with a viscous branch and "// &
                 "gamma_a; a spring with beta_v = mu_neq_const = mu_neq_slope = 0 has none in effect), "// &
                 "'thermoelastic' (no gamma and no fields of the viscous branch) or 'elastic' (no temperatures "// &
                 "either: no theta and no thermal fields)", spring_law_names), &
      text_field('spring_file', input%spring_file, 'the path of an HDF5 file (relative to this namelist''s '// &
                 'folder) of per-spring arrays: a 1-D dataset named as its field (natural_length, mu_eq_const, '// &
                 '..., mass with N values, conductivity with n_s - 1) with all of that field''s values, for '// &
                 'chains too long for a namelist; a field the file gives is not given here', ''), &
      text_field('family', input%family, "'springs' (each spring's values given: natural_length, mu_eq_const, ..., "// &
                 "mass, conductivity) or 'rod' (the n_s elements of a rod of length rod_length, with lumped "// &
                 "masses: the springs' values follow from rod_length, mass_per_length, axial_stiffness, ... as "// &
                 "docs/formulation.md section 10 gives them, and the springs' own fields are refused)", family_names), &
      reals_field('mass', input%mass, 'real numbers > 0 [kg], one for every mass or N (default 1)'//springs_only, &
                  'kg', minimum=0.0_real64, exclusive=.true., open_length=.true.), &
      per_spring('natural_length', input%natural_length, 'real numbers > 0 [m]'//each//'; default 2'//springs_only, &
                 'm', 0.0_real64, .true.), &
      per_spring('mu_eq_const', input%mu_eq_const, 'real numbers > 0 [J] (eq. (17))'//each//'; default 200'// &
                 springs_only, 'J', 0.0_real64, .true.), &
      per_spring('mu_eq_slope', input%mu_eq_slope, 'real numbers >= 0 [J/K] (eq. (17))'//each//'; default 0.5'// &
                 springs_only, 'J/K', 0.0_real64, .false.), &
      per_spring('mu_neq_const', input%mu_neq_const, 'real numbers >= 0 [J/m^2] (eq. (17))'//each//'; default 5'// &
                 springs_only, 'J/m^2', 0.0_real64, .false.), &
      per_spring('mu_neq_slope', input%mu_neq_slope, 'real numbers >= 0 [J/(K m^2)] (eq. (17))'//each// &
                 '; default 0.1'//springs_only, 'J/(K m^2)', 0.0_real64, .false.), &
      per_spring('heat_capacity', input%heat_capacity, 'real numbers > 0 [J/K]'//each//'; default 10'//springs_only, &
                 'J/K', 0.0_real64, .true.), &
      per_spring('viscosity_const', input%viscosity_const, 'real numbers > 0 [J s/m^2] (eq. (17))'//each// &
                 '; default 100'//springs_only, 'J s/m^2', 0.0_real64, .true.), &
      per_spring('viscosity_activation', input%viscosity_activation, 'real numbers > 0 [K] (eq. (17))'//each// &
                 '; default 10', 'K', 0.0_real64, .true.), &
      absolute_temperature(per_spring('theta_ref', input%theta_ref, 'real numbers > 0 [K]'//each//'; default 300', &
                                      'K', 0.0_real64, .true.)), &
      per_spring('beta', input%beta, 'real numbers [J/K]'//each//'; default 0.02'//springs_only, 'J/K', &
                 -huge(1.0_real64), .false.), &
      per_spring('beta_v', input%beta_v, 'real numbers >= 0'//each//'; default 0.5', '1', 0.0_real64, .false.), &
      reals_field('conductivity', input%conductivity, 'real numbers >= 0 [J/(K s)]: the links (a, a+1), one value '// &
                  'for every link or n_s - 1; default 1 (ends adiabatic)'//springs_only, 'J/(K s)', &
                  minimum=0.0_real64, open_length=.true.), &
      real_field('rod_length', input%rod%length, 'a real number > 0 [m]: the rod''s natural length L (each '// &
                 'element h = L/n_s)'//rod_only, 'm', minimum=0.0_real64, exclusive=.true.), &
      real_field('mass_per_length', input%rod%mass_per_length, 'a real number > 0 [kg/m]: rho A (m_i = rho A h, '// &
                 "the free end's half)"//rod_only, 'kg/m', minimum=0.0_real64, exclusive=.true.), &
      real_field('axial_stiffness', input%rod%axial_stiffness, 'a real number > 0 [N]: EA (mu_eq_const = EA h)'// &
                 rod_only, 'N', minimum=0.0_real64, exclusive=.true.), &
      real_field('stiffness_slope', input%rod%stiffness_slope, 'a real number >= 0 [N/K]: -d(EA)/dtheta, '// &
                 'a softening rate (mu_eq_slope = h stiffness_slope)'//rod_only, 'N/K', minimum=0.0_real64), &
      real_field('thermal_stress', input%rod%thermal_stress, 'a real number [N/K]: E A alpha (beta = E A alpha h)'// &
                 rod_only, 'N/K'), &
      real_field('rod_heat_capacity', input%rod%heat_capacity, 'a real number > 0 [J/(K m)]: c '// &
                 '(heat_capacity = c h)'//rod_only, 'J/(K m)', minimum=0.0_real64, exclusive=.true.), &
      real_field('maxwell_stiffness', input%rod%maxwell_stiffness, 'a real number >= 0 [N]: E^neq A, '// &
                 'half the Maxwell modulus (the paper''s mu^neq gamma^2; mu_neq_const = E^neq A/h)'//rod_only, &
                 'N', minimum=0.0_real64), &
      real_field('maxwell_slope', input%rod%maxwell_slope, 'a real number >= 0 [N/K]: -d(E^neq A)/dtheta, '// &
                 'a softening rate (mu_neq_slope = maxwell_slope/h)'//rod_only, 'N/K', minimum=0.0_real64), &
      real_field('viscosity', input%rod%viscosity, 'a real number > 0 [N s]: eta A (viscosity_const = eta A/h)'// &
                 rod_only, 'N s', minimum=0.0_real64, exclusive=.true.), &
      real_field('rod_conductivity', input%rod%conductivity, 'a real number >= 0 [W m/K]: k A (each link''s '// &
                 'conductivity k A/h)'//rod_only, 'W m/K', minimum=0.0_real64)]
  end function model_fields

  ! &initial's fields.
  function initial_fields(input) result(table)
    type(chain_input), intent(in), target :: input
    type(group_field), allocatable :: table(:)
    character(len=*), parameter :: not_with_file = '; not with file'

    table = [ &
      reals_field('x', input%x, 'N times dimension real numbers [m]: the masses'' positions, mass by mass '// &
                  '(default: each spring at stretch times its natural length along x from the support; '// &
                  '''fixed-fixed'': scaled to end at span)'//not_with_file, 'm', open_length=.true.), &
      reals_field('p', input%p, 'N times dimension real numbers [N s]: the masses'' momenta, mass by mass '// &
                  '(default 0)'//not_with_file, 'N s', open_length=.true.), &
      real_field('stretch', input%stretch, 'a real number > 0: the default positions'' stretch of every spring, '// &
                 'l_a = stretch l^0_a (''fixed-free'')'//not_with_file, '1', minimum=0.0_real64, exclusive=.true.), &
      reals_field('gamma', input%gamma, 'real numbers [m]: the dampers'' elongations, one for every spring or n_s '// &
                  '(default 0)'//not_with_file, 'm', open_length=.true.), &
      absolute_temperature(reals_field('theta', input%theta, 'real numbers > 0 [K], one for every spring or n_s, '// &
                                       'each below theta_ref + mu_eq_const/mu_eq_slope (default 280)'//not_with_file, &
                                       'K', minimum=0.0_real64, exclusive=.true., open_length=.true.)), &
      text_field('perturbation', input%perturbation, "'none', 'mode' (each mass moved along x by amplitude "// &
                 "sin(k pi i/(N + 1)) ('fixed-fixed') or amplitude sin((2k - 1) pi i/(2N)) ('fixed-free'), "// &
                 "k = mode_number) or 'random' (by amplitude (2 u_i - 1), u_i the i-th number in [0, 1) of "// &
                 "SplitMix64 from seed)"//not_with_file, perturbation_names), &
      integer_field('mode_number', input%mode_number, 'an integer from 1 to N: k of perturbation = ''mode''', &
                    minimum=1), &
      real_field('amplitude', input%amplitude, 'a real number [m]: the largest displacement along x of '// &
                 'perturbation = ''mode'' or ''random''', 'm'), &
      integer_field('seed', input%seed, 'an integer >= 0: SplitMix64''s seed for perturbation = ''random''', &
                    minimum=0), &
      text_field('file', input%file, 'the path of an HDF5 file (relative to this namelist''s folder) with '// &
                 'datasets q (N x dimension: the masses'' positions), p (N x dimension), gamma (n_s, '// &
                 'thermoviscoelastic only) and theta (n_s, K; not elastic), or a run file of the same chain '// &
                 'with /snapshots (its snapshot `snapshot`); instead of x, p, stretch, gamma, theta and a '// &
                 'perturbation', ''), &
      integer_field('snapshot', input%snapshot, 'an integer >= -1: with file = a run file, the snapshot to start '// &
                    'from, its row of /snapshots counted from 0, or -1 (the default) the last', minimum=-1)]
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

end module spring_chain_fields
