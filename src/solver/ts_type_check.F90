!> Which PETSc TS types can integrate the engine's models: PETSc is given z' = f(z) and its Jacobian
!> df/dz (TSSetRHSFunction, TSSetRHSJacobian) and nothing else. PETSc 3.18 also offers types that
!> need more of the problem; without it alpha2, discgrad and mimex crash inside their first step (a
!> segmentation fault, PETSc's traceback, a file left `incomplete: running`) and mprk and
!> basicsymplectic stop there. Such a type is refused when the integrator is set up, before anything
!> is written. Shared by the dense path's TS baselines (src/integrator/ts_stepper) and the chain's TS
!> split over ranks (src/model/spring_chain/spring_chain_ts_run).
module ts_type_check
#include <petsc/finclude/petscts.h>
  use petscts
  use failures, only: failure_type, fail, failure_input
  implicit none
  private
  public :: refuse_other_problem_forms

contains

  !> A failure (failure_input) naming -ts_type and what it needs when `ts`'s type, after the
  !> options, needs a form of the problem that the engine does not give PETSc.
  subroutine refuse_other_problem_forms(ts, failure)
    TS, intent(in) :: ts
    type(failure_type), intent(inout) :: failure
    character(len=32) :: ts_type
    character(len=:), allocatable :: needs
    PetscErrorCode :: ierr

    call TSGetType(ts, ts_type, ierr)
    if (ierr /= 0) return
    select case (trim(ts_type))
    case ('alpha2')
      needs = 'a second-order equation (TSSetI2Function)'
    case ('discgrad')
      needs = 'its own discrete-gradient formulation (TSDiscGradSetFormulation)'
    case ('mimex')
      needs = 'an implicit part of the equations (TSSetIFunction)'
    case ('mprk')
      needs = 'the right-hand side split into slow and fast parts (TSRHSSplitSetIS)'
    case ('basicsymplectic')
      needs = 'the right-hand side split into positions and momenta (TSRHSSplitSetIS)'
    case default
      return
    end select
    call fail(failure, failure_input, '-ts_type '//trim(ts_type)//' is not allowed: PETSc''s '//trim(ts_type)// &
              ' needs '//needs//', and the engine gives PETSc dz/dt = f(z) and df/dz only; allowed: a TS type '// &
              'for dz/dt = f(z), such as bdf, theta, cn, beuler, alpha, arkimex, rosw, eimex, rk, ssp, euler', 'ts_type')
  end subroutine refuse_other_problem_forms

end module ts_type_check
