!> What the chain's PETSc callbacks see on the sparse, distributed path (spring_chain_dmda): the
!> step's problem, the rank's part of the DMDA (its rows, its ghosted local vectors), the Jacobian's
!> coupling pattern (spring_chain_dmda_pattern) and the callbacks' buffers. A module of its own so
!> that the pattern, the assembly callbacks and the distributed chain share it; PETSc holds its
!> address, inside a distributed_chain.
module spring_chain_dmda_context
#include <petsc/finclude/petscdmda.h>
  use petscdmda
  use, intrinsic :: iso_fortran_env, only: real64
  use spring_chain_step, only: chain_step_problem
  implicit none
  private
  public :: chain_context, slice_points

  !> The points of a slice the callbacks evaluate at once (a few hundred kB of partials and band).
  integer, parameter :: slice_points = 128

  !> What the callbacks see (PETSc holds its address): the step's problem and the rank's part.
  type :: chain_context
    type(chain_step_problem) :: problem
    DM :: da
    Vec :: old_local               !! z_old on the rank's ghosted points
    Vec :: new_local               !! the iterate on the rank's ghosted points
    integer :: base = 0            !! the unknown before the ghosted part's first
    integer :: first_row = 1       !! the rank's rows (1-based unknowns), first .. last
    integer :: last_row = 0
    integer :: local_size = 0      !! the ghosted part's unknowns
    integer :: total = 0           !! every rank's unknowns (the DMDA's: point size x points)
    !> the step's tolerance on |R| (the input's newton_tol): options cannot loosen it, as on the
    !> dense path (a looser -snes_atol would accept the old state as the step's root)
    real(real64) :: newton_tol = 0.0_real64
    real(real64) :: update_floor = 0.0_real64   !! 16 eps |z_old|: updates below it are rounding
    !> pattern(v, w, o): unknown v of a point depends on unknown w of the point o further
    !> (coupling_pattern), v and w numbered as in a point holding a mass: (x, p, [gamma], [tau]).
    logical, allocatable :: pattern(:, :, :)
    !> What each slot of the last point holds in that numbering, 0 for an unused slot: a
    !> 'fixed-fixed' chain's point N + 1 holds spring N + 1's [gamma,] [tau] in its first slots.
    integer, allocatable :: last_point_slots(:)
    !> The pattern of a row of slot v at an interior point (two points from the first and three
    !> from the last): its interior_counts(v) columns relative to the point's first unknown,
    !> where they sit in the row's band (field_rows' storage) and which of them is the diagonal.
    integer, allocatable :: interior_columns(:, :), interior_counts(:), interior_band(:, :), interior_diagonal(:)
    !> -chain_check_pattern: the Jacobian callback fails when a block's derivative falls outside
    !> coupling_pattern (the pattern's test; it costs a pass over the band).
    logical :: check_pattern = .false.
    !> The Jacobian callback's buffers, sized once: a slice's rows of f and their band of df/dz,
    !> a row's columns and values.
    real(real64), allocatable :: rows(:), band(:, :), values(:)
    PetscInt, allocatable :: columns(:)
  end type chain_context

end module spring_chain_dmda_context
