!> Test support: the hand-written blocks the generated spring_chain_blocks (src/model/spring_chain/description.py)
!> replaced, kept as an independent reference (tests/unit/test_spring_chain_blocks.pf compares the two).
!> The chain's field f = L DE + K DS (docs/formulation.md section 10) as a sum of small dense blocks,
!> each with its derivative in the unknowns it touches (the local slots of spring_chain_layout):
!>  - mass i:  f(x_i) = v_i,  f(p_i) = m_i g;
!>  - spring a: f(p_{a-1}) = 2 r_a F_a, f(p_a) = -2 r_a F_a with F_a = D_C U_a - Theta_a D_C S_a;
!>    f(gamma_a) = (Theta_a D_gamma S_a - D_gamma U_a)/eta_a(Theta_a);
!>    f(tau_a) = -D_C S_a 2 r_a.(v_a - v_{a-1})/D_tau S_a - (D_gamma U_a/D_tau U_a) f(gamma_a);
!>  - link (a, b = a+1): f(tau_a) = kappa (Theta_b - Theta_a)/D_tau U_a, and the same with a, b swapped;
!> with Theta_a = D_tau U_a/D_tau S_a, the partials D of spring_chain_partials, r at the point they
!> give (r_mid for a step) and v there (v_mid = p_mid/m). A step's residual is
!> R = (z_{n+1} - z_n)/dt - sum of the blocks, its Jacobian I/dt - sum of their derivatives in the
!> new unknowns; the continuous field (partials_exact) is the sum itself, for PETSc TS.
module spring_chain_blocks_reference
  use, intrinsic :: iso_fortran_env, only: real64
  use invariant_function, only: potential_u, potential_s
  use spring_chain_spring, only: chain_spring
  use spring_chain_partials, only: spring_partials
  implicit none (type, external)
  private
  public :: mass_block, spring_block, link_block

