!> The settings of the &integrator namelist group that the integrators read (docs/input.md).
module integrator_settings
  use, intrinsic :: iso_fortran_env, only: real64, int64
  use thermo_variable_kinds, only: tau_temperature
  use discrete_gradient, only: gradient_gonzalez, metric_nondimensional
  implicit none (type, external)
  private
  public :: integrator_choice, step_count, default_step_budget, max_step_budget

  !> The step budget of a run (&integrator max_steps) when the input sets none, and the largest
  !> one a run takes: at a few microseconds a step, the default is minutes to hours of work.
  integer, parameter :: default_step_budget = 100000000
  integer, parameter :: max_step_budget = huge(1)

  !> Which integrator, in which thermodynamic variable, with which step and tolerances.
  type :: integrator_choice
    character(len=16) :: scheme = 'eme'              !! a name of the integrator registry
    integer :: thermo_variable = tau_temperature     !! tau_* of thermo_variable
    integer :: discrete_gradient = gradient_gonzalez
    integer :: metric = metric_nondimensional
    real(real64) :: dt = 0.15_real64                 !! the step, or the output interval [s]
    real(real64) :: t_end = 20.0_real64              !! [s]
    real(real64) :: newton_tol = 1.0e-8_real64       !! Newton's tolerance on the residual and the update
    integer :: newton_max_iterations = 50            !! per nonlinear solve
    !> The most accepted steps the whole run may take (continued parts included; rejected trial
    !> steps and substeps are not counted): a fixed-step plan above it is refused at input, an
    !> integrator that chooses its steps stops there (failure_kind 'step_budget').
    integer :: max_steps = default_step_budget
    real(real64) :: tolerance = 1.0e-10_real64       !! absolute and relative, per step, of every adaptive method
    !> The input set `tolerance`: the integrators with an error estimate but fixed steps by
    !> default (EME, the midpoint rule) control their steps, the relaxed ones test gamma.
    logical :: tolerance_given = .false.
  end type integrator_choice

contains

  !> Number of steps that cover [0, t_end]: the last time is the first n dt >= t_end
  !> (the paper's 20 s with dt = 0.15 s gives 134 steps ending at 20.1 s).
  !> A count beyond the 64-bit range (t_end/dt of 1e308) comes back as huge(1_int64).
  pure integer(int64) function step_count(choice)
    type(integrator_choice), intent(in) :: choice
    real(real64) :: ratio

    ratio = choice%t_end/choice%dt - 1.0e-9_real64
    if (ratio >= real(huge(1_int64), real64)) then
      step_count = huge(1_int64)
    else
      step_count = ceiling(ratio, int64)
    end if
  end function step_count

end module integrator_settings
