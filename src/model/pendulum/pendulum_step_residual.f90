!> The residual half of the double pendulum's fused step kernel (src/model/pendulum/pendulum_step_kernel):
!> the values pass at a point y of the condensed unknowns (the new and midpoint positions from the
!> condensation, each spring's invariants, its partials by Gonzalez's quotient with its fallback
!> or by the midpoint rule, from the generated element of the paper's spring), and the residual's
!> rows of p, gamma, tau and the constraints from it, in the
!> kernel's internal numbering (the full layout's; a reduced layout's rows are picked from it).
submodule (pendulum_step_kernel) pendulum_step_residual
  implicit none (type, external)

contains

  ! The values pass and the residual's internal rows at y; the point keeps the residual's scalars.
  module procedure residual_pass
    real(real64) :: h, theta_new, eta
    integer :: a, b, n

    h = self%fraction*self%dt
    call values_pass(self, y, point, stat)
    if (stat /= failure_none) return
    associate (partials => point%partials, theta => point%theta, thermal_force => point%thermal_force, &
               work => point%work, work_ratio => point%work_ratio, inv_u_tau => point%inv_u_tau)
      do a = 1, 2
        n = a + 1
        theta(a) = partials(n, potential_u, a)/partials(n, potential_s, a)
        thermal_force(a) = partials(1, potential_u, a) - theta(a)*partials(1, potential_s, a)
        work(a) = dot_product(point%q_mid(:, a), point%v(:, a))
        work_ratio(a) = partials(1, potential_s, a)/partials(n, potential_s, a)
        inv_u_tau(a) = 1.0_real64/partials(n, potential_u, a)
      end do
      ! Viscous rate (Theta_2 dS_2/dgamma - dU_2/dgamma)/eta(Theta_2) and its heating of tau_2;
      ! without the viscous branch they are 0 (no exponential spent on eta), gamma's row is
      ! 0 = (0 - 0)/h - 0 and dropped.
      if (self%viscous) then
        call self%spring(2)%viscosity(theta(2), eta, point%dinv_eta)
        point%inv_eta = 1.0_real64/eta
        point%rate = (theta(2)*partials(2, potential_s, 2) - partials(2, potential_u, 2))*point%inv_eta
        point%heating = partials(2, potential_u, 2)*inv_u_tau(2)
      else
        point%inv_eta = 0.0_real64
        point%dinv_eta = 0.0_real64
        point%rate = 0.0_real64
        point%heating = 0.0_real64
      end if
      do a = 1, 2
        b = 3 - a
        residual(p_index(:, a) - condensed_offset) = (point%p_new(:, a) - self%p_old(:, a))/h &
                                                     - self%force(:, a) + 2.0_real64*thermal_force(a)*point%q_mid(:, a)
        residual(row_tau(a)) = (point%tau_new(a) - self%tau_old(a))/h + 2.0_real64*work_ratio(a)*work(a) &
                               - self%params%conductivity*(theta(b) - theta(a))*inv_u_tau(a)
      end do
      residual(row_gamma) = (point%gamma_new - self%gamma_old)/h - point%rate
      residual(row_tau(2)) = residual(row_tau(2)) + point%heating*point%rate
      ! Constraints (docs/formulation.md section 7).
      point%lambda_length = 0.0_real64
      if (self%length_row > 0) then
        point%lambda_length = y(self%length_unknown)
        residual(1:3) = residual(1:3) + point%lambda_length*point%q_mid(:, 1)
        residual(self%length_row) = 0.5_real64*(dot_product(point%q_new(:, 1), point%q_new(:, 1)) - self%length**2)
      end if
      point%lambda_temperature = 0.0_real64
      if (self%temperature_row > 0) then
        point%lambda_temperature = y(self%temperature_unknown)
        a = self%temperature_part
        residual(row_tau(a)) = residual(row_tau(a)) - point%lambda_temperature*inv_u_tau(a)
        call new_temperature(self, a, point, theta_new, stat=stat)
        if (stat /= failure_none) return
        residual(self%temperature_row) = theta_new - self%temperature
      end if
    end associate
    if (.not. all(abs(residual) <= huge(1.0_real64))) stat = domain_overflow
  end procedure residual_pass

  !> The values pass at y: positions, midpoint, and every spring's partials. stat /= 0: a point
  !> the scheme needs is outside the model's domain.
  module procedure values_pass
    integer :: a, n, base

    if (self%full) then
      point%p_new(:, 1) = y(1:3)
      point%p_new(:, 2) = y(4:6)
      point%gamma_new = y(row_gamma)
      point%tau_new = y(row_tau)
    else
      point%p_new = new_momenta(self, y)
      base = self%eliminated
      point%gamma_new = 0.0_real64
      if (self%viscous) point%gamma_new = y(base + 1)
      point%tau_new = y(base + merge(1, 0, self%viscous) + [1, 2])
    end if
    point%v = velocity(self, point%p_new)
    point%q_new = self%q_old + (self%fraction*self%dt)*point%v
    point%q_mid = 0.5_real64*(self%q_old + point%q_new)
    stat = self%old_stat
    if (stat /= failure_none) return
    do a = 1, 2
      n = a + 1
      associate (sp => point%spring(a))
        if (self%partials_rule == partials_midpoint) then
          ! Exact partials at the invariants of z_mid: dC_mid/dq' = q_mid, d(gamma, tau)_mid/d(gamma, tau)' = 1/2.
          sp%mid(1) = dot_product(point%q_mid(:, a), point%q_mid(:, a))
          if (a == 2) sp%mid(2) = 0.5_real64*(self%gamma_old + point%gamma_new)
          sp%mid(n) = 0.5_real64*(self%tau_old(a) + point%tau_new(a))
          point%chain_c(:, a) = point%q_mid(:, a)
          point%chain_other = 0.5_real64
          call midpoint_values(self, a, sp, stat)
          point%partials(1:n, :, a) = sp%grad_m(1:n, :)
        else
          ! Discrete gradients between the invariants of z and z': dC'/dq' = 2 q'.
          sp%x(1) = dot_product(point%q_new(:, a), point%q_new(:, a))
          if (a == 2) sp%x(2) = point%gamma_new
          sp%x(n) = point%tau_new(a)
          point%chain_c(:, a) = 2.0_real64*point%q_new(:, a)
          point%chain_other = 1.0_real64
          if (self%gradient == gradient_gonzalez) then
            call gonzalez_values(self, a, sp, point%partials(:, :, a), stat)
          else
            call discrete_gradient_of(self%gradient, self%spring(a), self%old(a)%x(1:n), sp%x(1:n), &
                                      self%scale(1:n, a), point%partials(1:n, :, a), stat=stat)
          end if
        end if
      end associate
      if (stat /= failure_none) return
    end do
  end procedure values_pass

  !> The exact partials of spring a at sp%mid (the element's gradients there) and their Hessian.
  pure subroutine midpoint_values(self, a, sp, stat)
    class(pendulum_step), intent(in) :: self
    integer, intent(in) :: a
    type(spring_pass), intent(inout) :: sp
    integer, intent(out) :: stat
    real(real64) :: f(2)
    integer :: n

    n = a + 1
    call self%spring(a)%evaluate(sp%mid(1:n), f, sp%grad_m(1:n, :), sp%hess_m(1:n, 1:n, :), stat)
  end subroutine midpoint_values

  !> Gonzalez's discrete gradient of spring a's (U, S) from the old invariants to sp%x
  !> (src/scheme/discrete_gradient): grad f at the midpoint and f(x') - f(x) from the element's
  !> gonzalez_parts in one call, with the Hessian at the midpoint and grad f(x') kept for the
  !> derivative pass. dg's first n = a + 1 rows are written; the quotient's arrays are passed whole
  !> (3 rows), as a section of spring 1's 2 rows would be packed and unpacked in every pass.
  pure subroutine gonzalez_values(self, a, sp, dg, stat)
    class(pendulum_step), intent(in) :: self
    integer, intent(in) :: a
    type(spring_pass), intent(inout) :: sp
    real(real64), intent(inout), contiguous :: dg(:, :)
    integer, intent(out) :: stat
    integer :: n

    n = a + 1
    associate (old => self%old(a), x => sp%x(1:n), d => sp%d(1:n))
      d = x - old%x(1:n)
      sp%weight(1:n) = 1.0_real64/self%scale(1:n, a)**2
      sp%dwd = dot_product(d, sp%weight(1:n)*d)
      call self%spring(a)%gonzalez_parts(old%x(1:n), x, sp%grad_m, sp%delta_f, stat, sp%hess_m, sp%grad_b)
      if (stat /= failure_none) return
      sp%small = sqrt(sp%dwd) < quotient_threshold
      if (sp%small) then
        ! The fallback below the threshold: the midpoint derivative.
        dg(1:n, :) = sp%grad_m(1:n, :)
        return
      end if
      call gonzalez_from_parts(d, sp%weight(1:n), sp%dwd, sp%grad_m, sp%delta_f, dg)
    end associate
  end subroutine gonzalez_values

end submodule pendulum_step_residual
