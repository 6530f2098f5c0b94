!> What a PETSc TS runs as a run file records it (src/solver/solver_description): its type,
!> adaptivity, tolerances and step after the options database was applied, and for a method that
!> solves equations its SNES and linear solver. Shared by the dense path's TS baselines
!> (src/integrator/ts_stepper) and the chain's TS split over ranks
!> (src/model/spring_chain/spring_chain_ts_run).
module ts_description
#include <petsc/finclude/petscts.h>
  use petscts
  use solver_description, only: solver_report, add_setting, text_setting, number_setting
  use snes_description, only: describe_snes
  implicit none
  private
  public :: describe_ts

contains

  !> Adds the TS's settings to `report` under the name `name`; with `implicit`, its SNES's and
  !> linear solver's too (src/solver/snes_description; `ordering` the factorisation's ordering the
  !> caller set in code).
  subroutine describe_ts(ts, name, implicit, report, ierr, ordering)
    TS, intent(in) :: ts
    character(len=*), intent(in) :: name
    logical, intent(in) :: implicit
    type(solver_report), intent(inout) :: report
    PetscErrorCode, intent(out) :: ierr
    character(len=*), intent(in), optional :: ordering
    TSAdapt :: adapt
    SNES :: snes
    Vec :: vector_atol, vector_rtol
    PetscReal :: atol, rtol, dt
    character(len=32) :: ts_type, adapt_type

    PetscCall(TSGetType(ts, ts_type, ierr))
    PetscCall(TSGetAdapt(ts, adapt, ierr))
    PetscCall(TSAdaptGetType(adapt, adapt_type, ierr))
    PetscCall(TSGetTolerances(ts, atol, vector_atol, rtol, vector_rtol, ierr))
    PetscCall(TSGetTimeStep(ts, dt, ierr))
    call add_setting(report, text_setting('name', name))
    call add_setting(report, text_setting('ts_type', ts_type))
    call add_setting(report, text_setting('ts_adapt_type', adapt_type))
    call add_setting(report, number_setting('ts_atol', atol))
    call add_setting(report, number_setting('ts_rtol', rtol))
    call add_setting(report, number_setting('ts_dt', dt, 's'))
    if (.not. implicit) return
    PetscCall(TSGetSNES(ts, snes, ierr))
    PetscCall(describe_snes(snes, report, ierr, ordering))
  end subroutine describe_ts

end module ts_description
