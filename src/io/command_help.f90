!> What the drivers print for --help, and the integrator table: the input groups and their
!> fields come from the namelist tables, the integrators from the registry, so a new field,
!> integrator or model appears here by itself. (The output layout is printed by run_schema.)
module command_help
  use, intrinsic :: iso_fortran_env, only: real64
  use, intrinsic :: iso_c_binding, only: c_int, c_char, c_null_char
  use namelist_text, only: namelist_item
  use namelist_field, only: describe_group
  use model_registry, only: select_scene, model_names
  use model_scene, only: scene
  use failures, only: failure_type
  use run_config, only: run_configuration, integrator_fields, output_fields
  use study_config, only: study_fields, sweep_fields, max_sweep_values
  use integrator_registry, only: integrator_entry, registered_integrators, family_relaxation, keeps_structure
  use step_balances, only: balance_names
  implicit none (type, external)
  private
  public :: print_run_help, print_study_help, print_integrators, has_argument

  character(len=*), parameter :: exit_codes = &
    'Exit status: 0 complete, 2 bad input or usage, or another run writing the same output (nothing is '// &
    'written), 3 the run stopped early (its file is '// &
    'kept, marked incomplete, with the reason), 1 an I/O or PETSc error, 128 + N after signal N (SIGTERM: 143, '// &
    'SIGINT: 130; the file is kept, marked incomplete).'
  character(len=*), parameter :: petsc_options_text(4) = [character(len=100) :: &
    'PETSc options (one ''-'') reach every solver, before or after the input file: -snes_monitor,', &
    '-snes_converged_reason, -snes_test_jacobian, -pc_type lu, -ts_*, and the code''s own below (PETSc''s', &
    '-help lists them too). An argument after an option is its value unless it ends in .nml. Options', &
    'that nothing used are named in a warning at the end.']

  interface
    ! The code's own options, one by one (src/solver/petsc_options.c); 1 past the last.
    function c_option_help(i, name, value, help, size) result(past) bind(c, name='eme_option_help')
      import :: c_int, c_char
      integer(c_int), value :: i, size
      character(kind=c_char), intent(out) :: name(*), value(*), help(*)
      integer(c_int) :: past
    end function c_option_help
  end interface

