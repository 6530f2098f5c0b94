!> The models the code offers, one line each in `registered_models`: the name &model model_name
!> selects (default: the paper's double pendulum), the maker of its scene (its namelist groups,
!> src/model/model_scene) and, if the model has one, the maker of its fused step
!> (src/scheme/condensed_step). Adding a model: its folder src/model/NAME/ and one line in the
!> submodule src/model/model_registry_lines.f90 (docs/development.md, Adding a model), the only
!> code outside a model's folder that uses the model's modules (tests/architecture/test_layers.py).
!> An edit of the lines recompiles that submodule alone, and the programs relink.
module model_registry
  use namelist_text, only: namelist_item, group_items, item_name
  use model_scene, only: scene
  use step_residual, only: step_problem
  use condensed_step, only: condensed_step_problem
  use failures, only: failure_type, fail, failure_input
  implicit none (type, external)
  private
  public :: select_scene, model_names, fused_step_of

  !> One model.
  type :: model_entry
    character(len=24) :: name = ''
    procedure(scene_maker), pointer, nopass :: make_scene => null()
    !> The model's fused step for a step problem; not associated: the generic step serves.
    procedure(fused_step_maker), pointer, nopass :: make_fused_step => null()
  end type model_entry

  abstract interface
    subroutine scene_maker(made)
      import :: scene
      class(scene), allocatable, intent(out) :: made
    end subroutine scene_maker

    !> The fused step of `problem` if it is this model's and the fused step covers the scheme and
    !> the active constraints (built); otherwise built = .false.
    subroutine fused_step_maker(problem, kernel, built)
      import :: step_problem, condensed_step_problem
      type(step_problem), intent(in) :: problem
      class(condensed_step_problem), allocatable, intent(out) :: kernel
      logical, intent(out) :: built
    end subroutine fused_step_maker
  end interface

  interface
    !> The registry, a line per model; the first is the default model (model_registry_lines).
    module function registered_models() result(entries)
      type(model_entry), allocatable :: entries(:)
    end function registered_models
  end interface

contains


  !> The names of the models, blank-separated.
  function model_names() result(names)
    character(len=:), allocatable :: names
    type(model_entry), allocatable :: entries(:)
    integer :: i

    allocate (entries, source=registered_models())
    names = trim(entries(1)%name)
    do i = 2, size(entries)
      names = names//' '//trim(entries(i)%name)
    end do
  end function model_names

  !> The scene of the model that &model model_name (in the text or the `extra` items) names;
  !> a failure (failure_input, origin model_name) if it names none.
  subroutine select_scene(text, origin, extra, selected, failure)
    character(len=*), intent(in) :: text, origin
    type(namelist_item), intent(in) :: extra(:)
    class(scene), allocatable, intent(out) :: selected
    type(failure_type), intent(out) :: failure
    type(namelist_item), allocatable :: items(:)
    type(model_entry), allocatable :: entries(:)
    character(len=64) :: name
    character(len=:), allocatable :: where, message
    integer :: i, stat

    stat = 0
    allocate (entries, source=registered_models())
    name = entries(1)%name
    where = origin
    call group_items(text, 'model', [character(len=24) :: 'model_name'], origin, items, extra)
    do i = 1, size(items)
      if (item_name(items(i)%item) /= 'model_name') cycle
      read (items(i)%item(index(items(i)%item, '=') + 1:), *, iostat=stat) name
      where = items(i)%origin
    end do
    if (stat == 0) then
      stat = 1
      do i = 1, size(entries)
        if (trim(name) /= trim(entries(i)%name)) cycle
        call entries(i)%make_scene(selected)
        stat = 0
      end do
    end if
    if (stat /= 0) then
      message = where//': &model: model_name = '''//trim(name)//''' is not allowed; allowed: '''//trim(entries(1)%name)//''''
      do i = 2, size(entries)
        message = message//', '''//trim(entries(i)%name)//''''
      end do
      call fail(failure, failure_input, message, 'model_name')
    end if
  end subroutine select_scene

  !> The fused step that `problem`'s model offers for it, if any (built = .false.: none).
  subroutine fused_step_of(problem, kernel, built)
    type(step_problem), intent(in) :: problem
    class(condensed_step_problem), allocatable, intent(out) :: kernel
    logical, intent(out) :: built
    type(model_entry), allocatable :: entries(:)
    integer :: i

    built = .false.
    allocate (entries, source=registered_models())
    do i = 1, size(entries)
      if (.not. associated(entries(i)%make_fused_step)) cycle
      call entries(i)%make_fused_step(problem, kernel, built)
      if (built) return
    end do
  end subroutine fused_step_of

end module model_registry
