!> A table as one HDF5 compound dataset made by HDF5's high-level table API (H5TB): h5py loads it
!> in one call as a numpy structured array (`f["cases"][:]`), and HDF5's table tools know it
!> (attributes CLASS = TABLE, VERSION, TITLE, FIELD_n_NAME, as H5TBmake_table writes them).
!> Columns are chosen at run time (a study's sweeps name some of them): real64, integer or
!> fixed-length UTF-8 text, NUL-padded so that h5py gives the text without trailing blanks. The
!> dataset is chunked with HDF5's Fletcher-32 checksum (which H5TBmake_table cannot give), so
!> that a damaged byte fails the read instead of changing a row. Tables are written whole (made
!> here, then one H5TBwrite_fields_name per column) and read whole, column by column by name: a
!> column the file lacks (an index written before the column existed) reads as 0 or as an empty
!> text.
module hdf5_table
  use, intrinsic :: iso_fortran_env, only: real64
  use hdf5, only: hid_t, hsize_t, size_t, H5T_NATIVE_DOUBLE, H5T_NATIVE_INTEGER, H5T_NATIVE_CHARACTER, &
                  H5T_STR_NULLPAD_F, H5T_CSET_UTF8_F, h5tcopy_f, h5tset_size_f, h5tset_strpad_f, h5tset_cset_f, &
                  h5tclose_f, h5lexists_f, h5tcreate_f, h5tinsert_f, H5T_COMPOUND_F, h5screate_simple_f, h5sclose_f, &
                  H5S_UNLIMITED_F, h5pcreate_f, h5pclose_f, h5pset_chunk_f, h5pset_fletcher32_f, H5P_DATASET_CREATE_F, &
                  h5dcreate_f, h5dclose_f
  use h5lt, only: h5ltset_attribute_string_f
  use h5tb, only: h5tbwrite_field_name_f, h5tbread_field_name_f, h5tbget_table_info_f, &
                  h5tbget_field_info_f
  use hdf5_files, only: hdf5_failure
  use failures, only: failure_type
  implicit none (type, external)
  private
  public :: table_columns, column_real, column_integer, table_rows

  integer, parameter :: column_real = 0      !! width of a real64 column
  integer, parameter :: column_integer = -1  !! width of an integer column
  integer, parameter :: name_length = 64     !! longest column name
  integer, parameter :: chunk_rows = 1024

  !> The columns of a table: names and widths (column_real, column_integer, or a text length).
  type :: table_columns
    character(len=name_length), allocatable :: names(:)
    integer, allocatable :: widths(:)
  contains
    procedure :: add
    procedure :: numeric_count
    procedure :: text_count
    procedure :: write => write_table
    procedure :: read => read_table
  end type table_columns

contains

  !> Number of rows of table `name` in the open file, or -1 if there is none.
  integer function table_rows(file, name)
    integer(hid_t), intent(in) :: file
    character(len=*), intent(in) :: name
    integer(hsize_t) :: fields, records
    logical :: exists
    integer :: stat

    table_rows = -1
    call h5lexists_f(file, name, exists, stat)
    if (stat /= 0 .or. .not. exists) return
    call h5tbget_table_info_f(file, name, fields, records, stat)
    if (stat == 0) table_rows = int(records)
  end function table_rows

  !> Appends a column.
  subroutine add(self, name, width)
    class(table_columns), intent(inout) :: self
    character(len=*), intent(in) :: name
    integer, intent(in) :: width

    if (.not. allocated(self%names)) allocate (self%names(0), self%widths(0))
    self%names = [self%names, name]
    self%widths = [self%widths, width]
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

  !> Creates table `name` in the open file and writes every row: numbers(:, r) are row r's
  !> numeric columns in column order, texts(:, r) its text columns.
  subroutine write_table(self, file, name, numbers, texts, failure)
    class(table_columns), intent(in) :: self
    integer(hid_t), intent(in) :: file
    character(len=*), intent(in) :: name
    real(real64), intent(in) :: numbers(:, :)
    character(len=*), intent(in) :: texts(:, :)
    type(failure_type), intent(out) :: failure
    integer(hid_t) :: types(size(self%widths))
    integer(size_t) :: sizes(size(self%widths)), offsets(size(self%widths))
    integer(hsize_t) :: rows
    integer :: i, k, t, ignored, stat

    rows = size(numbers, 2, kind=hsize_t)
    call column_types(self, types, sizes, stat)
    call hdf5_failure(failure, stat, name)
    if (stat /= 0) return
    offsets(1) = 0
    do i = 2, size(sizes)
      offsets(i) = offsets(i - 1) + sizes(i - 1)
    end do
    call make_table(self, file, name, rows, types, sizes, offsets, stat)
    do i = 1, size(types)
      if (self%widths(i) > 0) call h5tclose_f(types(i), ignored)
    end do
    k = 0
    t = 0
    do i = 1, size(self%widths)
      if (stat /= 0 .or. rows == 0) exit
      select case (self%widths(i))
      case (column_real)
        k = k + 1
        call h5tbwrite_field_name_f(file, name, trim(self%names(i)), 0_hsize_t, rows, sizes(i), numbers(k, :), stat)
      case (column_integer)
        k = k + 1
        call h5tbwrite_field_name_f(file, name, trim(self%names(i)), 0_hsize_t, rows, sizes(i), nint(numbers(k, :)), &
                                    stat)
      case default
        t = t + 1
        call h5tbwrite_field_name_f(file, name, trim(self%names(i)), 0_hsize_t, rows, sizes(i), &
                                    nul_padded(texts(t, :), self%widths(i)), stat)
      end select
    end do
    call hdf5_failure(failure, stat, name)
  end subroutine write_table

  ! Creates the empty table `name` of `rows` rows (compound, its members the columns) with the
  ! attributes of HDF5's table API, chunked with a Fletcher-32 checksum.
  subroutine make_table(self, file, name, rows, types, sizes, offsets, stat)
    type(table_columns), intent(in) :: self
    integer(hid_t), intent(in) :: file
    character(len=*), intent(in) :: name
    integer(hsize_t), intent(in) :: rows
    integer(hid_t), intent(in) :: types(:)
    integer(size_t), intent(in) :: sizes(:), offsets(:)
    integer, intent(out) :: stat
    integer(hid_t) :: row_type, space, properties, dataset
    character(len=16) :: field
    integer :: i, ignored

    call h5tcreate_f(H5T_COMPOUND_F, sum(sizes), row_type, stat)
    if (stat /= 0) return
    do i = 1, size(types)
      if (stat == 0) call h5tinsert_f(row_type, trim(self%names(i)), offsets(i), types(i), stat)
    end do
    if (stat == 0) call h5screate_simple_f(1, [rows], space, stat, [H5S_UNLIMITED_F])
    if (stat /= 0) then
      call h5tclose_f(row_type, ignored)
      return
    end if
    call h5pcreate_f(H5P_DATASET_CREATE_F, properties, stat)
    if (stat == 0) call h5pset_chunk_f(properties, 1, [int(max(1_hsize_t, min(int(chunk_rows, hsize_t), rows)), hsize_t)], &
                                       stat)
    if (stat == 0) call h5pset_fletcher32_f(properties, stat)
    if (stat == 0) call h5dcreate_f(file, name, row_type, space, dataset, stat, properties)
    if (stat == 0) then
      call h5dclose_f(dataset, stat)
      if (stat == 0) call h5ltset_attribute_string_f(file, name, 'CLASS', 'TABLE', stat)
      if (stat == 0) call h5ltset_attribute_string_f(file, name, 'VERSION', '3.0', stat)
      if (stat == 0) call h5ltset_attribute_string_f(file, name, 'TITLE', name, stat)
      do i = 1, size(types)
        if (stat /= 0) exit
        write (field, '("FIELD_", i0, "_NAME")') i - 1
        call h5ltset_attribute_string_f(file, name, trim(field), trim(self%names(i)), stat)
      end do
    end if
    call h5pclose_f(properties, ignored)
    call h5sclose_f(space, ignored)
    call h5tclose_f(row_type, ignored)
  end subroutine make_table

  !> Reads every row of table `name` (table_rows of them) as write_table wrote them, column by
  !> column by name; columns the file lacks read as 0 or ''.
  subroutine read_table(self, file, name, numbers, texts, failure)
    class(table_columns), intent(in) :: self
    integer(hid_t), intent(in) :: file
    character(len=*), intent(in) :: name
    real(real64), intent(out) :: numbers(:, :)
    character(len=*), intent(out) :: texts(:, :)
    type(failure_type), intent(out) :: failure
    character(len=name_length), allocatable :: stored(:)
    integer(size_t), allocatable :: stored_sizes(:), stored_offsets(:)
    integer(size_t) :: row_size
    integer(hsize_t) :: fields, rows
    real(real64), allocatable :: reals(:)
    integer, allocatable :: integers(:)
    integer :: i, k, t, stat

    numbers = 0.0_real64
    texts = ''
    steps: block
      call h5tbget_table_info_f(file, name, fields, rows, stat)
      if (stat /= 0) exit steps
      if (rows /= size(numbers, 2, kind=hsize_t)) then
        stat = -1
        exit steps
      end if
      allocate (stored(fields), stored_sizes(fields), stored_offsets(fields))
      stored = ''
      call h5tbget_field_info_f(file, name, fields, stored, stored_sizes, stored_offsets, row_size, stat)
      if (stat /= 0) exit steps
      allocate (reals(rows), integers(rows))
      k = 0
      t = 0
      do i = 1, size(self%widths)
        if (self%widths(i) <= 0) then
          k = k + 1
        else
          t = t + 1
        end if
        if (rows == 0 .or. .not. any(stored == self%names(i))) cycle
        select case (self%widths(i))
        case (column_real)
          call h5tbread_field_name_f(file, name, trim(self%names(i)), 0_hsize_t, rows, 8_size_t, reals, stat)
          numbers(k, :) = reals
        case (column_integer)
          call h5tbread_field_name_f(file, name, trim(self%names(i)), 0_hsize_t, rows, &
                                     int(storage_size(integers)/8, size_t), integers, stat)
          numbers(k, :) = real(integers, real64)
        case default
          ! In the file's width, which a table written by another version may have changed.
          call read_texts(file, name, trim(self%names(i)), int(stored_sizes(findloc(stored, self%names(i), dim=1))), &
                          texts(t, :), stat)
        end select
        if (stat /= 0) exit steps
      end do
    end block steps
    call hdf5_failure(failure, stat, name)
  end subroutine read_table

  ! Text column `column` of table `name`, stored `width` characters wide, without its NULs.
  subroutine read_texts(file, name, column, width, texts, stat)
    integer(hid_t), intent(in) :: file
    character(len=*), intent(in) :: name, column
    integer, intent(in) :: width
    character(len=*), intent(inout) :: texts(:)
    integer, intent(out) :: stat
    character(len=width) :: stored(size(texts))
    integer :: r

    call h5tbread_field_name_f(file, name, column, 0_hsize_t, size(texts, kind=hsize_t), int(width, size_t), stored, &
                               stat)
    if (stat /= 0) return
    do r = 1, size(texts)
      texts(r) = without_nul(stored(r))
    end do
  end subroutine read_texts

  ! The HDF5 type and size of each column (text types are new and must be closed).
  subroutine column_types(columns, types, sizes, stat)
    type(table_columns), intent(in) :: columns
    integer(hid_t), intent(out) :: types(:)
    integer(size_t), intent(out) :: sizes(:)
    integer, intent(out) :: stat
    integer :: i
    integer :: probe

    stat = 0
    do i = 1, size(columns%widths)
      select case (columns%widths(i))
      case (column_real)
        types(i) = H5T_NATIVE_DOUBLE
        sizes(i) = 8
      case (column_integer)
        types(i) = H5T_NATIVE_INTEGER
        sizes(i) = int(storage_size(probe)/8, size_t)
      case default
        sizes(i) = int(columns%widths(i), size_t)
        call h5tcopy_f(H5T_NATIVE_CHARACTER, types(i), stat)
        if (stat == 0) call h5tset_size_f(types(i), sizes(i), stat)
        if (stat == 0) call h5tset_strpad_f(types(i), H5T_STR_NULLPAD_F, stat)
        if (stat == 0) call h5tset_cset_f(types(i), H5T_CSET_UTF8_F, stat)
      end select
      if (stat /= 0) return
    end do
  end subroutine column_types

  ! Texts of `width` characters, each NUL-padded after its last non-blank character.
  pure function nul_padded(texts, width) result(padded)
    character(len=*), intent(in) :: texts(:)
    integer, intent(in) :: width
    character(len=width) :: padded(size(texts))
    integer :: r, n

    do r = 1, size(texts)
      n = min(width, len_trim(texts(r)))
      padded(r) = texts(r)(1:n)//repeat(achar(0), width - n)
    end do
  end function nul_padded

  ! A stored text up to its first NUL.
  pure function without_nul(text) result(plain)
    character(len=*), intent(in) :: text
    character(len=:), allocatable :: plain
    integer :: nul

    nul = index(text, achar(0))
    if (nul == 0) nul = len(text) + 1
    plain = text(1:nul - 1)
  end function without_nul

end module hdf5_table
