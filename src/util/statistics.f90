!> Order statistics of timings: the median of repeated measurements (benchmarks report medians,
!> as docs/performance.md explains).
module statistics
  use, intrinsic :: iso_fortran_env, only: real64
  implicit none (type, external)
  private
  public :: median

contains

  !> The median of `values` (the mean of the two middle values for an even count).
  pure function median(values) result(m)
    real(real64), intent(in) :: values(:)
    real(real64) :: m, sorted(size(values)), swap
    integer :: i, j

    sorted = values
    do i = 2, size(sorted)        ! insertion sort: a handful of repeats
      swap = sorted(i)
      j = i - 1
      do while (j >= 1)
        if (sorted(j) <= swap) exit
        sorted(j + 1) = sorted(j)
        j = j - 1
      end do
      sorted(j + 1) = swap
    end do
    m = 0.5_real64*(sorted((size(sorted) + 1)/2) + sorted(size(sorted)/2 + 1))
  end function median

end module statistics