contains

  !> Whether the command line holds one of `options` (anywhere).
  logical function has_argument(options)
    character(len=*), intent(in) :: options(:)
    character(len=256) :: argument
    integer :: i

    has_argument = .false.
    do i = 1, command_argument_count()
      call get_command_argument(i, argument)
      if (any(options == argument)) has_argument = .true.
    end do
  end function has_argument

  !> eme_run --help.
  subroutine print_run_help(unit)
    integer, intent(in) :: unit
    type(run_configuration), target :: defaults
    type(namelist_item) :: no_items(0)
    character(len=16), allocatable :: groups(:)
    character(len=:), allocatable :: names, name
    class(scene), allocatable, target :: scene_of_model
    integer :: g, i
    type(failure_type) :: failure

    write (unit, '(a)') 'usage: eme_run [PETSc options] FILE.nml [PETSc options]', &
      '       eme_run --help | -h | --version | --integrators | --output-schema', '', &
      'Integrates one scene of a GENERIC model (&model model_name: by default the thermoviscoelastic double', &
      'pendulum of Valdes y Beck & Betsch, PAMM 2023) and writes an HDF5 file (&output file; docs/output.md).', &
      'mpirun -n P eme_run FILE.nml splits a spring chain over P ranks, as eme_run does on one rank beyond 64', &
      'unknowns with an integrator that solves equations and beyond 1000 with any (the sparse path: EME or midpoint', &
      'in fixed or adaptive steps, the relaxed family, PETSc TS; its state in /snapshots: docs/output.md;', &
      '-eme_split and -eme_dense choose the path on one process).', '', &
      '  --help, -h        this text', &
      '  --version         the code''s version and those of PETSc, HDF5, MPI, SUNDIALS, LAPACK and the compiler', &
      '  --integrators     the integrator registry as a tab-separated table', &
      '  --output-schema   the run file''s rows as a tab-separated table (not listed: a split chain''s /snapshots', &
      '                    and its per-step production minima: docs/output.md, A chain''s file)', '', &
      (trim(petsc_options_text(i)), i = 1, size(petsc_options_text))
    call print_own_options(unit)
    write (unit, '(a)') '', exit_codes, '', &
      'Paths: an output path (&output file, a study''s output_dir) is relative to the current folder; a path', &
      'that names another input (a study''s base) is relative to the file that names it.', &
      'Steps: a fixed-step integrator takes ceiling(t_end/dt) steps of dt and ends at that multiple of dt', &
      '(20.1 s for t_end = 20, dt = 0.15; dt > t_end is refused); one that chooses its steps lands on t_end.', '', &
      'Input: a namelist file with the groups of its model and &integrator and &output; left-out fields', &
      'keep their defaults (for the double pendulum, the paper''s scene). The models: '//model_names()//'.'
    names = model_names()//' '
    do while (len_trim(names) > 0)
      names = adjustl(names)
      name = names(1:index(names, ' ') - 1)
      names = names(index(names, ' ') + 1:)
      write (unit, '(a)') '', 'Model '''//name//''' (&model model_name = '''//name//'''):'
      call select_scene("&model model_name = '"//name//"' /", 'defaults', no_items, scene_of_model, failure)
      call scene_of_model%group_names(groups)
      do g = 1, size(groups)
        call describe_group(unit, trim(groups(g)), scene_of_model%fields(trim(groups(g))))
      end do
    end do
    call select_scene(' ', 'defaults', no_items, defaults%scene, failure)
    write (unit, '(a)') '', 'Every model:'
    call describe_group(unit, 'integrator', integrator_fields(defaults))
    call describe_group(unit, 'output', output_fields(defaults))
    write (unit, '(a)') '', 'Integrators (&integrator scheme):'
    call print_integrators(unit, tabular=.false.)
  end subroutine print_run_help

  !> eme_ensemble --help.
  subroutine print_study_help(unit)
    integer, intent(in) :: unit
    character(len=4096), target :: base, output_dir
    character(len=16), target :: combine
    logical, target :: index_only
    integer, target :: repeats
    character(len=64), target :: field, texts(max_sweep_values)
    real(real64), target :: values(max_sweep_values)
    integer :: i

    base = ''
    output_dir = ''
    combine = 'product'
    index_only = .false.
    repeats = 1
    field = ''
    texts = ''
    values = 0.0_real64
    write (unit, '(a)') 'usage: mpirun -n P eme_ensemble [PETSc options] STUDY.nml [PETSc options]', &
      '       eme_ensemble --help | -h | --version | --integrators', '', &
      'Runs the cases of a parameter study on P ranks (one rank: no mpirun needed): every case is an', &
      'eme_run scene, the base scene with one value of each sweep. Each case writes output_dir/case_NNNNN.h5;', &
      'output_dir/index.h5 (/cases) records every case''s status and figures, and running the study again', &
      'redoes only what is not complete. Exit status: 0 every case was attempted (failed cases are results),', &
      '2 bad study input or usage, or another study running in output_dir (nothing is written),', &
      '1 the index or a case''s output could not be written,', &
      '128 + N after signal N (the study stopped cleanly; running it again goes on).', &
      'Paths: base is relative to the study file''s folder, output_dir (and its default results/<study name>)', &
      'to the current folder.', '', &
      (trim(petsc_options_text(i)), i = 1, size(petsc_options_text))
    call print_own_options(unit)
    write (unit, '(a)') '', &
      'Input: one &study group and one &sweep group per swept field (eme_run --help lists the fields):'
    call describe_group(unit, 'study', study_fields(base, output_dir, combine, index_only, repeats))
    call describe_group(unit, 'sweep', sweep_fields(field, values, texts))
  end subroutine print_study_help

  ! The code's own -eme_* options with their defaults and descriptions (the table PETSc's -help
  ! shows them from).
  subroutine print_own_options(unit)
    integer, intent(in) :: unit
    character(kind=c_char, len=512) :: name, value, help
    integer(c_int) :: i

    i = 0
    do while (c_option_help(i, name, value, help, len(name, kind=c_int)) == 0)
      write (unit, '(4x, a)') before_nul(name)//' '//before_nul(value)
      write (unit, '(t28, a)') before_nul(help)
      i = i + 1
    end do
  end subroutine print_own_options

  pure function before_nul(text) result(plain)
    character(len=*), intent(in) :: text
    character(len=:), allocatable :: plain

    plain = text(1:index(text, c_null_char) - 1)
  end function before_nul

  !> The integrator registry: as a tab-separated table (name, family, label, constraints,
  !> adaptive, description) or as lines for --help.
  subroutine print_integrators(unit, tabular)
    integer, intent(in) :: unit
    logical, intent(in) :: tabular
    type(integrator_entry), allocatable :: entries(:)
    character(len=*), parameter :: tab = achar(9)
    integer :: i

    allocate (entries, source=registered_integrators())
    if (tabular) write (unit, '(a)') 'name'//tab//'family'//tab//'label'//tab//'takes_constraints'//tab//'adaptive' &
      //tab//'error_control'//tab//'keeps_structure'//tab//'guarantees'//tab//'description'
    do i = 1, size(entries)
      associate (e => entries(i))
        if (tabular) then
          write (unit, '(a)') trim(e%name)//tab//trim(e%family)//tab//trim(e%label)//tab// &
            trim(merge('yes', 'no ', e%takes_constraints))//tab//trim(merge('yes', 'no ', e%adaptive))//tab// &
            trim(merge('yes', 'no ', e%error_control))//tab//trim(merge('yes', 'no ', keeps_structure(e)))//tab// &
            guarantee_names(e)//tab//trim(e%description)
        else
          write (unit, '(4x, a, t20, a)') trim(e%name), trim(e%description)
          write (unit, '(t20, a)') 'family '//trim(e%family)//'; '//trim(merge('takes constraints   ', &
            'no constraints      ', e%takes_constraints))//'; '//trim(steps_text(e))
        end if
      end associate
    end do
  end subroutine print_integrators

  ! The balances an integrator guarantees on every step, comma-separated ('none' if none).
  function guarantee_names(entry) result(names)
    type(integrator_entry), intent(in) :: entry
    character(len=:), allocatable :: names
    integer :: k

    names = ''
    do k = 1, size(entry%guarantees)
      if (entry%guarantees(k)) names = names//','//trim(balance_names(k))
    end do
    if (len(names) == 0) then
      names = 'none'
    else
      names = names(2:)
    end if
  end function guarantee_names

  ! How an integrator's steps are chosen, for --help.
  function steps_text(entry) result(text)
    type(integrator_entry), intent(in) :: entry
    character(len=:), allocatable :: text

    if (entry%adaptive) then
      text = 'adaptive steps'
    else if (entry%error_control .and. entry%family == family_relaxation) then
      text = 'fixed steps; with a tolerance, gamma outside its band rejects a step'
    else if (entry%error_control) then
      text = 'fixed steps; adaptive with a tolerance'
    else
      text = 'fixed steps'
    end if
  end function steps_text

end module command_help
