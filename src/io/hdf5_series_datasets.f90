!> The dataset half of src/io/hdf5_series: a table's first write creates its datasets (contiguous
!> when their length is final, chunked and extendible otherwise, deflated on request) with their
!> attributes and dimension scales; every write puts the buffered rows in place.
submodule (hdf5_series) hdf5_series_datasets
  use, intrinsic :: iso_c_binding, only: c_char, c_int, c_int64_t, c_null_char
  use hdf5, only: hid_t, hsize_t, h5screate_simple_f, h5sclose_f, H5S_UNLIMITED_F, H5S_SELECT_SET_F, &
                  h5sselect_hyperslab_f, h5pcreate_f, h5pclose_f, h5pset_chunk_f, h5pset_layout_f, H5D_CONTIGUOUS_F, &
                  H5P_DATASET_CREATE_F, h5dcreate_f, h5dopen_f, h5dclose_f, h5dwrite_f, h5dset_extent_f, h5dget_space_f, &
                  h5pset_deflate_f, h5pset_shuffle_f, h5pset_fletcher32_f, H5T_NATIVE_DOUBLE, H5T_NATIVE_INTEGER
  implicit none (type, external)

  interface
    function c_column_scale(file, name, joined, scale) result(status) bind(c, name='eme_h5_column_scale')
      import :: c_char, c_int, c_int64_t
      integer(c_int64_t), value :: file
      character(kind=c_char), intent(in) :: name(*), joined(*)
      integer(c_int64_t), intent(out) :: scale
      integer(c_int) :: status
    end function c_column_scale
    function c_attach_scales(scale, name, count, datasets, columns) result(status) bind(c, name='eme_h5_attach_scales')
      import :: c_char, c_int, c_int64_t
      integer(c_int64_t), value :: scale
      character(kind=c_char), intent(in) :: name(*)
      integer(c_int), value :: count
      integer(c_int64_t), intent(in) :: datasets(*), columns(*)
      integer(c_int) :: status
    end function c_attach_scales
  end interface

