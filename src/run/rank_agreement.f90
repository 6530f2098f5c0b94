!> How the ranks of a run split over them (src/run/distributed_simulation) come to one outcome:
!> rank 0 writes the file and meets its failures, and every rank takes them, so that every rank
!> returns the same failure, status and failure kind (and the drivers the same exit status).
module rank_agreement
  use mpi_f08, only: MPI_Comm, MPI_Comm_rank, MPI_Bcast, MPI_INTEGER, MPI_CHARACTER
  use run_outcome, only: run_summary
  use failures, only: failure_type, set_failure => fail
  implicit none (type, external)
  private
  public :: agree, share_outcome

contains

  !> Every rank takes rank 0's failure (and failure kind) when it has none of its own (rank 0's
  !> is the output's); collective on `comm`.
  subroutine agree(failure, summary, comm, input_file)
    type(failure_type), intent(inout) :: failure
    type(run_summary), intent(inout) :: summary
    type(MPI_Comm), intent(in) :: comm
    character(len=*), intent(in) :: input_file
    integer :: code, rank
    character(len=:), allocatable :: text, kind

    call MPI_Comm_rank(comm, rank)
    code = failure%code
    call MPI_Bcast(code, 1, MPI_INTEGER, 0, comm)
    if (code == 0) return
    text = ''
    if (rank == 0) text = failure%message
    call share_text(text, comm)
    kind = summary%failure_kind
    call share_text(kind, comm)
    if (rank /= 0 .and. .not. failure%failed()) then
      call set_failure(failure, code, text, input_file)
      summary%failure_kind = kind
    end if
  end subroutine agree

  !> Rank 0's status, note and failure kind on every rank (the exit status depends on them).
  subroutine share_outcome(summary, comm)
    type(run_summary), intent(inout) :: summary
    type(MPI_Comm), intent(in) :: comm

    call share_text(summary%status, comm)
    call share_text(summary%failure_kind, comm)
    call share_text(summary%note, comm)
  end subroutine share_outcome

  ! Rank 0's `text` on every rank.
  subroutine share_text(text, comm)
    character(len=:), allocatable, intent(inout) :: text
    type(MPI_Comm), intent(in) :: comm
    integer :: length, rank

    call MPI_Comm_rank(comm, rank)
    length = len(text)
    call MPI_Bcast(length, 1, MPI_INTEGER, 0, comm)
    if (rank /= 0) then
      deallocate (text)
      allocate (character(len=length) :: text)
    end if
    if (length > 0) call MPI_Bcast(text, length, MPI_CHARACTER, 0, comm)
  end subroutine share_text

end module rank_agreement
