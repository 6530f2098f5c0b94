!> Oracle for the tests: the free energies psi_a(l, theta, gamma) of eqs. (16)-(17) typed
!> literally as the paper writes them, independent of the closed forms of src/model/pendulum/free_energy.
module paper_free_energy
  use, intrinsic :: iso_fortran_env, only: real64
  use model_parameters, only: pendulum_parameters
  implicit none (type, external)
  private
  public :: paper_psi

contains

  !> psi_a(l, theta, gamma) exactly as eqs. (16)-(17) write it; gamma is ignored for spring 1.
  pure function paper_psi(params, a, length, theta, gamma) result(psi)
    type(pendulum_parameters), intent(in) :: params
    integer, intent(in) :: a
    real(real64), intent(in) :: length, theta, gamma
    real(real64) :: psi
    real(real64) :: stretch_log, mu_eq, mu_neq, psi_eq, dpsi_eq_dl, theta_ref

    theta_ref = params%theta_ref
    stretch_log = log(length/params%natural_length(a))
    mu_eq = params%mu_eq_const(a) - params%mu_eq_slope(a)*(theta - theta_ref)
    psi_eq = 0.5_real64*mu_eq*stretch_log**2 - params%beta*(theta - theta_ref)*stretch_log &
             + params%heat_capacity(a)*(theta - theta_ref - theta*log(theta/theta_ref))
    psi = psi_eq
    if (a == 2) then
      mu_neq = params%mu_neq_const - params%mu_neq_slope*(theta - theta_ref)
      dpsi_eq_dl = (mu_eq*stretch_log - params%beta*(theta - theta_ref))/length
      psi = psi + params%beta_v*psi_eq + mu_neq*gamma**2 - params%beta_v*gamma*dpsi_eq_dl
    end if
  end function paper_psi

end module paper_free_energy
