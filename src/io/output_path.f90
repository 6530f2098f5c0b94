!> Whether a run may write its output file where the input says, checked before anything is
!> written: not over its own input file, a directory or a device, not over an HDF5 file that is
!> not a run file of this project (a study's index.h5, another program's data: never, whatever
!> `overwrite` says), not over a file that is not HDF5 unless replacing was asked for, and (for
!> eme_run) not into a study's output folder, whose files are the study's; and which files a run
!> or a study owns, so that no PETSc option may write over them (src/io/petsc_option_files.c;
!> docs/faults.md, "What never ends complete by mistake").
module output_path
  use, intrinsic :: iso_c_binding, only: c_char, c_int, c_null_char
  use hdf5_files, only: hdf5_file_kind, run_file_kind, other_hdf5
  use failures, only: failure_type, fail, failure_input
  implicit none (type, external)
  private
  public :: check_output_path, check_outside_studies, run_own_files, protected_entry, protected_entries

  integer, parameter :: path_absent = 0, path_regular = 1, path_directory = 2

  interface
    function c_path_kind(path) result(kind) bind(c, name='eme_path_kind')
      import :: c_char, c_int
      character(kind=c_char), intent(in) :: path(*)
      integer(c_int) :: kind
    end function c_path_kind
    function c_same_file(first, second) result(same) bind(c, name='eme_same_file')
      import :: c_char, c_int
      character(kind=c_char), intent(in) :: first(*), second(*)
      integer(c_int) :: same
    end function c_same_file
    function c_in_study_folder(path) result(inside) bind(c, name='eme_in_study_folder')
      import :: c_char, c_int
      character(kind=c_char), intent(in) :: path(*)
      integer(c_int) :: inside
    end function c_in_study_folder
  end interface

contains

  !> A failure (failure_input) with a message naming the input file, &output file and what is
  !> allowed if `output_file` must not be written: it is `input_file` itself, a directory or
  !> another non-regular file, an HDF5 file that is not a run file of this project (kept whatever
  !> `replace_allowed` says: remove it by hand), or (unless `replace_allowed`) an existing file
  !> that is not HDF5.
  subroutine check_output_path(output_file, input_file, replace_allowed, failure)
    character(len=*), intent(in) :: output_file, input_file
    logical, intent(in) :: replace_allowed
    type(failure_type), intent(out) :: failure
    character(len=:), allocatable :: where
    integer :: kind

    where = input_file//': &output: file = '''//output_file//''''
    select case (c_path_kind(output_file//c_null_char))
    case (path_absent)
      return
    case (path_regular)
      if (c_same_file(output_file//c_null_char, input_file//c_null_char) /= 0) then
        call fail(failure, failure_input, where//' is the input file itself; allowed: another path ending in .h5', &
                  input_file)
        return
      end if
      kind = hdf5_file_kind(output_file)
      if (kind == other_hdf5) then
        call fail(failure, failure_input, where//' is an HDF5 file that is not an eme run file (a study''s '// &
                  'index.h5, another program''s data), and is kept: no run replaces it, not even with &output '// &
                  'overwrite or -eme_overwrite; allowed: another path, or remove that file by hand first', input_file)
        return
      end if
      if (replace_allowed .or. kind == run_file_kind) return
      call fail(failure, failure_input, where//' exists and is not an HDF5 file, and is kept; allowed: another '// &
                'path, or &output overwrite = .true. (or -eme_overwrite) to replace it', input_file)
    case (path_directory)
      call fail(failure, failure_input, where//' is a directory; allowed: the path of a file ending in .h5', input_file)
    case default
      call fail(failure, failure_input, where//' exists and is not a regular file; allowed: the path of a file '// &
                'ending in .h5', input_file)
    end select
  end subroutine check_output_path

  !> A failure (failure_input) if `output_file` lies in a study's output folder (one with
  !> study.lock, index.journal, or a study's index.h5): every file there is the study's, and a run
  !> writing one would meet the study's own writes (eme_run's check; eme_ensemble writes there).
  subroutine check_outside_studies(output_file, input_file, failure)
    character(len=*), intent(in) :: output_file, input_file
    type(failure_type), intent(out) :: failure

    if (c_in_study_folder(output_file//c_null_char) == 0) return
    call fail(failure, failure_input, input_file//': &output: file = '''//output_file//''' lies in the output '// &
              'folder of a study (it holds study.lock, index.journal or a study''s index.h5), whose files are the '// &
              'study''s; allowed: a path in another folder', input_file)
  end subroutine check_outside_studies

  !> The files a run of `output_file` from `input_file` writes or reads, each as protected_entry
  !> gives it: the input, the output, FILE.part, its spare FILE.part.spare, FILE.lock and the
  !> temporary names they pass through (.tmp, .kept: src/io/posix_files.c, hdf5_storage.c).
  function run_own_files(output_file, input_file) result(entries)
    character(len=*), intent(in) :: output_file, input_file
    character(len=:), allocatable :: entries

    entries = protected_entry(input_file, 'the input file')// &
              protected_entry(output_file, 'the output file (&output file of '//input_file//')')// &
              protected_entry(output_file//'.part', 'the output file as it is written')// &
              protected_entry(output_file//'.part.spare', 'the spare copy of the output file')// &
              protected_entry(output_file//'.lock', 'the lock of the output file')// &
              protected_entry(output_file//'.part.tmp', 'a temporary name of the output file')// &
              protected_entry(output_file//'.part.spare.tmp', 'a temporary name of the output file')// &
              protected_entry(output_file//'.part.kept', 'a temporary name of the output file')
  end function run_own_files

  !> A path and what it is, as the option checks take them (src/io/petsc_option_files.c): each on a line.
  pure function protected_entry(path, label) result(entry)
    character(len=*), intent(in) :: path, label
    character(len=:), allocatable :: entry

    entry = path//new_line('a')//label//new_line('a')
  end function protected_entry

  !> protected_entry of each path of `paths` (each on a line), all with the same `label`.
  pure function protected_entries(paths, label) result(entries)
    character(len=*), intent(in) :: paths, label
    character(len=:), allocatable :: entries
    integer :: start, length

    entries = ''
    start = 1
    do while (start <= len(paths))
      length = index(paths(start:), new_line('a')) - 1
      if (length < 0) length = len(paths) - start + 1
      if (length > 0) entries = entries//protected_entry(paths(start:start + length - 1), label)
      start = start + length + 1
    end do
  end function protected_entries

end module output_path
