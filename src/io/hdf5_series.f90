!> HDF5 datasets that grow by rows, in a file of src/io/hdf5_files (built in memory and written in
!> one checked write; later rows are appended in short windows after their disk space is
!> reserved, to a copy that then takes the file's name: src/run/run_output.f90).
!> A `series_table` groups datasets that gain a row together (one per time point, or one per
!> step). Rows are buffered in memory (bounded: `capacity_rows`) and written a window at a time.
!> Datasets whose final length is known when they are first written are made of that length,
!> the others extendible; every dataset that holds a value is chunked with HDF5's Fletcher-32
!> checksum, and deflated (with the shuffle filter) when a compression level is set. Datasets are (rows) or (rows, width) as h5py shows them. A table's first dataset can be
!> the HDF5 dimension scale of the others' rows (src/io/hdf5_scales.c). A row of the file can
!> stand for several rows given to the table (`accumulate`, then `commit`): each dataset keeps
!> the last, the sum, the minimum, the maximum or the mean of them.
module hdf5_series
  use, intrinsic :: iso_fortran_env, only: real64, int64
  use hdf5_files, only: hdf5_file, hdf5_failure
  use failures, only: failure_type
  implicit none (type, external)
  private
  public :: series_table

  !> One dataset fed from columns offset+1 .. offset+width of its table's rows.
  type :: series
    character(len=:), allocatable :: name, units, description, columns, rows, source
    character(len=:), allocatable :: coordinates         !! CF auxiliary coordinates, '' for none
    integer :: width = 1
    logical :: vector = .false.          !! (rows, width) if true, (rows) if false
    logical :: integer_valued = .false.
    integer :: offset = 0
    character(len=4) :: combine = 'last' !! a file row for several given rows: last, sum, min, max or mean
    character(len=16), allocatable :: column_units(:)   !! of a vector's columns (attribute column_units)
    integer, allocatable :: flag_values(:)              !! CF flag_values and flag_meanings, if allocated
    character(len=:), allocatable :: flag_meanings
  end type series

  !> Datasets that gain a row together, with the row buffer. A writer that keeps two copies of a
  !> file (src/run/run_output) writes each row twice: `write` can keep the rows it wrote, and
  !> `forget` drops them once every copy holds them.
  type :: series_table
    type(series), allocatable :: items(:)
    integer :: row_width = 0
    !> Rows per chunk of a long run's datasets: 64 kB chunks of a scalar dataset, so that a window
    !> (at most 2 capacity_rows rows) adds a few chunks a dataset; the widest (15-column) chunk,
    !> 983 kB, still fits HDF5's 1 MiB chunk cache.
    integer :: chunk_rows = 8192
    integer :: capacity_rows = 16384     !! rows buffered at most before they must be written
    real(real64), allocatable :: buffer(:, :)
    integer :: buffered = 0
    integer(int64) :: first_row = 0      !! the row (from 0) of the datasets that buffer column 1 holds
    integer(int64) :: written = 0        !! rows in the file written last
    logical :: created = .false.         !! the datasets exist in the file
    logical :: scale = .false.           !! the first dataset is the dimension scale of the others' rows
    integer :: compression = 0           !! deflate level 0 (none) to 9 of chunked datasets
    real(real64), allocatable :: pending(:)   !! the combined row being accumulated
    integer :: pending_count = 0         !! rows accumulated into it
  contains
    procedure :: define
    procedure :: set_flags
    procedure :: append
    procedure :: accumulate
    procedure :: commit
    procedure :: full
    procedure :: window_bytes
    procedure :: layout
    procedure :: write => write_table
    procedure :: forget
  end type series_table

  ! The datasets' creation and writing (src/io/hdf5_series_datasets.f90).
  interface
    module subroutine write_table(self, file, final, failure, keep, held)
      class(series_table), intent(inout) :: self
      type(hdf5_file), intent(in) :: file
      logical, intent(in) :: final
      type(failure_type), intent(out) :: failure
      logical, intent(in), optional :: keep, held
    end subroutine write_table
  end interface

contains

  !> Adds a dataset of `width` values per row (a (rows, width) dataset if vector, else (rows))
  !> with `units` and `description` attributes, `columns` (names separated by blanks) and
  !> `column_units` for a vector, `rows` (what a row is), `source` (who defines it) and CF
  !> `coordinates` (auxiliary coordinate datasets); no `units` where they are ''. `combine` says
  !> what a file row that stands for several given rows holds ('last' by default). It is created
  !> in a file by the table's first `write`.
  subroutine define(self, name, width, vector, units, description, integer_valued, columns, rows, source, &
                    column_units, combine, coordinates)
    class(series_table), intent(inout) :: self
    character(len=*), intent(in) :: name, units, description
    integer, intent(in) :: width
    logical, intent(in) :: vector
    logical, intent(in), optional :: integer_valued
    character(len=*), intent(in), optional :: columns, rows, source, combine, coordinates
    character(len=*), intent(in), optional :: column_units(:)
    type(series) :: item

    item%name = name
    item%units = units
    item%description = description
    item%columns = ''
    item%rows = ''
    item%source = ''
    item%coordinates = ''
    if (present(coordinates)) item%coordinates = coordinates
    if (present(columns)) item%columns = columns
    if (present(rows)) item%rows = rows
    if (present(source)) item%source = source
    if (present(column_units)) item%column_units = column_units
    if (present(combine)) item%combine = combine
    item%width = width
    item%vector = vector
    if (present(integer_valued)) item%integer_valued = integer_valued
    item%offset = self%row_width
    self%row_width = self%row_width + width
    call append_series(self%items, item)
    if (allocated(self%buffer)) deallocate (self%buffer)
    allocate (self%buffer(self%row_width, 64))
  end subroutine define

  !> Gives dataset `name` the CF attributes flag_values and flag_meanings (a legend of codes).
  subroutine set_flags(self, name, values, meanings)
    class(series_table), intent(inout) :: self
    character(len=*), intent(in) :: name
    integer, intent(in) :: values(:)
    character(len=*), intent(in) :: meanings(:)
    integer :: i, k

    do i = 1, size(self%items)
      if (self%items(i)%name /= name) cycle
      self%items(i)%flag_values = values
      self%items(i)%flag_meanings = ''
      do k = 1, size(meanings)
        if (k > 1) self%items(i)%flag_meanings = self%items(i)%flag_meanings//' '
        self%items(i)%flag_meanings = self%items(i)%flag_meanings//trim(meanings(k))
      end do
    end do
  end subroutine set_flags

  !> Combines `row` into the pending file row, each dataset by its `combine` rule.
  subroutine accumulate(self, row)
    class(series_table), intent(inout) :: self
    real(real64), intent(in) :: row(:)
    integer :: i

    if (.not. allocated(self%pending)) allocate (self%pending(self%row_width))
    if (self%pending_count == 0) then
      self%pending = row
    else
      do i = 1, size(self%items)
        associate (p => self%pending(self%items(i)%offset + 1:self%items(i)%offset + self%items(i)%width), &
                   r => row(self%items(i)%offset + 1:self%items(i)%offset + self%items(i)%width))
          select case (self%items(i)%combine)
          case ('sum', 'mean')
            p = p + r
          case ('min')
            p = min(p, r)
          case ('max')
            p = max(p, r)
          case default
            p = r
          end select
        end associate
      end do
    end if
    self%pending_count = self%pending_count + 1
  end subroutine accumulate

  !> Buffers the pending file row (if any rows were accumulated) and starts a new one.
  subroutine commit(self)
    class(series_table), intent(inout) :: self
    integer :: i

    if (self%pending_count == 0) return
    do i = 1, size(self%items)
      if (self%items(i)%combine /= 'mean') cycle
      associate (p => self%pending(self%items(i)%offset + 1:self%items(i)%offset + self%items(i)%width))
        p = p/self%pending_count
      end associate
    end do
    call self%append(self%pending)
    self%pending_count = 0
  end subroutine commit

  !> Buffers one row (all datasets of the table at once). The buffer grows to capacity_rows rows
  !> not yet written, plus the rows a second copy of the file still needs.
  subroutine append(self, row)
    class(series_table), intent(inout) :: self
    real(real64), intent(in) :: row(:)
    real(real64), allocatable :: larger(:, :)

    if (self%buffered == size(self%buffer, 2)) then
      allocate (larger(self%row_width, max(self%buffered + 1, min(2*self%buffered, 2*self%capacity_rows))))
      larger(:, 1:self%buffered) = self%buffer(:, 1:self%buffered)
      call move_alloc(larger, self%buffer)
    end if
    self%buffered = self%buffered + 1
    self%buffer(:, self%buffered) = row
  end subroutine append

  !> Whether capacity_rows rows are buffered that no file holds yet: they must be written.
  logical function full(self)
    class(series_table), intent(in) :: self

    full = self%first_row + self%buffered - self%written >= self%capacity_rows
  end function full

  !> Disk space the table's buffered rows take when appended to its chunked datasets (whole new
  !> chunks) in a file that holds first_row rows, plus room for the chunk index.
  integer(int64) function window_bytes(self)
    class(series_table), intent(in) :: self
    integer(int64) :: chunks, chunk
    integer :: i

    chunk = self%chunk_rows
    chunks = (self%first_row + self%buffered + chunk - 1)/chunk - (self%first_row + chunk - 1)/chunk
    ! A compressed chunk that grows is written anew elsewhere in the file.
    if (self%compression > 0) chunks = chunks + 1
    window_bytes = 0
    do i = 1, size(self%items)
      ! (4 bytes a chunk: its Fletcher-32 checksum)
      window_bytes = window_bytes + chunks*(chunk*self%items(i)%width*merge(4, 8, self%items(i)%integer_valued) + 4) &
                     + 4096
    end do
  end function window_bytes

  !> What the table's first write (`final` or not) would create in a file, as a text: every
  !> dataset's name, shape, layout and attributes (the values aside). Two tables of the same
  !> layout create the same datasets; '' if the datasets exist already or the write would not
  !> fill them whole.
  function layout(self, final) result(text)
    class(series_table), intent(in) :: self
    logical, intent(in) :: final
    character(len=:), allocatable :: text
    character(len=:), allocatable :: buffer
    character(len=64) :: numbers
    integer :: i, k, used

    text = ''
    if (self%created .or. self%first_row /= 0) return
    allocate (character(len=4096) :: buffer)
    used = 0
    write (numbers, '(l1, 1x, l1, 3(1x, i0))') final, self%scale, self%compression, self%chunk_rows, self%buffered
    call add(trim(numbers))
    do i = 1, size(self%items)
      associate (item => self%items(i))
        write (numbers, '(i0, 1x, l1, 1x, l1)') item%width, item%vector, item%integer_valued
        call add(item%name)
        call add(trim(numbers))
        call add(item%units)
        call add(item%description)
        call add(item%columns)
        call add(item%rows)
        call add(item%source)
        call add(item%coordinates)
        if (allocated(item%column_units)) then
          do k = 1, size(item%column_units)
            call add(trim(item%column_units(k)))
          end do
        end if
        if (allocated(item%flag_values)) then
          do k = 1, size(item%flag_values)
            write (numbers, '(i0)') item%flag_values(k)
            call add(trim(numbers))
          end do
          call add(item%flag_meanings)
        end if
      end associate
    end do
    text = buffer(1:used)

  contains

    ! Appends `piece` and a separator (NUL) to buffer(1:used), growing it as needed.
    subroutine add(piece)
      character(len=*), intent(in) :: piece
      character(len=:), allocatable :: larger

      if (used + len(piece) + 1 > len(buffer)) then
        allocate (character(len=2*(used + len(piece) + 1)) :: larger)
        larger(1:used) = buffer(1:used)
        call move_alloc(larger, buffer)
      end if
      buffer(used + 1:used + len(piece)) = piece
      buffer(used + len(piece) + 1:used + len(piece) + 1) = achar(0)
      used = used + len(piece) + 1
    end subroutine add
  end function layout

  !> Drops the buffered rows before row `rows` (from 0): every file holds them.
  subroutine forget(self, rows)
    class(series_table), intent(inout) :: self
    integer(int64), intent(in) :: rows
    integer :: dropped

    dropped = int(min(max(rows - self%first_row, 0_int64), int(self%buffered, int64)))
    if (dropped == 0) return
    self%buffer(:, 1:self%buffered - dropped) = self%buffer(:, dropped + 1:self%buffered)
    self%buffered = self%buffered - dropped
    self%first_row = self%first_row + dropped
  end subroutine forget

  ! items := [items, item], explicitly (gfortran 12 mishandles array constructors of types with
  ! allocatable character components).
  subroutine append_series(items, item)
    type(series), allocatable, intent(inout) :: items(:)
    type(series), intent(in) :: item
    type(series), allocatable :: longer(:)
    integer :: i

    if (.not. allocated(items)) allocate (items(0))
    allocate (longer(size(items) + 1))
    do i = 1, size(items)
      call move_alloc(items(i)%name, longer(i)%name)
      call move_alloc(items(i)%units, longer(i)%units)
      call move_alloc(items(i)%coordinates, longer(i)%coordinates)
      call move_alloc(items(i)%description, longer(i)%description)
      call move_alloc(items(i)%columns, longer(i)%columns)
      call move_alloc(items(i)%rows, longer(i)%rows)
      call move_alloc(items(i)%source, longer(i)%source)
      longer(i)%width = items(i)%width
      longer(i)%vector = items(i)%vector
      longer(i)%integer_valued = items(i)%integer_valued
      longer(i)%offset = items(i)%offset
      longer(i)%combine = items(i)%combine
      if (allocated(items(i)%column_units)) call move_alloc(items(i)%column_units, longer(i)%column_units)
      if (allocated(items(i)%flag_values)) call move_alloc(items(i)%flag_values, longer(i)%flag_values)
      if (allocated(items(i)%flag_meanings)) call move_alloc(items(i)%flag_meanings, longer(i)%flag_meanings)
    end do
    longer(size(longer)) = item
    call move_alloc(longer, items)
  end subroutine append_series

end module hdf5_series
