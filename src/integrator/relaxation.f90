!> Relaxation of a Runge-Kutta step (Ketcheson 2019; Ranocha, Sayyari, Dalcin, Parsani,
!> Ketcheson 2020; docs/integrators.md): the step z + d is replaced by z_new(gamma) = P(z + gamma d),
!> where P projects onto the constraints and every conserved component of the momenta
!> (src/integrator/constrained_flow: positions, then the momenta, then slaved entries), and
!> gamma is the root near 1 of
!>   r(gamma) = [E(z_new) - E(z)] - thetabar [S(z_new) - S(z) - gamma e_S] = 0,
!> evaluated with the model's cancellation-free differences. thetabar = 0 for a closed system:
!> then E(z_new) = E(z). With a heat bath at thetabar (constraint g2), V = E - thetabar S
!> changes by exactly -thetabar gamma e_S. In entropy variables, with e_S the step's entropy
!> estimate h sum_i b_i sigma_i, the projection leaves the free subsystems' entropy alone, so
!> S(z_new) - S(z) = gamma e_S in a closed system.
!>
!> "To round-off" has a floor: z_new is rounded to doubles, which moves E by up to about
!> eps sum_i |z_i dE/dz_i| (1e-13 J on the paper scene) whatever gamma is. A gamma whose r is
!> below that floor is a root; an accurate small step can have r(1) below it already. The secant
!> search itself is src/solver/relaxation_root's, which the chain's split steps share.
module relaxation
  use, intrinsic :: iso_fortran_env, only: real64
  use invariant_function, only: potential_u, potential_s
  use failures, only: failure_none, domain_overflow
  use model_interface, only: generic_model
  use model_constraint, only: constraint_slot
  use constrained_flow, only: project_state, bath_temperature_of
  use relaxation_root, only: relaxation_function, find_relaxation_root, gamma_min, gamma_max
  implicit none (type, external)
  private
  public :: relax, gamma_min, gamma_max

  !> A step of the whole state as src/solver/relaxation_root searches it: r(gamma) from the
  !> model's cancellation-free differences (it lives for one `relax`, pointing at its arguments).
  type, extends(relaxation_function) :: dense_relaxation
    class(generic_model), pointer :: model => null()
    type(constraint_slot), pointer :: constraints(:) => null()
    real(real64), pointer :: z(:) => null(), d(:) => null(), z_new(:) => null()
    real(real64), allocatable :: momenta(:)          !! the conserved components at z
    real(real64) :: bath = 0.0_real64, entropy_estimate = 0.0_real64
  contains
    procedure :: move
    procedure :: scaled_residual
  end type dense_relaxation

contains

  !> gamma and z_new = P(z + gamma d) with r(gamma) = 0 to round-off; found = .false. when no
  !> root lies in [gamma_min, gamma_max] or an evaluation leaves the model's domain.
  !> `evaluations` counts the energy differences taken; `resolution`: relaxation_root's.
  subroutine relax(model, constraints, z, d, entropy_estimate, gamma, z_new, found, evaluations, resolution)
    class(generic_model), intent(in), target :: model
    type(constraint_slot), intent(in), target :: constraints(:)
    real(real64), intent(in), target :: z(:), d(:)
    real(real64), intent(in) :: entropy_estimate
    real(real64), intent(out) :: gamma
    real(real64), intent(out), target :: z_new(:)
    logical, intent(out) :: found
    integer, intent(out) :: evaluations
    real(real64), intent(out), optional :: resolution
    type(dense_relaxation) :: step
    real(real64) :: floor
    integer :: stat

    found = .false.
    evaluations = 0
    gamma = 1.0_real64
    step%model => model
    step%constraints => constraints
    step%z => z
    step%d => d
    step%z_new => z_new
    step%momenta = model%conserved_momenta(z)
    step%bath = bath_temperature_of(constraints)
    step%entropy_estimate = entropy_estimate
    call rounding_floor(floor, stat)
    if (stat /= failure_none) return
    call find_relaxation_root(step, floor, gamma, found, evaluations, resolution)

  contains

    ! The rounding floor of r: 8 eps sum_i |z_i| (|dE/dz_i| + thetabar |dS/dz_i|).
    subroutine rounding_floor(floor, stat)
      real(real64), intent(out) :: floor
      integer, intent(out) :: stat
      real(real64) :: partials(model%max_invariants, 2, model%subsystem_count()), weights(size(z))

      floor = 0.0_real64
      call model%exact_partials(z, partials, stat=stat)
      if (stat /= failure_none) return
      weights = abs(model%mechanical_energy_gradient(z) + model%subsystem_gradient(z, partials, potential_u))
      if (step%bath > 0.0_real64) weights = weights + step%bath*abs(model%subsystem_gradient(z, partials, potential_s))
      floor = 8*epsilon(1.0_real64)*sum(abs(z)*weights)
      if (.not. (floor > 0.0_real64)) floor = tiny(1.0_real64)
    end subroutine rounding_floor
  end subroutine relax

  !> z_new = P(z + gamma d).
  subroutine move(self, gamma, stat)
    class(dense_relaxation), intent(inout) :: self
    real(real64), intent(in) :: gamma
    integer, intent(out) :: stat

    self%z_new = self%z + gamma*self%d
    call project_state(self%model, self%constraints, self%momenta, self%z_new, stat)
  end subroutine move

  !> q = r(gamma)/gamma at z_new = P(z + gamma d).
  subroutine scaled_residual(self, gamma, q, stat)
    class(dense_relaxation), intent(inout) :: self
    real(real64), intent(in) :: gamma
    real(real64), intent(out) :: q
    integer, intent(out) :: stat
    real(real64) :: energy_change, entropy_change

    q = 0.0_real64
    call self%move(gamma, stat)
    if (stat /= failure_none) return
    call self%model%energy_difference(self%z, self%z_new, energy_change, stat, entropy_change)
    if (stat /= failure_none) return
    q = energy_change/gamma
    if (self%bath > 0.0_real64) q = q - self%bath*(entropy_change/gamma - self%entropy_estimate)
    if (.not. (abs(q) <= huge(q))) stat = domain_overflow
  end subroutine scaled_residual

end module relaxation
