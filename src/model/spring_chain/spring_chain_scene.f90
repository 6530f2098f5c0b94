!> The spring chain's input as a scene of the model registry (docs/input.md, docs/formulation.md
!> section 10), served by both paths: &model and &initial (their values: spring_chain_input;
!> their tables: spring_chain_fields; the initial state: spring_chain_initial). &model is read
!> twice, as the pendulum's: first with arrays long enough for any chain, to learn N, the ends,
!> the dimension, the rung and the family (and &initial's file or perturbation), then with the
!> scene's own fields, a field of another chain being refused with the choice that excludes it. A
!> per-spring field takes exactly one value or as many as its parts; anything else is refused
!> naming the file, group, field and the allowed counts. An &initial file's datasets are read
!> through the scene's array reader and checked element by element. No constraints. The sparse,
!> distributed path takes the same scene (`distributed`).
module spring_chain_scene
  use, intrinsic :: iso_fortran_env, only: real64
  use namelist_text, only: namelist_item, joined
  use namelist_field, only: group_field, field_names
  use namelist_group, only: read_group, value_origin, given_origin
  use number_text, only: integer_text, reals_text
  use failures, only: failure_none, failure_type, fail, failure_input, failure_code_name
  use model_interface, only: generic_model
  use model_constraint, only: constraint_slot
  use model_scene, only: scene
  use distributed_model, only: distributed_system
  use spring_chain_sparse_run, only: sparse_chain_run, ts_schemes, step_schemes
  use spring_chain_relaxed_run, only: relaxed_chain_run
  use spring_chain_ts_run, only: ts_chain_run
  use thermo_variable_kinds, only: tau_entropy
  use spring_chain_spring, only: rung_elastic
  use spring_chain_layout, only: ends_fixed_fixed
  use spring_chain_input, only: chain_input, size_arrays, complete_defaults, unset, max_links
  use spring_chain_fields, only: chain_fields, choices_text
  use spring_chain_initial, only: initial_state, stiffness_problem, spring_ends_text
  implicit none (type, external)
  private
  public :: spring_chain_name, new_spring_chain_scene

  character(len=*), parameter :: spring_chain_name = 'spring_chain'

  !> The chain's input as a scene.
  type, extends(scene) :: chain_scene
    type(chain_input) :: input
  contains
    procedure :: group_names
    procedure :: fields
    procedure :: read
    procedure :: build
    procedure :: default_theta_r
    procedure :: constraint_count
    procedure :: without_temperatures
    procedure :: distributed
  end type chain_scene

  interface
    !> The &initial file's datasets q, p, gamma and theta (or a run file's snapshot) into the
    !> input, each checked; `where` is where the namelist sets file (spring_chain_scene_files).
    module subroutine read_initial_file(self, where, failure)
      class(chain_scene), intent(inout) :: self
      character(len=*), intent(in) :: where
      type(failure_type), intent(out) :: failure
    end subroutine read_initial_file

    !> The &model spring_file's per-spring arrays into the input, each checked
    !> (spring_chain_scene_files).
    module subroutine read_spring_file(self, text, origin, extra, failure)
      class(chain_scene), intent(inout), target :: self
      character(len=*), intent(in) :: text, origin
      type(namelist_item), intent(in) :: extra(:)
      type(failure_type), intent(out) :: failure
    end subroutine read_spring_file
  end interface

