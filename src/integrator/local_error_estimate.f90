!> A local error estimate for one-step methods, from the continuous vector field f (of the
!> constrained flow, src/integrator/constrained_flow) at the step's two ends and at one more point
!> (docs/integrators.md, Adaptive steps).
!>
!> The cubic Hermite interpolant H of (z_n, f_n) and (z_{n+1}, f_{n+1}) over the step of h has, at
!> the step's middle,
!>   H(1/2)  = (z_n + z_{n+1})/2 + h (f_n - f_{n+1})/8,
!>   H'(1/2) = 3 (z_{n+1} - z_n)/(2 h) - (f_n + f_{n+1})/4.
!> For the exact solution through z_n the defect d = H'(1/2) - f(H(1/2)) is O(h**4): the
!> interpolation error's derivative vanishes at the middle. An error e in z_{n+1} changes it by
!> 3 e/(2 h) + O(e), so the method's local error is
!>   e ~ (2 h/3) d,
!> asymptotically exact for any method of order >= 1 (for EME and the midpoint rule, O(h**3)).
!> f_{n+1} is the next step's f_n, so a step costs two evaluations of f.
!>
!> With the temperature constraint g2 the slaved entry tau_a carries no estimate of its own: its
!> field row is not its rate (the continuous form slaves it to Theta_a = thetabar), and its error
!> follows from the others'. The fixed-length constraint g1 is not taken with step control
!> (src/io/run_config): the discrete-gradient step enforces g1 on positions only, and its end
!> momenta carry a normal velocity q1.v1 of alternating sign that grows from step to step and that
!> smaller steps make harder, not easier, to solve (measured: docs/integrators.md).
module local_error_estimate
  use, intrinsic :: iso_fortran_env, only: real64
  use failures, only: failure_none
  use model_interface, only: generic_model
  use model_constraint, only: constraint_slot
  use constrained_flow, only: constrained_field, slaved_entries
  implicit none (type, external)
  private
  public :: hermite_defect_estimate, weighted_rms_norm, hermite_middle, hermite_defect, weighted_square_sum

contains

  !> The estimate e of the local error of the step of h from z_old (where the field is f_old) to
  !> z_new; f_new is the field at z_new. stat /= failure_none if a field is undefined.
  pure subroutine hermite_defect_estimate(model, constraints, z_old, f_old, z_new, h, estimate, f_new, stat)
    class(generic_model), intent(in) :: model
    type(constraint_slot), intent(in) :: constraints(:)
    real(real64), intent(in) :: z_old(:), f_old(:), z_new(:), h
    real(real64), intent(out) :: estimate(:), f_new(:)
    integer, intent(out) :: stat
    real(real64) :: z_middle(size(z_old)), f_middle(size(z_old))

    estimate = 0.0_real64
    call constrained_field(model, constraints, z_new, f_new, stat)
    if (stat /= failure_none) return
    z_middle = hermite_middle(z_old, f_old, z_new, f_new, h)
    call constrained_field(model, constraints, z_middle, f_middle, stat)
    if (stat /= failure_none) return
    estimate = hermite_defect(z_old, f_old, z_new, f_new, f_middle, h)
    where (slaved_entries(model, constraints, z_new)) estimate = 0.0_real64
  end subroutine hermite_defect_estimate

  !> The root mean square of e_i / (1 + max(|z_old,i|, |z_new,i|)): an error measured absolutely
  !> where a component is below 1 and relatively above (the scale relaxed_dp853 uses). A step of
  !> tolerance tol is accepted when this norm is at most tol.
  pure real(real64) function weighted_rms_norm(estimate, z_old, z_new) result(norm)
    real(real64), intent(in) :: estimate(:), z_old(:), z_new(:)

    norm = sqrt(weighted_square_sum(estimate, z_old, z_new)/size(estimate))
  end function weighted_rms_norm

  !> The sum of (e_i / (1 + max(|z_old,i|, |z_new,i|)))**2: weighted_rms_norm's, of a part of
  !> the state (a rank's rows, whose sums over the ranks make the whole state's).
  pure real(real64) function weighted_square_sum(estimate, z_old, z_new) result(total)
    real(real64), intent(in) :: estimate(:), z_old(:), z_new(:)

    total = sum((estimate/(1.0_real64 + max(abs(z_old), abs(z_new))))**2)
  end function weighted_square_sum

  !> H(1/2), the Hermite interpolant of (z_old, f_old) and (z_new, f_new) over the step of h at
  !> its middle (module header); entry by entry, so a rank's rows give the rank's rows.
  pure function hermite_middle(z_old, f_old, z_new, f_new, h) result(z_middle)
    real(real64), intent(in) :: z_old(:), f_old(:), z_new(:), f_new(:), h
    real(real64) :: z_middle(size(z_old))

    z_middle = 0.5_real64*(z_old + z_new) + 0.125_real64*h*(f_old - f_new)
  end function hermite_middle

  !> The estimate (2 h/3) (H'(1/2) - f(H(1/2))) of the step's local error (module header), f_middle
  !> the field at hermite_middle's point; entry by entry.
  pure function hermite_defect(z_old, f_old, z_new, f_new, f_middle, h) result(estimate)
    real(real64), intent(in) :: z_old(:), f_old(:), z_new(:), f_new(:), f_middle(:), h
    real(real64) :: estimate(size(z_old))

    estimate = (2.0_real64*h/3.0_real64)*(1.5_real64*(z_new - z_old)/h - 0.25_real64*(f_old + f_new) - f_middle)
  end function hermite_defect

end module local_error_estimate
