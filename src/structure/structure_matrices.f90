!> Oracle: the GENERIC structure with Mielke's split assembled as dense matrices for any model
!> of src/structure/model_interface (paper eqs. (7)-(9), docs/formulation.md section 4):
!>   L = M_S L0 M_S^T,   K = M_E K0 M_E^T,   zdot = L grad E + K grad S.
!> Every quantity is built from `partials`, the derivatives of U_a and S_a in subsystem a's
!> invariants: exact ones at a state give the continuous structure, discrete gradients the
!> discrete one of (15). The integrators never use these matrices; they use the models'
!> written-out vector fields, which tests/unit/test_structure_matrices proves equal to
!> L grad E + K grad S, along with the degeneracy conditions (5) of L and K themselves.
module structure_matrices
  use, intrinsic :: iso_fortran_env, only: real64
  use invariant_function, only: potential_u, potential_s
  use model_interface, only: generic_model
  implicit none (type, external)
  private
  public :: energy_gradient, entropy_gradient, mielke_transpose, poisson_matrix, friction_matrix

contains

  !> grad E: the mechanical energy's gradient and the subsystems' U_a by the chain rule.
  pure function energy_gradient(model, z, partials) result(g)
    class(generic_model), intent(in) :: model
    real(real64), intent(in) :: z(:), partials(:, :, :)
    real(real64) :: g(model%state_size)

    g = model%mechanical_energy_gradient(z) + model%subsystem_gradient(z, partials, potential_u)
  end function energy_gradient

  !> grad S: only the subsystems contribute.
  pure function entropy_gradient(model, z, partials) result(g)
    class(generic_model), intent(in) :: model
    real(real64), intent(in) :: z(:), partials(:, :, :)
    real(real64) :: g(model%state_size)

    g = model%subsystem_gradient(z, partials, potential_s)
  end function entropy_gradient

  !> M_H^T = [[I, B_H], [0, D_H^-1]] of eq. (7) for H = sum_a H_a with H_a = U_a or S_a:
  !> column tau_a of B_H is -grad_omega H_a / d_tau_a H_a, D_H = diag(d_tau_a H_a).
  pure function mielke_transpose(model, z, partials, potential) result(mt)
    class(generic_model), intent(in) :: model
    real(real64), intent(in) :: z(:), partials(:, :, :)
    integer, intent(in) :: potential
    real(real64) :: mt(model%state_size, model%state_size)
    real(real64) :: x(model%max_invariants), dx(model%max_invariants, model%state_size)
    real(real64) :: g(model%state_size), dtau
    integer :: a, i, n, m

    mt = 0.0_real64
    do i = 1, model%state_size
      mt(i, i) = 1.0_real64
    end do
    do a = 1, model%temperature_count()      ! a mechanical model (no tau) has M = I: L = L0, K = K0
      associate (part => model%subsystems(a))
        n = part%invariant_count
        m = size(part%columns)
        call model%invariants(z, a, x(1:n), dx(1:n, 1:m))
        g = 0.0_real64
        g(part%columns) = matmul(partials(1:n, potential, a), dx(1:n, 1:m))
        dtau = partials(n, potential, a)
        do i = 1, m
          if (part%columns(i) /= part%tau_column) mt(part%columns(i), part%tau_column) = -g(part%columns(i))/dtau
        end do
        mt(part%tau_column, part%tau_column) = 1.0_real64/dtau
      end associate
    end do
  end function mielke_transpose

  !> L = M_S L0 M_S^T, eq. (8).
  pure function poisson_matrix(model, z, partials) result(l)
    class(generic_model), intent(in) :: model
    real(real64), intent(in) :: z(:), partials(:, :, :)
    real(real64) :: l(model%state_size, model%state_size)
    real(real64) :: mt(model%state_size, model%state_size)

    mt = mielke_transpose(model, z, partials, potential_s)
    l = matmul(transpose(mt), matmul(model%poisson_matrix_0(), mt))
  end function poisson_matrix

  !> K = M_E K0 M_E^T, eq. (8), with K0 at z and the partials' temperatures (friction_matrix_0_at).
  pure function friction_matrix(model, z, partials) result(k)
    class(generic_model), intent(in) :: model
    real(real64), intent(in) :: z(:), partials(:, :, :)
    real(real64) :: k(model%state_size, model%state_size)
    real(real64) :: mt(model%state_size, model%state_size)

    mt = mielke_transpose(model, z, partials, potential_u)
    k = matmul(transpose(mt), matmul(model%friction_matrix_0_at(z, partials), mt))
  end function friction_matrix

end module structure_matrices
