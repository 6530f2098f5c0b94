!> A table as one HDF5 compound dataset (src/io/compound_table.c): h5py loads it in one call as a
!> numpy structured array. Columns are real64, integer or fixed-length text; tables are written
!> and read whole.
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
    procedure :: numeric_count
    procedure :: text_count
    procedure :: write => write_table
    procedure :: read => read_table
  end type table_columns

  interface
    function c_table_write(file, name, count, names, widths, rows, numbers, texts) result(status) &
        bind(c, name='eme_table_write')
      import :: c_int64_t, c_char, c_int, c_long, c_double
      integer(c_int64_t), value :: file
      character(kind=c_char), intent(in) :: name(*), names(*), texts(*)
      integer(c_int), value :: count
      integer(c_int), intent(in) :: widths(*)
      integer(c_long), value :: rows
      real(c_double), intent(in) :: numbers(*)
      integer(c_int) :: status
    end function c_table_write
    function c_table_read(file, name, count, names, widths, rows, numbers, texts, capacity) result(status) &
        bind(c, name='eme_table_read')
      import :: c_int64_t, c_char, c_int, c_long, c_double
      integer(c_int64_t), value :: file
      character(kind=c_char), intent(in) :: name(*), names(*)
      character(kind=c_char), intent(out) :: texts(*)
      integer(c_int), value :: count
      integer(c_int), intent(in) :: widths(*)
      integer(c_long), value :: rows, capacity
      real(c_double), intent(out) :: numbers(*)
      integer(c_int) :: status
    end function c_table_read
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

  !> Number of numeric (real or integer) columns.
  integer function numeric_count(self)
    class(table_columns), intent(in) :: self

    numeric_count = count(self%widths <= 0)
  end function numeric_count

  !> Number of text columns.
  integer function text_count(self)
    class(table_columns), intent(in) :: self

    text_count = count(self%widths > 0)
  end function text_count

  !> Creates dataset `name` in the open file and writes every row: numbers(:, r) are row r's
  !> numeric columns in column order, texts(:, r) its text columns.
  subroutine write_table(self, file, name, numbers, texts, stat)
    class(table_columns), intent(in) :: self
    integer(hid_t), intent(in) :: file
    character(len=*), intent(in) :: name
    real(real64), intent(in) :: numbers(:, :)
    character(len=*), intent(in) :: texts(:, :)
    integer, intent(out) :: stat
    character(len=:), allocatable :: joined
    integer :: i, r, at, total

    total = 0
    do r = 1, size(texts, 2)
      do i = 1, size(texts, 1)
        total = total + len_trim(texts(i, r)) + 1
      end do
    end do
    allocate (character(len=total + 1) :: joined)
    at = 0
    do r = 1, size(texts, 2)
      do i = 1, size(texts, 1)
        joined(at + 1:at + len_trim(texts(i, r)) + 1) = trim(texts(i, r))//new_line('a')
        at = at + len_trim(texts(i, r)) + 1
      end do
    end do
    joined(at + 1:at + 1) = c_null_char
    stat = int(c_table_write(int(file, c_int64_t), name//c_null_char, size(self%widths, kind=c_int), &
                             self%names//c_null_char, self%widths, int(size(numbers, 2), c_long), numbers, joined))
  end subroutine write_table

  !> Reads every row of dataset `name` (table_rows of them) as write_table wrote them.
  subroutine read_table(self, file, name, numbers, texts, stat)
    class(table_columns), intent(in) :: self
    integer(hid_t), intent(in) :: file
    character(len=*), intent(in) :: name
    real(real64), intent(out) :: numbers(:, :)
    character(len=*), intent(out) :: texts(:, :)
    integer, intent(out) :: stat
    character(len=:), allocatable :: joined
    integer :: i, r, start, finish

    allocate (character(len=size(texts)*(len(texts) + 1) + 1) :: joined)
    stat = int(c_table_read(int(file, c_int64_t), name//c_null_char, size(self%widths, kind=c_int), &
                            self%names//c_null_char, self%widths, int(size(numbers, 2), c_long), numbers, joined, &
                            int(len(joined), c_long)))
    texts = ''
    if (stat /= 0) return
    start = 1
    do r = 1, size(texts, 2)
      do i = 1, size(texts, 1)
        finish = index(joined(start:), new_line('a')) + start - 2
        if (finish < start - 1) then
          stat = -1
          return
        end if
        texts(i, r) = joined(start:finish)
        start = finish + 2
      end do
    end do
  end subroutine read_table

end module hdf5_table