contains

  !> Mass i's block on (x_i, p_i): v = p/m at p = (1 - weight) p_old + weight p_new, and m g.
  pure subroutine mass_block(mass, gravity, p_old, p_new, weight, f, df)
    real(real64), intent(in) :: mass, gravity(:), p_old(:), p_new(:), weight
    real(real64), intent(out) :: f(:), df(:, :)
    integer :: d, c

    d = size(gravity)
    f(1:d) = ((1.0_real64 - weight)*p_old + weight*p_new)/mass
    f(d + 1:2*d) = mass*gravity
    df = 0.0_real64
    do c = 1, d
      df(c, d + c) = weight/mass
    end do
  end subroutine mass_block

  !> Spring `part`'s block on its local slots (the old and new values `old`, `new`; the end
  !> masses' inverses, 0 for a support): f and optionally df/d(new slots) (a residual needs f
  !> alone); optionally f's derivatives in the spring's partials, df_dpartials(:, i, k) = df/d
  !> partials(i, k) (through Theta_a too), which a model's written-out field hands on
  !> (spring_chain_model).
  pure subroutine spring_block(spring, part, old, new, inverse_mass_left, inverse_mass_right, f, df, df_dpartials_out)
    type(chain_spring), intent(in) :: spring
    type(spring_partials), intent(in) :: part
    real(real64), intent(in) :: old(:), new(:), inverse_mass_left, inverse_mass_right
    real(real64), intent(out) :: f(:)
    real(real64), intent(out), optional :: df(:, :), df_dpartials_out(:, :, :)
    real(real64) :: df_dpartials(size(f), 3, 2), df_dtheta(size(f))
    real(real64) :: v_left(3), v_right(3), force, work, w, eta, dinverse_eta, rate, drate(3), heating
    integer :: n, d, c, i, k
    logical :: derivatives

    n = part%invariants
    d = count(part%slots%x_left > 0)
    w = part%weight
    ! A residual wants f alone: the derivatives in the partials are skipped (they cost most).
    derivatives = present(df) .or. present(df_dpartials_out)
    f = 0.0_real64
    if (derivatives) then
      df_dpartials = 0.0_real64
      df_dtheta = 0.0_real64
    end if
    associate (s => part%slots, p => part%partials, theta => part%theta, rr => part%r(1:d))
      ! Momentum rows: the force -dC/dx F on each end.
      force = p(1, potential_u) - theta*p(1, potential_s)
      f(s%p_left(1:d)) = 2.0_real64*force*rr
      f(s%p_right(1:d)) = -2.0_real64*force*rr
      if (derivatives) then
        df_dpartials(s%p_left(1:d), 1, potential_u) = 2.0_real64*rr
        df_dpartials(s%p_right(1:d), 1, potential_u) = -2.0_real64*rr
        df_dpartials(s%p_left(1:d), 1, potential_s) = -2.0_real64*theta*rr
        df_dpartials(s%p_right(1:d), 1, potential_s) = 2.0_real64*theta*rr
        df_dtheta(s%p_left(1:d)) = -2.0_real64*p(1, potential_s)*rr
        df_dtheta(s%p_right(1:d)) = 2.0_real64*p(1, potential_s)*rr
      end if

      if (n >= 2) then
        ! tau row, reversible part: -D_C S (dC/dt)/D_tau S with dC/dt = 2 r.(v_right - v_left).
        v_left(1:d) = inverse_mass_left*((1.0_real64 - w)*old(s%p_left(1:d)) + w*new(s%p_left(1:d)))
        v_right(1:d) = inverse_mass_right*((1.0_real64 - w)*old(s%p_right(1:d)) + w*new(s%p_right(1:d)))
        work = 2.0_real64*dot_product(rr, v_right(1:d) - v_left(1:d))
        f(s%tau) = -p(1, potential_s)*work/p(n, potential_s)
        if (derivatives) then
          df_dpartials(s%tau, 1, potential_s) = -work/p(n, potential_s)
          df_dpartials(s%tau, n, potential_s) = p(1, potential_s)*work/p(n, potential_s)**2
        end if
      end if

      if (n == 3) then
        ! gamma row and the tau row's viscous heating -(D_gamma U/D_tau U) rate.
        call spring%viscosity(theta, eta, dinverse_eta)
        rate = (theta*p(2, potential_s) - p(2, potential_u))/eta
        f(s%gamma) = rate
        heating = -p(2, potential_u)/p(n, potential_u)
        f(s%tau) = f(s%tau) + heating*rate
        if (derivatives) then
          drate = [theta/eta, -1.0_real64/eta, p(2, potential_s)/eta + (theta*p(2, potential_s) - p(2, potential_u))*dinverse_eta]
          df_dpartials(s%gamma, 2, potential_s) = drate(1)
          df_dpartials(s%gamma, 2, potential_u) = drate(2)
          df_dtheta(s%gamma) = drate(3)
          df_dpartials(s%tau, 2, potential_s) = df_dpartials(s%tau, 2, potential_s) + heating*drate(1)
          df_dpartials(s%tau, 2, potential_u) = df_dpartials(s%tau, 2, potential_u) + heating*drate(2) &
                                                - rate/p(n, potential_u)
          df_dpartials(s%tau, n, potential_u) = df_dpartials(s%tau, n, potential_u) &
                                                + p(2, potential_u)*rate/p(n, potential_u)**2
          df_dtheta(s%tau) = df_dtheta(s%tau) + heating*drate(3)
        end if
      end if
      if (.not. derivatives) return

      ! Theta = D_tau U/D_tau S, then the partials' own derivatives in the slots.
      if (n >= 2) then
        df_dpartials(:, n, potential_u) = df_dpartials(:, n, potential_u) + df_dtheta/p(n, potential_s)
        df_dpartials(:, n, potential_s) = df_dpartials(:, n, potential_s) - df_dtheta*theta/p(n, potential_s)
      end if
      if (present(df_dpartials_out)) df_dpartials_out = df_dpartials
      if (.not. present(df)) return
      df = 0.0_real64
      if (n >= 2) then
        do c = 1, d
          associate (scale => -2.0_real64*p(1, potential_s)/p(n, potential_s))
            df(s%tau, s%x_right(c)) = scale*(v_right(c) - v_left(c))*w
            df(s%tau, s%x_left(c)) = -scale*(v_right(c) - v_left(c))*w
            df(s%tau, s%p_right(c)) = scale*rr(c)*w*inverse_mass_right
            df(s%tau, s%p_left(c)) = -scale*rr(c)*w*inverse_mass_left
          end associate
        end do
      end if
      do c = 1, d
        df(s%p_left(c), s%x_right(c)) = 2.0_real64*force*w
        df(s%p_left(c), s%x_left(c)) = -2.0_real64*force*w
        df(s%p_right(c), s%x_right(c)) = -2.0_real64*force*w
        df(s%p_right(c), s%x_left(c)) = 2.0_real64*force*w
      end do
      do k = 1, 2
        do i = 1, n
          do c = 1, s%size
            df(:, c) = df(:, c) + df_dpartials(:, i, k)*part%dpartials(i, k, c)
          end do
        end do
      end do
    end associate
  end subroutine spring_block

  !> Link (a, b = a+1)'s conduction block with conductivity kappa, on its local slots (x_{a-1},
  !> x_a, x_{a+1}, [gamma_a,] tau_a, [gamma_b,] tau_b): f and optionally df/d(new slots) and f's
  !> derivatives in the two springs' tau partials, df_dtau_partials(:, k, side) = df/d partials(n,
  !> k) of spring a (side 1) or b (side 2), the only partials a link reads.
  pure subroutine link_block(conductivity, part_a, part_b, f, df, df_dtau_partials)
    real(real64), intent(in) :: conductivity
    type(spring_partials), intent(in) :: part_a, part_b
    real(real64), intent(out) :: f(:)
    real(real64), intent(out), optional :: df(:, :), df_dtau_partials(:, :, :)
    real(real64) :: flow, tau_partials(2, size(f), 2)   ! (k, row, side): df(row)/d partials(n, k) of spring a or b
    integer :: n, d, m, tau_a, tau_b

    n = part_a%invariants
    d = count(part_a%slots%x_left > 0)
    m = n - 1                                   ! slots of a spring's own: [gamma,] tau
    tau_a = 3*d + m
    tau_b = 3*d + 2*m
    f = 0.0_real64
    flow = conductivity*(part_b%theta - part_a%theta)
    f(tau_a) = flow/part_a%partials(n, potential_u)
    f(tau_b) = -flow/part_b%partials(n, potential_u)
    if (.not. present(df)) return
    df = 0.0_real64
    tau_partials = 0.0_real64
    ! Row tau_a, then tau_b, through each spring's (D_tau U, D_tau S): Theta and the own D_tau U.
    call add_spring(part_a, 0, tau_a, -conductivity/part_a%partials(n, potential_u), &
                    -flow/part_a%partials(n, potential_u)**2, df, tau_partials(:, tau_a, 1))
    call add_spring(part_b, d, tau_a, conductivity/part_a%partials(n, potential_u), 0.0_real64, df, &
                    tau_partials(:, tau_a, 2))
    call add_spring(part_a, 0, tau_b, conductivity/part_b%partials(n, potential_u), 0.0_real64, df, &
                    tau_partials(:, tau_b, 1))
    call add_spring(part_b, d, tau_b, -conductivity/part_b%partials(n, potential_u), &
                    flow/part_b%partials(n, potential_u)**2, df, tau_partials(:, tau_b, 2))
    if (present(df_dtau_partials)) df_dtau_partials = reshape(tau_partials, shape(df_dtau_partials), &
                                                              order=[2, 1, 3])

  contains

    ! Row `row` += (d f/d Theta of `part`) dTheta + (d f/d D_tau U direct) dD_tau U, mapped from the
    ! spring's slots to the link's: its x_left to x_{a-1} (spring a) or x_a (spring b, shift d);
    ! tau_derivative: the row's derivatives in the spring's (D_tau U, D_tau S).
    pure subroutine add_spring(part, shift, row, df_dtheta, df_du_direct, jacobian, tau_derivative)
      type(spring_partials), intent(in) :: part
      integer, intent(in) :: shift, row
      real(real64), intent(in) :: df_dtheta, df_du_direct
      real(real64), intent(inout) :: jacobian(:, :)
      real(real64), intent(out) :: tau_derivative(2)
      real(real64) :: g_u, g_s
      integer :: c, own

      g_u = df_du_direct + df_dtheta/part%partials(n, potential_s)
      g_s = -df_dtheta*part%theta/part%partials(n, potential_s)
      tau_derivative = [g_u, g_s]
      associate (s => part%slots, du => part%dpartials(n, potential_u, :), ds => part%dpartials(n, potential_s, :))
        do c = 1, d
          jacobian(row, shift + c) = jacobian(row, shift + c) + (g_u*du(s%x_left(c)) + g_s*ds(s%x_left(c)))
          jacobian(row, shift + d + c) = jacobian(row, shift + d + c) + (g_u*du(s%x_right(c)) + g_s*ds(s%x_right(c)))
        end do
        own = 3*d + merge(0, m, shift == 0)
        if (s%gamma > 0) jacobian(row, own + 1) = jacobian(row, own + 1) + (g_u*du(s%gamma) + g_s*ds(s%gamma))
        jacobian(row, own + m) = jacobian(row, own + m) + (g_u*du(s%tau) + g_s*ds(s%tau))
      end associate
    end subroutine add_spring
  end subroutine link_block

end module spring_chain_blocks_reference
