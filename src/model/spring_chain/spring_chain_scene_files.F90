!> The files a chain's input names, read through the scene's array reader (model_scene): the
!> &initial file's state (datasets q, p, gamma, theta, or a run file's snapshot) and the &model
!> spring_file's per-spring arrays, each value checked before it is taken. A submodule of
!> spring_chain_scene, whose `read` calls them.
submodule (spring_chain_scene) spring_chain_scene_files
  use namelist_field, only: first_outside
  use spring_chain_initial, only: dataset_problem
  implicit none (type, external)

contains

  ! The datasets q, p, gamma (thermoviscoelastic) and theta (not elastic) of the &initial file,
  ! each checked (spring_chain_initial's dataset_problem) before it is taken. `where` is where
  ! the namelist sets file.
  module subroutine read_initial_file(self, where, failure)
    class(chain_scene), intent(inout) :: self
    character(len=*), intent(in) :: where
    type(failure_type), intent(out) :: failure
    character(len=*), parameter :: names(4) = [character(len=5) :: 'q', 'p', 'gamma', 'theta']
    character(len=:), allocatable :: prefix, problem, name, group
    real(real64), allocatable :: values(:)
    integer, allocatable :: shape(:)
    logical :: found
    integer :: k, row

    associate (input => self%input)
      prefix = where//": &initial: file = '"//trim(input%file)//"'"
      if (.not. allocated(self%arrays)) then
        call fail(failure, failure_input, prefix//': no reader of array files here', 'file')
        return
      end if
      call snapshot_row(self, prefix, group, row, failure)
      if (failure%failed()) return
      if (len(group) > 0) prefix = prefix//', snapshot '//integer_text(row)
      do k = 1, size(names)
        name = trim(names(k))
        if (len(group) > 0) then
          call self%arrays%read_array(trim(input%file), group//name, values, shape, found, failure, row)
        else
          call self%arrays%read_array(trim(input%file), name, values, shape, found, failure)
        end if
        if (failure%failed()) then
          failure%message = prefix//': '//failure%message//'; allowed: an HDF5 file with datasets '// &
                            'q, p, gamma and theta, or a run file with /snapshots (docs/input.md)'
          failure%code = failure_input
          return
        end if
        problem = dataset_problem(input, name, found, shape, values)
        if (len(problem) > 0) then
          call fail(failure, failure_input, prefix//': '//problem, 'file')
          return
        end if
        if (.not. found) cycle
        select case (name)
        case ('q')
          input%x = values
        case ('p')
          input%p = values
        case ('gamma')
          input%gamma = values
        case ('theta')
          input%theta = values
        end select
      end do
    end associate
  end subroutine read_initial_file

  ! The per-spring arrays of the &model spring_file: each 1-D dataset named as a real array field
  ! of &model holds all of that field's values (n_s, N for mass, n_s - 1 for conductivity), each
  ! finite and within the field's bounds; a field both there and in the namelist is refused, and
  ! so is a member of the file named as none of this chain's fields (a misspelt name would
  ! otherwise leave the field at its default). The fields read are noted (input%from_file) and
  ! leave the group's table.
  module subroutine read_spring_file(self, text, origin, extra, failure)
    class(chain_scene), intent(inout), target :: self
    character(len=*), intent(in) :: text, origin
    type(namelist_item), intent(in) :: extra(:)
    type(failure_type), intent(out) :: failure
    type(group_field), allocatable :: table(:)
    character(len=:), allocatable :: prefix, name
    real(real64), allocatable :: values(:)
    integer, allocatable :: shape(:)
    logical :: found
    integer :: k, bad, i

    prefix = value_origin(text, 'model', 'spring_file', origin, extra)//": &model: spring_file = '"// &
             trim(self%input%spring_file)//"'"
    if (.not. allocated(self%arrays)) then
      call fail(failure, failure_input, prefix//': no reader of array files here', 'spring_file')
      return
    end if
    allocate (self%input%from_file(0))
    table = self%fields('model')
    call refuse_other_members(self, prefix, table, failure)
    if (failure%failed()) return
    do k = 1, size(table)
      if (.not. associated(table(k)%real_values) .or. table(k)%name == 'gravity') cycle
      name = trim(table(k)%name)
      call self%arrays%read_array(trim(self%input%spring_file), name, values, shape, found, failure)
      if (failure%failed()) then
        failure%message = prefix//': '//failure%message//'; allowed: an HDF5 file of per-spring arrays (docs/input.md)'
        failure%code = failure_input
        return
      end if
      if (.not. found) cycle
      if (len(given_origin(text, 'model', table, origin, name, extra)) > 0) then
        call fail(failure, failure_input, prefix//': dataset '//name//' and the namelist''s '//name//' both give '// &
                  'it; allowed: one of them', name)
        return
      end if
      if (size(shape) /= 1 .or. size(values) /= size(table(k)%real_values)) then
        call fail(failure, failure_input, prefix//': dataset '//name//' has '//integer_text(size(values))// &
                  ' values in '//integer_text(size(shape))//' dimensions; allowed: a 1-D dataset of '// &
                  integer_text(size(table(k)%real_values))//' values, '//trim(table(k)%allowed), name)
        return
      end if
      bad = 0
      do i = size(values), 1, -1      ! the first value that is not finite
        if (.not. abs(values(i)) <= huge(1.0_real64)) bad = i
      end do
      if (bad == 0) bad = first_outside(table(k), values)
      if (bad > 0) then
        call fail(failure, failure_input, prefix//': dataset '//name//'['//integer_text(bad - 1)//'] = '// &
                  reals_text(values(bad:bad))//' is not allowed; allowed: '//trim(table(k)%allowed), name)
        return
      end if
      table(k)%real_values = values
      self%input%from_file = [self%input%from_file, table(k)%name]
    end do
  end subroutine read_spring_file

  ! Refuses a member of the spring_file that names none of the per-spring fields in `table`.
  subroutine refuse_other_members(self, prefix, table, failure)
    class(chain_scene), intent(in) :: self
    character(len=*), intent(in) :: prefix
    type(group_field), intent(in) :: table(:)
    type(failure_type), intent(out) :: failure
    character(len=256), allocatable :: members(:)
    character(len=:), allocatable :: allowed
    logical :: per_spring(size(table))
    integer :: k, j

    call self%arrays%member_names(trim(self%input%spring_file), members, failure)
    if (failure%failed()) then
      failure%message = prefix//': '//failure%message//'; allowed: an HDF5 file of per-spring arrays (docs/input.md)'
      failure%code = failure_input
      return
    end if
    do k = 1, size(table)
      per_spring(k) = associated(table(k)%real_values) .and. table(k)%name /= 'gravity'
    end do
    do k = 1, size(members)
      if (any(per_spring .and. table%name == members(k))) cycle
      allowed = ''
      do j = 1, size(table)
        if (per_spring(j)) allowed = allowed//', '//trim(table(j)%name)
      end do
      call fail(failure, failure_input, prefix//': '//trim(members(k))//' is not a per-spring field of this '// &
                'chain''s &model (spring_law = '''//trim(self%input%spring_law)//''', family = '''// &
                trim(self%input%family)//'''); allowed: members named '// &
                allowed(3:)//' (docs/input.md)', 'spring_file')
      return
    end do
  end subroutine refuse_other_members

  ! Where the &initial file's state lies: a run file's /snapshots (group 'snapshots/', `row` the
  ! snapshot asked for, -1 the last) or the file's root (group '', row -1). A snapshot asked of a
  ! file without /snapshots, or beyond its last, is refused.
  subroutine snapshot_row(self, prefix, group, row, failure)
    class(chain_scene), intent(in) :: self
    character(len=*), intent(in) :: prefix
    character(len=:), allocatable, intent(out) :: group
    integer, intent(out) :: row
    type(failure_type), intent(out) :: failure
    real(real64), allocatable :: times(:)
    integer, allocatable :: shape(:)
    logical :: found

    group = ''
    row = -1
    call self%arrays%read_array(trim(self%input%file), 'snapshots/time', times, shape, found, failure)
    if (failure%failed()) then
      failure%message = prefix//': '//failure%message
      failure%code = failure_input
      return
    end if
    if (.not. found) then
      call refuse_dense_run_file(self, prefix, failure)
      if (failure%failed()) return
    end if
    if (.not. found .and. self%input%snapshot /= -1) then
      call fail(failure, failure_input, prefix//': snapshot = '//integer_text(self%input%snapshot)//' is not '// &
                'allowed: the file has no /snapshots; allowed: snapshot with a run file that has them (the split '// &
                'path''s: docs/output.md)', 'snapshot')
    else if (found .and. self%input%snapshot >= size(times)) then
      call fail(failure, failure_input, prefix//': snapshot = '//integer_text(self%input%snapshot)//' is not '// &
                'allowed: the file has '//integer_text(size(times))//' snapshots; allowed: 0 to '// &
                integer_text(size(times) - 1)//', or -1 for the last', 'snapshot')
    else if (found .and. size(times) == 0) then
      call fail(failure, failure_input, prefix//': its /snapshots hold no snapshot yet; allowed: a run file '// &
                'with at least one', 'snapshot')
    else if (found) then
      group = 'snapshots/'
      row = self%input%snapshot
      if (row == -1) row = size(times) - 1
    end if
  end subroutine snapshot_row

  ! A run file of the dense path (/state rows, no /snapshots and no q) is refused by name: its
  ! state is a row of the integrator's unknowns, not the datasets q, p, gamma and theta.
  subroutine refuse_dense_run_file(self, prefix, failure)
    class(chain_scene), intent(in) :: self
    character(len=*), intent(in) :: prefix
    type(failure_type), intent(out) :: failure
    character(len=256), allocatable :: members(:)

    call self%arrays%member_names(trim(self%input%file), members, failure)
    if (failure%failed()) then
      failure%message = prefix//': '//failure%message
      failure%code = failure_input
      return
    end if
    if (any(members == 'state') .and. .not. any(members == 'q')) &
      call fail(failure, failure_input, prefix//' is a run file of the dense path (/state rows, no /snapshots); '// &
                'allowed: a split run''s file, which has /snapshots (run with -eme_split, or under mpirun: '// &
                'docs/output.md), or a file with datasets q, p, gamma and theta', 'file')
  end subroutine refuse_dense_run_file

end submodule spring_chain_scene_files