contains

  !> A scene of the chain with the defaults (the model registry's maker): N = 2 hanging in 3D.
  subroutine new_spring_chain_scene(made)
    class(scene), allocatable, intent(out) :: made
    type(chain_scene) :: defaults

    call size_arrays(defaults%input, defaults%input%springs(), defaults%input%links, defaults%input%dimension)
    call complete_defaults(defaults%input)
    defaults%input%span = unset      ! its default follows from the chain read (--help says which)
    allocate (made, source=defaults)
  end subroutine new_spring_chain_scene

  !> &model, &initial.
  pure subroutine group_names(self, names)
    class(chain_scene), intent(in) :: self
    character(len=16), allocatable, intent(out) :: names(:)

    names = [character(len=16) :: 'model', 'initial']
  end subroutine group_names

  !> The fields of one group (docs/input.md), for the scene's chain (spring_chain_fields).
  function fields(self, group) result(table)
    class(chain_scene), intent(in), target :: self
    character(len=*), intent(in) :: group
    type(group_field), allocatable :: table(:)

    table = chain_fields(self%input, group)
  end function fields

  !> Reads &model and &initial (a first pass for the choices, then the chain's own fields), checks
  !> every per-part count, reads an &initial file, and builds the initial state once to refuse
  !> one outside the model's domain.
  subroutine read(self, text, origin, extra, failure)
    class(chain_scene), intent(inout), target :: self
    character(len=*), intent(in) :: text, origin
    type(namelist_item), intent(in) :: extra(:)
    type(failure_type), intent(out) :: failure
    type(chain_input), target :: probe
    class(generic_model), allocatable :: model
    real(real64), allocatable :: z0(:)
    real(real64) :: stiffness
    character(len=:), allocatable :: where
    integer :: stat, a
    logical :: positions_given, by_perturbation

    ! First pass: every field, arrays long enough for any chain.
    call size_arrays(probe, max_links + 1, max_links, 3)
    call read_group(text, 'model', chain_fields(probe, 'model'), origin, failure, extra)
    if (failure%failed()) return
    call read_group(text, 'initial', chain_fields(probe, 'initial'), origin, failure, extra)
    if (failure%failed()) return
    associate (input => self%input)
      input%links = probe%links
      input%ends = probe%ends
      input%dimension = probe%dimension
      input%spring_law = probe%spring_law
      input%family = probe%family
      input%perturbation = probe%perturbation
      input%file = probe%file
      input%chosen = .true.
      input%span = unset   ! the default chain's was completed; this one's default is its own
      if (input%dimension == 2) input%gravity = [0.0_real64, -9.81_real64, 0.0_real64]
      if (input%dimension == 1) input%gravity = 0.0_real64
      call size_arrays(input, input%springs(), input%links, input%dimension)
      call refuse_other_parts(self, text, 'model', chain_fields(probe, 'model'), origin, extra, failure)
      if (failure%failed()) return
      call read_group(text, 'model', self%fields('model'), origin, failure, extra)
      if (failure%failed()) return
      if (allocated(input%from_file)) deallocate (input%from_file)
      if (len_trim(input%spring_file) > 0) call read_spring_file(self, text, origin, extra, failure)
      if (failure%failed()) return
      call refuse_other_parts(self, text, 'initial', chain_fields(probe, 'initial'), origin, extra, failure)
      if (failure%failed()) return
      call read_group(text, 'initial', self%fields('initial'), origin, failure, extra)
      if (failure%failed()) return
      call check_counts(self, text, origin, extra, failure)
      if (failure%failed()) return
      if (input%mode_number > input%links) then
        call fail(failure, failure_input, value_origin(text, 'initial', 'mode_number', origin, extra)// &
                  ': &initial: mode_number = '//integer_text(input%mode_number)//' is not allowed; allowed: 1 to '// &
                  'N = '//integer_text(input%links), 'mode_number')
        return
      end if
      positions_given = any(input%x < unset)
      call complete_defaults(input)
      where = value_origin(text, 'initial', 'file', origin, extra)
      if (len_trim(input%file) > 0) then
        call read_initial_file(self, where, failure)
        if (failure%failed()) return
      end if
      call stiffness_problem(input, a, stiffness)
      if (a > 0) then
        ! The one temperature by its index (h5py's from 0, the namelist's from 1), not the list.
        if (len_trim(input%file) > 0) then
          where = where//": &initial: file = '"//trim(input%file)//"': dataset theta["//integer_text(a - 1)//'] = '
        else if (size(input%theta) > 1) then
          where = value_origin(text, 'initial', 'theta', origin, extra)//': &initial: theta('//integer_text(a)//') = '
        else
          where = value_origin(text, 'initial', 'theta', origin, extra)//': &initial: theta = '
        end if
        call fail(failure, failure_input, where//reals_text(input%theta(a:a))//' is not allowed: spring '// &
                  integer_text(a)//'''s stiffness mu_eq(theta) of eq. (17) is '//reals_text([stiffness])// &
                  ' J; allowed: temperatures below theta_ref + mu_eq_const/mu_eq_slope', 'theta')
        return
      end if
      call initial_state(input, tau_entropy, model, z0, stat, a, by_perturbation)
      if (a > 0) then
        ! Named by the field that put the masses there: the perturbation's amplitude, x, or the
        ! default positions' span ('fixed-fixed') or stretch.
        if (by_perturbation) then
          where = 'amplitude'
        else if (positions_given) then
          where = 'x'
        else
          where = trim(merge('span   ', 'stretch', input%ends == ends_fixed_fixed))
        end if
        call fail(failure, failure_input, value_origin(text, merge('model  ', 'initial', where == 'span'), where, &
                                                       origin, extra)//': &'//trim(merge('model  ', 'initial', &
                                                       where == 'span'))//': '//where//' gives spring '// &
                  integer_text(a)//' ('//spring_ends_text(input, a, .false.)//') the length 0; allowed: masses '// &
                  'apart from each other and from the supports', where)
        return
      end if
    end associate
    if (stat /= failure_none) call fail(failure, failure_input, value_origin(text, 'initial', 'x', origin, extra)// &
      ': &initial: the initial state is not allowed (a spring''s potentials give '//failure_code_name(stat)// &
      '); allowed: masses apart from each other and the supports, temperatures in each spring''s domain', 'x')
  end subroutine read

  ! A field that another chain has (in `every_field`, not in the scene's table) is refused with
  ! the choices that exclude it, rather than as an unknown field.
  subroutine refuse_other_parts(self, text, group, every_field, origin, extra, failure)
    class(chain_scene), intent(in), target :: self
    character(len=*), intent(in) :: text, group, origin
    type(group_field), intent(in) :: every_field(:)
    type(namelist_item), intent(in) :: extra(:)
    type(failure_type), intent(out) :: failure
    type(group_field), allocatable :: own(:)
    character(len=:), allocatable :: where
    integer :: k

    own = self%fields(group)
    do k = 1, size(every_field)
      if (any(field_names(own) == every_field(k)%name)) cycle
      where = given_origin(text, group, every_field, origin, trim(every_field(k)%name), extra)
      if (len(where) == 0) cycle
      call fail(failure, failure_input, where//': &'//group//': '//trim(every_field(k)%name)//' is not a field of '// &
                choices_text(self%input, group)//'; allowed: '//joined(field_names(own), ', '), trim(every_field(k)%name))
      return
    end do
  end subroutine refuse_other_parts

  ! Every array field holds one value (the first element) or all of its elements, or none.
  subroutine check_counts(self, text, origin, extra, failure)
    class(chain_scene), intent(inout), target :: self
    character(len=*), intent(in) :: text, origin
    type(namelist_item), intent(in) :: extra(:)
    type(failure_type), intent(out) :: failure
    type(group_field), allocatable :: table(:)
    integer :: k, g, given, n
    character(len=8), parameter :: groups(2) = [character(len=8) :: 'model', 'initial']
    character(len=:), allocatable :: counts

    associate (input => self%input)
      do g = 1, 2
        table = self%fields(trim(groups(g)))
        do k = 1, size(table)
          if (.not. associated(table(k)%real_values) .or. table(k)%name == 'gravity') cycle
          n = size(table(k)%real_values)
          given = count(table(k)%real_values < unset)
          if (given == 0 .or. given == n) cycle
          if (given == 1 .and. table(k)%real_values(1) < unset .and. .not. any(table(k)%name == ['x', 'p'])) cycle
          select case (trim(table(k)%name))
          case ('x', 'p')
            counts = integer_text(n)//' (N = '//integer_text(input%links)//' masses times dimension = '// &
                     integer_text(input%dimension)//')'
          case ('mass')
            counts = '1 or '//integer_text(n)//' (N, links = '//integer_text(input%links)//')'
          case ('conductivity')
            counts = '1 or '//integer_text(n)//' (n_s - 1 links)'
          case default
            counts = '1 or '//integer_text(n)//' (n_s = '//integer_text(n)//' springs: links = '// &
                     integer_text(input%links)//", ends = '"//trim(input%ends)//"')"
          end select
          call fail(failure, failure_input, value_origin(text, trim(groups(g)), trim(table(k)%name), origin, extra)// &
                    ': &'//trim(groups(g))//': '//trim(table(k)%name)//' has '//integer_text(given)//' value'// &
                    trim(merge('s', ' ', given > 1))//'; allowed: '//counts//' values', trim(table(k)%name))
          return
        end do
      end do
    end associate
  end subroutine check_counts

  !> The chain in thermodynamic variable `variable` and its initial state (no constraints).
  subroutine build(self, variable, model, z0, constraints, failure)
    class(chain_scene), intent(in) :: self
    integer, intent(in) :: variable
    class(generic_model), allocatable, intent(out) :: model
    real(real64), allocatable, intent(out) :: z0(:)
    type(constraint_slot), allocatable, intent(out) :: constraints(:)
    type(failure_type), intent(out) :: failure
    integer :: stat

    allocate (constraints(0))
    call initial_state(self%input, variable, model, z0, stat)
    if (stat /= failure_none) call fail(failure, stat, '&initial: the initial state lies outside the model''s domain', &
                                        '&initial')
  end subroutine build

  !> theta_ref of spring 1 (the Lyapunov reference temperature unless &output sets theta_r).
  pure function default_theta_r(self) result(theta_r)
    class(chain_scene), intent(in) :: self
    real(real64) :: theta_r

    theta_r = self%input%theta_ref(1)
  end function default_theta_r

  !> None: the chain takes no constraints.
  pure integer function constraint_count(self)
    class(chain_scene), intent(in) :: self

    constraint_count = 0
  end function constraint_count

  !> Elastic springs have no thermodynamic variables: why, for run-level fields that need them.
  pure function without_temperatures(self) result(reason)
    class(chain_scene), intent(in) :: self
    character(len=:), allocatable :: reason

    reason = ''
    if (self%input%rung() == rung_elastic) reason = "spring_law = '"//trim(self%input%spring_law)// &
                                                    "' has no thermodynamic variables and no entropy"
  end function without_temperatures

  !> The chain on the sparse, distributed path: stepped by PETSc TS for a TS integrator
  !> (spring_chain_ts_run), by its own SNES for EME and the midpoint rule
  !> (spring_chain_sparse_run), else by a relaxed Runge-Kutta tableau (spring_chain_relaxed_run;
  !> what has none, or none the path can run, is refused there).
  subroutine distributed(self, scheme, system)
    class(chain_scene), intent(in) :: self
    character(len=*), intent(in) :: scheme
    class(distributed_system), allocatable, intent(out) :: system

    if (any(scheme == ts_schemes)) then
      allocate (ts_chain_run :: system)
    else if (any(scheme == step_schemes)) then
      allocate (sparse_chain_run :: system)
    else
      allocate (relaxed_chain_run :: system)
    end if
  end subroutine distributed

end module spring_chain_scene
