!> A table as one HDF5 compound dataset (src/io/compound_table.c): h5py loads it in one call as a
!> numpy structured array. Columns are real64, integer or fixed-length text.
module hdf5_table
  use, intrinsic :: iso_fortran_env, only: real64
  use, intrinsic :: iso_c_binding, only: c_char, c_int, c_long, c_double, c_int64_t, c_null_char
  use hdf5, only: hid_t
  implicit none (type, external)
  private
  public :: table_columns, column_real, column_integer, table_rows

  integer, parameter :: column_real = 0      !! width of a real64 column
  integer, parameter :: column_integer = -1  !! width of an integer column

  !> The columns of a table: names and widths (column_real, column_integer, or a text length).
  type :: table_columns
    character(len=:), allocatable :: names   !! each name followed by a newline
    integer(c_int), allocatable :: widths(:)
  contains
    procedure :: add
    procedure :: create
    procedure :: write_row
    procedure :: read_row
  end type table_columns

  interface
    function c_table_create(file, name, count, names, widths, rows) result(status) bind(c, name='eme_table_create')
      import :: c_int64_t, c_char, c_int, c_long
      integer(c_int64_t), value :: file
      character(kind=c_char), intent(in) :: name(*), names(*)
      integer(c_int), value :: count
      integer(c_int), intent(in) :: widths(*)
      integer(c_long), value :: rows
      integer(c_int) :: status
    end function c_table_create
    function c_table_write_row(file, name, count, names, widths, row, numbers, texts) result(status) &
        bind(c, name='eme_table_write_row')
      import :: c_int64_t, c_char, c_int, c_long, c_double
      integer(c_int64_t), value :: file
      character(kind=c_char), intent(in) :: name(*), names(*), texts(*)
      integer(c_int), value :: count
      integer(c_int), intent(in) :: widths(*)
      integer(c_long), value :: row
      real(c_double), intent(in) :: numbers(*)
      integer(c_int) :: status
    end function c_table_write_row
    function c_table_read_row(file, name, count, names, widths, row, numbers, texts, capacity) result(status) &
        bind(c, name='eme_table_read_row')
      import :: c_int64_t, c_char, c_int, c_long, c_double
      integer(c_int64_t), value :: file
      character(kind=c_char), intent(in) :: name(*), names(*)
      character(kind=c_char), intent(out) :: texts(*)
      integer(c_int), value :: count
      integer(c_int), intent(in) :: widths(*)
      integer(c_long), value :: row, capacity
      real(c_double), intent(out) :: numbers(*)
      integer(c_int) :: status
    end function c_table_read_row
    function c_table_rows(file, name) result(rows) bind(c, name='eme_table_rows')
      import :: c_int64_t, c_char, c_long
      integer(c_int64_t), value :: file
      character(kind=c_char), intent(in) :: name(*)
      integer(c_long) :: rows
    end function c_table_rows
  end interface

contains

  !> Number of rows of table `name` in the open file, or -1 if there is none.
  integer function table_rows(file, name)
    integer(hid_t), intent(in) :: file
    character(len=*), intent(in) :: name

    table_rows = int(c_table_rows(int(file, c_int64_t), name//c_null_char))
  end function table_rows

  !> Appends a column.
  subroutine add(self, name, width)
    class(table_columns), intent(inout) :: self
    character(len=*), intent(in) :: name
    integer, intent(in) :: width

    if (.not. allocated(self%names)) then
      self%names = ''
      allocate (self%widths(0))
    end if
    self%names = self%names//name//new_line('a')
    self%widths = [self%widths, int(width, c_int)]
  end subroutine add

  !> Creates dataset `name` of `rows` empty rows in the open file `file`.
  subroutine create(self, file, name, rows, stat)
    class(table_columns), intent(in) :: self
    integer(hid_t), intent(in) :: file
    character(len=*), intent(in) :: name
    integer, intent(in) :: rows
    integer, intent(out) :: stat

    stat = int(c_table_create(int(file, c_int64_t), name//c_null_char, size(self%widths, kind=c_int), &
                              self%names//c_null_char, self%widths, int(rows, c_long)))
  end subroutine create

  !> Writes row `row` (1-based): numbers in column order, texts in column order.
  subroutine write_row(self, file, name, row, numbers, texts, stat)
    class(table_columns), intent(in) :: self
    integer(hid_t), intent(in) :: file
    character(len=*), intent(in) :: name
    integer, intent(in) :: row
    real(real64), intent(in) :: numbers(:)
    character(len=*), intent(in) :: texts(:)
    integer, intent(out) :: stat
    character(len=:), allocatable :: joined
    integer :: i

    joined = ''
    do i = 1, size(texts)
      joined = joined//trim(texts(i))//new_line('a')
    end do
    stat = int(c_table_write_row(int(file, c_int64_t), name//c_null_char, size(self%widths, kind=c_int), &
                                 self%names//c_null_char, self%widths, int(row - 1, c_long), numbers, &
                                 joined//c_null_char))
  end subroutine write_row

  !> Reads row `row` (1-based) into numbers and texts.
  subroutine read_row(self, file, name, row, numbers, texts, stat)
    class(table_columns), intent(in) :: self
    integer(hid_t), intent(in) :: file
    character(len=*), intent(in) :: name
    integer, intent(in) :: row
    real(real64), intent(out) :: numbers(:)
    character(len=*), intent(out) :: texts(:)
    integer, intent(out) :: stat
    character(len=4096) :: joined
    integer :: i, start, finish

    joined = ''
    stat = int(c_table_read_row(int(file, c_int64_t), name//c_null_char, size(self%widths, kind=c_int), &
                                self%names//c_null_char, self%widths, int(row - 1, c_long), numbers, joined, &
                                int(len(joined), c_long)))
    start = 1
    do i = 1, size(texts)
      finish = index(joined(start:), new_line('a')) + start - 2
      if (finish < start - 1) then
        texts(i) = ''
        cycle
      end if
      texts(i) = joined(start:finish)
      start = finish + 2
    end do
  end subroutine read_row

end module hdf5_table
