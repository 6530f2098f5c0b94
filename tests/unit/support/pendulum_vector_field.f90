!> The GENERIC vector field f = L grad E + K grad S of eq. (8), written out component by
!> component (docs/formulation.md section 4), with its derivatives for the Newton Jacobian:
!>   dq/dt       = m^-1 p
!>   dp_a/dt     = -grad_qa V_g - 2 q_a (dU_a/dC - Theta_a dS_a/dC)
!>   dgamma/dt   = (Theta_2/eta(Theta_2)) y,  y = dS_2/dgamma - (dU_2/dgamma)/Theta_2
!>   dtau_a/dt   = -2 (dS_a/dC) q_a.(m^-1 p)_a / (dS_a/dtau) + kappa (Theta_b - Theta_a)/(dU_a/dtau)
!>                 - [a = 2] (dU_2/dgamma)/(dU_2/dtau) dgamma/dt
!> with Theta_a = (dU_a/dtau)/(dS_a/dtau), eq. (2); without the viscous branch there is no gamma
!> row and no viscous heating. partials(i, k, a) is the derivative of potential k of spring a in
!> its invariant i: slot_c = C, slot_gamma = gamma (spring 2, viscous) and tau_slot(a) = tau_a,
!> the last (model_interface). They are exact derivatives for the midpoint rule and
!> the TS baselines, discrete gradients for EME; tests/unit/test_structure_matrices checks that
!> f equals the assembled L grad E + K grad S (src/structure/structure_matrices).
module pendulum_vector_field
  use, intrinsic :: iso_fortran_env, only: real64
  use model_parameters, only: pendulum_parameters
  use free_energy, only: viscosity
  use invariant_function, only: potential_u, potential_s
  use model_interface, only: add_temperature_chain
  use double_pendulum, only: pendulum_layout, inverse_mass_times
  implicit none (type, external)
  private
  public :: vector_field, slot_c, slot_gamma

  integer, parameter :: slot_c = 1                   !! C_a = q_a.q_a, both springs
  integer, parameter :: slot_gamma = 2               !! gamma, spring 2 of the viscous branch