contains

  !> Writes the buffered rows to every dataset of the table in `file`, which holds first_row rows,
  !> and empties the buffer, unless `keep` (then `forget` drops the rows once no file needs them).
  !> The first write creates the datasets: contiguous of exactly the buffered rows if `final` (no
  !> row will follow), chunked and extendible otherwise; with `held`, the file holds them already,
  !> as that write would create them (the table's `layout`), and only their values are given to
  !> it (hdf5_file's put_values, before the file is open).
  module procedure write_table
    integer(hid_t) :: dataset, file_space, memory_space
    integer(hsize_t) :: extent(2), offset(2), count(2)
    integer(hid_t) :: opened(size(self%items))   !! the new datasets, while their scales are attached
    integer :: i, rank, ignored, close_stat, stat
    logical :: attaching, filling

    stat = 0
    filling = .false.
    if (present(held)) filling = held .and. .not. self%created
    attaching = .not. (self%created .or. filling) .and. self%scale
    opened = -1
    do i = 1, size(self%items)
      associate (item => self%items(i), first => self%items(i)%offset + 1, last => self%items(i)%offset + self%items(i)%width)
        if (filling) then
          if (self%buffered > 0) call fill(item, self%buffer(first:last, 1:self%buffered))
          if (stat /= 0) exit
          cycle
        end if
        rank = merge(2, 1, item%vector)
        if (item%vector) then
          extent = [int(item%width, hsize_t), self%first_row + self%buffered]
          offset = [0_hsize_t, self%first_row]
          count = [int(item%width, hsize_t), int(self%buffered, hsize_t)]
        else
          extent = [self%first_row + self%buffered, 0_hsize_t]
          offset = [self%first_row, 0_hsize_t]
          count = [int(self%buffered, hsize_t), 0_hsize_t]
        end if
        if (self%created) then
          call h5dopen_f(file%id, item%name, dataset, stat)
          if (stat /= 0) exit
          call h5dset_extent_f(dataset, extent(1:rank), stat)
        else
          call create_dataset(file, item, rank, extent, final, self%chunk_rows, self%compression, dataset, failure)
          if (failure%failed()) then
            stat = -1
            if (dataset >= 0) call h5dclose_f(dataset, ignored)
            exit
          end if
        end if
        if (stat == 0 .and. self%buffered > 0) then
          call h5dget_space_f(dataset, file_space, stat)
          if (stat == 0) then
            call h5sselect_hyperslab_f(file_space, H5S_SELECT_SET_F, offset(1:rank), count(1:rank), stat)
            if (stat == 0) call h5screate_simple_f(rank, count(1:rank), memory_space, stat)
            if (stat == 0) then
              if (item%integer_valued) then
                call h5dwrite_f(dataset, H5T_NATIVE_INTEGER, nint(self%buffer(first:last, 1:self%buffered)), &
                                count(1:rank), stat, memory_space, file_space)
              else
                call h5dwrite_f(dataset, H5T_NATIVE_DOUBLE, self%buffer(first:last, 1:self%buffered), &
                                count(1:rank), stat, memory_space, file_space)
              end if
              call h5sclose_f(memory_space, ignored)
            end if
            call h5sclose_f(file_space, ignored)
          end if
        end if
        if (attaching .and. stat == 0) then
          opened(i) = dataset               ! kept open for attach_scale
        else
          call h5dclose_f(dataset, close_stat)
          if (stat == 0) stat = close_stat
        end if
        if (stat /= 0) exit
      end associate
    end do
    if (attaching .and. stat == 0) then
      call attach_scale(file, self%items, opened, failure)
      if (failure%failed()) stat = -1
    end if
    if (attaching) then
      do i = 1, size(opened)
        if (opened(i) >= 0) call h5dclose_f(opened(i), ignored)
      end do
    end if
    if (.not. failure%failed()) call hdf5_failure(failure, stat, 'write_table')
    if (stat /= 0) return
    self%created = .true.
    self%written = self%first_row + self%buffered
    if (present(keep)) then
      if (keep) return
    end if
    call self%forget(self%written)

  contains

    ! The values of `item` (its columns of the buffered rows) as the bytes of its stored type:
    ! rows after rows, as HDF5 lays out a (rows, width) dataset.
    subroutine fill(item, values)
      type(series), intent(in) :: item
      real(real64), intent(in) :: values(:, :)
      character(len=merge(4, 8, item%integer_valued)*size(values)) :: bytes

      if (item%integer_valued) then
        bytes = transfer(nint(values), bytes)
      else
        bytes = transfer(values, bytes)
      end if
      call file%put_values(item%name, bytes, failure)
      if (failure%failed()) stat = -1
    end subroutine fill
  end procedure write_table

  ! Makes the first dataset the dimension scale (named after it) of the other datasets' rows,
  ! and gives each vector dataset X the scale X_column of its columns' names
  ! (src/io/hdf5_scales.c: every scale attribute written once).
  subroutine attach_scale(file, items, opened, failure)
    type(hdf5_file), intent(in) :: file
    type(series), intent(in) :: items(:)
    integer(hid_t), intent(in) :: opened(:)    !! the datasets of `items`, open
    type(failure_type), intent(out) :: failure
    integer(c_int64_t) :: datasets(size(items) - 1), columns(size(items) - 1)
    integer :: i, ignored, stat

    datasets = int(opened(2:), c_int64_t)
    columns = -1
    stat = 0
    do i = 2, size(items)
      if (stat /= 0) exit
      if (items(i)%vector) stat = int(c_column_scale(int(file%id, c_int64_t), items(i)%name//'_column'//c_null_char, &
                                                     words_as_lines(items(i)%columns)//c_null_char, columns(i - 1)))
    end do
    if (stat == 0) stat = int(c_attach_scales(int(opened(1), c_int64_t), items(1)%name//c_null_char, &
                                              int(size(items) - 1, c_int), datasets, columns))
    do i = 1, size(columns)
      if (columns(i) >= 0) call h5dclose_f(int(columns(i), hid_t), ignored)
    end do
    call hdf5_failure(failure, stat, 'attach_scale')
  end subroutine attach_scale

  ! Creates one dataset of the table with its attributes: chunked with an unlimited row count,
  ! or of `extent` if `final` (one chunk of every row up to chunk_rows); deflated at level
  ! `compression` (after the shuffle filter) if that is > 0. Every dataset that holds a value,
  ! one or many, carries HDF5's Fletcher-32 checksum, first in the filter pipeline (over the
  ! values themselves), so that a damaged chunk fails its read instead of giving other numbers;
  ! only an empty one (no chunk to check) is contiguous (docs/output.md, Checksums).
  subroutine create_dataset(file, item, rank, extent, final, chunk_rows, compression, dataset, failure)
    type(hdf5_file), intent(in) :: file
    type(series), intent(in) :: item
    integer, intent(in) :: rank, chunk_rows, compression
    integer(hsize_t), intent(in) :: extent(2)
    logical, intent(in) :: final
    integer(hid_t), intent(out) :: dataset
    type(failure_type), intent(out) :: failure
    type(hdf5_file) :: fresh_object
    integer(hid_t) :: space, properties, kind
    integer(hsize_t) :: max_dims(2), chunk(2)
    integer :: ignored, stat
    logical :: compressed, checked

    dataset = -1
    kind = H5T_NATIVE_DOUBLE
    if (item%integer_valued) kind = H5T_NATIVE_INTEGER
    max_dims = extent
    max_dims(rank) = H5S_UNLIMITED_F
    chunk = extent
    chunk(rank) = int(chunk_rows, hsize_t)
    if (final) then
      max_dims = extent
      chunk(rank) = min(chunk(rank), extent(rank))
    end if
    checked = .not. final .or. product(extent(1:rank)) > 0
    compressed = compression > 0 .and. chunk(rank) > 0 .and. checked
    call h5screate_simple_f(rank, extent(1:rank), space, stat, max_dims(1:rank))
    call hdf5_failure(failure, stat, item%name)
    if (stat /= 0) return
    call h5pcreate_f(H5P_DATASET_CREATE_F, properties, stat)
    if (stat == 0) then
      if (.not. checked) then
        call h5pset_layout_f(properties, H5D_CONTIGUOUS_F, stat)
      else
        call h5pset_chunk_f(properties, rank, chunk(1:rank), stat)
      end if
    end if
    if (stat == 0 .and. checked) call h5pset_fletcher32_f(properties, stat)
    if (stat == 0 .and. compressed) call h5pset_shuffle_f(properties, stat)
    if (stat == 0 .and. compressed) call h5pset_deflate_f(properties, compression, stat)
    if (stat == 0) call h5dcreate_f(file%id, item%name, kind, space, dataset, stat, properties)
    call h5pclose_f(properties, ignored)
    call h5sclose_f(space, ignored)
    call hdf5_failure(failure, stat, item%name)
    if (stat /= 0) return
    ! A new dataset has no attributes: no existence queries.
    fresh_object%id = file%id
    fresh_object%fresh = .true.
    if (len(item%units) > 0) call fresh_object%set_text('units', item%units, failure, dataset)
    if (.not. failure%failed()) call fresh_object%set_text('description', item%description, failure, dataset)
    if (.not. failure%failed() .and. len(item%coordinates) > 0) &
      call fresh_object%set_text('coordinates', item%coordinates, failure, dataset)
    if (.not. failure%failed() .and. len(item%columns) > 0) &
      call fresh_object%set_text('columns', item%columns, failure, dataset)
    if (.not. failure%failed() .and. len(item%rows) > 0) call fresh_object%set_text('rows', item%rows, failure, dataset)
    if (.not. failure%failed() .and. len(item%source) > 0) &
      call fresh_object%set_text('source', item%source, failure, dataset)
    if (.not. failure%failed() .and. allocated(item%column_units)) &
      call fresh_object%set_texts('column_units', item%column_units, failure, dataset)
    if (.not. failure%failed() .and. allocated(item%flag_values)) then
      call fresh_object%set_integers('flag_values', item%flag_values, failure, dataset)
      if (.not. failure%failed()) call fresh_object%set_text('flag_meanings', item%flag_meanings, failure, dataset)
    end if
  end subroutine create_dataset

  ! The blank-separated words of `text`, each ended by a newline.
  pure function words_as_lines(text) result(lines)
    character(len=*), intent(in) :: text
    character(len=:), allocatable :: lines
    integer :: i

    lines = ''
    do i = 1, len(text)
      if (text(i:i) /= ' ') then
        lines = lines//text(i:i)
      else if (i > 1) then
        if (text(i - 1:i - 1) /= ' ') lines = lines//new_line('a')
      end if
    end do
    if (len(text) > 0) then
      if (text(len(text):len(text)) /= ' ') lines = lines//new_line('a')
    end if
  end function words_as_lines

end submodule hdf5_series_datasets
