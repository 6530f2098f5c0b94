!> The Jacobian half of the double pendulum's fused step kernel (src/model/pendulum/pendulum_step_kernel):
!> the derivative pass, which differentiates each spring's partials (Gonzalez's quotient and its
!> fallback, or the midpoint rule's exact partials) in the variables they depend on, and the
!> assembly of the condensed Jacobian dR/dy = dR/dz'|_y + dR/dq' (h/2) m^-1 from them and the
!> scalars the residual's pass kept at the same point, in the kernel's internal numbering (a
!> reduced layout's rows and columns are picked from it at the end).
submodule (pendulum_step_kernel) pendulum_step_jacobian
  implicit none (type, external)

contains

  ! The derivative pass and dR/dy at a point whose residual pass is done.
  module procedure jacobian_pass
    real(real64) :: theta_new, dtheta_new(3)

    call derivative_pass(self, point, stat)
    if (stat /= failure_none) return
    dtheta_new = 0.0_real64
    if (self%temperature_row > 0) then
      call new_temperature(self, self%temperature_part, point, theta_new, dtheta_new(1:self%temperature_part + 1), stat)
      if (stat /= failure_none) return
    end if
    call assemble_jacobian(self, point, dtheta_new, jacobian)
  end procedure jacobian_pass

  !> The derivative pass at a point whose values pass is done: dP/dxi for every spring.
  pure subroutine derivative_pass(self, point, stat)
    class(pendulum_step), intent(in) :: self
    type(step_point), intent(inout) :: point
    integer, intent(out) :: stat
    real(real64) :: partials(3, 2), hess(3, 3, 2)
    integer :: a, n

    stat = failure_none
    do a = 1, 2
      n = a + 1
      associate (sp => point%spring(a))
        if (self%partials_rule == partials_midpoint) then
          hess(1:n, 1:n, :) = sp%hess_m(1:n, 1:n, :)
        else if (self%gradient == gradient_gonzalez) then
          call gonzalez_derivatives(a, sp, hess)
        else
          call discrete_gradient_of(self%gradient, self%spring(a), self%old(a)%x(1:n), sp%x(1:n), self%scale(1:n, a), &
                                    partials(1:n, :), hess(1:n, 1:n, :), stat=stat)
          if (stat /= failure_none) return
        end if
        point%dpartials(1:n, 1:n, :, a) = hess(1:n, 1:n, :)
      end associate
    end do
  end subroutine derivative_pass

  !> The derivative of Gonzalez's discrete gradient in x' from its values pass (the element's
  !> Hessian at the midpoint and grad f(x'), kept there), in ddg's first n = a + 1 rows and
  !> columns. The arrays are passed whole (3 rows): sections of spring 1's 2 rows would be packed
  !> and unpacked in every pass.
  pure subroutine gonzalez_derivatives(a, sp, ddg)
    integer, intent(in) :: a
    type(spring_pass), intent(in) :: sp
    real(real64), intent(inout), contiguous :: ddg(:, :, :)
    real(real64) :: dg(3, 2)
    integer :: n

    n = a + 1
    if (sp%small) then
      ddg(1:n, 1:n, :) = 0.5_real64*sp%hess_m(1:n, 1:n, :)
      return
    end if
    call gonzalez_from_parts(sp%d(1:n), sp%weight(1:n), sp%dwd, sp%grad_m, sp%delta_f, dg, sp%hess_m, sp%grad_b, ddg)
  end subroutine gonzalez_derivatives

  ! dR/dy from the point's partials and derivatives and the scalars of its residual pass. The
  ! fixed-size work arrays are zeroed whole: plain loops, not strided ones over their first rows
  ! (docs/performance.md, Issue 42).
  pure subroutine assemble_jacobian(self, point, dtheta_new, jacobian)
    class(pendulum_step), intent(in) :: self
    type(step_point), intent(in) :: point
    real(real64), intent(in) :: dtheta_new(3)
    real(real64), intent(out) :: jacobian(:, :)
    ! Derivatives in the variables xi_a of each spring (1..n_a) of the scalars the rows use.
    real(real64) :: dtheta(3, 2), dforce(3, 2), dratio(3, 2), dinv_u(3, 2), drate(3), dheating(3), dinv_eta
    ! Each row's derivative in xi of each spring, then in q' (condensed at the end), and the
    ! Jacobian, in arrays of fixed size (no descriptors, no vector subscripts in the loops).
    real(real64) :: drow(max_rows, 3, 2), dq(max_rows, 3, 2), jac(max_rows, max_rows)
    real(real64) :: kappa, s_tau, h
    integer :: a, b, n, l, i, col, rows, p0

    rows = size(jacobian, 1)
    if (.not. self%full) rows = self%internal_count
    h = self%fraction*self%dt
    kappa = self%params%conductivity
    jac = 0.0_real64
    dq = 0.0_real64
    drow = 0.0_real64
    associate (partials => point%partials, dp => point%dpartials, theta => point%theta, &
               thermal_force => point%thermal_force, work => point%work, work_ratio => point%work_ratio, &
               inv_u_tau => point%inv_u_tau, inv_eta => point%inv_eta, rate => point%rate, heating => point%heating, &
               lambda_length => point%lambda_length, lambda_temperature => point%lambda_temperature)
      do a = 1, 2
        n = a + 1
        s_tau = partials(n, potential_s, a)
        do l = 1, n
          dtheta(l, a) = (dp(n, l, potential_u, a) - theta(a)*dp(n, l, potential_s, a))/s_tau
          dforce(l, a) = dp(1, l, potential_u, a) - theta(a)*dp(1, l, potential_s, a) &
                         - partials(1, potential_s, a)*dtheta(l, a)
          dratio(l, a) = (dp(1, l, potential_s, a) - work_ratio(a)*dp(n, l, potential_s, a))/s_tau
          dinv_u(l, a) = -dp(n, l, potential_u, a)*inv_u_tau(a)**2
        end do
      end do
      ! d(1/eta)/dTheta, eq. (17), as the element's viscosity gave it. Without the viscous branch 1/eta,
      ! the rate, its heating and spring 2's gamma partials and their derivatives are all 0, so
      ! drate and dheating are 0 too, with no branch the full layout would pay for.
      dinv_eta = point%dinv_eta
      do l = 1, 3
        drate(l) = (dtheta(l, 2)*partials(2, potential_s, 2) + theta(2)*dp(2, l, potential_s, 2) &
                    - dp(2, l, potential_u, 2))*inv_eta &
                   + (theta(2)*partials(2, potential_s, 2) - partials(2, potential_u, 2))*dinv_eta*dtheta(l, 2)
        dheating(l) = (dp(2, l, potential_u, 2) - heating*dp(3, l, potential_u, 2))*inv_u_tau(2)
      end do

    do a = 1, 2
      b = 3 - a
      n = a + 1
      p0 = 3*(a - 1)                  ! the rows (and columns) of p_a are p0 + 1..p0 + 3
      do l = 1, n
        ! momentum rows: 2 T_a q_mid_a
        drow(p0 + 1:p0 + 3, l, a) = 2.0_real64*point%q_mid(:, a)*dforce(l, a)
        ! tau_a rows: 2 (S_C/S_tau) w - kappa (Theta_b - Theta_a)/U_tau
        drow(row_tau(a), l, a) = drow(row_tau(a), l, a) + 2.0_real64*work(a)*dratio(l, a) &
                                 + kappa*dtheta(l, a)*inv_u_tau(a) &
                                 - kappa*(theta(b) - theta(a))*dinv_u(l, a)
      end do
      do l = 1, b + 1
        drow(row_tau(a), l, b) = drow(row_tau(a), l, b) - kappa*dtheta(l, b)*inv_u_tau(a)
      end do
    end do
    drow(row_gamma, :, 2) = -drate
    drow(row_tau(2), :, 2) = drow(row_tau(2), :, 2) + dheating*rate + heating*drate
    if (self%temperature_row > 0) then
      a = self%temperature_part
      drow(row_tau(a), 1:a + 1, a) = drow(row_tau(a), 1:a + 1, a) - lambda_temperature*dinv_u(1:a + 1, a)
    end if

    ! Through the partials' variables xi into the columns of q', gamma', tau'.
    do a = 1, 2
      n = a + 1
      do i = 1, 3
        dq(1:rows, i, a) = drow(1:rows, 1, a)*point%chain_c(i, a)
      end do
      if (a == 2) jac(1:rows, row_gamma) = drow(1:rows, 2, 2)*point%chain_other
      jac(1:rows, row_tau(a)) = drow(1:rows, n, a)*point%chain_other
    end do

    ! Direct dependencies: (z' - z)/h, q_mid in the forces, w = q_mid.v.
    do col = 1, row_tau(2)
      jac(col, col) = jac(col, col) + 1.0_real64/h
    end do
    do a = 1, 2
      p0 = 3*(a - 1)
      do i = 1, 3
        dq(p0 + i, i, a) = dq(p0 + i, i, a) + thermal_force(a)
      end do
      ! w_a = q_mid_a . v_a: dw/dq_a' = v_a/2, dw/dp_b' = q_mid_a m^-1_ab/2.
      dq(row_tau(a), :, a) = dq(row_tau(a), :, a) + work_ratio(a)*point%v(:, a)
      do b = 1, 2
        jac(row_tau(a), 3*b - 2:3*b) = jac(row_tau(a), 3*b - 2:3*b) &
                                       + work_ratio(a)*self%inverse_mass(a, b)*point%q_mid(:, a)
      end do
    end do
    if (self%length_row > 0) then
      do i = 1, 3
        dq(i, i, 1) = dq(i, i, 1) + 0.5_real64*lambda_length
      end do
      jac(1:3, self%length_row) = point%q_mid(:, 1)
      dq(self%length_row, :, 1) = point%q_new(:, 1)
    end if
    if (self%temperature_row > 0) then
      a = self%temperature_part
      n = a + 1
      jac(row_tau(a), self%temperature_row) = -inv_u_tau(a)
      ! g2 = theta(z') - temperature, through the invariants of z' (C' = q'.q').
      dq(self%temperature_row, :, a) = dtheta_new(1)*2.0_real64*point%q_new(:, a)
      if (a == 2) jac(self%temperature_row, row_gamma) = dtheta_new(2)
      jac(self%temperature_row, row_tau(a)) = dtheta_new(n)
    end if

    ! Condensation: q_a' = q_a + h m^-1 p_mid, so dq_a'/dp_b' = (h/2) m^-1_ab.
    do b = 1, 2
      do a = 1, 2
        jac(1:rows, 3*b - 2:3*b) = jac(1:rows, 3*b - 2:3*b) + (0.5_real64*h*self%inverse_mass(a, b))*dq(1:rows, :, a)
      end do
    end do
    if (self%full) then
      jacobian = jac(1:rows, 1:rows)
    else
      ! The layout's rows and columns of the internal ones (the third components' and gamma's dropped).
      associate (kept => self%internal_of(1:size(jacobian, 1)))
        jacobian = jac(kept, kept)
      end associate
    end if
    end associate
  end subroutine assemble_jacobian

end submodule pendulum_step_jacobian
