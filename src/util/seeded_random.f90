!> Reproducible pseudorandom numbers for inputs (a seeded perturbation of an initial state): the
!> SplitMix64 generator of src/util/splitmix64.c, which gives the same numbers from the same seed
!> on every machine and compiler (a compiler's random_number does not promise that).
module seeded_random
  use, intrinsic :: iso_fortran_env, only: real64
  use, intrinsic :: iso_c_binding, only: c_double, c_int64_t, c_long
  implicit none (type, external)
  private
  public :: uniform_numbers

  interface
    pure subroutine c_splitmix64_uniform(seed, count, values) bind(c, name='eme_splitmix64_uniform')
      import :: c_double, c_int64_t, c_long
      integer(c_int64_t), value, intent(in) :: seed
      integer(c_long), value, intent(in) :: count
      real(c_double), intent(out) :: values(*)
    end subroutine c_splitmix64_uniform
  end interface

contains

  !> The first `count` numbers in [0, 1) of SplitMix64 from `seed` (>= 0: the generator's state).
  pure function uniform_numbers(seed, count) result(values)
    integer, intent(in) :: seed, count
    real(real64) :: values(count)

    if (count > 0) call c_splitmix64_uniform(int(seed, c_int64_t), int(count, c_long), values)
  end function uniform_numbers

end module seeded_random
