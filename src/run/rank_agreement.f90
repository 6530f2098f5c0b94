!> How the ranks of a run split over them (src/run/distributed_simulation) come to one outcome:
!> rank 0 writes the file and meets its failures, any rank may meet one of its own part, and every
!> rank takes the failure of the lowest rank that has one, so that every rank returns the same
!> failure, status and failure kind (and the drivers the same exit status).
module rank_agreement
  use mpi_f08, only: MPI_Comm, MPI_Comm_rank, MPI_Bcast, MPI_Allreduce, MPI_IN_PLACE, MPI_MIN, MPI_INTEGER, MPI_CHARACTER
  use run_outcome, only: run_summary
  use failures, only: failure_type, set_failure => fail
  implicit none (type, external)
  private
  public :: agree, share_outcome

contains

  !> Every rank takes the failure (and failure kind) of the lowest rank that has one (rank 0's is
  !> the output's) when it has none of its own; collective on `comm`.
  subroutine agree(failure, summary, comm, input_file)
    type(failure_type), intent(inout) :: failure
    type(run_summary), intent(inout) :: summary
    type(MPI_Comm), intent(in) :: comm
    character(len=*), intent(in) :: input_file
    integer :: code, rank, failed_rank
    character(len=:), allocatable :: text, kind

    call MPI_Comm_rank(comm, rank)
    failed_rank = merge(rank, huge(rank), failure%failed())
    call MPI_Allreduce(MPI_IN_PLACE, failed_rank, 1, MPI_INTEGER, MPI_MIN, comm)
    if (failed_rank == huge(rank)) return
    code = failure%code
    call MPI_Bcast(code, 1, MPI_INTEGER, failed_rank, comm)
    text = ''
    if (rank == failed_rank) text = failure%message
    call share_text(text, comm, failed_rank)
    kind = summary%failure_kind
    call share_text(kind, comm, failed_rank)
    if (.not. failure%failed()) then
      call set_failure(failure, code, text, input_file)
      summary%failure_kind = kind
    end if
  end subroutine agree

  !> Rank 0's status, note and failure kind on every rank (the exit status depends on them).
  subroutine share_outcome(summary, comm)
    type(run_summary), intent(inout) :: summary
    type(MPI_Comm), intent(in) :: comm

    call share_text(summary%status, comm, 0)
    call share_text(summary%failure_kind, comm, 0)
    call share_text(summary%note, comm, 0)
  end subroutine share_outcome

  ! Rank `root`'s `text` on every rank.
  subroutine share_text(text, comm, root)
    character(len=:), allocatable, intent(inout) :: text
    type(MPI_Comm), intent(in) :: comm
    integer, intent(in) :: root
    integer :: length, rank

    call MPI_Comm_rank(comm, rank)
    length = len(text)
    call MPI_Bcast(length, 1, MPI_INTEGER, root, comm)
    if (rank /= root) then
      deallocate (text)
      allocate (character(len=length) :: text)
    end if
    if (length > 0) call MPI_Bcast(text, length, MPI_CHARACTER, root, comm)
  end subroutine share_text

end module rank_agreement
