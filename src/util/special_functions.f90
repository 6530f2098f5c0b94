!> log1p and expm1 from the C library (Fortran has no intrinsic for them): ln(1 + x) and
!> exp(x) - 1 to full relative precision for small x, where the plain forms cancel.
module special_functions
  use, intrinsic :: iso_c_binding, only: c_double
  implicit none (type, external)
  private
  public :: log1p, expm1

  interface
    !> ln(1 + x).
    pure function log1p(x) result(y) bind(c, name='log1p')
      import :: c_double
      real(c_double), value :: x
      real(c_double) :: y
    end function log1p
    !> exp(x) - 1.
    pure function expm1(x) result(y) bind(c, name='expm1')
      import :: c_double
      real(c_double), value :: x
      real(c_double) :: y
    end function expm1
  end interface

end module special_functions
