!> A whole chain's step assembled dense from its blocks (docs/formulation.md section 10): the
!> residual R = (z_{n+1} - z_n)/dt - f and its Jacobian, f the sum of the mass, spring and link
!> blocks (spring_chain_blocks) scattered by the layout's indices; also the continuous field
!> f(z) with df/dz (partials_exact). It is the reference a distributed assembly is checked
!> against, and the step of a small chain (a nonlinear_system the dense solvers take); its E
!> and S sum the parts of spring_chain_balance.
module spring_chain_step
  use, intrinsic :: iso_fortran_env, only: real64
  use failures, only: failure_none, domain_nonpositive_temperature, domain_overflow
  use invariant_function, only: potential_u, potential_s
  use nonlinear_problem, only: nonlinear_system
  use discrete_gradient, only: gradient_gonzalez, metric_nondimensional
  use spring_chain_spring, only: chain_spring
  use spring_chain_layout, only: chain_layout, spring_slots, slots_of
  use spring_chain_partials, only: spring_partials, evaluate_spring_partials, partials_discrete_gradient, partials_exact
  use spring_chain_blocks, only: mass_block, spring_block, link_block
  use spring_chain_balance, only: mass_energy, mass_energy_difference, spring_values, spring_differences
  implicit none (type, external)
  private
  public :: chain_step_problem, scatter

  !> One step z_old -> z of a chain, or its field (rule partials_exact).
  type, extends(nonlinear_system) :: chain_step_problem
    type(chain_layout) :: layout
    type(chain_spring), allocatable :: springs(:)
    real(real64), allocatable :: masses(:)
    real(real64), allocatable :: conductivity(:)          !! one per link (a, a+1)
    real(real64), allocatable :: gravity(:)               !! `dimension` components
    integer :: rule = partials_discrete_gradient
    integer :: gradient = gradient_gonzalez
    integer :: metric = metric_nondimensional
    real(real64) :: dt = 0.0_real64
    real(real64) :: fraction = 1.0_real64                 !! continuation: the step of fraction dt
    real(real64), allocatable :: z_old(:)
  contains
    procedure :: unknowns
    procedure :: evaluate
    procedure :: check_root
    procedure :: set_continuation
    procedure :: field
    procedure :: field_rows
    procedure :: band_half_width
    procedure :: partials_of
    procedure :: energy_difference
    procedure :: energy_entropy
  end type chain_step_problem

