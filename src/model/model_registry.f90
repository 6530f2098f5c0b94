!> The models the code offers, by the name &model model_name selects (default: the paper's
!> double pendulum). Adding a model: its modules in src/model (a generic_model, a scene with its
!> namelist groups) and one case below.
module model_registry
  use namelist_text, only: namelist_item, group_items, item_name
  use model_scene, only: scene
  use pendulum_scene, only: double_pendulum_scene, double_pendulum_name
  implicit none (type, external)
  private
  public :: select_scene, model_names

contains

  !> The names of the models, blank-separated.
  pure function model_names() result(names)
    character(len=:), allocatable :: names

    names = double_pendulum_name
  end function model_names

  !> The scene of the model that &model model_name (in the text or the `extra` items) names;
  !> stat /= 0 with a message if it names none.
  subroutine select_scene(text, origin, extra, selected, stat, message)
    character(len=*), intent(in) :: text, origin
    type(namelist_item), intent(in) :: extra(:)
    class(scene), allocatable, intent(out) :: selected
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: message
    type(namelist_item), allocatable :: items(:)
    character(len=64) :: name
    character(len=:), allocatable :: where
    integer :: i

    stat = 0
    message = ''
    name = double_pendulum_name
    where = origin
    call group_items(text, 'model', [character(len=24) :: 'model_name'], origin, items, extra)
    do i = 1, size(items)
      if (item_name(items(i)%item) /= 'model_name') cycle
      read (items(i)%item(index(items(i)%item, '=') + 1:), *, iostat=stat) name
      where = items(i)%origin
    end do
    select case (trim(name))
    case (double_pendulum_name)
      if (stat == 0) allocate (double_pendulum_scene :: selected)
    case default
      stat = 1
    end select
    if (stat /= 0) message = where//': &model: model_name = '''//trim(name)//''' is not allowed; allowed: ''' &
                             //model_names()//''''
  end subroutine select_scene

end module model_registry
