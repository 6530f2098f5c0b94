!> The lines of the model registry (src/model/model_registry): a model is one line here, its name
!> (&model model_name), the maker of its scene and, if it has one, the maker of its fused step.
!> A submodule, so that an edit recompiles this file alone.
submodule (model_registry) model_registry_lines
  use pendulum_scene, only: double_pendulum_name, new_double_pendulum_scene
  use pendulum_step_kernel, only: pendulum_fused_step
  use gas_containers_scene, only: gas_containers_name, new_gas_containers_scene
  use spring_chain_scene, only: spring_chain_name, new_spring_chain_scene
  use heat_bath_scene, only: heat_bath_name, new_heat_bath_scene
  implicit none (type, external)

contains

  module procedure registered_models
    entries = [model_entry(double_pendulum_name, new_double_pendulum_scene, pendulum_fused_step), &
               model_entry(gas_containers_name, new_gas_containers_scene), &
               model_entry(spring_chain_name, new_spring_chain_scene), &
               model_entry(heat_bath_name, new_heat_bath_scene)]
  end procedure registered_models

end submodule model_registry_lines