contains

  !> f(z, partials), and optionally df/dz (with the partials held fixed) and df/dpartials.
  pure subroutine vector_field(params, layout, z, partials, f, df_dz, df_dpartials)
    type(pendulum_parameters), intent(in) :: params
    type(pendulum_layout), intent(in) :: layout
    real(real64), intent(in) :: z(:), partials(:, :, :)
    real(real64), intent(out) :: f(:)
    real(real64), intent(out), optional :: df_dz(:, :)
    real(real64), intent(out), optional :: df_dpartials(:, :, :, :)

    real(real64) :: p(layout%dimension, 2), v(layout%dimension, 2), force(layout%dimension, 2)
    real(real64) :: theta(2), thermal_force(2), work_rate(2)
    real(real64) :: inverse_mass(2, 2), rate_gamma, inv_eta, dinv_eta, drate_dtheta
    real(real64) :: df_dtheta(size(z), 2), u_g, u_tau2, s_g
    integer :: a, b, i, j, d, tau_slot(2)

    d = layout%dimension
    tau_slot = [layout%invariant_count(1), layout%invariant_count(2)]
    p = layout%momenta(z)
    v = inverse_mass_times(params, p)
    force = layout%gravity_force(params)
    theta = 0.0_real64                 ! elastic springs: S = 0, no temperature
    if (layout%thermal) theta = [(partials(tau_slot(a), potential_u, a)/partials(tau_slot(a), potential_s, a), a=1, 2)]
    inverse_mass = reshape([1.0_real64, -1.0_real64, -1.0_real64, &
                            (params%mass(1) + params%mass(2))/params%mass(2)], [2, 2])/params%mass(1)

    ! Viscous rate: dgamma/dt = (Theta_2 dS/dgamma - dU/dgamma)/eta(Theta_2).
    u_g = 0.0_real64
    s_g = 0.0_real64
    rate_gamma = 0.0_real64
    inv_eta = 0.0_real64
    u_tau2 = partials(tau_slot(2), potential_u, 2)
    if (layout%viscous) then
      u_g = partials(slot_gamma, potential_u, 2)
      s_g = partials(slot_gamma, potential_s, 2)
      inv_eta = 1.0_real64/viscosity(params, theta(2))
      rate_gamma = (theta(2)*s_g - u_g)*inv_eta
    end if

    do a = 1, 2
      b = 3 - a
      associate (q => z(layout%q(1:d, a)))
        thermal_force(a) = partials(slot_c, potential_u, a) - theta(a)*partials(slot_c, potential_s, a)
        work_rate(a) = dot_product(q, v(:, a))
        f(layout%q(1:d, a)) = v(:, a)
        f(layout%p(1:d, a)) = force(:, a) - 2.0_real64*thermal_force(a)*q
        if (layout%thermal) f(layout%tau(a)) = -2.0_real64*partials(slot_c, potential_s, a)*work_rate(a) &
                                               /partials(tau_slot(a), potential_s, a) &
                                               + params%conductivity*(theta(b) - theta(a))/partials(tau_slot(a), potential_u, a)
      end associate
    end do
    if (layout%viscous) then
      f(layout%gamma) = rate_gamma
      f(layout%tau(2)) = f(layout%tau(2)) - u_g/u_tau2*rate_gamma
    end if

    if (present(df_dz)) then
      df_dz = 0.0_real64
      do a = 1, 2
        do b = 1, 2
          do i = 1, d
            df_dz(layout%q(i, a), layout%p(i, b)) = inverse_mass(a, b)
          end do
          if (.not. layout%thermal) cycle
          ! d(q_a . v_a)/dp_b = q_a m^-1_ab
          df_dz(layout%tau(a), layout%p(1:d, b)) = -2.0_real64*partials(slot_c, potential_s, a) &
            /partials(tau_slot(a), potential_s, a)*inverse_mass(a, b)*z(layout%q(1:d, a))
        end do
        do i = 1, d
          df_dz(layout%p(i, a), layout%q(i, a)) = -2.0_real64*thermal_force(a)
        end do
        if (layout%thermal) df_dz(layout%tau(a), layout%q(1:d, a)) = -2.0_real64*partials(slot_c, potential_s, a) &
                                                 /partials(tau_slot(a), potential_s, a)*v(:, a)
      end do
    end if

    if (present(df_dpartials)) then
      df_dpartials = 0.0_real64
      df_dtheta = 0.0_real64
      do a = 1, 2
        b = 3 - a
        associate (s_c => partials(slot_c, potential_s, a), s_tau => partials(tau_slot(a), potential_s, a), &
                   u_tau => partials(tau_slot(a), potential_u, a), q => z(layout%q(1:d, a)), &
                   p_rows => layout%p(1:d, a), tau_row => layout%tau(a))
          ! momentum rows
          df_dpartials(p_rows, slot_c, potential_u, a) = -2.0_real64*q
          df_dpartials(p_rows, slot_c, potential_s, a) = 2.0_real64*theta(a)*q
          df_dtheta(p_rows, a) = 2.0_real64*s_c*q
          if (.not. layout%thermal) cycle
          ! tau rows: reversible part and conduction
          df_dpartials(tau_row, slot_c, potential_s, a) = -2.0_real64*work_rate(a)/s_tau
          df_dpartials(tau_row, tau_slot(a), potential_s, a) = 2.0_real64*s_c*work_rate(a)/s_tau**2
          df_dpartials(tau_row, tau_slot(a), potential_u, a) = &
            -params%conductivity*(theta(b) - theta(a))/u_tau**2
          df_dtheta(tau_row, b) = params%conductivity/u_tau
          df_dtheta(tau_row, a) = -params%conductivity/u_tau
        end associate
      end do
      if (layout%viscous) then
        ! gamma row; d(1/eta)/dTheta = (1/eta) eta_theta / Theta^2
        dinv_eta = inv_eta*params%viscosity_activation/theta(2)**2
        drate_dtheta = s_g*inv_eta + (theta(2)*s_g - u_g)*dinv_eta
        df_dpartials(layout%gamma, slot_gamma, potential_s, 2) = theta(2)*inv_eta
        df_dpartials(layout%gamma, slot_gamma, potential_u, 2) = -inv_eta
        df_dtheta(layout%gamma, 2) = drate_dtheta
      end if
      if (layout%thermal) call add_temperature_chain(partials, tau_slot, df_dtheta, df_dpartials)
      if (layout%viscous) then
        ! tau_2 row's viscous heating -(U_gamma/U_tau2) rate_gamma: rate_gamma's full row, then own terms.
        do j = 1, 2
          do i = 1, size(partials, 1)
            df_dpartials(layout%tau(2), i, j, :) = df_dpartials(layout%tau(2), i, j, :) &
              - u_g/u_tau2*df_dpartials(layout%gamma, i, j, :)
          end do
        end do
        df_dpartials(layout%tau(2), slot_gamma, potential_u, 2) = &
          df_dpartials(layout%tau(2), slot_gamma, potential_u, 2) - rate_gamma/u_tau2
        df_dpartials(layout%tau(2), tau_slot(2), potential_u, 2) = &
          df_dpartials(layout%tau(2), tau_slot(2), potential_u, 2) + u_g*rate_gamma/u_tau2**2
      end if
    end if
  end subroutine vector_field

end module pendulum_vector_field
