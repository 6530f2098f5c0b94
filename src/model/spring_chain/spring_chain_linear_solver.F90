!> The chain's default linear solver (a step's Newton iterations on spring_chain_dmda, or a
!> PETSc TS's in spring_chain_ts_run): on one rank a direct factorisation (PETSc's LU, RCM order),
!> on several GMRES on block Jacobi with each rank's block so factored; the options may choose
!> others. A module of its own because the SNES of the steps and the TS both set it.
module spring_chain_linear_solver
#include <petsc/finclude/petscksp.h>
  use petscksp
  use, intrinsic :: iso_fortran_env, only: real64
  implicit none
  private
  public :: set_default_linear_solver, set_rounding_tolerance, settings_in_code

  !> The factorisation's ordering set_default_linear_solver sets in code on one rank.
  character(len=*), parameter :: one_rank_ordering = MATORDERINGRCM

contains

  !> The chain's default linear solver on `comm` for `ksp` (a step's Newton iterations, or a
  !> TS's): on one rank a direct factorisation (PETSc's LU, RCM order), on several GMRES on
  !> block Jacobi with each rank's block so factored; the options may choose others.
  subroutine set_default_linear_solver(ksp, comm, ierr)
    KSP, intent(in) :: ksp
    MPI_Comm, intent(in) :: comm
    PetscErrorCode, intent(out) :: ierr
    PC :: pc
    PetscMPIInt :: ranks

    PetscCall(KSPGetPC(ksp, pc, ierr))
    PetscCall(MPI_Comm_size(comm, ranks, ierr))
    if (ranks == 1) then
      PetscCall(KSPSetType(ksp, KSPPREONLY, ierr))
      PetscCall(PCSetType(pc, PCLU, ierr))
      ! Reverse Cuthill-McKee keeps the chain's factors banded; PETSc's default nested dissection
      ! cost more to order (0.16 s at 4e4 unknowns) and factored 1.4 times slower.
      PetscCall(PCFactorSetMatOrderingType(pc, one_rank_ordering, ierr))
    else
      ! Each rank factors its own diagonal block (block Jacobi, LU in RCM order: the sub-PC's
      ! options unless given) and GMRES mends the couplings across
      ! the cuts, a few columns per cut: 6 to 8 iterations a Newton step at 4e4 unknowns on 2
      ! ranks. MUMPS on 2 ranks executed 2.1 to 2.4 times one rank's instructions per rank
      ! (its analysis, its factorisation's load messages); this 0.63 (callgrind, 2 steps).
      ! The solve is tight (1e-12 relative), so Newton takes the direct solver's iterates.
      PetscCall(KSPSetType(ksp, KSPGMRES, ierr))
      PetscCall(KSPSetTolerances(ksp, 1.0e-12_real64, 0.0_real64, PETSC_DEFAULT_REAL, PETSC_DEFAULT_INTEGER, ierr))
      PetscCall(PCSetType(pc, PCBJACOBI, ierr))
      PetscCall(default_option('-sub_pc_type', 'lu', ierr))
      PetscCall(default_option('-sub_pc_factor_mat_ordering_type', 'rcm', ierr))
    end if
  end subroutine set_default_linear_solver

  !> On several ranks (GMRES by default) the solve also stops at the rounding of the unknowns: an
  !> absolute tolerance `floor` (eps |z| for a step) on the preconditioned residual, which block
  !> Jacobi's exact blocks make about the update's error, unless -ksp_atol is given. Without it the
  !> last Newton iterations, whose right-hand side is near the rounding floor, asked GMRES for 1e-12
  !> of it: 7, 35 and 33 iterations in the first step at 1e5 springs on 2 ranks, 6, 3 and 1 with it
  !> (the same Newton iterations, E to 4e-17).
  subroutine set_rounding_tolerance(ksp, floor, ierr)
    KSP, intent(in) :: ksp
    real(real64), intent(in) :: floor
    PetscErrorCode, intent(out) :: ierr
    PetscReal :: rtol, atol, dtol
    PetscInt :: max_iterations
    PetscMPIInt :: ranks
    PetscBool :: given
    MPI_Comm :: comm

    PetscCall(PetscObjectGetComm(ksp, comm, ierr))
    PetscCall(MPI_Comm_size(comm, ranks, ierr))
    if (ranks == 1) return
    PetscCall(PetscOptionsHasName(PETSC_NULL_OPTIONS, PETSC_NULL_CHARACTER, '-ksp_atol', given, ierr))
    if (given) return
    PetscCall(KSPGetTolerances(ksp, rtol, atol, dtol, max_iterations, ierr))
    PetscCall(KSPSetTolerances(ksp, rtol, floor, dtol, max_iterations, ierr))
  end subroutine set_rounding_tolerance

  !> What this module sets in code, not in the options database, for `ksp`, as a run
  !> file records it (src/solver/snes_description): the factorisation's ordering on one rank
  !> (blank on several: the blocks' is an option), and whether set_rounding_tolerance sets the
  !> linear solves' absolute tolerance (on several ranks, unless -ksp_atol is given).
  subroutine settings_in_code(ksp, ordering, floor_set, ierr)
    KSP, intent(in) :: ksp
    character(len=:), allocatable, intent(out) :: ordering
    logical, intent(out) :: floor_set
    PetscErrorCode, intent(out) :: ierr
    PetscMPIInt :: ranks
    PetscBool :: given
    MPI_Comm :: comm

    ordering = ''
    floor_set = .false.
    PetscCall(PetscObjectGetComm(ksp, comm, ierr))
    PetscCall(MPI_Comm_size(comm, ranks, ierr))
    if (ranks == 1) then
      ordering = one_rank_ordering
      return
    end if
    PetscCall(PetscOptionsHasName(PETSC_NULL_OPTIONS, PETSC_NULL_CHARACTER, '-ksp_atol', given, ierr))
    floor_set = .not. given
  end subroutine settings_in_code

  ! Sets PETSc option `name` to `value` unless the options give it.
  subroutine default_option(name, value, ierr)
    character(len=*), intent(in) :: name, value
    PetscErrorCode, intent(out) :: ierr
    PetscBool :: given

    PetscCall(PetscOptionsHasName(PETSC_NULL_OPTIONS, PETSC_NULL_CHARACTER, name, given, ierr))
    if (.not. given) then
      PetscCall(PetscOptionsSetValue(PETSC_NULL_OPTIONS, name, value, ierr))
      ! Looked up once, it counts as used: a run that stops before its first solve (a refused
      ! -eme_continue) does not warn of options the user never gave.
      PetscCall(PetscOptionsHasName(PETSC_NULL_OPTIONS, PETSC_NULL_CHARACTER, name, given, ierr))
    end if
  end subroutine default_option

end module spring_chain_linear_solver
