!> GENERIC structure with Mielke's split for two subsystems, assembled as dense matrices
!> (paper eqs. (7)-(12), FORMULATION section 4):
!>   L = M_S L0 M_S^T,   K = M_E K0 M_E^T,   zdot = L grad E + K grad S.
!> Every quantity is built from `partials(var, potential, a)`, the derivatives of U_a and S_a
!> with respect to spring a's invariants (C, gamma, tau). With exact partials at a state this is
!> the continuous structure; with discrete-gradient partials it is the discrete one of (15).
!> The time steppers use the same product in written-out form (generic_vector_field); the unit
!> tests prove the two agree.
module structure_matrices
  use, intrinsic :: iso_fortran_env, only: real64
  use model_parameters, only: pendulum_parameters
  use free_energy, only: viscosity
  use thermo_variable, only: potential_u, potential_s
  use double_pendulum, only: state_size, q_index, p_index, gamma_index, tau_index, &
                             var_c, var_gamma, var_tau, inverse_mass_times, gravity_force
  implicit none (type, external)
  private
  public :: energy_gradient, entropy_gradient, mielke_transpose
  public :: poisson_matrix, friction_matrix

contains

  !> grad E: spring parts 2 q_a dU_a/dC, gravity, m^-1 p, dU_2/dgamma and dU_a/dtau_a.
  pure function energy_gradient(params, z, partials) result(g)
    type(pendulum_parameters), intent(in) :: params
    real(real64), intent(in) :: z(state_size), partials(3, 2, 2)
    real(real64) :: g(state_size)
    real(real64) :: force(3, 2), v(3, 2)
    integer :: a

    force = gravity_force(params)
    v = inverse_mass_times(params, reshape(z(p_index(1, 1):p_index(3, 2)), [3, 2]))
    g = spring_gradient(z, partials, potential_u)
    do a = 1, 2
      g(q_index(:, a)) = g(q_index(:, a)) - force(:, a)
      g(p_index(:, a)) = v(:, a)
    end do
  end function energy_gradient

  !> grad S: only the springs contribute.
  pure function entropy_gradient(z, partials) result(g)
    real(real64), intent(in) :: z(state_size), partials(3, 2, 2)
    real(real64) :: g(state_size)

    g = spring_gradient(z, partials, potential_s)
  end function entropy_gradient

  !> M_H^T = [[I, B_H], [0, D_H^-1]] of eq. (7) for H = sum_a H_a with H_a = U_a or S_a:
  !> column a of B_H is -grad_omega H_a / d_tau_a H_a, D_H = diag(d_tau_a H_a).
  pure function mielke_transpose(z, partials, potential) result(mt)
    real(real64), intent(in) :: z(state_size), partials(3, 2, 2)
    integer, intent(in) :: potential
    real(real64) :: mt(state_size, state_size)
    real(real64) :: g(state_size), dtau
    integer :: a, i

    mt = 0.0_real64
    do i = 1, state_size
      mt(i, i) = 1.0_real64
    end do
    g = spring_gradient(z, partials, potential)
    do a = 1, 2
      dtau = partials(var_tau, potential, a)
      mt(q_index(:, a), tau_index(a)) = -g(q_index(:, a))/dtau
      if (a == 2) mt(gamma_index, tau_index(a)) = -g(gamma_index)/dtau
      mt(tau_index(a), tau_index(a)) = 1.0_real64/dtau
    end do
  end function mielke_transpose

  !> L0 of eq. (12): the canonical symplectic matrix on (q, p), zero elsewhere.
  pure function poisson_matrix_0() result(l0)
    real(real64) :: l0(state_size, state_size)
    integer :: i

    l0 = 0.0_real64
    do i = 1, 6
      l0(q_index(1, 1) - 1 + i, p_index(1, 1) - 1 + i) = 1.0_real64
      l0(p_index(1, 1) - 1 + i, q_index(1, 1) - 1 + i) = -1.0_real64
    end do
  end function poisson_matrix_0

  !> K0 of eq. (12) at the temperatures Theta_a = d_tau U_a / d_tau S_a, eq. (2).
  pure function friction_matrix_0(params, partials) result(k0)
    type(pendulum_parameters), intent(in) :: params
    real(real64), intent(in) :: partials(3, 2, 2)
    real(real64) :: k0(state_size, state_size)
    real(real64) :: theta(2), conduction

    theta = partials(var_tau, potential_u, :)/partials(var_tau, potential_s, :)
    k0 = 0.0_real64
    k0(gamma_index, gamma_index) = theta(2)/viscosity(params, theta(2))
    conduction = params%conductivity*theta(1)*theta(2)
    k0(tau_index, tau_index) = reshape([conduction, -conduction, -conduction, conduction], [2, 2])
  end function friction_matrix_0

  !> L = M_S L0 M_S^T, eq. (8).
  pure function poisson_matrix(z, partials) result(l)
    real(real64), intent(in) :: z(state_size), partials(3, 2, 2)
    real(real64) :: l(state_size, state_size)
    real(real64) :: mt(state_size, state_size)

    mt = mielke_transpose(z, partials, potential_s)
    l = matmul(transpose(mt), matmul(poisson_matrix_0(), mt))
  end function poisson_matrix

  !> K = M_E K0 M_E^T, eq. (8).
  pure function friction_matrix(params, z, partials) result(k)
    type(pendulum_parameters), intent(in) :: params
    real(real64), intent(in) :: z(state_size), partials(3, 2, 2)
    real(real64) :: k(state_size, state_size)
    real(real64) :: mt(state_size, state_size)

    mt = mielke_transpose(z, partials, potential_u)
    k = matmul(transpose(mt), matmul(friction_matrix_0(params, partials), mt))
  end function friction_matrix

  ! Gradient of sum_a H_a in z for H_a = U_a or S_a: q_a part 2 q_a dH_a/dC (the chain rule
  ! through C = q.q), gamma part dH_2/dgamma, tau parts dH_a/dtau_a.
  pure function spring_gradient(z, partials, potential) result(g)
    real(real64), intent(in) :: z(state_size), partials(3, 2, 2)
    integer, intent(in) :: potential
    real(real64) :: g(state_size)
    integer :: a

    g = 0.0_real64
    do a = 1, 2
      g(q_index(:, a)) = 2.0_real64*z(q_index(:, a))*partials(var_c, potential, a)
      g(tau_index(a)) = partials(var_tau, potential, a)
    end do
    g(gamma_index) = partials(var_gamma, potential, 2)
  end function spring_gradient

end module structure_matrices
