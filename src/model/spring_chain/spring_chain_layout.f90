!> Where the chain's unknowns live (docs/formulation.md section 10, "State"): point k holds mass k
!> and spring k, (x_k, p_k, [gamma_k], [tau_k]); with 'fixed-fixed' ends a last point N + 1 holds
!> spring N + 1's gamma and tau only. Indices are 1-based into z; 0 marks a slot that is no unknown
!> (a support's position or momentum), which an assembly skips (PETSc's MatSetValues and
!> VecSetValues skip the 0-based -1 it becomes).
!>
!> A block's local slots: spring a's are (x_{a-1}, p_{a-1}, x_a, p_a, gamma_a, tau_a), the left end
!> first; link (a, a+1)'s are (x_{a-1}, x_a, x_{a+1}, gamma_a, tau_a, gamma_{a+1}, tau_{a+1}); mass
!> i's are (x_i, p_i). `spring_slots` numbers a spring's local slots for the kernels.
module spring_chain_layout
  use, intrinsic :: iso_fortran_env, only: real64
  implicit none (type, external)
  private
  public :: chain_layout, make_chain_layout, spring_slots, slots_of, ends_fixed_free, ends_fixed_fixed

  character(len=*), parameter :: ends_fixed_free = 'fixed-free'     !! a hanging chain: n_s = N springs
  character(len=*), parameter :: ends_fixed_fixed = 'fixed-fixed'   !! a second support at span e_x: N + 1

  !> The local slots of one spring block, for d components and n invariants (its rung).
  type :: spring_slots
    integer :: x_left(3) = 0, p_left(3) = 0, x_right(3) = 0, p_right(3) = 0
    integer :: gamma = 0        !! 0: no viscous branch
    integer :: tau = 0          !! 0: no thermodynamic variable
    integer :: size = 0
  end type spring_slots

  !> The layout of z for N masses in `dimension` components, n_s springs of one rung.
  type :: chain_layout
    integer :: masses = 0
    integer :: springs = 0
    integer :: dimension = 3
    integer :: invariant_count = 3     !! the rung: 1 (C), 2 (C, tau), 3 (C, gamma, tau)
    logical :: fixed_fixed = .false.
    real(real64) :: span = 0.0_real64  !! the second support's distance along x
  contains
    procedure, non_overridable :: point_size
    procedure, non_overridable :: spring_size
    procedure, non_overridable :: state_size
    procedure, non_overridable :: points
    procedure, non_overridable :: point_of
    procedure, non_overridable :: offset
    procedure, non_overridable :: q_index
    procedure, non_overridable :: p_index
    procedure, non_overridable :: gamma_index
    procedure, non_overridable :: tau_index
    procedure, non_overridable :: support
    procedure, non_overridable :: mass_indices
    procedure, non_overridable :: spring_indices
    procedure, non_overridable :: link_indices
    procedure, non_overridable :: gather_spring
  end type chain_layout

