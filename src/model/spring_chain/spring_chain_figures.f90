!> The figures a run checks and records on every step of the chain (src/model/distributed_model's
!> distributed_figures), for a share of its points (a rank's, or all of them): E and S of the new
!> state with their rounding scales (src/structure/step_balances), the step's dE and dS as sums
!> of the parts' differences, J = sum_i x_i x p_i, the conserved components of J = sum_i x_i x p_i about the scene's
!> axes (spring_chain_balance's conserved_axes) and their change, the lowest temperature, and the
!> step's smallest entropy production of a viscous branch and of a conducting link
!> (docs/formulation.md section 10). A rank's figures are partial sums: the caller adds (and takes
!> the minima of) the ranks' shares.
module spring_chain_figures
  use, intrinsic :: iso_fortran_env, only: real64
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
  use model_interface, only: model_step_figure
  use spring_chain_layout, only: chain_layout
  use spring_chain_spring, only: chain_spring
  use invariant_function, only: potential_u, potential_s
  use failures, only: failure_none
  use distributed_model, only: distributed_figures
  use spring_chain_partials, only: spring_partials, partials_discrete_gradient, partials_midpoint, partials_exact, &
                                   evaluate_spring_partials
  use spring_chain_balance, only: mass_energy, spring_values, viscous_production, link_production, angular_momentum, &
                                  conserved_axes
  use spring_chain_step, only: chain_step_problem
  implicit none (type, external)
  private
  public :: share_figures, production_figures, whole_chain_minima

contains

  !> The figures of the step old -> new (problem's rule and gradient) over points first..last
  !> (`points`), old and new holding the unknowns base + 1 .. base + size(old) (the share's points
  !> and two on either side); stat /= failure_none outside a spring's domain.
  pure subroutine share_figures(problem, old, new, base, points, values, stat)
    type(chain_step_problem), intent(in) :: problem
    real(real64), intent(in) :: old(:), new(:)
    integer, intent(in) :: base, points(2)
    type(distributed_figures), intent(out) :: values
    integer, intent(out) :: stat
    type(spring_partials), allocatable :: parts(:)
    real(real64), allocatable :: axes(:, :)
    real(real64) :: f(2), scales(2), theta, j_old(3), j_new(3)
    integer :: i, a, d, k, last_mass, last_spring

    associate (layout => problem%layout)
      d = layout%dimension
      last_mass = min(layout%masses, points(2))
      last_spring = min(layout%springs, points(2))
      call problem%energy_difference(old, new, values%delta_energy, values%delta_entropy, stat, base, points)
      if (stat /= failure_none) return
      axes = conserved_axes(layout, problem%gravity)
      values%conserved_count = size(axes, 2)
      do i = points(1), last_mass
        associate (x => layout%mass_indices(i) - base)
          values%energy = values%energy + mass_energy(problem%masses(i), problem%gravity, new(x(1:d)), new(x(d + 1:)))
          values%energy_scale = values%energy_scale + sum(new(x(d + 1:))**2)/(2.0_real64*problem%masses(i)) &
                                + problem%masses(i)*sum(abs(problem%gravity*new(x(1:d))))
          j_new = angular_momentum(new(x(1:d)), new(x(d + 1:)))
          values%angular_momentum = values%angular_momentum + j_new
          if (values%conserved_count == 0) cycle
          j_old = angular_momentum(old(x(1:d)), old(x(d + 1:)))
          do k = 1, values%conserved_count
            values%conserved(k) = values%conserved(k) + dot_product(axes(:, k), j_new)
            values%delta_conserved(k) = values%delta_conserved(k) + dot_product(axes(:, k), j_new - j_old)
          end do
          values%momentum_scale = values%momentum_scale + norm2(new(x(1:d)))*norm2(new(x(d + 1:)))
        end associate
      end do
      do a = points(1), last_spring
        call spring_values(problem%springs(a), d, layout%gather_spring(new, a, base), f, theta, stat, scales)
        if (stat /= failure_none) return
        values%energy = values%energy + f(potential_u)
        values%entropy = values%entropy + f(potential_s)
        values%energy_scale = values%energy_scale + scales(potential_u)
        values%entropy_scale = values%entropy_scale + scales(potential_s)
        if (layout%invariant_count > 1) values%min_temperature = min(values%min_temperature, theta)
      end do
      if (layout%invariant_count == 1 .or. last_spring < points(1)) return
      ! The step's partials of springs first - 1 .. last: link (a, a + 1) is the share's that
      ! holds spring a + 1.
      allocate (parts(max(1, points(1) - 1):last_spring))
      call problem%partials_of(old, new, parts, stat, base, lbound(parts, 1))
      if (stat /= failure_none) return
      call lower_production_minima(layout, problem%springs, problem%conductivity, parts, points(1), &
                                   values%min_viscous_production, values%min_link_production)
    end associate
  end subroutine share_figures

  ! The smallest entropy productions of the viscous branches of springs first .. ubound(parts)
  ! and of their links to the spring before, from the step's partials `parts` (from spring
  ! max(1, first - 1) on), lowering min_viscous and min_link.
  pure subroutine lower_production_minima(layout, springs, conductivity, parts, first, min_viscous, min_link)
    type(chain_layout), intent(in) :: layout
    type(chain_spring), intent(in) :: springs(:)
    real(real64), intent(in) :: conductivity(:)
    integer, intent(in) :: first
    type(spring_partials), intent(in) :: parts(max(1, first - 1):)
    real(real64), intent(inout) :: min_viscous, min_link
    integer :: a

    do a = first, ubound(parts, 1)
      if (layout%invariant_count == 3) min_viscous = min(min_viscous, viscous_production(springs(a), parts(a)))
      if (a > 1) min_link = min(min_link, link_production(conductivity(a - 1), parts(a - 1), parts(a)))
    end do
  end subroutine lower_production_minima

  !> The chain's figures of each step beyond a run file's schema (the split path's rows, and a
  !> dense chain run's through the model: spring_chain_model's step_figure_list).
  function production_figures() result(figures)
    type(model_step_figure) :: figures(2)

    figures(1) = model_step_figure(name='min_viscous_production', units='W/K', combine='min', description= &
                                   'the step''s smallest entropy production of a spring''s viscous branch, Theta y^2/eta '// &
                                   '(docs/formulation.md section 10); NaN without viscous branches')
    figures(2) = model_step_figure(name='min_link_production', units='W/K', combine='min', description= &
                                   'the step''s smallest entropy production of a conducting link, kappa (Theta_a - '// &
                                   'Theta_b)^2/(Theta_a Theta_b); NaN without links')
  end function production_figures

  !> production_figures' values for the step old -> new of the whole chain (states in the layout's
  !> order, as the dense path holds them, without building a step problem: the springs are the
  !> model's own): its springs' partials by the rule of `scheme` (EME's
  !> discrete gradient `gradient` with `metric`, the midpoint rule's, or the exact partials at the
  !> step's end of any other scheme), as the split path takes them; NaN where the chain has no
  !> such branch or link; stat /= failure_none outside a spring's domain.
  pure subroutine whole_chain_minima(layout, springs, conductivity, scheme, gradient, metric, old, new, minima, stat)
    type(chain_layout), intent(in) :: layout
    type(chain_spring), intent(in) :: springs(:)
    real(real64), intent(in) :: conductivity(:), old(:), new(:)
    character(len=*), intent(in) :: scheme
    integer, intent(in) :: gradient, metric
    real(real64), intent(out) :: minima(2)
    integer, intent(out) :: stat
    type(spring_partials), allocatable :: parts(:)
    integer :: rule, a

    minima = huge(1.0_real64)
    stat = failure_none
    if (layout%invariant_count > 1) then
      select case (scheme)
      case ('eme')
        rule = partials_discrete_gradient
      case ('midpoint')
        rule = partials_midpoint
      case default
        rule = partials_exact
      end select
      allocate (parts(layout%springs))
      do a = 1, layout%springs
        call evaluate_spring_partials(springs(a), rule, gradient, metric, layout%dimension, &
                                      layout%gather_spring(old, a, 0), layout%gather_spring(new, a, 0), parts(a), stat)
        if (stat /= failure_none) return
      end do
      call lower_production_minima(layout, springs, conductivity, parts, 1, minima(1), minima(2))
    end if
    where (minima >= huge(1.0_real64)) minima = ieee_value(1.0_real64, ieee_quiet_nan)
  end subroutine whole_chain_minima

end module spring_chain_figures
