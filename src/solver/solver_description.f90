!> What an integrator's solver used, as a run file records it (docs/output.md): its
!> settings as they stood after the options database was applied (e.g. SNES's absolute
!> tolerance after -snes_atol), and the legend of its per-step converged reason (the solver's
!> own numbering and names, e.g. PETSc's SNESConvergedReason).
module solver_description
  use, intrinsic :: iso_fortran_env, only: real64
  use, intrinsic :: iso_c_binding, only: c_int, c_char
  use failures, only: failure_type, fail, failure_library
  implicit none (type, external)
  private
  public :: setting, solver_report, text_setting, number_setting, integer_setting, no_solver, add_setting
  public :: set_petsc_reasons
  public :: reasons_snes, reasons_ts

  !> Families of PETSc converged reasons (src/solver/converged_reasons.c).
  integer, parameter :: reasons_snes = 1, reasons_ts = 2

  interface
    function c_converged_reasons(family, capacity, codes, names, names_size) result(count) &
        bind(c, name='eme_converged_reasons')
      import :: c_int, c_char
      integer(c_int), value :: family, capacity, names_size
      integer(c_int), intent(out) :: codes(*)
      character(kind=c_char), intent(out) :: names(*)
      integer(c_int) :: count
    end function c_converged_reasons
  end interface

  !> One setting: a text (a type name), or a number when `text` is not allocated.
  type :: setting
    character(len=32) :: name = ''
    character(len=:), allocatable :: text
    real(real64) :: value = 0.0_real64
    logical :: integer_valued = .false.   !! a count or a flag (written as an integer)
    character(len=8) :: units = '1'
  end type setting

  !> An integrator's solver: its settings and what its converged reasons mean.
  type :: solver_report
    type(setting), allocatable :: settings(:)
    integer, allocatable :: reason_codes(:)
    character(len=40), allocatable :: reason_names(:)
  end type solver_report

contains

  !> A text setting.
  function text_setting(name, text) result(item)
    character(len=*), intent(in) :: name, text
    type(setting) :: item

    item%name = name
    item%text = trim(text)
  end function text_setting

  !> A numeric setting with its units ('1' if none given).
  function number_setting(name, value, units) result(item)
    character(len=*), intent(in) :: name
    real(real64), intent(in) :: value
    character(len=*), intent(in), optional :: units
    type(setting) :: item

    item%name = name
    item%value = value
    if (present(units)) item%units = units
  end function number_setting

  !> An integrator that solves no nonlinear system (explicit stages): reason 0 on every step.
  !> An integer setting (an iteration limit, a lag, a depth).
  function integer_setting(name, value) result(item)
    character(len=*), intent(in) :: name
    integer, intent(in) :: value
    type(setting) :: item

    item%name = name
    item%value = real(value, real64)
    item%integer_valued = .true.
  end function integer_setting

  function no_solver(what) result(report)
    character(len=*), intent(in) :: what
    type(solver_report) :: report

    call add_setting(report, text_setting('name', 'none: '//what))
    report%reason_codes = [0]
    report%reason_names = [character(len=40) :: 'NO_NONLINEAR_SOLVE']
  end function no_solver

  !> The report's legend: PETSc's converged reasons of `family` (reasons_snes or reasons_ts) with
  !> PETSc's names. A failure (failure_library) if PETSc's table does not fit.
  subroutine set_petsc_reasons(report, family, failure)
    type(solver_report), intent(inout) :: report
    integer, intent(in) :: family
    type(failure_type), intent(out) :: failure
    integer(c_int) :: codes(64)
    character(kind=c_char, len=4096) :: names
    integer :: count, i, start, finish

    count = int(c_converged_reasons(int(family, c_int), int(size(codes), c_int), codes, names, len(names, kind=c_int)))
    if (count <= 0) then
      call fail(failure, failure_library, 'PETSc''s table of converged reasons does not fit', 'set_petsc_reasons')
      return
    end if
    report%reason_codes = int(codes(1:count))
    allocate (report%reason_names(count))
    start = 1
    do i = 1, count
      finish = start + index(names(start:), new_line('a')) - 2
      report%reason_names(i) = names(start:finish)
      start = finish + 2
    end do
  end subroutine set_petsc_reasons

  !> Appends `item` to the report's settings (explicitly: gfortran 12 mishandles array
  !> constructors of types with allocatable character components).
  subroutine add_setting(report, item)
    type(solver_report), intent(inout) :: report
    type(setting), intent(in) :: item
    type(setting), allocatable :: longer(:)
    integer :: i

    if (.not. allocated(report%settings)) allocate (report%settings(0))
    allocate (longer(size(report%settings) + 1))
    do i = 1, size(report%settings)
      longer(i)%name = report%settings(i)%name
      if (allocated(report%settings(i)%text)) call move_alloc(report%settings(i)%text, longer(i)%text)
      longer(i)%value = report%settings(i)%value
      longer(i)%integer_valued = report%settings(i)%integer_valued
      longer(i)%units = report%settings(i)%units
    end do
    longer(size(longer))%name = item%name
    if (allocated(item%text)) longer(size(longer))%text = item%text
    longer(size(longer))%value = item%value
    longer(size(longer))%integer_valued = item%integer_valued
    longer(size(longer))%units = item%units
    call move_alloc(longer, report%settings)
  end subroutine add_setting

end module solver_description
