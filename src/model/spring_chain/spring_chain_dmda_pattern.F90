!> The sparse pattern of the chain's Jacobian on the DMDA (docs/formulation.md section 10, "Sparse
!> and distributed"): which entries of dR/dz the blocks can make nonzero (coupling_pattern: 26 of
!> the stencil's 80 entries per point in 1D, 80 of 320 in 3D), each row's columns in it, where an
!> interior row's entries sit in the band that field_rows fills, and the AIJ matrix preallocated
!> with exactly these entries. Apart from the assembly (spring_chain_dmda_assembly), which reads
!> what is set here every Newton iteration, because the pattern is made once per chain.
module spring_chain_dmda_pattern
#include <petsc/finclude/petscmat.h>
  use petscmat
  use, intrinsic :: iso_fortran_env, only: real64
  use spring_chain_layout, only: chain_layout
  use spring_chain_dmda_context, only: chain_context
  implicit none
  private
  public :: hold_pattern, pattern_columns, create_jacobian_matrix

contains

  !> Sets the context's coupling pattern for its problem's layout of `dof` unknowns a point (after
  !> its problem and rows): the pattern, what the last point's slots hold, and the columns of an
  !> interior point's rows with their places in the band.
  subroutine hold_pattern(context, dof)
    type(chain_context), intent(inout) :: context
    integer, intent(in) :: dof
    integer :: k, o, w

    allocate (context%pattern(dof, dof, -2:2))      ! the bounds the assignment keeps
    context%pattern = coupling_pattern(context%problem%layout)
    context%last_point_slots = [(k, k=1, dof)]
    if (context%problem%layout%fixed_fixed) then
      context%last_point_slots = 0
      context%last_point_slots(1:context%problem%layout%invariant_count - 1) = [(k, k=2*context%problem%layout%dimension + 1, dof)]
    end if
    allocate (context%interior_columns(size(context%pattern(1, :, :)), dof), context%interior_counts(dof))
    allocate (context%interior_band, mold=context%interior_columns)
    allocate (context%interior_diagonal(dof))
    context%interior_counts = 0
    do k = 1, dof
      do o = -2, 2
        do w = 1, dof
          if (.not. context%pattern(k, w, o)) cycle
          context%interior_counts(k) = context%interior_counts(k) + 1
          associate (j => context%interior_counts(k))
            context%interior_columns(j, k) = o*dof + w - 1
            ! band(c - g + half + 1, .) for row g = point start + k, column c = point start + that - 1 (1-based)
            context%interior_band(j, k) = o*dof + w - k + context%problem%band_half_width() + 1
            if (o == 0 .and. w == k) context%interior_diagonal(k) = j
          end associate
        end do
      end do
    end do
  end subroutine hold_pattern

  ! Which entries of dR/dz can be nonzero, from the blocks of spring_chain_blocks (docs/
  ! formulation.md section 10), point k holding (x_k, p_k, [gamma_k], [tau_k]) and spring k
  ! joining masses k - 1 and k: pattern(v, w, o) is true when row v of point k depends on
  ! unknown w of point k + o.
  !  - every unknown (I/h); x_k on p_k (v = p/m, the same component);
  !  - p_k on the forces of springs k and k + 1: on x_{k-1}, x_k, x_{k+1} (every component,
  !    through C) and on gamma, tau of points k and k + 1;
  !  - gamma_k on spring k: x_{k-1}, x_k, gamma_k, tau_k;
  !  - tau_k on spring k (x_{k-1}, x_k, p_{k-1}, p_k, gamma_k, tau_k) and on links (k-1, k) and
  !    (k, k+1): x_{k-2} .. x_{k+1}, gamma and tau of points k - 1 .. k + 1.
  pure function coupling_pattern(layout) result(pattern)
    type(chain_layout), intent(in) :: layout
    logical :: pattern(layout%point_size(), layout%point_size(), -2:2)
    integer :: d, c, x(layout%dimension), p(layout%dimension), own(layout%invariant_count - 1)

    d = layout%dimension
    x = [(c, c=1, d)]
    p = [(d + c, c=1, d)]
    own = [(c, c=2*d + 1, layout%point_size())]        ! [gamma,] [tau]
    pattern = .false.
    do c = 1, layout%point_size()
      pattern(c, c, 0) = .true.
    end do
    do c = 1, d
      pattern(x(c), p(c), 0) = .true.
    end do
    pattern(p, x, -1:1) = .true.
    pattern(p, own, 0:1) = .true.
    if (layout%invariant_count == 3) then
      pattern(own(1), x, -1:0) = .true.
      pattern(own(1), own, 0) = .true.
    end if
    if (layout%invariant_count >= 2) then
      associate (tau => layout%point_size())
        pattern(tau, x, -2:1) = .true.
        pattern(tau, p, -1:0) = .true.
        pattern(tau, own, -1:1) = .true.
      end associate
    end if
  end function coupling_pattern

  ! Row `row`'s (1-based) columns in coupling_pattern (0-based, ascending, within the points);
  ! an unused slot's row has its diagonal alone.
  subroutine pattern_columns(context, row, columns, count)
    type(chain_context), intent(in) :: context
    integer, intent(in) :: row
    PetscInt, intent(out) :: columns(:)
    PetscInt, intent(out) :: count
    integer :: dof, points, point, v, o, w

    dof = size(context%pattern, 1)
    points = context%total/dof
    point = (row - 1)/dof + 1
    if (point >= 3 .and. point <= points - 3) then
      v = row - (point - 1)*dof
      count = context%interior_counts(v)
      columns(1:count) = (point - 1)*dof + context%interior_columns(1:count, v)
      return
    end if
    v = slot_kind(point, row - (point - 1)*dof)
    count = 0
    if (v == 0) then
      count = 1
      columns(1) = row - 1
      return
    end if
    do o = max(-2, 1 - point), min(2, points - point)
      do w = 1, dof
        if (slot_kind(point + o, w) == 0) cycle
        if (.not. context%pattern(v, slot_kind(point + o, w), o)) cycle
        count = count + 1
        columns(count) = (point + o - 1)*dof + w - 1
      end do
    end do

  contains

    ! What slot `slot` of point `k` holds, in a mass point's numbering (0: unused).
    pure integer function slot_kind(k, slot)
      integer, intent(in) :: k, slot

      slot_kind = slot
      if (k == points) slot_kind = context%last_point_slots(slot)
    end function slot_kind
  end subroutine pattern_columns

  ! The Jacobian's matrix: AIJ with the rank's rows, preallocated with coupling_pattern's entries
  ! exactly and assembled with them (zeros), so that a later insertion outside them is an error.
  subroutine create_jacobian_matrix(context, comm, matrix, ierr)
    type(chain_context), intent(inout) :: context
    MPI_Comm, intent(in) :: comm
    Mat, intent(out) :: matrix
    PetscErrorCode, intent(out) :: ierr
    PetscInt, allocatable :: diagonal_counts(:), off_counts(:)
    PetscInt :: owned, total, entries, zero, one, row_index(1)
    integer :: row

    owned = context%last_row - context%first_row + 1
    total = context%total
    allocate (diagonal_counts(owned), off_counts(owned))
    do row = context%first_row, context%last_row
      call pattern_columns(context, row, context%columns, entries)
      diagonal_counts(row - context%first_row + 1) = count(context%columns(1:entries) >= context%first_row - 1 .and. &
                                                           context%columns(1:entries) <= context%last_row - 1)
      off_counts(row - context%first_row + 1) = entries - diagonal_counts(row - context%first_row + 1)
    end do
    zero = 0
    PetscCall(MatCreate(comm, matrix, ierr))
    PetscCall(MatSetSizes(matrix, owned, owned, total, total, ierr))
    PetscCall(MatSetType(matrix, MATAIJ, ierr))
    PetscCall(MatSeqAIJSetPreallocation(matrix, zero, diagonal_counts, ierr))
    PetscCall(MatMPIAIJSetPreallocation(matrix, zero, diagonal_counts, zero, off_counts, ierr))
    one = 1
    context%values = 0.0_real64
    do row = context%first_row, context%last_row
      call pattern_columns(context, row, context%columns, entries)
      row_index(1) = row - 1
      PetscCall(MatSetValues(matrix, one, row_index, entries, context%columns, context%values, INSERT_VALUES, ierr))
    end do
    PetscCall(MatAssemblyBegin(matrix, MAT_FINAL_ASSEMBLY, ierr))
    PetscCall(MatAssemblyEnd(matrix, MAT_FINAL_ASSEMBLY, ierr))
    PetscCall(MatSetOption(matrix, MAT_NEW_NONZERO_LOCATION_ERR, PETSC_TRUE, ierr))
    ! Each rank sets its own rows only: the assemblies skip the exchange of other ranks' entries
    ! (PetscCommBuildTwoSided, a synchronisation of the ranks at every assembly: on 2 ranks at 1e4
    ! springs it was up to 1.6 % of one rank's instructions in the loop, mostly waiting).
    PetscCall(MatSetOption(matrix, MAT_NO_OFF_PROC_ENTRIES, PETSC_TRUE, ierr))
  end subroutine create_jacobian_matrix

end module spring_chain_dmda_pattern
