!> Where a continued run starts (-eme_continue; docs/faults.md, Continuing a run): the resume
!> record of the output file or of its FILE.part, checked against the input before anything is
!> copied or appended. Both time loops use it: the dense one (src/run/simulation) goes on from the
!> record's state, the split one (src/run/distributed_simulation) from the file's last snapshot,
!> at which its record stands.
module run_continuation
  use, intrinsic :: iso_fortran_env, only: real64
  use integrator_settings, only: step_count
  use run_config, only: run_configuration
  use resume_records, only: resume_record, read_resume_record
  use run_outcome, only: failure_input, failure_io
  use hdf5_files, only: check_file_integrity
  use filesystem, only: file_exists, copy_file
  use number_text, only: integer_text, fixed_text
  use effective_namelist, only: namelist_of_run
  use failures, only: failure_type
  implicit none (type, external)
  private
  public :: find_resume_record

contains

  !> The resume record of config's output file, or of FILE.part (the one further on, if both hold
  !> one), which FILE.part becomes a copy of. `kind` is '' when found; otherwise a run_outcome
  !> failure kind (failure_input, or failure_io if the copy fails) and `text` says why: the file
  !> holds a complete run or no record, was run with another input than t_end and max_steps, or
  !> has reached t_end (`chooses_time`: the integrator chooses its times) or its step count, or
  !> max_steps (the budget of the whole run, not of the continuation).
  subroutine find_resume_record(config, chooses_time, resume, kind, text)
    type(run_configuration), intent(in) :: config
    logical, intent(in) :: chooses_time
    type(resume_record), intent(out) :: resume
    character(len=:), allocatable, intent(out) :: kind, text
    type(resume_record) :: candidate
    character(len=:), allocatable :: status, stored, source, where, part
    character(len=:), allocatable :: unwritten   ! a .part whose run stopped at a failed write
    type(failure_type) :: reading, copying
    logical :: complete, any_file, beyond
    real(real64) :: t_end

    kind = failure_input
    text = ''
    part = config%output_file//'.part'
    t_end = config%integrator%t_end
    where = ' ('//config%input_file//', -eme_continue)'
    source = ''
    unwritten = ''
    complete = .false.
    if (file_exists(config%output_file)) then
      call read_resume_record(config%output_file, candidate, status, stored, reading)
      complete = .not. reading%failed() .and. status == 'complete'
      if (.not. reading%failed() .and. candidate%held .and. candidate%stopped_early) then
        resume = candidate
        source = config%output_file
      end if
    end if
    if (complete) then
      text = config%output_file//' holds a complete run: there is nothing to continue'//where// &
             '; allowed: the file of a run that stopped early'
      return
    end if
    if (file_exists(part)) then
      call read_resume_record(part, candidate, status, stored, reading)
      if (.not. reading%failed()) then
        if (index(status, 'incomplete: cannot write the output file') == 1) unwritten = part
      end if
      if (.not. reading%failed() .and. candidate%held .and. candidate%stopped_early) then
        if (len(source) == 0) then
          resume = candidate
          source = part
        else if (candidate%step > resume%step) then
          resume = candidate
          source = part
        end if
      end if
    end if
    if (len(source) == 0) then
      any_file = file_exists(config%output_file)
      if (.not. any_file) any_file = file_exists(part)
      if (len(unwritten) > 0) then
        text = unwritten//' keeps no step to continue from: its run stopped at a failed write before it kept '// &
               'one'//where//'; allowed: run it again without -eme_continue, with -eme_overwrite (or &output '// &
               'overwrite = .true.) to replace that file'
      else if (any_file) then
        text = config%output_file//' (or its .part) holds no run to continue (a run that stopped at a step it '// &
               'could not solve, a file of an older version, or not a run file)'//where//'; allowed: the file '// &
               'of a run stopped by a signal, a kill, its step budget or a failed write'
      else
        text = 'neither '//config%output_file//' nor '//part//' exists'//where// &
               '; allowed: the output file of a run that stopped early'
      end if
      return
    end if
    ! A damaged file is named as the input it is, before anything is copied or appended.
    call check_file_integrity(source, reading)
    if (reading%failed()) then
      text = source//': '//reading%message//'; it cannot be continued'//where//'; allowed: an undamaged file '// &
             'of a run that stopped early (or run afresh without -eme_continue)'
      return
    end if
    call read_resume_record(source, candidate, status, stored, reading)
    if (len(first_difference(stored, namelist_of_run(config))) > 0) then
      text = source//': its input differs from '//config%input_file//': '// &
             first_difference(stored, namelist_of_run(config))//where//'; allowed: the same input, with '// &
             '&integrator t_end and max_steps changed only'
      return
    end if
    ! The run must have somewhere to go: a later t_end (or, at fixed steps, more steps).
    if (chooses_time) then
      beyond = resume%time >= t_end*(1.0_real64 - 8*epsilon(1.0_real64))
    else
      beyond = resume%step >= step_count(config%integrator)
    end if
    if (beyond) then
      text = source//': its run reached t = '//fixed_text(resume%time, 6)//' s, and &integrator t_end = '// &
             fixed_text(t_end, 6)//' s in '//config%input_file//' leaves nothing to continue'//where// &
             '; allowed: a later t_end'
      return
    end if
    ! The step budget counts the whole run's steps, those before the continuation too.
    if (resume%step >= config%integrator%max_steps) then
      text = source//': its run took '//integer_text(resume%step)//' steps, and &integrator max_steps = '// &
             integer_text(config%integrator%max_steps)//' in '//config%input_file//', the budget of the whole '// &
             'run, leaves none to add'//where//'; allowed: max_steps > '//integer_text(resume%step)
      return
    end if
    if (source /= part) then
      call copy_file(source, part, copying)
      if (copying%failed()) then
        kind = failure_io
        text = "cannot copy '"//source//"' to '"//part//"' ("//config%input_file//'): '//copying%message
        return
      end if
    end if
    kind = ''
  end subroutine find_resume_record

  ! The first line (a field of the effective namelist, src/io/effective_namelist) in which `stored`
  ! and `given` differ, other than t_end and max_steps, as 'stored' against 'given'; '' if none.
  function first_difference(stored, given) result(text)
    character(len=*), intent(in) :: stored, given
    character(len=:), allocatable :: text
    character(len=:), allocatable :: a, b
    integer :: ia, ib

    text = ''
    ia = 1
    ib = 1
    do
      call next_line(stored, ia, a)
      call next_line(given, ib, b)
      if (a /= b) then
        text = "'"//trim(adjustl(a))//"' against '"//trim(adjustl(b))//"'"
        return
      end if
      if (ia > len(stored) .and. ib > len(given)) return
    end do

  contains

    ! The next line from position `at` that is not t_end or max_steps ('' at the end).
    subroutine next_line(text, at, line)
      character(len=*), intent(in) :: text
      integer, intent(inout) :: at
      character(len=:), allocatable, intent(out) :: line
      integer :: length

      line = ''
      do while (at <= len(text))
        length = index(text(at:), new_line('a')) - 1
        if (length < 0) length = len(text) - at + 1
        line = text(at:at + length - 1)
        at = at + length + 1
        if (index(adjustl(line), 't_end ') /= 1 .and. index(adjustl(line), 'max_steps ') /= 1) return
        line = ''
      end do
    end subroutine next_line
  end function first_difference

end module run_continuation
