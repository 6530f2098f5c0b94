!> What a PETSc TS runs as a run file records it (src/solver/solver_description): its type,
!> adaptivity, tolerances and step after the options database was applied, and for a method that
!> solves equations its SNES and linear solver. Shared by the dense path's TS baselines
!> (src/integrator/ts_stepper) and the chain's TS split over ranks
!> (src/model/spring_chain/spring_chain_ts_run).
module ts_description
#include <petsc/finclude/petscts.h>
  use petscts
  use solver_description, only: solver_report, add_setting, text_setting, number_setting, integer_setting
  implicit none
  private
  public :: describe_ts

contains

  !> Adds the TS's settings to `report` under the name `name`; with `implicit`, its SNES's and
  !> linear solver's too.
  subroutine describe_ts(ts, name, implicit, report, ierr)
    TS, intent(in) :: ts
    character(len=*), intent(in) :: name
    logical, intent(in) :: implicit
    type(solver_report), intent(inout) :: report
    PetscErrorCode, intent(out) :: ierr
    TSAdapt :: adapt
    SNES :: snes
    KSP :: ksp
    PC :: pc
    Vec :: vector_atol, vector_rtol
    PetscReal :: atol, rtol, stol, dt
    PetscInt :: max_iterations, max_evaluations
    character(len=32) :: ts_type, adapt_type, snes_type, ksp_type, pc_type

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
    PetscCall(SNESGetType(snes, snes_type, ierr))
    PetscCall(SNESGetTolerances(snes, atol, rtol, stol, max_iterations, max_evaluations, ierr))
    PetscCall(SNESGetKSP(snes, ksp, ierr))
    PetscCall(KSPGetType(ksp, ksp_type, ierr))
    PetscCall(KSPGetPC(ksp, pc, ierr))
    PetscCall(PCGetType(pc, pc_type, ierr))
    call add_setting(report, text_setting('snes_type', snes_type))
    call add_setting(report, number_setting('snes_atol', atol))
    call add_setting(report, number_setting('snes_rtol', rtol))
    call add_setting(report, number_setting('snes_stol', stol))
    call add_setting(report, integer_setting('snes_max_it', max_iterations))
    call add_setting(report, text_setting('ksp_type', ksp_type))
    call add_setting(report, text_setting('pc_type', pc_type))
  end subroutine describe_ts

end module ts_description