contains

  !> The layout of `masses` masses, `ends` (ends_fixed_free or ends_fixed_fixed), rung `invariant_count`.
  pure function make_chain_layout(masses, dimension, ends, invariant_count, span) result(layout)
    integer, intent(in) :: masses, dimension, invariant_count
    character(len=*), intent(in) :: ends
    real(real64), intent(in) :: span
    type(chain_layout) :: layout

    layout%masses = masses
    layout%dimension = dimension
    layout%invariant_count = invariant_count
    layout%fixed_fixed = ends == ends_fixed_fixed
    layout%span = span
    layout%springs = masses
    if (layout%fixed_fixed) layout%springs = masses + 1
  end function make_chain_layout

  !> The local slots of a spring block with d components and n invariants.
  pure function slots_of(d, n) result(slots)
    integer, intent(in) :: d, n
    type(spring_slots) :: slots
    integer :: c

    do c = 1, d          ! a loop, not array constructors: this runs for every spring of every solve
      slots%x_left(c) = c
      slots%p_left(c) = d + c
      slots%x_right(c) = 2*d + c
      slots%p_right(c) = 3*d + c
    end do
    slots%size = 4*d
    if (n == 3) then
      slots%size = slots%size + 1
      slots%gamma = slots%size
    end if
    if (n >= 2) then
      slots%size = slots%size + 1
      slots%tau = slots%size
    end if
  end function slots_of

  !> Unknowns of a point holding a mass: 2d, plus gamma and tau as the rung has them.
  pure integer function point_size(self)
    class(chain_layout), intent(in) :: self

    point_size = 2*self%dimension + self%invariant_count - 1
  end function point_size

  !> The number of a spring block's local slots: 4 d + 1 + 1 (gamma and tau as the rung has them).
  pure integer function spring_size(self)
    class(chain_layout), intent(in) :: self

    spring_size = 4*self%dimension + self%invariant_count - 1
  end function spring_size

  !> The number of unknowns.
  pure integer function state_size(self)
    class(chain_layout), intent(in) :: self

    state_size = self%masses*self%point_size()
    if (self%fixed_fixed) state_size = state_size + self%invariant_count - 1
  end function state_size

  !> The point that unknown g (1-based) belongs to.
  pure integer function point_of(self, g)
    class(chain_layout), intent(in) :: self
    integer, intent(in) :: g

    point_of = (g - 1)/self%point_size() + 1
  end function point_of

  !> The number of points: N, and N + 1 with 'fixed-fixed' ends (the last holds one spring's
  !> gamma and tau only).
  pure integer function points(self)
    class(chain_layout), intent(in) :: self

    points = self%springs
  end function points

  !> z index before point k's first unknown.
  pure integer function offset(self, k)
    class(chain_layout), intent(in) :: self
    integer, intent(in) :: k

    offset = (k - 1)*self%point_size()
  end function offset

  !> Component c of x_i.
  pure integer function q_index(self, i, c)
    class(chain_layout), intent(in) :: self
    integer, intent(in) :: i, c

    q_index = self%offset(i) + c
  end function q_index

  !> Component c of p_i.
  pure integer function p_index(self, i, c)
    class(chain_layout), intent(in) :: self
    integer, intent(in) :: i, c

    p_index = self%offset(i) + self%dimension + c
  end function p_index

  !> gamma_a (0 without a viscous branch).
  pure integer function gamma_index(self, a)
    class(chain_layout), intent(in) :: self
    integer, intent(in) :: a

    gamma_index = 0
    if (self%invariant_count == 3) gamma_index = self%tau_index(a) - 1
  end function gamma_index

  !> tau_a (0 on the elastic rung). Point N + 1 of 'fixed-fixed' ends has no mass slots.
  pure integer function tau_index(self, a)
    class(chain_layout), intent(in) :: self
    integer, intent(in) :: a

    tau_index = 0
    if (self%invariant_count == 1) return
    if (a <= self%masses) then
      tau_index = self%offset(a) + self%point_size()
    else
      tau_index = self%offset(a) + self%invariant_count - 1
    end if
  end function tau_index

  !> The position of node i when it is a support: x_0 = 0 and, 'fixed-fixed', x_{N+1} = span e_x.
  pure function support(self, i) result(x)
    class(chain_layout), intent(in) :: self
    integer, intent(in) :: i
    real(real64) :: x(self%dimension)

    x = 0.0_real64
    if (i > self%masses) x(1) = self%span
  end function support

  !> z indices of mass i's slots (x_i, p_i).
  pure function mass_indices(self, i) result(indices)
    class(chain_layout), intent(in) :: self
    integer, intent(in) :: i
    integer :: indices(2*self%dimension)
    integer :: c, first

    first = self%offset(i)          ! x_i then p_i: q_index and p_index, without a call per slot
    do c = 1, 2*self%dimension      ! a loop: the array constructor cost the chain's loop 58e6 of 1.5e9 instructions
      indices(c) = first + c
    end do
  end function mass_indices

  !> z indices of spring a's local slots, 0 for a support's.
  pure function spring_indices(self, a) result(indices)
    class(chain_layout), intent(in) :: self
    integer, intent(in) :: a
    integer :: indices(self%spring_size())
    integer :: d

    d = self%dimension
    indices = 0
    if (a > 1) indices(1:2*d) = self%mass_indices(a - 1)
    if (a <= self%masses) indices(2*d + 1:4*d) = self%mass_indices(a)
    if (self%invariant_count == 3) indices(4*d + 1) = self%gamma_index(a)
    if (self%invariant_count >= 2) indices(size(indices)) = self%tau_index(a)
  end function spring_indices

  !> z indices of link (a, a+1)'s local slots (x_{a-1}, x_a, x_{a+1}, gamma_a, tau_a,
  !> gamma_{a+1}, tau_{a+1}), 0 for a support's; the thermal rungs only.
  pure function link_indices(self, a) result(indices)
    class(chain_layout), intent(in) :: self
    integer, intent(in) :: a
    integer :: indices(3*self%dimension + 2*(self%invariant_count - 1))
    integer :: d, c, node, k

    d = self%dimension
    indices = 0
    do node = a - 1, a + 1
      if (node < 1 .or. node > self%masses) cycle
      do c = 1, d
        indices((node - a + 1)*d + c) = self%offset(node) + c    ! q_index(node, c)
      end do
    end do
    k = 3*d
    do node = a, a + 1
      if (self%invariant_count == 3) then
        k = k + 1
        indices(k) = self%gamma_index(node)
      end if
      k = k + 1
      indices(k) = self%tau_index(node)
    end do
  end function link_indices

  !> Spring a's local slots' values from z (a support's position, and zero momentum); z holds
  !> the unknowns base + 1 .. base + size(z) (default base 0: the whole state). `at`: the slots'
  !> indices if the caller has them (spring_indices(a)).
  pure function gather_spring(self, z, a, base, at) result(values)
    class(chain_layout), intent(in) :: self
    real(real64), intent(in) :: z(:)
    integer, intent(in) :: a
    integer, intent(in), optional :: base, at(:)
    real(real64) :: values(self%spring_size())
    integer :: indices(size(values)), d, shift, k

    d = self%dimension
    shift = 0
    if (present(base)) shift = base
    if (present(at)) then
      indices = at
    else
      indices = self%spring_indices(a)
    end if
    do k = 1, size(values)
      values(k) = 0.0_real64
      if (indices(k) > 0) values(k) = z(indices(k) - shift)
    end do
    if (a == 1) values(1:d) = self%support(0)
    if (a > self%masses) values(2*d + 1:3*d) = self%support(a)
  end function gather_spring

end module spring_chain_layout
