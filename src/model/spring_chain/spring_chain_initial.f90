!> The spring chain's initial state (docs/input.md, &initial): the masses' positions with the
!> optional perturbation along x (a mode's shape, or SplitMix64 numbers from a seed), the checks of
!> the arrays an &initial file gives (shapes, finite values, springs of positive length,
!> temperatures > 0 and in each spring's domain), and the model with its state z0.
module spring_chain_initial
  use, intrinsic :: iso_fortran_env, only: real64
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite, ieee_is_nan
  use number_text, only: integer_text, reals_text
  use failures, only: failure_none, domain_nonpositive_length
  use model_interface, only: generic_model
  use seeded_random, only: uniform_numbers
  use spring_chain_spring, only: spring_data, rung_thermoviscoelastic, rung_elastic
  use spring_chain_layout, only: chain_layout, make_chain_layout, ends_fixed_fixed
  use spring_chain_model, only: spring_chain, make_spring_chain
  use spring_chain_input, only: chain_input, perturbation_mode, perturbation_random
  implicit none (type, external)
  private
  public :: perturbation_shape, initial_state, dataset_problem, stiffness_problem, spring_ends_text

  character(len=*), parameter :: axes = 'xyz'

contains

  !> The displacement along x of masses 1..N per unit amplitude: perturbation = 'mode' is mode k
  !> of a uniform chain, sin(k pi i/(N + 1)) with 'fixed-fixed' ends (docs/formulation.md section
  !> 10's exact linear modes), sin((2k - 1) pi i/(2N)) with 'fixed-free' (the rod family's: its free
  !> end holds half a mass, so the free end is an antinode); 'random' is 2 u_i - 1, u_i the i-th
  !> number of SplitMix64 from `seed`; 0 for 'none'.
  pure function perturbation_shape(kind, ends, n, k, seed) result(shape)
    character(len=*), intent(in) :: kind, ends
    integer, intent(in) :: n, k, seed
    real(real64) :: shape(n)
    real(real64), parameter :: pi = acos(-1.0_real64)
    integer :: i

    select case (kind)
    case (perturbation_mode)
      if (ends == ends_fixed_fixed) then
        shape = [(sin(k*pi*i/real(n + 1, real64)), i=1, n)]
      else
        shape = [(sin((2*k - 1)*pi*i/real(2*n, real64)), i=1, n)]
      end if
    case (perturbation_random)
      shape = 2.0_real64*uniform_numbers(seed, n) - 1.0_real64
    case default
      shape = 0.0_real64
    end select
  end function perturbation_shape

  !> The model of `input` in thermodynamic variable `variable` and its initial state z0 (x with
  !> the perturbation); stat a domain code (a spring of zero length, a temperature outside a
  !> spring's domain).
  subroutine initial_state(input, variable, model, z0, stat, failed_spring, by_perturbation)
    type(chain_input), intent(in) :: input
    integer, intent(in) :: variable
    class(generic_model), allocatable, intent(out) :: model
    real(real64), allocatable, intent(out) :: z0(:)
    integer, intent(out) :: stat
    integer, intent(out), optional :: failed_spring     !! a spring of length 0 (then stat says so), else 0
    logical, intent(out), optional :: by_perturbation   !! whether the perturbation made it so
    type(spring_chain) :: chain
    type(spring_data), allocatable :: data(:)
    type(chain_layout) :: layout
    real(real64), allocatable :: x(:, :)
    integer :: a, d

    d = input%dimension
    layout = make_chain_layout(input%links, d, trim(input%ends), input%rung(), input%span)
    allocate (data(input%springs()))
    do a = 1, size(data)
      data(a) = spring_data(input%natural_length(a), input%mu_eq_const(a), input%mu_eq_slope(a), &
                            input%mu_neq_const(a), input%mu_neq_slope(a), input%heat_capacity(a), &
                            input%viscosity_const(a), input%viscosity_activation(a), input%theta_ref(a), input%beta(a), &
                            input%beta_v(a))
    end do
    chain = make_spring_chain(layout, data, input%mass, input%conductivity(1:size(data) - 1), input%gravity(1:d), &
                              variable)
    x = reshape(input%x, [d, input%links])
    ! A spring of length 0 (its square underflowing too) is named before any potential sees it:
    ! one of the given (or default) positions, else one the perturbation made.
    a = zero_length_spring(input, x)
    if (present(by_perturbation)) by_perturbation = a == 0
    x(1, :) = x(1, :) + input%amplitude*perturbation_shape(trim(input%perturbation), trim(input%ends), input%links, &
                                                           input%mode_number, input%seed)
    allocate (z0(chain%state_size))
    if (a == 0) a = zero_length_spring(input, x)
    if (present(failed_spring)) failed_spring = a
    if (a > 0) then
      stat = domain_nonpositive_length
      allocate (model, source=chain)
      return
    end if
    call chain%state_from_temperatures(x, reshape(input%p, [d, input%links]), input%gamma, input%theta, z0, stat)
    if (stat == failure_none) call positive_lengths(chain, z0, stat)
    allocate (model, source=chain)
  end subroutine initial_state

  ! stat = domain code of a spring of zero length (C_a = 0: no direction, ln l undefined). Asked
  ! of the chain's springs, which answer on every rung (an elastic subsystem's potential has no
  ! temperature to give, and says so with a domain code).
  pure subroutine positive_lengths(chain, z, stat)
    type(spring_chain), intent(in) :: chain
    real(real64), intent(in) :: z(:)
    integer, intent(inout) :: stat
    real(real64) :: x(3), f(2), theta
    integer :: a, n

    n = chain%layout%invariant_count
    do a = 1, chain%layout%springs
      call chain%invariants(z, a, x(1:n))
      call chain%springs(a)%values_and_temperature(x(1:n), f, theta, stat)
      if (stat /= failure_none) return
    end do
  end subroutine positive_lengths

  !> The first spring a whose stiffness mu_eq(theta_a) of eq. (17) is not > 0 (0 if none), and
  !> that stiffness [J].
  pure subroutine stiffness_problem(input, a, stiffness)
    type(chain_input), intent(in) :: input
    integer, intent(out) :: a
    real(real64), intent(out) :: stiffness
    real(real64) :: each(input%springs())

    a = 0
    stiffness = 0.0_real64
    if (input%rung() == rung_elastic) return
    each = input%mu_eq_const - input%mu_eq_slope*(input%theta - input%theta_ref)
    a = findloc(each > 0.0_real64, .false., dim=1)
    if (a > 0) stiffness = each(a)
  end subroutine stiffness_problem

  !> What is wrong with dataset `name` of an &initial file ('' if nothing) for `input`'s chain,
  !> `found` or not, with its `shape` (as h5py gives it) and `values` (in that order, row by row):
  !> q and p are needed, N x dimension (N values with dimension = 1 too); gamma (thermoviscoelastic
  !> only) and theta (not elastic) n_s; every value finite, theta > 0, and no spring of q of zero
  !> length (`input`'s ends and span give the supports).
  pure function dataset_problem(input, name, found, shape, values) result(problem)
    type(chain_input), intent(in) :: input
    character(len=*), intent(in) :: name
    logical, intent(in) :: found
    integer, intent(in) :: shape(:)
    real(real64), intent(in) :: values(:)
    character(len=:), allocatable :: problem
    integer :: k, n, d, a
    logical :: wanted

    n = input%links
    d = input%dimension
    problem = ''
    wanted = name == 'q' .or. name == 'p' .or. name == 'gamma' .and. input%rung() == rung_thermoviscoelastic .or. &
             name == 'theta' .and. input%rung() /= rung_elastic
    if (wanted .and. .not. found) then
      problem = 'has no dataset '''//name//'''; allowed: an HDF5 file with datasets q and p (N x dimension)'// &
                trim(merge(', gamma (n_s)', '             ', input%rung() == rung_thermoviscoelastic))// &
                trim(merge(' and theta (n_s)', '                ', input%rung() /= rung_elastic))
      return
    else if (found .and. .not. wanted) then
      problem = 'has a dataset '''//name//''', which spring_law = '''//trim(input%spring_law)// &
                ''' does not take; allowed: q, p'//trim(merge(', theta', '       ', input%rung() /= rung_elastic))
      return
    else if (.not. found) then
      return
    end if
    problem = 'dataset '
    select case (name)
    case ('q', 'p')
      if (.not. (same_shape(shape, [n, d]) .or. d == 1 .and. same_shape(shape, [n]))) then
        problem = problem//name//' has the shape '//shape_text(shape)//'; allowed: ('//integer_text(n)//', '// &
                  integer_text(d)//') (N masses x dimension)'
        return
      end if
    case ('gamma', 'theta')
      if (.not. same_shape(shape, [input%springs()])) then
        problem = problem//name//' has the shape '//shape_text(shape)//'; allowed: ('//integer_text(input%springs())// &
                  ',) (n_s springs)'
        return
      end if
    end select
    k = findloc(ieee_is_finite(values), .false., dim=1)
    if (k > 0) then
      problem = problem//index_text(name, k, d)//' '//trim(merge('is NaN       ', 'is not finite', &
                                                                  ieee_is_nan(values(k))))//'; allowed: finite numbers'
      return
    end if
    k = 0
    if (name == 'theta') k = findloc(values > 0.0_real64, .false., dim=1)
    if (k > 0) then
      problem = problem//index_text(name, k, d)//' = '//reals_text([values(k)])//' K; allowed: temperatures > 0 K'
      return
    end if
    a = 0
    if (name == 'q') a = zero_length_spring(input, reshape(values, [d, n]))
    if (a > 0) then
      problem = problem//'q gives spring '//integer_text(a)//' ('//spring_ends_text(input, a, .true.)//') the length 0; '// &
                'allowed: masses apart from each other and from the supports'
      return
    end if
    problem = ''
  end function dataset_problem

  ! Whether `shape` is `expected`.
  pure logical function same_shape(shape, expected)
    integer, intent(in) :: shape(:), expected(:)

    same_shape = size(shape) == size(expected)
    if (same_shape) same_shape = all(shape == expected)
  end function same_shape

  ! The first spring of zero length for positions x(:, i) (0 if none).
  pure integer function zero_length_spring(input, x)
    type(chain_input), intent(in) :: input
    real(real64), intent(in) :: x(:, :)
    real(real64) :: before(size(x, 1)), after(size(x, 1))
    integer :: a

    zero_length_spring = 0
    do a = 1, input%springs()
      before = 0.0_real64
      if (a > 1) before = x(:, a - 1)
      if (a <= input%links) then
        after = x(:, a)
      else
        after = 0.0_real64
        after(1) = input%span
      end if
      if (sum((after - before)**2) <= 0.0_real64) then
        zero_length_spring = a
        return
      end if
    end do
  end function zero_length_spring

  !> 'from mass a-1, q[a-2] to mass a, q[a-1]' (the &initial file's rows; without `rows`, 'from
  !> mass a-1 to mass a'), with the supports named.
  pure function spring_ends_text(input, a, rows) result(text)
    type(chain_input), intent(in) :: input
    integer, intent(in) :: a
    logical, intent(in) :: rows
    character(len=:), allocatable :: text

    if (a == 1) then
      text = 'from the support at the origin'
    else
      text = 'from '//mass_text(a - 1)
    end if
    if (a <= input%links) then
      text = text//' to '//mass_text(a)
    else
      text = text//' to the second support at span'
    end if

  contains

    pure function mass_text(i) result(named)
      integer, intent(in) :: i
      character(len=:), allocatable :: named

      named = 'mass '//integer_text(i)
      if (rows) named = named//', q['//integer_text(i - 1)//']'
    end function mass_text
  end function spring_ends_text

  ! 'q[3, 1] (mass 4, component y)' or 'theta[2] (spring 3)': element k (1-based, row by row).
  pure function index_text(name, k, d) result(text)
    character(len=*), intent(in) :: name
    integer, intent(in) :: k, d
    character(len=:), allocatable :: text
    integer :: row, column

    select case (name)
    case ('q', 'p')
      row = (k - 1)/d
      column = mod(k - 1, d)
      text = name//'['//integer_text(row)//', '//integer_text(column)//'] (mass '//integer_text(row + 1)// &
             ', component '//axes(column + 1:column + 1)//')'
    case default
      text = name//'['//integer_text(k - 1)//'] (spring '//integer_text(k)//')'
    end select
  end function index_text

  ! '(3, 2)' as h5py writes a shape; '()' for a scalar.
  pure function shape_text(shape) result(text)
    integer, intent(in) :: shape(:)
    character(len=:), allocatable :: text
    integer :: i

    text = '('
    do i = 1, size(shape)
      if (i > 1) text = text//', '
      text = text//integer_text(shape(i))
    end do
    if (size(shape) == 1) text = text//','
    text = text//')'
  end function shape_text

end module spring_chain_initial