contains

  !> The chain's unknowns.
  pure integer function unknowns(self)
    class(chain_step_problem), intent(in) :: self

    unknowns = self%layout%state_size()
  end function unknowns

  !> The step of s dt from the same old state.
  pure subroutine set_continuation(self, s)
    class(chain_step_problem), intent(inout) :: self
    real(real64), intent(in) :: s

    self%fraction = s
  end subroutine set_continuation

  !> R(z) = (z - z_old)/h - f(z_old, z) and optionally dR/dz, h = fraction dt.
  pure subroutine evaluate(self, x, residual, jacobian, stat)
    class(chain_step_problem), intent(in) :: self
    real(real64), intent(in) :: x(:)
    real(real64), intent(out) :: residual(:)
    real(real64), intent(out), optional :: jacobian(:, :)
    integer, intent(out) :: stat
    real(real64) :: h
    integer :: i

    h = self%fraction*self%dt
    call self%field(self%z_old, x, residual, jacobian, stat)
    if (stat /= failure_none) return
    residual = (x - self%z_old)/h - residual
    if (present(jacobian)) then
      jacobian = -jacobian
      do i = 1, size(x)
        jacobian(i, i) = jacobian(i, i) + 1.0_real64/h
      end do
    end if
    if (.not. all(abs(residual) <= huge(1.0_real64))) stat = domain_overflow
  end subroutine evaluate

  !> Springs first..last's partials for the step old -> new (or the field at new); old and new
  !> hold the unknowns base + 1 .. base + size(old).
  pure subroutine partials_of(self, old, new, parts, stat, base, first)
    class(chain_step_problem), intent(in) :: self
    real(real64), intent(in) :: old(:), new(:)
    type(spring_partials), intent(out) :: parts(:)
    integer, intent(out) :: stat
    integer, intent(in), optional :: base, first
    integer :: a, shift, a0

    stat = failure_none
    shift = 0
    if (present(base)) shift = base
    a0 = 1
    if (present(first)) a0 = first
    do a = a0, a0 + size(parts) - 1
      call evaluate_spring_partials(self%springs(a), self%rule, self%gradient, self%metric, self%layout%dimension, &
                                    self%layout%gather_spring(old, a, shift), self%layout%gather_spring(new, a, shift), &
                                    parts(a - a0 + 1), stat)
      if (stat /= failure_none) return
    end do
  end subroutine partials_of

  !> The half width of a row's band of df/dz: a link couples points a - 1 .. a + 1, so an unknown
  !> couples unknowns of at most two points on either side.
  pure integer function band_half_width(self)
    class(chain_step_problem), intent(in) :: self

    band_half_width = 3*self%layout%point_size() - 1
  end function band_half_width

  !> f = the sum of the blocks for the step old -> new (the field at new for partials_exact) and
  !> optionally df/d new, dense (the whole state; field_rows assembles).
  pure subroutine field(self, old, new, f, df, stat)
    class(chain_step_problem), intent(in) :: self
    real(real64), intent(in) :: old(:), new(:)
    real(real64), intent(out) :: f(:)
    real(real64), intent(out), optional :: df(:, :)
    integer, intent(out) :: stat
    real(real64), allocatable :: band(:, :)
    integer :: r, c, half, n

    n = size(f)
    if (.not. present(df)) then
      call self%field_rows(old, new, 0, 1, n, f, stat=stat)
      return
    end if
    half = self%band_half_width()
    allocate (band(2*half + 1, n))
    call self%field_rows(old, new, 0, 1, n, f, band, stat)
    df = 0.0_real64
    do r = 1, n
      do c = max(1, r - half), min(n, r + half)
        df(r, c) = band(c - r + half + 1, r)
      end do
    end do
  end subroutine field

  !> Rows first_row..last_row of f = the sum of the mass, spring and link blocks for the step
  !> old -> new (the field at new for partials_exact), and optionally their df/d new in band
  !> storage: band(c - g + half + 1, r) holds row g = first_row + r - 1, column c (half =
  !> band_half_width; a row's band is contiguous). old and new hold the unknowns base + 1 ..
  !> base + size(old) and must cover
  !> the rows' points and two points either side (a rank's ghosted part of a DMDA of stencil
  !> width 2; base 0 and the whole state on one process). Only the blocks that touch the rows
  !> are evaluated, and only the rows' entries kept: ranks owning disjoint rows assemble the
  !> whole f and df between them, each without the others' rows. Without `band` no derivative
  !> is computed (a residual's evaluation); a caller may take a rank's rows in slices, so that
  !> the springs' partials and the band stay small (each slice evaluates 3 springs beyond its
  !> points).
  pure subroutine field_rows(self, old, new, base, first_row, last_row, f, band, stat)
    class(chain_step_problem), intent(in) :: self
    real(real64), intent(in) :: old(:), new(:)
    integer, intent(in) :: base, first_row, last_row
    real(real64), intent(out) :: f(:)
    real(real64), intent(out), optional :: band(:, :)
    integer, intent(out) :: stat
    integer :: first_point, last_point, a_first, a_last, a, i, d, half, m, c
    type(spring_partials), allocatable :: parts(:)
    type(spring_slots) :: slots
    real(real64) :: weight
    ! The rows a spring block and a link block can fill (a spring's x rows and a link's x and
    ! gamma rows are zero: the velocities are the masses', the links conduct heat only).
    integer :: spring_rows(2*self%layout%dimension + self%layout%invariant_count - 1), link_rows(2)

    f = 0.0_real64
    if (present(band)) band = 0.0_real64
    d = self%layout%dimension
    half = self%band_half_width()
    first_point = self%layout%point_of(first_row)
    last_point = self%layout%point_of(last_row)
    weight = merge(1.0_real64, 0.5_real64, self%rule == partials_exact)
    slots = slots_of(d, self%layout%invariant_count)
    do c = 1, d
      spring_rows(c) = slots%p_left(c)
      spring_rows(d + c) = slots%p_right(c)
    end do
    if (slots%gamma > 0) spring_rows(2*d + 1) = slots%gamma
    if (slots%tau > 0) spring_rows(size(spring_rows)) = slots%tau
    m = self%layout%invariant_count - 1
    link_rows = [3*d + m, 3*d + 2*m]
    do i = max(1, first_point), min(self%layout%masses, last_point)
      block
        integer :: indices(2*d)
        real(real64) :: fl(2*d), dfl(2*d, 2*d)

        indices = self%layout%mass_indices(i)
        call mass_block(self%masses(i), self%gravity, old(indices(d + 1:) - base), new(indices(d + 1:) - base), weight, &
                        fl, dfl)
        call add_rows(indices, fl, first_row, last_row, half, f, dfl, band)
      end block
    end do
    ! Spring a touches points a - 1 and a; link (a, a+1) needs springs a and a + 1. Each spring's
    ! slots are gathered once, for its partials and its block.
    a_first = max(1, first_point - 1)
    a_last = min(self%layout%springs, last_point + 2)
    allocate (parts(a_first:a_last))
    do a = a_first, a_last
      block
        real(real64) :: old_slots(self%layout%spring_size()), new_slots(size(old_slots)), fl(size(old_slots))
        real(real64) :: dfl(size(old_slots), size(old_slots))
        integer :: indices(size(old_slots))

        indices = self%layout%spring_indices(a)
        old_slots = self%layout%gather_spring(old, a, base, indices)
        new_slots = self%layout%gather_spring(new, a, base, indices)
        call evaluate_spring_partials(self%springs(a), self%rule, self%gradient, self%metric, d, old_slots, new_slots, &
                                      parts(a), stat, with_derivatives=present(band))
        if (stat /= failure_none) return
        if (a >= first_point .and. a <= last_point + 1) then
          if (present(band)) then
            call spring_block(self%springs(a), parts(a), old_slots, new_slots, inverse_mass(a - 1), inverse_mass(a), fl, dfl)
            call add_rows(indices, fl, first_row, last_row, half, f, dfl, band, spring_rows)
          else
            call spring_block(self%springs(a), parts(a), old_slots, new_slots, inverse_mass(a - 1), inverse_mass(a), fl)
            call add_rows(indices, fl, first_row, last_row, half, f, only=spring_rows)
          end if
        end if
      end block
    end do
    if (self%layout%invariant_count == 1) return
    do a = max(1, first_point - 1), min(self%layout%springs - 1, last_point + 1)
      block
        integer :: indices(3*d + 2*(self%layout%invariant_count - 1))
        real(real64) :: fl(size(indices)), dfl(size(indices), size(indices))

        indices = self%layout%link_indices(a)
        if (present(band)) then
          call link_block(self%conductivity(a), parts(a), parts(a + 1), fl, dfl)
          call add_rows(indices, fl, first_row, last_row, half, f, dfl, band, link_rows)
        else
          call link_block(self%conductivity(a), parts(a), parts(a + 1), fl)
          call add_rows(indices, fl, first_row, last_row, half, f, only=link_rows)
        end if
      end block
    end do

  contains

    pure real(real64) function inverse_mass(i)
      integer, intent(in) :: i

      inverse_mass = 0.0_real64
      if (i >= 1 .and. i <= self%layout%masses) inverse_mass = 1.0_real64/self%masses(i)
    end function inverse_mass

  end subroutine field_rows

  ! Adds a block's rows that lie in first_row..last_row to f and, with dfl, to the band
  ! (field_rows' storage); index 0, a support's slot, is no unknown. `only`: the block's rows
  ! that can be nonzero (default all).
  pure subroutine add_rows(indices, fl, first_row, last_row, half, f, dfl, band, only)
    integer, intent(in) :: indices(:), first_row, last_row, half
    real(real64), intent(in) :: fl(:)
    real(real64), intent(inout) :: f(:)
    real(real64), intent(in), optional :: dfl(:, :)
    real(real64), intent(inout), optional :: band(:, :)
    integer, intent(in), optional :: only(:)
    integer :: k, r, c, row, shift

    do k = 1, size(indices)
      r = k
      if (present(only)) then
        if (k > size(only)) exit
        r = only(k)
      end if
      if (indices(r) < first_row .or. indices(r) > last_row) cycle
      row = indices(r) - first_row + 1
      f(row) = f(row) + fl(r)
      if (.not. present(band)) cycle
      shift = half + 1 - indices(r)
      do c = 1, size(indices)
        if (indices(c) > 0) band(indices(c) + shift, row) = band(indices(c) + shift, row) + dfl(r, c)
      end do
    end do
  end subroutine add_rows

  !> Adds a block into f and df, skipping the slots that are no unknowns (index 0).
  pure subroutine scatter(indices, fl, dfl, f, df)
    integer, intent(in) :: indices(:)
    real(real64), intent(in) :: fl(:), dfl(:, :)
    real(real64), intent(inout) :: f(:)
    real(real64), intent(inout), optional :: df(:, :)
    integer :: r, c

    do r = 1, size(indices)
      if (indices(r) == 0) cycle
      f(indices(r)) = f(indices(r)) + fl(r)
      if (.not. present(df)) cycle
      do c = 1, size(indices)
        if (indices(c) > 0) df(indices(r), indices(c)) = df(indices(r), indices(c)) + dfl(r, c)
      end do
    end do
  end subroutine scatter

  !> Why z is no physical root ('' if it is): the temperatures at z and the scheme's temperatures
  !> (discrete, or midpoint) must be positive (docs/formulation.md section 5).
  pure subroutine check_root(self, x, problem_text)
    class(chain_step_problem), intent(in) :: self
    real(real64), intent(in) :: x(:)
    character(len=:), allocatable, intent(out) :: problem_text
    type(spring_partials) :: parts(self%layout%springs)
    real(real64) :: f(2), theta
    integer :: a, stat

    problem_text = ''
    if (self%layout%invariant_count == 1) return
    do a = 1, self%layout%springs
      call spring_values(self%springs(a), self%layout%dimension, self%layout%gather_spring(x, a), f, theta, stat)
      if (stat /= failure_none) then
        problem_text = 'a spring is outside the domain at the new state'
        return
      end if
    end do
    call self%partials_of(self%z_old, x, parts, stat)
    if (stat == failure_none .and. all(parts%theta > 0.0_real64)) return
    problem_text = 'non-positive scheme temperature (D_tau U/D_tau S)'
    if (stat /= failure_none .and. stat /= domain_nonpositive_temperature) &
      problem_text = 'the scheme''s temperatures are undefined between the states'
  end subroutine check_root

  !> E(new) - E(old) and S(new) - S(old) as sums of the parts' differences (no cancellation);
  !> with `points` (first, last), only the masses and springs of those points (a rank's share),
  !> old and new then holding the unknowns base + 1 .. base + size(old).
  pure subroutine energy_difference(self, old, new, delta_energy, delta_entropy, stat, base, points)
    class(chain_step_problem), intent(in) :: self
    real(real64), intent(in) :: old(:), new(:)
    real(real64), intent(out) :: delta_energy, delta_entropy
    integer, intent(out) :: stat
    integer, intent(in), optional :: base, points(2)
    real(real64) :: delta(2)
    integer :: i, a, d, shift, range(2)

    call share(self%layout, base, points, shift, range)
    d = self%layout%dimension
    delta_energy = 0.0_real64
    delta_entropy = 0.0_real64
    stat = failure_none
    do i = range(1), min(self%layout%masses, range(2))
      associate (x => self%layout%mass_indices(i) - shift)
        delta_energy = delta_energy + mass_energy_difference(self%masses(i), self%gravity, old(x(1:d)), old(x(d + 1:)), &
                                                             new(x(1:d)), new(x(d + 1:)))
      end associate
    end do
    do a = range(1), range(2)
      call spring_differences(self%springs(a), d, self%layout%gather_spring(old, a, shift), &
                              self%layout%gather_spring(new, a, shift), delta, stat)
      if (stat /= failure_none) return
      delta_energy = delta_energy + delta(potential_u)
      delta_entropy = delta_entropy + delta(potential_s)
    end do
  end subroutine energy_difference

  !> E = sum of the masses' T + V_g and the springs' U_a, S = sum of the S_a at z; with `points`,
  !> only those points' masses and springs (as energy_difference).
  pure subroutine energy_entropy(self, z, energy, entropy, stat, base, points)
    class(chain_step_problem), intent(in) :: self
    real(real64), intent(in) :: z(:)
    real(real64), intent(out) :: energy, entropy
    integer, intent(out) :: stat
    integer, intent(in), optional :: base, points(2)
    real(real64) :: f(2), theta
    integer :: i, a, d, shift, range(2)

    call share(self%layout, base, points, shift, range)
    d = self%layout%dimension
    energy = 0.0_real64
    entropy = 0.0_real64
    stat = failure_none
    do i = range(1), min(self%layout%masses, range(2))
      associate (x => self%layout%mass_indices(i) - shift)
        energy = energy + mass_energy(self%masses(i), self%gravity, z(x(1:d)), z(x(d + 1:)))
      end associate
    end do
    do a = range(1), range(2)
      call spring_values(self%springs(a), d, self%layout%gather_spring(z, a, shift), f, theta, stat)
      if (stat /= failure_none) return
      energy = energy + f(potential_u)
      entropy = entropy + f(potential_s)
    end do
  end subroutine energy_entropy

  ! The shift of the arrays and the points summed: the optional arguments, or every point.
  pure subroutine share(layout, base, points, shift, range)
    type(chain_layout), intent(in) :: layout
    integer, intent(in), optional :: base, points(2)
    integer, intent(out) :: shift, range(2)

    shift = 0
    if (present(base)) shift = base
    range = [1, layout%points()]
    if (present(points)) range = points
  end subroutine share

end module spring_chain_step
