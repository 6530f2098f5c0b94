!> The thermodynamic variables tau a model's subsystems can be written in (paper section 2.3,
!> docs/formulation.md section 3): every model names its choice by these constants, and the input
!> and the output by these spellings.
module thermo_variable_kinds
  implicit none (type, external)
  private
  public :: tau_entropy, tau_temperature, tau_internal_energy, thermo_variable_names

  integer, parameter :: tau_entropy = 1          !! tau = s
  integer, parameter :: tau_temperature = 2      !! tau = theta
  integer, parameter :: tau_internal_energy = 3  !! tau = u
  !> Namelist spellings, indexed by the constants above.
  character(len=*), parameter :: thermo_variable_names(3) = &
    [character(len=15) :: 'entropy', 'temperature', 'internal_energy']

end module thermo_variable_kinds
