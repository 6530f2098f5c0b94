!> A PETSc vector's n entries as a Fortran array pointer, lent and given back through PETSc's C
!> accessors (src/solver/vector_access.c) instead of its Fortran ones, which build an array
!> descriptor per call (docs/performance.md, "Issue 22's four ratios"). The vector is passed as
!> PETSc's Fortran interfaces pass it; no PETSc module is needed here.
module vector_arrays
  use, intrinsic :: iso_fortran_env, only: real64
  use, intrinsic :: iso_c_binding, only: c_int, c_ptr, c_loc, c_f_pointer
  implicit none (type, external)
  private
  public :: borrow, give_back, borrow_read, give_back_read

  interface
    integer(c_int) function eme_vec_get_array(vector, values) bind(C, name='eme_vec_get_array')
      import :: c_int, c_ptr
      type(*), intent(in) :: vector
      type(c_ptr), intent(out) :: values
    end function eme_vec_get_array
    integer(c_int) function eme_vec_restore_array(vector, values) bind(C, name='eme_vec_restore_array')
      import :: c_int, c_ptr
      type(*), intent(in) :: vector
      type(c_ptr), intent(inout) :: values
    end function eme_vec_restore_array
    integer(c_int) function eme_vec_get_array_read(vector, values) bind(C, name='eme_vec_get_array_read')
      import :: c_int, c_ptr
      type(*), intent(in) :: vector
      type(c_ptr), intent(out) :: values
    end function eme_vec_get_array_read
    integer(c_int) function eme_vec_restore_array_read(vector, values) bind(C, name='eme_vec_restore_array_read')
      import :: c_int, c_ptr
      type(*), intent(in) :: vector
      type(c_ptr), intent(inout) :: values
    end function eme_vec_restore_array_read
  end interface

contains

  !> The vector's n entries, to read and write; ierr is PETSc's.
  subroutine borrow(vector, n, values, ierr)
    type(*), intent(in) :: vector
    integer, intent(in) :: n
    real(real64), pointer, intent(out) :: values(:)
    integer, intent(out) :: ierr
    type(c_ptr) :: address

    ierr = eme_vec_get_array(vector, address)
    if (ierr == 0) call c_f_pointer(address, values, [n])
  end subroutine borrow

  !> Gives back what borrow lent (the vector's state then records the change).
  subroutine give_back(vector, values, ierr)
    type(*), intent(in) :: vector
    real(real64), pointer, intent(inout) :: values(:)
    integer, intent(out) :: ierr
    type(c_ptr) :: address

    address = c_loc(values)
    ierr = eme_vec_restore_array(vector, address)
    nullify (values)
  end subroutine give_back

  !> The vector's n entries, to read only.
  subroutine borrow_read(vector, n, values, ierr)
    type(*), intent(in) :: vector
    integer, intent(in) :: n
    real(real64), pointer, intent(out) :: values(:)
    integer, intent(out) :: ierr
    type(c_ptr) :: address

    ierr = eme_vec_get_array_read(vector, address)
    if (ierr == 0) call c_f_pointer(address, values, [n])
  end subroutine borrow_read

  !> Gives back what borrow_read lent.
  subroutine give_back_read(vector, values, ierr)
    type(*), intent(in) :: vector
    real(real64), pointer, intent(inout) :: values(:)
    integer, intent(out) :: ierr
    type(c_ptr) :: address

    address = c_loc(values)
    ierr = eme_vec_restore_array_read(vector, address)
    nullify (values)
  end subroutine give_back_read

end module vector_arrays
