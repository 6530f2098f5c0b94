!> The HDF5 files of the output, written so that a full disk or a kill never leaves a file that
!> lies (src/io/hdf5_storage.c says how): a file is built in memory (src/io/hdf5_file_image.c)
!> and written in one checked write (`create_in_memory`, `store`), or opened for appending after
!> the disk space of what will be added was reserved, waiting for readers that hold it open
!> (`open_existing`); the root's and the datasets' attributes (src/io/hdf5_file_attributes: text
!> attributes are UTF-8 variable-length strings, which h5py reads as str; numbers are rewritten in
!> place when their size is unchanged); a series of similar files made from the first one's image
!> (src/io/hdf5_file_templates); and the read-back check of a run file (`check_run_file`:
!> src/io/hdf5_run_file_check.c). The tables of rows that grow in such a file are hdf5_series'.
module hdf5_files
  use, intrinsic :: iso_fortran_env, only: real64, int64
  use, intrinsic :: iso_c_binding, only: c_char, c_int, c_long, c_int64_t, c_null_char
  use hdf5, only: hid_t, h5open_f, h5eset_auto_f, h5fclose_f
  use failures, only: failure_type, fail, failure_io, failure_library, failure_mismatch
  use filesystem, only: os_failure
  implicit none (type, external)
  private
  public :: hdf5_file, file_template, check_run_file, check_file_integrity, hdf5_failure, hdf5_file_kind, &
            not_hdf5, run_file_kind, other_hdf5
  ! For the submodules only: gfortran gives a module's private procedures internal linkage,
  ! which a submodule, compiled apart, cannot reach.
  public :: open_library

  integer, parameter :: file_in_use = -3   !! open_existing: a reader holds the file open
  !> What hdf5_file_kind finds at a path: no HDF5 file that opens, a run file of this project,
  !> another HDF5 file.
  integer, parameter :: not_hdf5 = 0, run_file_kind = 1, other_hdf5 = 2

  !> A root attribute of a template: its name and value (a kind letter and the value's bytes).
  type :: remembered_attribute
    character(len=:), allocatable :: name, value
  end type remembered_attribute

  !> The root attributes that a series of similar files share (a study's case files), kept
  !> by whoever writes the series: the image of its first file, taken before any dataset was
  !> written, and each root attribute that file then held. A file made from it
  !> (`create_from_template`) starts as that image, writes only the attributes whose values
  !> differ and removes those it does not set (`settle_template`), so it holds what the same
  !> calls would have written into an empty file; one HDF5 attribute costs 2 to 5 us, and a run
  !> file has about 150 on its root (docs/performance.md, Ensemble throughput).
  !> The template keeps a second image of its first file, taken once the datasets were written
  !> (before the attributes of the run's outcome), with the layout of those datasets (names,
  !> shapes, attributes: hdf5_series' `layout`) and where each dataset's values lie in it
  !> (datasets of native numbers, contiguous or of one chunk followed by its Fletcher-32
  !> checksum). A file of that layout starts from a copy of this image with its own values put
  !> in place, checksums recomputed (`template_datasets`, `put_values`):
  !> creating the datasets and their attributes was half of a case file's cost, opening them to
  !> write the values a fifth of what was left. Such a file opens only then: the root attributes
  !> that differ wait in the template until `settle_template`.
  type :: file_template
    logical :: ready = .false.           !! the image and its attributes are kept
    logical, private :: recording = .false.
    character(len=:), allocatable, private :: image
    character(len=:), allocatable, private :: image_texts     !! the texts of image, as the checksum's book keeps them
    character(len=:), allocatable, private :: dataset_image   !! the first file with its datasets
    character(len=:), allocatable, private :: dataset_texts   !! the texts of dataset_image
    character(len=:), allocatable, private :: layout          !! of the datasets in dataset_image
    character(len=:), allocatable, private :: names           !! its numeric datasets, each ended by a newline
    integer(int64), allocatable, private :: offsets(:), sizes(:)   !! their values' place in it (bytes)
    logical, allocatable, private :: sealed(:)        !! a Fletcher-32 checksum follows the values
    character(len=:), allocatable, private :: copy            !! dataset_image, with a file's values
    type(remembered_attribute), allocatable, private :: waiting(:)   !! root attributes not yet written
    integer, private :: waiting_count = 0
    type(remembered_attribute), allocatable, private :: attributes(:)
    integer, private :: count = 0
    logical, allocatable, private :: touched(:)
    integer, private :: cursor = 0
  end type file_template

  !> An open HDF5 file (in memory until stored, or on disk).
  type :: hdf5_file
    integer(hid_t) :: id = -1
    logical :: fresh = .false.           !! created by this process: no attribute exists yet
    !> While the root attributes are written, the template they are recorded in or compared with
    !> (a pointer, so that the attribute writers keep intent(in)).
    type(file_template), pointer :: template => null()
    !> The template the file was made from, until its datasets are written (template_datasets).
    type(file_template), pointer, private :: origin => null()
    logical, private :: first_of_template = .false.   !! the file whose images the template keeps
    logical, private :: deferred = .false.            !! not open yet: its root attributes wait
    logical, private :: from_datasets = .false.       !! to open from the template's copy
    logical, private :: writable = .false.            !! opened on disk for writing: sealed at close
  contains
    procedure :: create_in_memory
    procedure :: create_from_template
    procedure :: settle_template
    procedure :: template_datasets
    procedure :: put_values
    procedure :: keep_template_datasets
    procedure :: store
    procedure :: open_existing
    procedure :: close => close_file
    procedure :: seal_texts
    procedure :: check_texts
    procedure :: set_text
    procedure :: set_real
    procedure :: set_reals
    procedure :: set_integer
    procedure :: set_integers
    procedure :: set_texts
    procedure :: set_dataset_texts
    procedure :: get_text
    procedure :: get_reals
  end type hdf5_file

  ! h5open_f rebuilds HDF5's table of Fortran types on every call (~1.5 ms): call it once.
  logical, save :: library_open = .false.
  integer, save :: memory_files = 0

  interface
    function c_write_text_attribute(object, name, value, fresh) result(status) &
        bind(c, name='eme_h5_write_text_attribute')
      import :: c_char, c_int, c_int64_t
      integer(c_int64_t), value :: object   ! hid_t is int64_t in HDF5 1.10
      character(kind=c_char), intent(in) :: name(*), value(*)
      integer(c_int), value :: fresh
      integer(c_int) :: status
    end function c_write_text_attribute
    function c_write_text_array_attribute(object, name, joined) result(status) &
        bind(c, name='eme_h5_write_text_array_attribute')
      import :: c_char, c_int, c_int64_t
      integer(c_int64_t), value :: object
      character(kind=c_char), intent(in) :: name(*), joined(*)
      integer(c_int) :: status
    end function c_write_text_array_attribute
    ! src/io/hdf5_file_image.c
    function c_create_in_memory(label, file) result(status) bind(c, name='eme_h5_create_in_memory')
      import :: c_char, c_int, c_int64_t
      character(kind=c_char), intent(in) :: label(*)
      integer(c_int64_t), intent(out) :: file
      integer(c_int) :: status
    end function c_create_in_memory
    function c_image_size(file) result(size) bind(c, name='eme_h5_image_size')
      import :: c_long, c_int64_t
      integer(c_int64_t), value :: file
      integer(c_long) :: size
    end function c_image_size
    function c_copy_image(file, image, size) result(status) bind(c, name='eme_h5_copy_image')
      import :: c_char, c_int, c_long, c_int64_t
      integer(c_int64_t), value :: file
      character(kind=c_char), intent(out) :: image(*)
      integer(c_long), value :: size
      integer(c_int) :: status
    end function c_copy_image
    function c_open_image(label, image, size, file) result(status) bind(c, name='eme_h5_open_image')
      import :: c_char, c_int, c_long, c_int64_t
      character(kind=c_char), intent(in) :: label(*), image(*)
      integer(c_long), value :: size
      integer(c_int64_t), intent(out) :: file
      integer(c_int) :: status
    end function c_open_image
    function c_numeric_datasets(file, image, image_size, names, capacity, offsets, sizes, sealed, count) &
        result(status) bind(c, name='eme_h5_numeric_datasets')
      import :: c_char, c_int, c_long, c_int64_t
      integer(c_int64_t), value :: file
      character(kind=c_char), intent(in) :: image(*)
      integer(c_long), value :: image_size
      character(kind=c_char), intent(out) :: names(*)
      integer(c_int), value :: capacity
      integer(c_int64_t), intent(out) :: offsets(*), sizes(*)
      integer(c_int), intent(out) :: sealed(*)
      integer(c_int), intent(inout) :: count
      integer(c_int) :: status
    end function c_numeric_datasets
    subroutine c_seal_chunk(data, size) bind(c, name='eme_h5_seal_chunk')
      import :: c_char, c_long
      character(kind=c_char), intent(inout) :: data(*)
      integer(c_long), value :: size
    end subroutine c_seal_chunk
    ! src/io/hdf5_storage.c
    function c_store_image(file, path, sync) result(status) bind(c, name='eme_h5_store_image')
      import :: c_char, c_int, c_int64_t
      integer(c_int64_t), value :: file
      character(kind=c_char), intent(in) :: path(*)
      integer(c_int), value :: sync
      integer(c_int) :: status
    end function c_store_image
    function c_open_file(path, writable, reserve, wait_ms, file) result(status) bind(c, name='eme_h5_open_file')
      import :: c_char, c_int, c_long, c_int64_t
      character(kind=c_char), intent(in) :: path(*)
      integer(c_int), value :: writable, wait_ms
      integer(c_long), value :: reserve
      integer(c_int64_t), intent(out) :: file
      integer(c_int) :: status
    end function c_open_file
    ! src/io/hdf5_run_file_check.c
    function c_check_run_file(path, status_text, capacity, steps, whole) result(status) &
        bind(c, name='eme_h5_check_run_file')
      import :: c_char, c_int, c_long
      character(kind=c_char), intent(in) :: path(*)
      character(kind=c_char), intent(out) :: status_text(*)
      integer(c_int), value :: capacity, whole
      integer(c_long), intent(out) :: steps
      integer(c_int) :: status
    end function c_check_run_file
    function c_file_kind(path) result(kind) bind(c, name='eme_h5_file_kind')
      import :: c_char, c_int
      character(kind=c_char), intent(in) :: path(*)
      integer(c_int) :: kind
    end function c_file_kind
    function c_check_integrity(path) result(status) bind(c, name='eme_h5_check_integrity')
      import :: c_char, c_int
      character(kind=c_char), intent(in) :: path(*)
      integer(c_int) :: status
    end function c_check_integrity
    ! src/io/hdf5_text_checksum.c
    function c_seal_texts(file) result(status) bind(c, name='eme_h5_seal_texts')
      import :: c_int, c_int64_t
      integer(c_int64_t), value :: file
      integer(c_int) :: status
    end function c_seal_texts
    function c_verify_texts(file) result(status) bind(c, name='eme_h5_verify_texts')
      import :: c_int, c_int64_t
      integer(c_int64_t), value :: file
      integer(c_int) :: status
    end function c_verify_texts
    function c_texts_begin(file, read_back) result(status) bind(c, name='eme_h5_texts_begin')
      import :: c_int, c_int64_t
      integer(c_int64_t), value :: file
      integer(c_int), value :: read_back
      integer(c_int) :: status
    end function c_texts_begin
    subroutine c_texts_end(file) bind(c, name='eme_h5_texts_end')
      import :: c_int64_t
      integer(c_int64_t), value :: file
    end subroutine c_texts_end
    function c_texts_export(file, buffer, capacity) result(size) bind(c, name='eme_h5_texts_export')
      import :: c_char, c_long, c_int64_t
      integer(c_int64_t), value :: file
      character(kind=c_char), intent(out) :: buffer(*)
      integer(c_long), value :: capacity
      integer(c_long) :: size
    end function c_texts_export
    function c_texts_import(file, buffer, size) result(status) bind(c, name='eme_h5_texts_import')
      import :: c_char, c_int, c_long, c_int64_t
      integer(c_int64_t), value :: file
      character(kind=c_char), intent(in) :: buffer(*)
      integer(c_long), value :: size
      integer(c_int) :: status
    end function c_texts_import
    function c_delete_attribute(object, name) result(status) bind(c, name='eme_h5_delete_attribute')
      import :: c_char, c_int, c_int64_t
      integer(c_int64_t), value :: object
      character(kind=c_char), intent(in) :: name(*)
      integer(c_int) :: status
    end function c_delete_attribute
  end interface

  ! The template half (src/io/hdf5_file_templates): a rank's case files start from its first one.
  interface
    module subroutine create_from_template(self, template, failure)
      class(hdf5_file), intent(inout) :: self
      type(file_template), intent(inout), target :: template
      type(failure_type), intent(out) :: failure
    end subroutine create_from_template
    module subroutine template_datasets(self, layout, held)
      class(hdf5_file), intent(inout) :: self
      character(len=*), intent(in) :: layout
      logical, intent(out) :: held
    end subroutine template_datasets
    module subroutine put_values(self, name, bytes, failure)
      class(hdf5_file), intent(in) :: self
      character(len=*), intent(in) :: name, bytes
      type(failure_type), intent(out) :: failure
    end subroutine put_values
    module subroutine settle_template(self, failure)
      class(hdf5_file), intent(inout) :: self
      type(failure_type), intent(out) :: failure
    end subroutine settle_template
    module subroutine keep_template_datasets(self)
      class(hdf5_file), intent(inout) :: self
    end subroutine keep_template_datasets
    module subroutine compare_with_template(template, name, value, write, fresh, file_fresh, deferred)
      type(file_template), pointer, intent(in) :: template
      character(len=*), intent(in) :: name, value
      logical, intent(out) :: write, fresh
      logical, intent(in) :: file_fresh, deferred
    end subroutine compare_with_template
  end interface

  ! The attributes (src/io/hdf5_file_attributes): written, rewritten in place, read back.
  interface
    module subroutine set_text(self, name, value, failure, object)
      class(hdf5_file), intent(in) :: self
      character(len=*), intent(in) :: name, value
      type(failure_type), intent(out) :: failure
      integer(hid_t), intent(in), optional :: object
    end subroutine set_text
    module subroutine set_texts(self, name, values, failure, object)
      class(hdf5_file), intent(in) :: self
      character(len=*), intent(in) :: name, values(:)
      type(failure_type), intent(out) :: failure
      integer(hid_t), intent(in), optional :: object
    end subroutine set_texts
    module subroutine set_dataset_texts(self, dataset, name, values, failure)
      class(hdf5_file), intent(in) :: self
      character(len=*), intent(in) :: dataset, name, values(:)
      type(failure_type), intent(out) :: failure
    end subroutine set_dataset_texts
    module subroutine set_real(self, name, value, failure, units)
      class(hdf5_file), intent(in) :: self
      character(len=*), intent(in) :: name
      real(real64), intent(in) :: value
      type(failure_type), intent(out) :: failure
      character(len=*), intent(in), optional :: units
    end subroutine set_real
    module subroutine set_reals(self, name, values, failure, units, row_length)
      class(hdf5_file), intent(in) :: self
      character(len=*), intent(in) :: name
      real(real64), intent(in) :: values(:)
      type(failure_type), intent(out) :: failure
      character(len=*), intent(in), optional :: units
      !> stored as rows of this many values (a 2D attribute of size(values)/row_length rows)
      integer, intent(in), optional :: row_length
    end subroutine set_reals
    module subroutine set_integer(self, name, value, failure, units)
      class(hdf5_file), intent(in) :: self
      character(len=*), intent(in) :: name
      integer, intent(in) :: value
      type(failure_type), intent(out) :: failure
      character(len=*), intent(in), optional :: units
    end subroutine set_integer
    module subroutine set_integers(self, name, values, failure, object)
      class(hdf5_file), intent(in) :: self
      character(len=*), intent(in) :: name
      integer, intent(in) :: values(:)
      type(failure_type), intent(out) :: failure
      integer(hid_t), intent(in), optional :: object
    end subroutine set_integers
    module subroutine get_text(self, name, value, failure)
      class(hdf5_file), intent(in) :: self
      character(len=*), intent(in) :: name
      character(len=:), allocatable, intent(out) :: value
      type(failure_type), intent(out) :: failure
    end subroutine get_text
    module subroutine get_reals(self, name, values, failure)
      class(hdf5_file), intent(in) :: self
      character(len=*), intent(in) :: name
      real(real64), allocatable, intent(out) :: values(:)
      type(failure_type), intent(out) :: failure
    end subroutine get_reals
    module subroutine write_numeric_attribute(object, name, values, scalar, fresh, failure, integer_valued, row_length)
      integer(hid_t), intent(in) :: object
      character(len=*), intent(in) :: name
      real(real64), intent(in) :: values(:)
      logical, intent(in) :: scalar, fresh
      type(failure_type), intent(out) :: failure
      logical, intent(in), optional :: integer_valued
      integer, intent(in), optional :: row_length
    end subroutine write_numeric_attribute
  end interface

contains

  !> Creates an empty file in memory; `store` writes it to disk. A failure if HDF5 failed.
  subroutine create_in_memory(self, failure)
    class(hdf5_file), intent(inout) :: self
    type(failure_type), intent(out) :: failure
    character(len=32) :: label
    integer(c_int64_t) :: id

    call open_library(failure)
    if (failure%failed()) return
    memory_files = memory_files + 1
    write (label, '("eme_memory_file_", i0)') memory_files
    call hdf5_failure(failure, int(c_create_in_memory(trim(label)//c_null_char, id)), 'create_in_memory')
    self%id = int(id, hid_t)
    self%fresh = .true.
  end subroutine create_in_memory

  !> Writes the in-memory file as the whole of `path` (on disk before return with `sync`); the
  !> file stays open. A failure (hdf5_failure): the OS's words (the partial file is removed), or HDF5's.
  subroutine store(self, path, sync, failure)
    class(hdf5_file), intent(inout) :: self
    character(len=*), intent(in) :: path
    logical, intent(in) :: sync
    type(failure_type), intent(out) :: failure

    call self%seal_texts(failure)
    if (failure%failed()) return
    call hdf5_failure(failure, int(c_store_image(int(self%id, c_int64_t), trim(path)//c_null_char, &
                                                 merge(1_c_int, 0_c_int, sync))), path)
  end subroutine store

  !> Writes the root attribute text_checksum, the checksum of every variable-length text of the
  !> file (src/io/hdf5_text_checksum.c; docs/output.md, Checksums): `store` and the close of a
  !> file opened for writing do it, after the last text was written. A failure if HDF5 failed.
  subroutine seal_texts(self, failure)
    class(hdf5_file), intent(in) :: self
    type(failure_type), intent(out) :: failure

    call hdf5_failure(failure, int(c_seal_texts(int(self%id, c_int64_t))), 'text_checksum')
  end subroutine seal_texts

  !> A failure (failure_mismatch) if the file's texts are not those its text_checksum was computed
  !> from (a damaged text), failure_io if one cannot be read; nothing for a file written before
  !> text_checksum existed.
  subroutine check_texts(self, path, failure)
    class(hdf5_file), intent(in) :: self
    character(len=*), intent(in) :: path
    type(failure_type), intent(out) :: failure

    select case (c_verify_texts(int(self%id, c_int64_t)))
    case (0, 2)
    case (1)
      call fail(failure, failure_mismatch, 'a text of the file fails its checksum (text_checksum): the file is '// &
                'damaged', path)
    case default
      call fail(failure, failure_io, 'a text of the file cannot be read: the file is damaged', path)
    end select
  end subroutine check_texts

  !> Opens an existing file read-only, or for writing after reserving `reserve` bytes of disk for
  !> what will be added (default 64 KiB). A writer waits for readers that hold the file open:
  !> with `wait_ms` < 0 not at all (`busy`, with a failure: write later), else up to wait_ms
  !> milliseconds (default 5000), then it writes without HDF5's lock. A failure: the OS's words
  !> from the reservation (the file is untouched), a reader holding the file (`busy`), or HDF5's
  !> (it could not open it).
  subroutine open_existing(self, path, writable, failure, reserve, wait_ms, busy)
    class(hdf5_file), intent(inout) :: self
    character(len=*), intent(in) :: path
    logical, intent(in) :: writable
    type(failure_type), intent(out) :: failure
    integer(int64), intent(in), optional :: reserve
    integer, intent(in), optional :: wait_ms
    logical, intent(out), optional :: busy
    integer(c_int64_t) :: id
    integer(c_long) :: bytes
    integer(c_int) :: patience
    integer :: stat

    if (present(busy)) busy = .false.
    call open_library(failure)
    if (failure%failed()) return
    bytes = 65536
    if (present(reserve)) bytes = int(reserve, c_long)
    patience = 5000
    if (present(wait_ms)) patience = int(wait_ms, c_int)
    stat = int(c_open_file(trim(path)//c_null_char, merge(1_c_int, 0_c_int, writable), bytes, patience, id))
    if (stat == file_in_use) then
      if (present(busy)) busy = .true.
      call fail(failure, failure_io, 'a reader holds the file open', path)
    else
      call hdf5_failure(failure, stat, path)
    end if
    self%id = int(id, hid_t)
    self%fresh = .false.
    self%writable = writable .and. .not. failure%failed()
  end subroutine open_existing

  !> Closes the file, a file opened for writing after sealing its texts (seal_texts). (The HDF5
  !> library stays open: other files may be in use.)
  subroutine close_file(self, failure)
    class(hdf5_file), intent(inout) :: self
    type(failure_type), intent(out) :: failure
    integer :: stat

    if (self%id < 0) return
    if (self%writable) call self%seal_texts(failure)
    call c_texts_end(int(self%id, c_int64_t))
    call h5fclose_f(self%id, stat)
    if (.not. failure%failed()) call hdf5_failure(failure, stat, 'close')
    self%id = -1
    self%writable = .false.
  end subroutine close_file

  !> Reads the run file at `path` back: its status and steps_completed, and whether every
  !> per-point dataset has R + 1 rows and every per-step dataset R, R being the attribute
  !> step_rows (steps_completed in files without it) (src/io/hdf5_run_file_check.c). With
  !> `whole`, also every dataset read whole and the texts checked (their checksums) and the
  !> summary attributes (newton_iterations_total, run_figures) checked against the datasets they
  !> summarise. A failure unless all holds: failure_io if the file is unreadable, else
  !> failure_mismatch (no status, lengths disagree, a dataset or a text fails its checksum, a
  !> summary disagrees: the message says which).
  subroutine check_run_file(path, status, steps_completed, failure, whole)
    character(len=*), intent(in) :: path
    character(len=:), allocatable, intent(out) :: status
    integer, intent(out) :: steps_completed
    type(failure_type), intent(out) :: failure
    logical, intent(in), optional :: whole
    character(len=1024) :: buffer
    integer(c_long) :: steps
    integer(c_int) :: reading
    integer :: stat

    reading = 0
    if (present(whole)) reading = merge(1, 0, whole)
    buffer = c_null_char
    steps = -1
    call open_library(failure)
    stat = 1
    if (.not. failure%failed()) stat = int(c_check_run_file(trim(path)//c_null_char, buffer, int(len(buffer), c_int), &
                                                            steps, reading))
    status = buffer(1:max(0, index(buffer, c_null_char) - 1))
    steps_completed = int(steps)
    select case (stat)
    case (0)
    case (2)
      call fail(failure, failure_mismatch, 'the run file has no status', path)
    case (3)
      call fail(failure, failure_mismatch, 'the run file''s dataset lengths disagree', path)
    case (4)
      call fail(failure, failure_mismatch, 'a dataset of the run file fails its checksum', path)
    case (5)
      call fail(failure, failure_mismatch, 'a summary attribute of the run file disagrees with its datasets', path)
    case (6)
      call fail(failure, failure_mismatch, 'a text of the run file fails its checksum (text_checksum)', path)
    case default
      call fail(failure, failure_io, 'the run file cannot be read', path)
    end select
  end subroutine check_run_file

  !> What the existing file at `path` is: not_hdf5 (or an HDF5 file that does not open), a run
  !> file of this project (run_file_kind: its root has status and steps_completed), or another
  !> HDF5 file (other_hdf5: a study's index.h5, another program's data).
  integer function hdf5_file_kind(path)
    character(len=*), intent(in) :: path
    type(failure_type) :: failure

    hdf5_file_kind = not_hdf5
    call open_library(failure)
    if (.not. failure%failed()) hdf5_file_kind = int(c_file_kind(trim(path)//c_null_char))
  end function hdf5_file_kind

  !> A failure unless every dataset of the file at `path` reads whole (their Fletcher-32 checksums)
  !> and its texts are those its text_checksum was computed from: failure_io if it cannot be
  !> opened, else failure_mismatch saying which (src/io/hdf5_run_file_check.c).
  subroutine check_file_integrity(path, failure)
    character(len=*), intent(in) :: path
    type(failure_type), intent(out) :: failure
    integer :: stat

    call open_library(failure)
    if (failure%failed()) return
    stat = int(c_check_integrity(trim(path)//c_null_char))
    select case (stat)
    case (0)
    case (4)
      call fail(failure, failure_mismatch, 'a dataset fails its checksum (Fletcher-32): the file is damaged', path)
    case (6)
      call fail(failure, failure_mismatch, 'a text fails its checksum (text_checksum): the file is damaged', path)
    case default
      call fail(failure, failure_io, 'the file cannot be read as HDF5: it is damaged', path)
    end select
  end subroutine check_file_integrity

  !> Turns a storage status into a failure at `origin` (0 leaves `failure` as it was): an OS error
  !> number (> 0) is the OS's words (failure_io); -2, the file did not read back as written
  !> (failure_mismatch); any other, HDF5 failed (failure_library). The messages are those the
  !> callers put after "cannot write the output file ...: ".
  subroutine hdf5_failure(failure, status, origin)
    type(failure_type), intent(inout) :: failure
    integer, intent(in) :: status
    character(len=*), intent(in) :: origin

    if (status > 0) then
      call os_failure(failure, status, origin)
    else if (status == -2) then
      call fail(failure, failure_mismatch, 'the file did not read back as written', origin)
    else if (status /= 0) then
      call fail(failure, failure_library, 'HDF5 failed', origin)
    end if
  end subroutine hdf5_failure

  ! Opens the HDF5 library once per process, with its own error printing off.
  module subroutine open_library(failure)
    type(failure_type), intent(out) :: failure
    integer :: stat

    if (library_open) return
    call h5open_f(stat)
    if (stat == 0) call h5eset_auto_f(0, stat)
    library_open = stat == 0
    call hdf5_failure(failure, stat, 'the HDF5 library')
  end subroutine open_library

end module hdf5_files
