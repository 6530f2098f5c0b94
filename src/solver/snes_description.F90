!> What a PETSc SNES and its linear solver are, as a run file records them (src/solver/
!> solver_description, docs/output.md): the Newton method's type and tolerances, and the KSP and PC
!> with theirs, after the options database was applied. Shared by the PETSc TS baselines
!> (ts_description) and the spring chain's steps split over ranks (src/model/spring_chain/
!> spring_chain_sparse_run), whose linear solver the options may choose.
module snes_description
#include <petsc/finclude/petscsnes.h>
  use petscsnes
  use solver_description, only: solver_report, add_setting, text_setting, number_setting, integer_setting
  implicit none
  private
  public :: describe_snes

contains

  !> Adds `snes`'s settings to `report`: snes_type, its tolerances, iteration limit, Jacobian lag
  !> and line search, then ksp_type, ksp_rtol, ksp_atol, ksp_max_it and pc_type; for a
  !> factorisation its ordering and package (pc_factor_*), for block Jacobi the blocks' solver
  !> (sub_ksp_type, sub_pc_type, sub_pc_factor_*) as the options database gives them, the
  !> factorisation's ordering `ordering` where the caller set it in code and no option replaced it
  !> (none when blank); `atol_rule`, unless blank, stands for ksp_atol where the caller sets it at
  !> each solve, and `line_search` for the line search's type where the caller's shell stands in
  !> for a named one (src/solver/snes_solver).
  subroutine describe_snes(snes, report, ierr, ordering, atol_rule, line_search)
    SNES, intent(in) :: snes
    type(solver_report), intent(inout) :: report
    PetscErrorCode, intent(out) :: ierr
    character(len=*), intent(in), optional :: ordering, atol_rule, line_search
    KSP :: ksp
    PC :: pc
    SNESLineSearch :: search
    PetscReal :: atol, rtol, stol, divergence
    PetscInt :: max_iterations, max_evaluations, lag
    character(len=32) :: snes_type, line_search_type, ksp_type, pc_type

    PetscCall(SNESGetType(snes, snes_type, ierr))
    PetscCall(SNESGetTolerances(snes, atol, rtol, stol, max_iterations, max_evaluations, ierr))
    PetscCall(SNESGetLagJacobian(snes, lag, ierr))
    PetscCall(SNESGetLineSearch(snes, search, ierr))
    PetscCall(SNESLineSearchGetType(search, line_search_type, ierr))
    call add_setting(report, text_setting('snes_type', snes_type))
    call add_setting(report, number_setting('snes_atol', atol))
    call add_setting(report, number_setting('snes_rtol', rtol))
    call add_setting(report, number_setting('snes_stol', stol))
    call add_setting(report, integer_setting('snes_max_it', max_iterations))
    call add_setting(report, integer_setting('snes_lag_jacobian', lag))
    if (.not. blank(line_search)) line_search_type = line_search
    call add_setting(report, text_setting('snes_linesearch_type', line_search_type))
    PetscCall(SNESGetKSP(snes, ksp, ierr))
    PetscCall(KSPGetType(ksp, ksp_type, ierr))
    PetscCall(KSPGetTolerances(ksp, rtol, atol, divergence, max_iterations, ierr))
    PetscCall(KSPGetPC(ksp, pc, ierr))
    PetscCall(PCGetType(pc, pc_type, ierr))
    call add_setting(report, text_setting('ksp_type', ksp_type))
    if (ksp_type /= KSPPREONLY) then
      call add_setting(report, number_setting('ksp_rtol', rtol))
      if (blank(atol_rule)) then
        call add_setting(report, number_setting('ksp_atol', atol))
      else
        call add_setting(report, text_setting('ksp_atol', atol_rule))
      end if
      call add_setting(report, integer_setting('ksp_max_it', max_iterations))
    end if
    call add_setting(report, text_setting('pc_type', pc_type))
    if (pc_type == PCLU .or. pc_type == PCILU .or. pc_type == PCCHOLESKY .or. pc_type == PCICC) then
      PetscCall(add_option(report, '-pc_factor_mat_ordering_type', ierr, ordering))
      PetscCall(add_option(report, '-pc_factor_mat_solver_type', ierr))
    else if (pc_type == PCBJACOBI .or. pc_type == PCASM) then
      PetscCall(add_option(report, '-sub_ksp_type', ierr))
      PetscCall(add_option(report, '-sub_pc_type', ierr))
      PetscCall(add_option(report, '-sub_pc_factor_mat_ordering_type', ierr))
      PetscCall(add_option(report, '-sub_pc_factor_mat_solver_type', ierr))
    end if
  end subroutine describe_snes

  ! Adds option `name`'s value (its name without the dash) when the options database holds one (a
  ! default the code set there, as spring_chain_linear_solver does, or the command line's), else
  ! `otherwise` if present and not blank.
  subroutine add_option(report, name, ierr, otherwise)
    type(solver_report), intent(inout) :: report
    character(len=*), intent(in) :: name
    PetscErrorCode, intent(out) :: ierr
    character(len=*), intent(in), optional :: otherwise
    character(len=64) :: value
    PetscBool :: given

    PetscCall(PetscOptionsGetString(PETSC_NULL_OPTIONS, PETSC_NULL_CHARACTER, name, value, given, ierr))
    if (given) then
      call add_setting(report, text_setting(name(2:), value))
    else if (.not. blank(otherwise)) then
      call add_setting(report, text_setting(name(2:), otherwise))
    end if
  end subroutine add_option

  ! Whether an optional text is absent or blank.
  pure logical function blank(text)
    character(len=*), intent(in), optional :: text

    blank = .true.
    if (present(text)) blank = len_trim(text) == 0
  end function blank

end module snes_description
